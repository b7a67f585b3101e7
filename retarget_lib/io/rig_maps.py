"""Joint-name maps of common character rigs onto the canonical 22 joints, and mapping files.

A rig's joints are matched by name, after removing a namespace prefix (``mixamorig:``,
``Armature|``), Rigify's ``DEF-`` prefix and letter case. The known rigs (:data:`RIG_MAPS`):

=============  ==========================================================================
rig            names (left side; right side alike)
=============  ==========================================================================
``mixamo``     ``mixamorig:Hips``, ``Spine``, ``Spine1``, ``Spine2`` ... ``LeftUpLeg`` (Mixamo)
``cmu``        ``LowerBack``, ``Spine``, ``Spine1`` ... (CMU BVH; see ``core.canonical``)
``biovision``  ``Ab``, ``Chest``, ``LeftHip`` ... (needs an inserted ``Spine2``: BVH only)
``smplx``      ``pelvis``, ``spine1`` ... ``left_hip``, ``left_collar`` (SMPL-X, mannequin-x)
``smpl``       ``Pelvis``, ``Spine1`` ... ``L_Hip``, ``L_Collar`` (SMPL / SMPL-H exports)
``vrm``        VRM humanoid bones ``hips``, ``spine``, ``chest``, ``upperChest``,
               ``leftUpperLeg`` ...; VRoid node names ``J_Bip_C_Hips``, ``J_Bip_L_UpperLeg``
``unreal``     ``pelvis``, ``spine_01``-``spine_03``, ``neck_01``, ``thigh_l``, ``calf_l``,
               ``clavicle_l``, ``upperarm_l`` ... (UE4/UE5 mannequin; ``root`` above is kept)
``rigify``     ``DEF-spine`` (hips), ``DEF-spine.001``-``.003``, ``DEF-spine.004`` (neck),
               ``DEF-spine.006`` (head), ``DEF-thigh.L``, ``DEF-shin.L``, ``DEF-upper_arm.L``
=============  ==========================================================================

:func:`map_joints` picks the rig that maps the most canonical joints, checks that the mapped
joints form the canonical tree (each canonical parent an ancestor in the file), and raises
:class:`~retarget_lib.core.skeleton.JointSetError` naming the joints it could not map. A mapping
file (:func:`load_mapping_file`, YAML or JSON ``{canonical name: file joint name}``) fixes or
completes the detected map. Joints left unmapped (fingers, twist bones, an Unreal ``root``) are
kept by the readers and writers: they follow their parent.
"""

from __future__ import annotations

import os
from typing import Mapping, Sequence

from ..core.canonical import NAME_MAPS, strip_prefix
from ..core.skeleton import CANONICAL22, CANONICAL22_PARENTS, J, JointSetError
from ..errors import short_repr
from ..files import read_yaml

__all__ = ["RIG_MAPS", "joint_key", "map_joints", "load_mapping_file"]

_SIDES = (("Left", "l", "L"), ("Right", "r", "R"))


def _sided(pattern: dict[str, str]) -> dict[str, str]:
    """Expand ``{"{Side}Arm": "upperarm_{s}"}``-style templates to both sides."""
    out = {}
    for side, s, S in _SIDES:
        for canon, name in pattern.items():
            out[canon.format(Side=side)] = name.format(s=s, S=S, side=side.lower(), Side=side)
    return out


def _limbs(leg: tuple[str, str, str, str], arm: tuple[str, str, str, str]) -> dict[str, str]:
    names = ("{Side}UpLeg", "{Side}Leg", "{Side}Foot", "{Side}ToeBase",
             "{Side}Shoulder", "{Side}Arm", "{Side}ForeArm", "{Side}Hand")
    return _sided(dict(zip(names, leg + arm)))


def _table(spine: tuple[str, ...], leg, arm) -> dict[str, str]:
    """``{file name: canonical name}`` from the six spine names and the limb templates."""
    canon_of = dict(zip(CANONICAL22[:6], spine)) | _limbs(leg, arm)
    return {v: k for k, v in canon_of.items()}


