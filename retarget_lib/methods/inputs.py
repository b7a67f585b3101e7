"""What the files of ``retarget retarget`` are: a source motion and a target character, by suffix.

================  =====================================================================
source            read as
================  =====================================================================
``.bvh``          any BVH whose joints a rig convention or the joint map names
                  (:func:`~retarget_lib.io.joint_maps.to_canonical22`)
``.npz``          an SMPL-X / AMASS motion (:func:`~retarget_lib.io.amass.load_amass`)
``.glb/.gltf``    the first animation of a skinned glTF file (``.vrm`` too); its mesh is the source
                  character (hand contacts for ``contact``)
``.fbx``          the same through the optional FBX reader (``pip install -e .[fbx]``)
================  =====================================================================

================  =====================================================================
target            gives
================  =====================================================================
``.bvh``          the skeleton; the result is written on its joints, channels and unit
``.glb/.gltf``    skeleton, mesh and skin, all its joints (a GLB result keeps them); a
                  ``.vrm`` avatar (VRM 0.x or 1.0 humanoid bones name its joints)
``.fbx``          the same through the optional FBX reader
``.npz``          a character shape file (mesh), or an SMPL-X/AMASS file (the skeleton
                  of its betas)
a name            a synthetic character or ``mannequin-x`` (skeleton and mesh)
================  =====================================================================

Every file goes through the same detection of its rig convention and the same joint map
(``--source-joint-map`` / ``--joint-map``, :mod:`~retarget_lib.io.joint_maps`): a BVH, glTF/GLB/VRM,
FBX, shape ``.npz`` or SMPL-X/AMASS ``.npz`` alike (the last one's joints are the SMPL-X body
joints, :data:`~retarget_lib.io.amass.SMPLX_BODY_NAMES`).
"""

from __future__ import annotations

import os
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..core.canonical import fold_to_canonical22, stand_upright
from ..core.character import Character
from ..core.measures import mesh_standing_height
from ..core.motion import Motion
from ..core.rig import Rig
from ..core.skeleton import Skeleton
from ..data.sources.mannequin import load_mannequin
from ..data.synthetic.characters import CHARACTER_NAMES, make_character
from ..errors import InputFileError, RetargetInputError, RetargetWarning
from ..io import fbx
from ..io.amass import load_amass, smplx_skeleton
from ..io.bvh import load_bvh
from ..io.gltf import NoSkinError, load_gltf_animation, load_gltf_motion, load_gltf_rig
from ..io.joint_maps import present_map, to_canonical22
from ..io.shape import SHAPE_KEYS, ShapeError, load_shape_npz
from ..io.untrusted import npz_keys

__all__ = ["SOURCE_SUFFIXES", "TARGET_SUFFIXES", "Source", "Target", "load_source", "load_target"]

SOURCE_SUFFIXES = (".bvh", ".npz", ".glb", ".gltf", ".vrm", ".fbx")
TARGET_SUFFIXES = (".bvh", ".glb", ".gltf", ".vrm", ".fbx", ".npz")
#: glTF 2.0 files: a VRM avatar is a GLB with a humanoid extension (VRM 0.x or 1.0)
_GLTF = (".glb", ".gltf", ".vrm")
#: a character shorter than this (metres, :meth:`~retarget_lib.core.skeleton.Skeleton.height`) is
#: refused by name: no person or toy is; a unit or scale error in the file is (a 1.7e-7 m rig
#: retargets to noise that later checks would blame on the other file)
MIN_HEIGHT = 0.01


@dataclass
class Source:
    """A source clip.

    Attributes:
        motion: the canonical-22 motion at the file's frame rate.
        meta: the file's layout (length unit) for writing a named target in it.
        character: the source's skinned character when the file has a mesh (GLB/FBX), else None.
    """

    motion: Motion
    meta: dict
    character: Character | None


@dataclass
class Target:
    """A target character.

    Attributes:
        skeleton: its canonical-22 skeleton.
        character: its canonical-22 skinned character when a mesh is known, else None.
        rig: the character on its own joints (a GLB/FBX file's, else the canonical one) when a mesh
            is known: what a ``.glb`` / ``.fbx`` result is written with.
        bvh: the full target BVH motion (its joints, channels and unit) for a ``.bvh`` target.
        bvh_map: ``{BVH joint index: canonical index}`` of the joints it has (a ``.bvh`` target;
            else empty).
    """

    skeleton: Skeleton
    character: Character | None = None
    rig: Rig | None = None
    bvh: Motion | None = None
    bvh_map: dict[int, int] = field(default_factory=dict)


