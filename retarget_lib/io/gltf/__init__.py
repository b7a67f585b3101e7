"""Reading skinned characters and their animations from glTF 2.0 files (``.glb`` / ``.gltf``).

The GLB container and the JSON are parsed here (:func:`parse_gltf_bytes`), and every JSON field
the reader uses is type-checked before use (:data:`_GLTF_JSON`, through
:func:`~retarget_lib.io.untrusted.typed_json`); accessors are decoded with NumPy, each checked for
its role (type, component type, count within a limit) before anything is allocated. glTF's
conventions are the library's: metres, +Y up, the asset facing +Z, quaternions stored
``(x, y, z, w)`` (converted to wxyz on read).

What is read (:func:`load_gltf_rig`):

* **Skeleton** = the union of the joints of every skin used by a mesh node, as one tree (the
  nearest joint ancestor of a joint is its parent; one root: a second, smaller tree, a prop rigged
  to its own armature, is hung under the skeleton's nearest joint, :func:`_hang_small_trees`). Rest
  pose = the nodes' own transforms (the file as it shows without animation), including any non-joint
  ancestors such as an ``Armature`` node with a 0.01 scale: rest joint positions are world
  positions. Joints themselves must not scale (scale 1 within 1e-3, else
  :class:`~retarget_lib.errors.GLTFError`).
* **Mesh** = every triangle primitive of every skinned mesh node, merged, posed into the rest pose
  by the file's own skinning (``world(joint) @ inverseBindMatrix``; every inverse bind matrix must
  be an invertible affine matrix), so the rest vertices are what a viewer shows; then every mesh
  node without a skin under a joint (an eye parented to the head bone), weighted wholly to its
  nearest joint ancestor. Materials, UVs
  and morph targets are not read; a Draco- or meshopt-compressed mesh is refused by name.
* **Weights** = ``JOINTS_n`` / ``WEIGHTS_n`` (any number of sets) as a dense ``(V, J)`` array.
* **Joint map** onto the canonical 22 by :func:`~retarget_lib.io.rig_maps.map_joints`: the rig's
  names, a VRM file's humanoid bones (``VRM`` / ``VRMC_vrm`` extension), then a mapping file.

:func:`load_gltf_motion` samples an animation of the same file at a frame rate (the ``fps`` the
library wrote into the animation's ``extras``, else the rate of the keys when they lie on one
regular grid (:func:`key_rate`: an export with a key on every frame, as Mixamo's), else 30):
rotations and the root's translation (LINEAR = slerp / lerp, STEP, CUBICSPLINE = its key values);
other joints' translation and scale channels are not representable in a
:class:`~retarget_lib.core.motion.Motion` and are ignored.
Library rotations are relative to the rest pose: ``Q_j(t) = G_j(t) R_j^T`` with ``G_j`` the
animated and ``R_j`` the rest world rotation of joint ``j``.

:func:`load_gltf_animation` samples the same way from a file **with or without a skin** (a motion
exported "Without Skin": an armature and its animation): without a skinned mesh the joints are the
nodes the animation moves and every node below them (end sites), except mesh nodes and the pivot
helpers assimp inserts when it converts an FBX (``..._$AssimpFbx$_...``), whose transforms are
applied as those of any non-joint ancestor in the rest pose; in the animation they are folded into
the joint below, whose keys assimp bakes them into (:func:`.animation._fold_assimp_pivots`).

Bounds (:class:`~retarget_lib.errors.LimitError` naming the limit): file size 256 MiB, 100,000
nodes, 1000 joints, 2,000,000 vertices, 4,000,000 triangles, 1,000,000 keys per channel and
frames per animation, and the budgets of :mod:`~retarget_lib.io.untrusted` (1 GiB per decoded
array and for all the accessors of a file, 3,000,000 joint-frames per sampled motion, JSON
nesting 64); vertices and triangles are counted over all primitives, and each property of a node
may have one animation channel. External buffers only beside
the ``.gltf`` file (:func:`~retarget_lib.files.read_beside`: no ``..``, no absolute paths, no
URLs, no symbolic link leading out of its folder). Node hierarchies are walked iteratively (any
depth, linear time).

The package, by idea: :mod:`.document` (the container, the JSON, buffers and accessors),
:mod:`.transforms` (node transforms, joint trees, standing the rest pose up), :mod:`.skin` (the
skinned character) and :mod:`.animation` (sampling animations).
"""

from __future__ import annotations

from ...errors import GLTFError
from .animation import animation_from, key_rate, load_gltf_animation, load_gltf_motion, motion_from
from .document import (
    DEFAULT_FPS,
    MAX_FILE_BYTES,
    MAX_FRAMES,
    MAX_JOINTS,
    MAX_NODES,
    MAX_TRIANGLES,
    MAX_VERTICES,
    NoSkinError,
    parse_gltf_bytes,
)
from .skin import load_gltf_rig, rig_from

__all__ = [
    "GLTFError",
    "NoSkinError",
    "MAX_FILE_BYTES",
    "MAX_NODES",
    "MAX_JOINTS",
    "MAX_VERTICES",
    "MAX_TRIANGLES",
    "MAX_FRAMES",
    "DEFAULT_FPS",
    "key_rate",
    "load_gltf_rig",
    "load_gltf_motion",
    "load_gltf_animation",
    "parse_gltf_bytes",
    "rig_from",
    "motion_from",
    "animation_from",
]
