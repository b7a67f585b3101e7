"""File formats: BVH (any joint set) and the character shape ``.npz`` of public Mixamo preprocessing."""

from .bvh import BVHError, load_bvh, load_canonical_bvh, save_bvh
from .shape import ShapeError, load_shape_npz, save_shape_npz

__all__ = ["BVHError", "load_bvh", "load_canonical_bvh", "save_bvh", "ShapeError", "load_shape_npz", "save_shape_npz"]
