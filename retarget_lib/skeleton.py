"""Stable public API: skeletons, the canonical 22 joints, and folding any joint set onto them.

``from retarget_lib.skeleton import to_canonical22`` is part of the suite's public contract
(`docs/architecture.md`, "Public contract"), so this module keeps those names importable whatever
moves inside the library. It only re-exports :mod:`retarget_lib.core.skeleton`,
:mod:`retarget_lib.core.canonical` (folding with an index map), :mod:`retarget_lib.io.rig_maps` (the
rig conventions' names) and :func:`retarget_lib.io.joint_maps.to_canonical22` (a motion on any named
joint set), where the code lives; the library itself imports from there.
"""

from .core.canonical import fit_global_rotations, fold_to_canonical22, unfold_from_canonical22
from .core.skeleton import (
    CANONICAL22,
    CANONICAL22_PARENTS,
    FOOT_CONTACT_JOINTS,
    HEIGHT_BONES,
    MIRROR22,
    MIRROR_POSITION,
    MIRROR_QUATERNION,
    J,
    JointSetError,
    Skeleton,
    canonical22_skeleton,
)
from .io.joint_maps import to_canonical22
from .io.rig_maps import RIG_MAPS, map_joints, strip_prefix

__all__ = [
    "CANONICAL22",
    "CANONICAL22_PARENTS",
    "FOOT_CONTACT_JOINTS",
    "HEIGHT_BONES",
    "MIRROR22",
    "MIRROR_POSITION",
    "MIRROR_QUATERNION",
    "J",
    "JointSetError",
    "Skeleton",
    "canonical22_skeleton",
    "RIG_MAPS",
    "fit_global_rotations",
    "fold_to_canonical22",
    "map_joints",
    "strip_prefix",
    "to_canonical22",
    "unfold_from_canonical22",
]
