"""Every file's joints onto the canonical 22: the one path of BVH, glTF/GLB/VRM, FBX, SMPL-X/AMASS
and shape files.

The rig conventions are detected (:func:`~retarget_lib.io.rig_maps.map_joints`, the one table
:data:`~retarget_lib.io.rig_maps.RIG_MAPS`), then a joint map
(:func:`~retarget_lib.io.rig_maps.load_mapping_file`) fixes or completes what was detected: a line
``LeftUpLeg: Thigh_L`` names the file's joint, ``Spine2: null`` says the rig has no such joint
(only :data:`~retarget_lib.core.virtual_joints.MAY_BE_ABSENT` may be absent). An absent joint is
inserted as a virtual joint (:mod:`retarget_lib.core.virtual_joints`: on the bone between its
neighbours, a toe at its foot with a zero-length bone) and the motion folded
(:func:`~retarget_lib.core.canonical.fold_to_canonical22`), so that the rest of the library always
sees the canonical 22.
"""

from __future__ import annotations

from ..core.canonical import fold_to_canonical22
from ..core.motion import Motion
from ..core.skeleton import Skeleton
from ..core.virtual_joints import MAY_BE_ABSENT
from .rig_maps import JointMapLike, map_joints, read_mapping

__all__ = ["present_map", "to_canonical22"]


def present_map(
    skeleton: Skeleton,
    mapping: JointMapLike = None,
    what: str = "the rig",
    mapping_source: str = "the joint map",
    convention: str | None = None,
) -> tuple[dict[int, int], str]:
    """The canonical joints a file's skeleton has.

    Args:
        skeleton: the file's skeleton (``J`` joints).
        mapping: a joint map file or its entries (null entries allowed for :data:`MAY_BE_ABSENT`),
            or None.
        what: the file, for messages.
        mapping_source: what to call ``mapping`` in messages when it is given as entries.
        convention: a key of :data:`~retarget_lib.io.rig_maps.RIG_MAPS` instead of detecting one.

    Returns:
        ``({file joint index: canonical index}, rig naming used)``.

    Raises:
        JointSetError: :func:`~retarget_lib.io.rig_maps.map_joints`' errors, naming ``what``.
    """
    entries, source = read_mapping(mapping, mapping_source)
    return map_joints(
        skeleton.joint_names,
        skeleton.parents,
        entries,
        what=what,
        mapping_source=source,
        may_be_absent=MAY_BE_ABSENT,
        convention=convention,
    )


def to_canonical22(
    motion: Motion,
    convention: str | None = None,
    mapping: JointMapLike = None,
    what: str | None = None,
) -> Motion:
    """Fold a motion on any named joint set onto the canonical 22 joints (a motion already on them
    is copied).

    Args:
        motion: a motion read from a file, ``rotations (T, J, 4)``.
        convention: a key of :data:`~retarget_lib.io.rig_maps.RIG_MAPS` instead of detecting one.
        mapping: a joint map file or its entries (module docstring), or None.
        what: the file, for messages (default: ``motion.meta["source"]``, else the motion's name).

    Returns:
        A new Motion on :data:`~retarget_lib.core.skeleton.CANONICAL22` (``rotations (T, 22, 4)``),
        same fps and frames; ``meta["folded_from"]`` names the rig naming used.

    Raises:
        JointSetError: joints that cannot be mapped, a bad joint map (:func:`present_map`).
    """
    if mapping is None and motion.skeleton.is_canonical22():
        return motion.copy()
    found, rig = present_map(
        motion.skeleton,
        mapping,
        what or str(motion.meta.get("source", motion.name)),
        convention=convention,
    )
    return fold_to_canonical22(motion, found, label=rig)