def _suffix(path: str | os.PathLike) -> str:
    return Path(path).suffix.lower()


def check_height(
    skeleton: Skeleton, path: str | os.PathLike, character: Character | None = None
) -> None:
    """Refuse a character shorter than :data:`MIN_HEIGHT` (or of no finite height), naming
    ``path``: its rest skeleton, and its rest mesh when it has one (the height the result's
    posture check, the contact thresholds and the PointNet input divide by)."""
    heights = [(skeleton.height(), "its rest skeleton")]
    if character is not None:
        heights.append((mesh_standing_height(character.rest_vertices), "its rest mesh"))
    for height, what in heights:
        if not height >= MIN_HEIGHT:
            raise InputFileError(
                f"{path}: the character is {height:.3g} m tall ({what}); at least "
                f"{MIN_HEIGHT} m is expected: check the file's scale and units"
            )


def load_source(path: str | os.PathLike, joint_map: str | os.PathLike | None = None) -> Source:
    """Read a source clip by suffix (module docstring).

    Args:
        path: ``.bvh``, ``.npz``, ``.glb``/``.gltf``/``.vrm`` or ``.fbx``.
        joint_map: a joint map file for joints the rig conventions do not name (docs/joint-maps.md).

    Raises:
        RetargetInputError: an unsupported suffix, a character under :data:`MIN_HEIGHT`, or the
            reader's error for a bad file or joint map.
    """
    source = _read_source(path, joint_map)
    check_height(source.motion.skeleton, path, source.character)
    return source


def _read_source(path: str | os.PathLike, joint_map: str | os.PathLike | None) -> Source:
    suffix = _suffix(path)
    if suffix == ".bvh":
        raw = load_bvh(path)
        return Source(
            stand_upright(to_canonical22(raw, mapping=joint_map, what=str(path))), raw.meta, None
        )
    if suffix == ".npz":
        return Source(load_amass(path, mapping=joint_map), {}, None)
    if suffix in _GLTF or suffix == ".fbx":
        try:
            motion, rig = (
                load_gltf_motion(path, mapping=joint_map)
                if suffix in _GLTF
                else fbx.load_fbx_motion(path, mapping=joint_map)
            )
        except NoSkinError:  # a clip downloaded "Without Skin": joints and animation only
            motion, ids = (
                load_gltf_animation(path, mapping=joint_map)
                if suffix in _GLTF
                else fbx.load_fbx_animation(path, mapping=joint_map)
            )
            return Source(
                fold_to_canonical22(motion, ids), {}, None
            )  # absent (null) joints inserted
        return Source(rig.motion_to_canonical(motion), {}, rig.character())
    raise InputFileError(
        f"{path}: cannot read a {suffix or 'suffix-less'} source; supported: "
        f"{', '.join(SOURCE_SUFFIXES)}"
    )


def _is_shape_npz(path: str | os.PathLike) -> bool:
    """Whether an ``.npz`` is a character shape file (else it is read as SMPL-X/AMASS)."""
    try:
        return set(SHAPE_KEYS) <= set(npz_keys(path, ShapeError))
    except (ShapeError, OSError):
        return True  # let the shape reader name the problem


