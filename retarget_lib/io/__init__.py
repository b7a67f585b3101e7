"""File formats: BVH (any joint set), character shape ``.npz``, Collada ``.dae``, glTF export."""

from .bvh import BVHError, load_bvh, save_bvh

__all__ = ["BVHError", "load_bvh", "save_bvh"]
