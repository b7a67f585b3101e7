"""Stable public API: skeletons, the canonical 22 joints, and folding any joint set onto them.

``from retarget_lib.skeleton import to_canonical22`` is part of the suite's public contract
(`docs/architecture.md`, "Public contract"), so this module keeps those names importable whatever moves inside
the library. It only re-exports :mod:`retarget_lib.core.skeleton` and
:mod:`retarget_lib.core.canonical`, where the code lives; the library itself imports from there.
"""

from .core.canonical import (BIOVISION_MAP, CMU_MAP, MIXAMO_MAP, NAME_MAPS, SMPLX_BODY_NAMES, SMPLX_MAP,
                             canonical_name_map, detect_convention, fit_global_rotations, from_canonical22,
                             strip_prefix, to_canonical22)
from .core.skeleton import (CANONICAL22, CANONICAL22_PARENTS, FOOT_CONTACT_JOINTS, HEIGHT_BONES, MIRROR22, J,
                            JointSetError, Skeleton, canonical22_skeleton)

__all__ = [
    "CANONICAL22", "CANONICAL22_PARENTS", "FOOT_CONTACT_JOINTS", "HEIGHT_BONES", "MIRROR22", "J", "JointSetError",
    "Skeleton", "canonical22_skeleton",
    "BIOVISION_MAP", "CMU_MAP", "MIXAMO_MAP", "NAME_MAPS", "SMPLX_BODY_NAMES", "SMPLX_MAP", "canonical_name_map",
    "detect_convention", "fit_global_rotations", "from_canonical22", "strip_prefix", "to_canonical22",
]
