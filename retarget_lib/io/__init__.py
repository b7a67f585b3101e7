"""File formats: BVH (any joint set), the character shape ``.npz`` of public Mixamo preprocessing,
glTF/GLB skinned characters and animations (read and write), binary FBX (write; reading FBX is
:mod:`retarget_lib.io.fbx`, the optional extra), rig name maps."""

from .bvh import BVHError, load_bvh, load_canonical_bvh, save_bvh
from .fbx_write import save_fbx
from .gltf import GLTFError, load_gltf_motion, load_gltf_rig
from .gltf_write import save_glb
from .shape import ShapeError, load_shape_npz, save_shape_npz

__all__ = [
    "BVHError",
    "load_bvh",
    "load_canonical_bvh",
    "save_bvh",
    "ShapeError",
    "load_shape_npz",
    "save_shape_npz",
    "GLTFError",
    "load_gltf_rig",
    "load_gltf_motion",
    "save_glb",
    "save_fbx",
]