#: ``{rig: {file joint name: canonical name}}``; matched with :func:`joint_key`
RIG_MAPS: dict[str, dict[str, str]] = {
    **{k: dict(v) for k, v in NAME_MAPS.items() if k != "biovision"},
    "smpl": _table(("Pelvis", "Spine1", "Spine2", "Spine3", "Neck", "Head"),
                   ("{S}_Hip", "{S}_Knee", "{S}_Ankle", "{S}_Foot"),
                   ("{S}_Collar", "{S}_Shoulder", "{S}_Elbow", "{S}_Wrist")),
    "vrm": _table(("hips", "spine", "chest", "upperChest", "neck", "head"),
                  ("{side}UpperLeg", "{side}LowerLeg", "{side}Foot", "{side}Toes"),
                  ("{side}Shoulder", "{side}UpperArm", "{side}LowerArm", "{side}Hand")),
    "vroid": _table(("J_Bip_C_Hips", "J_Bip_C_Spine", "J_Bip_C_Chest", "J_Bip_C_UpperChest", "J_Bip_C_Neck",
                     "J_Bip_C_Head"),
                    ("J_Bip_{S}_UpperLeg", "J_Bip_{S}_LowerLeg", "J_Bip_{S}_Foot", "J_Bip_{S}_ToeBase"),
                    ("J_Bip_{S}_Shoulder", "J_Bip_{S}_UpperArm", "J_Bip_{S}_LowerArm", "J_Bip_{S}_Hand")),
    "unreal": _table(("pelvis", "spine_01", "spine_02", "spine_03", "neck_01", "head"),
                     ("thigh_{s}", "calf_{s}", "foot_{s}", "ball_{s}"),
                     ("clavicle_{s}", "upperarm_{s}", "lowerarm_{s}", "hand_{s}")),
    "rigify": _table(("spine", "spine.001", "spine.002", "spine.003", "spine.004", "spine.006"),
                     ("thigh.{S}", "shin.{S}", "foot.{S}", "toe.{S}"),
                     ("shoulder.{S}", "upper_arm.{S}", "forearm.{S}", "hand.{S}")),
}


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