def load_target(
    target: str,
    target_mesh: str | os.PathLike | None = None,
    joint_map: str | os.PathLike | None = None,
) -> Target:
    """Resolve ``--target`` (a file by suffix, or a character name) and ``--target-mesh``.

    Args:
        target: a ``.bvh``, ``.glb``/``.gltf``/``.vrm``, ``.fbx`` or ``.npz`` file, or a character
            name.
        target_mesh: a shape ``.npz`` for a target without a mesh.
        joint_map: a joint map file for the target file's joints (docs/joint-maps.md).

    Raises:
        RetargetInputError: an unknown name or suffix, a joint map for a character name, a
            character under :data:`MIN_HEIGHT`, or the reader's error for a bad file or joint map.
    """
    suffix = _suffix(target)
    if joint_map is not None and not suffix:
        raise RetargetInputError(
            f"{joint_map}: --joint-map is for a target file's joints; the character {target!r} "
            "is on the canonical 22 already"
        )
    if suffix == ".bvh":
        full = load_bvh(target)
        rest = full.slice(0, 1)
        bvh_map, naming = present_map(rest.skeleton, joint_map, str(target))
        out = Target(fold_to_canonical22(rest, bvh_map, naming).skeleton, bvh=full, bvh_map=bvh_map)
    elif suffix in _GLTF or suffix == ".fbx":
        rig = (
            load_gltf_rig(target, joint_map)
            if suffix in _GLTF
            else fbx.load_fbx_rig(target, joint_map)
        )
        character = rig.character()
        out = Target(character.skeleton, character, rig)
    elif suffix == ".npz":
        if _is_shape_npz(target):
            character = load_shape_npz(target, mapping=joint_map)
            out = Target(character.skeleton, character, Rig.from_character(character))
        else:
            out = Target(smplx_skeleton(load_amass(target).meta["betas"], joint_map, str(target)))
    elif suffix:
        raise InputFileError(
            f"{target}: cannot read a {suffix} target; supported: {', '.join(TARGET_SUFFIXES)} "
            "or a character name"
        )
    elif target == "mannequin-x" or target in CHARACTER_NAMES:
        character = load_mannequin() if target == "mannequin-x" else make_character(target)
        out = Target(character.skeleton, character, Rig.from_character(character))
    else:
        raise RetargetInputError(
            f"target {target!r} is neither a file ({', '.join(TARGET_SUFFIXES)}) nor a "
            f"character; characters: {', '.join(CHARACTER_NAMES)}, mannequin-x"
        )
    check_height(out.skeleton, target, out.character)
    if target_mesh is not None:
        character = load_shape_npz(target_mesh)
        check_height(character.skeleton, target_mesh, character)
        character = _fit_mesh(character, out.skeleton, target_mesh, target)
        out.character, out.rig = character, Rig.from_character(character)
    return out


#: a target mesh whose rest skeleton differs from the target's by more than this fraction of the
#: target's height is named in a warning (float32 exports and unit round trips move joints by
#: < 0.1 %; real exports of one character's mesh and motion files, by 1-2.5 cm)
MESH_WARN = 0.01
#: ... and refused beyond this one: a mesh of another character
MESH_LIMIT = 0.05


def _fit_mesh(character: Character, target_skeleton: Skeleton, target_mesh, target) -> Character:
    """A target mesh on the target's skeleton: refused when its rest joints differ from the
    target's by more than :data:`MESH_LIMIT` of the target's height, else rebound
    (:func:`rebind_mesh`), with a warning beyond :data:`MESH_WARN`."""
    height = target_skeleton.height()
    diff = float(np.abs(_root_relative(character.skeleton) - _root_relative(target_skeleton)).max())
    what = (
        f"its skeleton differs from the target {target} by {diff * 100:.1f} cm "
        f"({diff / height:.1%} of its height)"
    )
    if diff > MESH_LIMIT * height:
        raise RetargetInputError(
            f"{target_mesh}: {what}, more than {MESH_LIMIT:.0%}: a mesh of another character?"
        )
    if diff > MESH_WARN * height:
        warnings.warn(
            f"{target_mesh}: {what}; the mesh is rebound to the target's skeleton",
            RetargetWarning,
            stacklevel=2,
        )
    return rebind_mesh(character, target_skeleton)


def _root_relative(skeleton: Skeleton) -> np.ndarray:
    """``(J, 3)`` rest joint positions relative to the root (where a file puts its root differs)."""
    rest = skeleton.rest_positions()
    return rest - rest[0]


def rebind_mesh(character: Character, skeleton: Skeleton) -> Character:
    """``character``'s mesh bound to another rest skeleton with the same joints: each vertex moves
    with its joints' root-relative rest positions (``v + sum_j w_vj (p'_j - p_j)``, linear blend
    skinning of the translation between the two rests), faces and weights kept; the character's
    own root placement (its feet on ``y = 0``) is kept.

    Args:
        character: a canonical-22 character (mesh, weights, its own skeleton).
        skeleton: the canonical-22 skeleton to bind to (same joint names).
    """
    moved = _root_relative(skeleton) - _root_relative(character.skeleton)  # (22, 3)
    bound = skeleton.copy()
    bound.offsets[0] = character.skeleton.offsets[0]
    return Character(
        character.name,
        bound,
        character.rest_vertices + character.weights @ moved,
        character.faces,
        character.weights,
        character.bulk,
        dict(character.style),
    )
