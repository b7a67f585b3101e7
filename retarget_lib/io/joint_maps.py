"""Joint maps for rigs and motions read from any file.

A joint map (:func:`~retarget_lib.io.rig_maps.load_mapping_file`) names, for canonical joints the
automatic detection cannot find, the file's joint (``LeftUpLeg: Thigh_L``) or ``null``: the rig
has no such joint (only :data:`~retarget_lib.core.virtual_joints.MAY_BE_ABSENT` may be). The
absent joints become virtual joints (:mod:`retarget_lib.core.virtual_joints`), so that the rest of
the library always sees the canonical 22.
"""

from __future__ import annotations

from typing import Mapping


from ..core.canonical import to_canonical22
from ..core.motion import Motion
from ..core.skeleton import Skeleton
from ..core.virtual_joints import MAY_BE_ABSENT, with_virtual_joints
from .rig_maps import map_joints

__all__ = ["fold_with_map", "present_map"]

def present_map(skeleton: Skeleton, mapping: Mapping[str, str | None] | None, what: str,
                mapping_source: str = "the joint map") -> dict[int, int]:
    """``{file joint index: canonical index}`` of a rig's joints with a joint map (null entries
    allowed for :data:`MAY_BE_ABSENT`); :func:`~retarget_lib.io.rig_maps.map_joints`' errors."""
    found, _ = map_joints(skeleton.joint_names, skeleton.parents, mapping, what=what, mapping_source=mapping_source,
                          may_be_absent=MAY_BE_ABSENT)
    return found


def fold_with_map(motion: Motion, mapping: Mapping[str, str | None] | None, what: str,
                  mapping_source: str = "the joint map") -> Motion:
    """A file's motion on the canonical 22 through a joint map: detection completed by ``mapping``,
    absent joints inserted (:func:`with_virtual_joints`), then folded
    (:func:`~retarget_lib.core.canonical.to_canonical22`)."""
    augmented, full = with_virtual_joints(motion, present_map(motion.skeleton, mapping, what, mapping_source))
    return to_canonical22(augmented, joint_map=full)