def map_joints(names: Sequence[str], parents: Sequence[int], mapping: Mapping[str, str | None] | None = None,
               what: str = "the rig", mapping_source: str = "the mapping",
               may_be_absent: Sequence[str] = ()) -> tuple[dict[int, int], str]:
    """Map a rig's joints onto the canonical 22.

    Args:
        names: ``J`` joint names as in the file.
        parents: ``J`` parent indices (root ``-1``, parents first).
        mapping: ``{canonical name: file joint name}`` entries that replace or complete the
            detected map (a mapping file, or a VRM file's humanoid bones); ``None`` marks a
            canonical joint the rig does not have.
        what: the file, for messages.
        mapping_source: where ``mapping`` comes from (a joint map file), for messages.
        may_be_absent: canonical joints the caller can do without (it inserts them:
            :mod:`~retarget_lib.core.virtual_joints`); a ``None`` entry for another joint is an error.

    Returns:
        ``({file joint index: canonical index} for the canonical joints the rig has: all 22 but
        those ``mapping`` marks absent, rig name)``; the rig name is that of :data:`RIG_MAPS` that
        matched most, with ``"+mapping"`` when ``mapping`` changed it.

    Raises:
        JointSetError: canonical joints nothing maps to (named, with the file's joints and the
            hint to pass a mapping file), a mapping entry naming an unknown joint, or mapped
            joints that do not form the canonical tree.
    """
    scored = [(len(_match(names, table)), rig) for rig, table in RIG_MAPS.items()]
    rig = max(scored, key=lambda x: x[0])[1]
    found = _match(names, RIG_MAPS[rig])
    absent: set[int] = set()
    if mapping:
        keys = [joint_key(n) for n in names]
        for canon, file_name in mapping.items():
            if canon not in J:
                raise JointSetError(f"{what}: {mapping_source} names {short_repr(canon)}, not a canonical joint "
                                    f"({', '.join(CANONICAL22)})")
            if file_name is None:
                if canon not in may_be_absent:
                    can = f"only {', '.join(may_be_absent)} may be" if may_be_absent else "no joint may be"
                    raise JointSetError(f"{what}: {mapping_source} marks {canon} absent (null); {can} absent"
                                        + ("" if may_be_absent else " in this format"))
                found = {i: c for i, c in found.items() if c != J[canon]}
                absent.add(J[canon])
                continue
            if joint_key(file_name) not in keys:
                raise JointSetError(f"{what}: {mapping_source} maps {canon} to {short_repr(file_name)}, which is not a "
                                    "joint of the rig")
            found = {i: c for i, c in found.items() if c != J[canon]}
            found[keys.index(joint_key(file_name))] = J[canon]
        rig += "+mapping"
    with_mapping = f", with {mapping_source}" if mapping else ""
    missing = [CANONICAL22[c] for c in range(22) if c not in found.values() and c not in absent]
    if missing:
        null = f"; 'Name: null' marks one the rig does not have ({', '.join(may_be_absent)})" if may_be_absent else ""
        raise JointSetError(
            f"{what}: cannot map joints {missing} onto the canonical 22 (closest rig naming: {rig}{with_mapping}); "
            f"give a joint map (a YAML file with a line 'CanonicalName: file_joint_name' for each joint listed{null}; "
            f"--joint-map for a target, --source-joint-map for a source); the rig's joints: {_listed(names)}")
    file_of = {c: i for i, c in found.items()}
    for c, p in enumerate(CANONICAL22_PARENTS):
        while p in absent:  # an absent joint's children hang below its nearest present ancestor
            p = CANONICAL22_PARENTS[p]
        if c in absent or p < 0:
            continue
        if file_of[p] not in _ancestors(file_of[c], parents):
            raise JointSetError(f"{what}: {short_repr(names[file_of[c]])} (mapped to {CANONICAL22[c]}) is not below "
                                f"{short_repr(names[file_of[p]])} (mapped to {CANONICAL22[p]}) in the joint tree"
                                f"{with_mapping}")
    return found, rig


def _listed(names: Sequence[str], limit: int = 60) -> str:
    shown = ", ".join(short_repr(str(n)) for n in names[:limit])
    return f"[{shown}{f', ... ({len(names)} in all)' if len(names) > limit else ''}]"


def load_mapping_file(path: str | os.PathLike) -> dict[str, str | None]:
    """Read a joint mapping file: YAML or JSON, ``{canonical name: file joint name or null}``, read within
    the bounds of :func:`~retarget_lib.files.read_yaml` (1 MiB, nesting, aliases; a key given twice
    is an error, not a silently dropped line).

    Raises:
        JointSetError: malformed, not a mapping of strings to strings, a canonical name given
            twice, or two canonical joints mapped to one file joint.
        InputFileError: missing, empty or unreadable.
    """
    data = read_yaml(path, "joint mapping file", JointSetError)
    if not isinstance(data, dict) or not all(isinstance(k, str) and (v is None or isinstance(v, str))
                                             for k, v in data.items()):
        raise JointSetError(f"{path}: a joint mapping file holds lines 'CanonicalName: file_joint_name' (or "
                            "'CanonicalName: null' for a joint the rig does not have)")
    first: dict[str, str] = {}
    for canon, file_name in data.items():
        if file_name is None:
            continue
        if joint_key(file_name) in first:
            raise JointSetError(f"{path}: maps both {first[joint_key(file_name)]} and {canon} to "
                                f"{short_repr(file_name)}; a file joint can stand for one canonical joint")
        first[joint_key(file_name)] = canon
    return data
