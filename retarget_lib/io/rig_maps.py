"""The one table of rig naming conventions, the one detector of a rig's joints, and joint map files.

Every reader (BVH, glTF/GLB/VRM, FBX, SMPL-X/AMASS, character shape ``.npz``) finds a file's
canonical joints here (:func:`map_joints`, through :mod:`~retarget_lib.io.joint_maps` for motions).
Names are matched after removing a namespace prefix (``mixamorig:``, ``Armature|``,
:func:`strip_prefix`), Rigify's ``DEF-`` prefix and letter case (:func:`joint_key`). The known
conventions (:data:`RIG_MAPS`):

=============  ==========================================================================
rig            names (left side; right side alike)
=============  ==========================================================================
``mixamo``     the canonical names: ``mixamorig:Hips``, ``Spine``, ``Spine1``, ``Spine2``,
               ``LeftUpLeg`` ... (Mixamo)
``cmu``        ``Hips``, ``LowerBack``, ``Spine``, ``Spine1``, ``Neck``, ``Head`` ...
               (CMU, cgspeed BVH conversion; ``LHipJoint``, ``Neck1``, fingers are folded)
``biovision``  ``Hips``, ``Ab``, ``Chest``, ``LeftHip``, ``LeftCollar``, ``LeftShoulder`` (the
               upper arm) ... (Biovision/MotionBuilder 21 joints, ``Boxing_Toes.bvh``): no
               ``Spine2``, which is inserted halfway along Chest -> Neck
``smplx``      ``pelvis``, ``spine1`` ... ``left_hip``, ``left_collar`` (SMPL-X body joints:
               AMASS files, mannequin-x)
``smpl``       ``Pelvis``, ``Spine1`` ... ``L_Hip``, ``L_Collar`` (SMPL / SMPL-H exports)
``vrm``        VRM humanoid bones ``hips``, ``spine``, ``chest``, ``upperChest``,
               ``leftUpperLeg`` ... (a VRM file's humanoid extension names them too)
``vroid``      VRoid node names ``J_Bip_C_Hips``, ``J_Bip_L_UpperLeg`` ...
``unreal``     ``pelvis``, ``spine_01``-``spine_03``, ``neck_01``, ``thigh_l``, ``calf_l``,
               ``clavicle_l``, ``upperarm_l`` ... (UE4/UE5 mannequin; ``root`` above is kept)
``rigify``     ``DEF-spine`` (hips), ``DEF-spine.001``-``.003``, ``DEF-spine.004`` (neck),
               ``DEF-spine.006`` (head), ``DEF-thigh.L``, ``DEF-shin.L``, ``DEF-upper_arm.L``
=============  ==========================================================================

:func:`map_joints` picks the convention that maps the most canonical joints, lets a joint map
(:func:`load_mapping_file`, YAML or JSON ``{canonical name: file joint name or null}``) fix or
complete it, checks that the mapped joints form the canonical tree (each canonical parent an
ancestor in the file), and raises :class:`~retarget_lib.core.skeleton.JointSetError` naming the
file and every joint it could not map. Joints left unmapped (fingers, twist bones, an Unreal
``root``) are kept by the readers and writers: they follow their parent.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence

from ..core.skeleton import CANONICAL22, CANONICAL22_PARENTS, J, JointSetError
from ..errors import short_repr
from ..files import read_yaml

__all__ = [
    "RIG_MAPS",
    "JointMapLike",
    "strip_prefix",
    "joint_key",
    "map_joints",
    "load_mapping_file",
    "read_mapping",
]

#: what a reader takes as a joint map: a mapping file's path, ``{canonical name: file joint name or
#: None}``, or None (detection alone)
JointMapLike = str | os.PathLike | Mapping[str, str | None] | None

_SIDES = (("Left", "l", "L"), ("Right", "r", "R"))


def _sided(pattern: dict[str, str]) -> dict[str, str]:
    """Expand ``{"{Side}Arm": "upperarm_{s}"}``-style templates to both sides."""
    out = {}
    for side, s, S in _SIDES:
        for canon, name in pattern.items():
            out[canon.format(Side=side)] = name.format(s=s, S=S, side=side.lower(), Side=side)
    return out


def _table(
    spine: tuple[str | None, ...], leg: tuple[str, ...], arm: tuple[str, ...]
) -> dict[str, str]:
    """``{file name: canonical name}`` from the six spine names (Hips, Spine, Spine1, Spine2, Neck,
    Head; None for one the convention lacks) and the leg (UpLeg, Leg, Foot, ToeBase) and arm
    (Shoulder, Arm, ForeArm, Hand) templates of :func:`_sided`."""
    limbs = (
        "{Side}UpLeg",
        "{Side}Leg",
        "{Side}Foot",
        "{Side}ToeBase",
        "{Side}Shoulder",
        "{Side}Arm",
        "{Side}ForeArm",
        "{Side}Hand",
    )
    canon_of = {
        c: n for c, n in zip(CANONICAL22[:6], spine, strict=False) if n is not None
    } | _sided(dict(zip(limbs, leg + arm, strict=False)))
    return {v: k for k, v in canon_of.items()}


#: ``{rig: {file joint name: canonical name}}``, matched with :func:`joint_key`; a canonical joint
#: no name stands for is one the convention lacks (inserted where the reader may: Biovision's
#: Spine2)
RIG_MAPS: dict[str, dict[str, str]] = {
    "mixamo": {n: n for n in CANONICAL22},
    "cmu": _table(
        ("Hips", "LowerBack", "Spine", "Spine1", "Neck", "Head"),
        ("{Side}UpLeg", "{Side}Leg", "{Side}Foot", "{Side}ToeBase"),
        ("{Side}Shoulder", "{Side}Arm", "{Side}ForeArm", "{Side}Hand"),
    ),
    "biovision": _table(
        ("Hips", "Ab", "Chest", None, "Neck", "Head"),
        ("{Side}Hip", "{Side}Knee", "{Side}Ankle", "{Side}Toes"),
        ("{Side}Collar", "{Side}Shoulder", "{Side}Elbow", "{Side}Wrist"),
    ),
    "smplx": _table(
        ("pelvis", "spine1", "spine2", "spine3", "neck", "head"),
        ("{side}_hip", "{side}_knee", "{side}_ankle", "{side}_foot"),
        ("{side}_collar", "{side}_shoulder", "{side}_elbow", "{side}_wrist"),
    ),
    "smpl": _table(
        ("Pelvis", "Spine1", "Spine2", "Spine3", "Neck", "Head"),
        ("{S}_Hip", "{S}_Knee", "{S}_Ankle", "{S}_Foot"),
        ("{S}_Collar", "{S}_Shoulder", "{S}_Elbow", "{S}_Wrist"),
    ),
    "vrm": _table(
        ("hips", "spine", "chest", "upperChest", "neck", "head"),
        ("{side}UpperLeg", "{side}LowerLeg", "{side}Foot", "{side}Toes"),
        ("{side}Shoulder", "{side}UpperArm", "{side}LowerArm", "{side}Hand"),
    ),
    "vroid": _table(
        (
            "J_Bip_C_Hips",
            "J_Bip_C_Spine",
            "J_Bip_C_Chest",
            "J_Bip_C_UpperChest",
            "J_Bip_C_Neck",
            "J_Bip_C_Head",
        ),
        ("J_Bip_{S}_UpperLeg", "J_Bip_{S}_LowerLeg", "J_Bip_{S}_Foot", "J_Bip_{S}_ToeBase"),
        ("J_Bip_{S}_Shoulder", "J_Bip_{S}_UpperArm", "J_Bip_{S}_LowerArm", "J_Bip_{S}_Hand"),
    ),
    "unreal": _table(
        ("pelvis", "spine_01", "spine_02", "spine_03", "neck_01", "head"),
        ("thigh_{s}", "calf_{s}", "foot_{s}", "ball_{s}"),
        ("clavicle_{s}", "upperarm_{s}", "lowerarm_{s}", "hand_{s}"),
    ),
    "rigify": _table(
        ("spine", "spine.001", "spine.002", "spine.003", "spine.004", "spine.006"),
        ("thigh.{S}", "shin.{S}", "foot.{S}", "toe.{S}"),
        ("shoulder.{S}", "upper_arm.{S}", "forearm.{S}", "hand.{S}"),
    ),
}


def strip_prefix(name: str) -> str:
    """Remove a namespace prefix such as ``mixamorig:`` / ``mixamorig1:`` / ``Armature|``."""
    for sep in (":", "|"):
        if sep in name:
            name = name.rsplit(sep, 1)[1]
    return name


def joint_key(name: str) -> str:
    """The form names are matched in: namespace and ``DEF-`` prefixes removed, lower case."""
    key = strip_prefix(str(name)).lower()
    return key[4:] if key.startswith("def-") else key


def _match(names: Sequence[str], table: Mapping[str, str]) -> dict[int, int]:
    """``{file index: canonical index}``; the first (root-most) file joint wins a canonical name."""
    lookup = {joint_key(k): J[v] for k, v in table.items()}
    out: dict[int, int] = {}
    for i, n in enumerate(names):
        c = lookup.get(joint_key(n))
        if c is not None and c not in out.values():
            out[i] = c
    return out


def _ancestors(j: int, parents: Sequence[int]) -> set[int]:
    out = set()
    while parents[j] >= 0:
        j = parents[j]
        out.add(j)
    return out


def _detect(names: Sequence[str], convention: str | None, what: str) -> tuple[str, dict[int, int]]:
    """The convention of :data:`RIG_MAPS` that maps the most canonical joints of ``names`` (the
    first in the table's order on a tie), or ``convention``, and its ``{file index: canonical
    index}``."""
    if convention is not None:
        if convention not in RIG_MAPS:
            raise JointSetError(
                f"{what}: unknown joint-name convention {short_repr(convention)}; known: "
                f"{', '.join(RIG_MAPS)}"
            )
        return convention, _match(names, RIG_MAPS[convention])
    matches = {rig: _match(names, table) for rig, table in RIG_MAPS.items()}
    rig = max(matches, key=lambda r: len(matches[r]))
    return rig, matches[rig]


def map_joints(
    names: Sequence[str],
    parents: Sequence[int] | None,
    mapping: Mapping[str, str | None] | None = None,
    what: str = "the rig",
    mapping_source: str = "the mapping",
    may_be_absent: Sequence[str] = (),
    convention: str | None = None,
) -> tuple[dict[int, int], str]:
    """Map a rig's joints onto the canonical 22: the one detector.

    Args:
        names: ``J`` joint names as in the file.
        parents: ``J`` parent indices (root ``-1``, parents first), or None for a file that has no
            tree of its own (a shape ``.npz``: its 22 rows are the canonical tree); then the tree
            is not checked.
        mapping: ``{canonical name: file joint name}`` entries that replace or complete the
            detected map (a joint map, or a VRM file's humanoid bones); ``None`` marks a canonical
            joint the rig does not have.
        what: the file, for messages.
        mapping_source: where ``mapping`` comes from (a joint map file), for messages.
        may_be_absent: canonical joints the caller can do without (it inserts them:
            :mod:`~retarget_lib.core.virtual_joints`); a ``None`` entry for another joint is an
            error, and so is a convention lacking another one.
        convention: a key of :data:`RIG_MAPS` to use instead of detecting one.

    Returns:
        ``({file joint index: canonical index} for the canonical joints the rig has, rig name)``:
        all 22 but those ``mapping`` marks absent or the convention lacks (Biovision's Spine2)
        when they may be absent; the rig name is the convention of :data:`RIG_MAPS` used, with
        ``"+mapping"`` when ``mapping`` changed it.

    Raises:
        JointSetError: naming ``what``: an unknown ``convention``; canonical joints nothing maps to
            (all of them, with the file's joints and the hint to pass a joint map; a joint the
            mapping took from another canonical joint is named as the duplicate), a mapping entry
            naming an unknown joint or marking a needed one absent, or mapped joints that do not
            form the canonical tree.
    """
    rig, found = _detect(names, convention, what)
    lacks = {J[c] for c in CANONICAL22 if c not in RIG_MAPS[rig].values()}
    absent = {c for c in lacks if CANONICAL22[c] in may_be_absent}
    taken: dict[
        int, tuple[str, str]
    ] = {}  # canonical joint -> (file joint, the canonical joint given it)
    if mapping:
        keys = [joint_key(n) for n in names]
        for canon, file_name in mapping.items():
            if canon not in J:
                raise JointSetError(
                    f"{what}: {mapping_source} names {short_repr(canon)}, not a canonical joint "
                    f"({', '.join(CANONICAL22)})"
                )
            found = {i: c for i, c in found.items() if c != J[canon]}
            taken.pop(J[canon], None)
            if file_name is None:
                if canon not in may_be_absent:
                    can = (
                        f"only {', '.join(may_be_absent)} may be"
                        if may_be_absent
                        else "no joint may be"
                    )
                    raise JointSetError(
                        f"{what}: {mapping_source} marks {canon} absent (null); {can} absent"
                        + ("" if may_be_absent else " in this format")
                    )
                absent.add(J[canon])
                continue
            if joint_key(file_name) not in keys:
                raise JointSetError(
                    f"{what}: {mapping_source} maps {canon} to {short_repr(file_name)}, which is "
                    "not a "
                    "joint of the rig"
                )
            i = keys.index(joint_key(file_name))
            if i in found:  # the joint stood for another canonical joint
                taken[found[i]] = (names[i], canon)
            found[i] = J[canon]
            absent.discard(J[canon])
        rig += "+mapping"
    with_mapping = f", with {mapping_source}" if mapping else ""
    missing = [CANONICAL22[c] for c in range(22) if c not in found.values() and c not in absent]
    if missing:
        null = (
            f"; 'Name: null' marks one the rig does not have ({', '.join(may_be_absent)})"
            if may_be_absent
            else ""
        )
        dup = "".join(
            f"; {short_repr(n)} stood for {CANONICAL22[c]} but {mapping_source} maps {canon} to it "
            f"(two canonical joints on one bone)"
            for c, (n, canon) in taken.items()
            if CANONICAL22[c] in missing
        )
        raise JointSetError(
            f"{what}: cannot map joints {missing} onto the canonical 22 (closest rig naming: "
            f"{rig}{with_mapping})"
            f"{dup}; "
            "give a joint map (a YAML file with a line 'CanonicalName: file_joint_name' for each "
            f"joint listed{null}; "
            "--joint-map for a target, --source-joint-map for a source); the rig's joints: "
            f"{_listed(names)}"
        )
    if parents is not None:
        _check_tree(names, parents, found, absent, what, with_mapping)
    return found, rig


def _check_tree(
    names: Sequence[str],
    parents: Sequence[int],
    found: Mapping[int, int],
    absent: set[int],
    what: str,
    with_mapping: str,
) -> None:
    """Raise :class:`JointSetError` unless each mapped joint is below its canonical parent's joint
    (an absent parent's: its nearest present ancestor's)."""
    file_of = {c: i for i, c in found.items()}
    for c, p in enumerate(CANONICAL22_PARENTS):
        while p in absent:  # an absent joint's children hang below its nearest present ancestor
            p = CANONICAL22_PARENTS[p]
        if c in absent or p < 0:
            continue
        if file_of[p] not in _ancestors(file_of[c], parents):
            raise JointSetError(
                f"{what}: {short_repr(names[file_of[c]])} (mapped to {CANONICAL22[c]}) is not "
                "below "
                f"{short_repr(names[file_of[p]])} (mapped to {CANONICAL22[p]}) in the joint tree"
                f"{with_mapping}"
            )


def _listed(names: Sequence[str], limit: int = 60) -> str:
    shown = ", ".join(short_repr(str(n)) for n in names[:limit])
    return f"[{shown}{f', ... ({len(names)} in all)' if len(names) > limit else ''}]"


def load_mapping_file(path: str | os.PathLike) -> dict[str, str | None]:
    """Read a joint mapping file: YAML or JSON, ``{canonical name: file joint name or null}``, read
    within the bounds of :func:`~retarget_lib.files.read_yaml` (1 MiB, nesting, aliases; a key given
    twice is an error, not a silently dropped line).

    Raises:
        JointSetError: malformed, not a mapping of strings to strings, a canonical name given
            twice, or two canonical joints mapped to one file joint (both named).
        InputFileError: missing, empty or unreadable.
    """
    data = read_yaml(path, "joint mapping file", JointSetError)
    if not isinstance(data, dict) or not all(
        isinstance(k, str) and (v is None or isinstance(v, str)) for k, v in data.items()
    ):
        raise JointSetError(
            f"{path}: a joint mapping file holds lines 'CanonicalName: file_joint_name' (or "
            "'CanonicalName: null' for a joint the rig does not have)"
        )
    first: dict[str, str] = {}
    for canon, file_name in data.items():
        if file_name is None:
            continue
        if joint_key(file_name) in first:
            raise JointSetError(
                f"{path}: maps both {first[joint_key(file_name)]} and {canon} to "
                f"{short_repr(file_name)}; a file joint can stand for one canonical joint"
            )
        first[joint_key(file_name)] = canon
    return data


def read_mapping(
    mapping: JointMapLike,
    default_source: str = "the mapping",
) -> tuple[dict[str, str | None] | None, str]:
    """A joint map's entries and what to call it in messages.

    Args:
        mapping: a joint map file's path (read by :func:`load_mapping_file`), its entries
            ``{canonical name: file joint name or None}``, or None.
        default_source: what to call entries given directly.

    Returns:
        ``(entries or None, "the joint map <path>" or default_source)``.

    Raises:
        JointSetError, InputFileError: :func:`load_mapping_file`'s.
    """
    if isinstance(mapping, (str, os.PathLike)):
        return load_mapping_file(mapping), f"the joint map {mapping}"
    return (None if mapping is None else dict(mapping)), default_source
