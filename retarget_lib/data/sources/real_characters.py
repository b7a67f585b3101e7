"""The ``real-characters`` source: publicly released skinned humanoids in several rig conventions,
shipped in the repository under ``data/real_characters/`` (a validation set: real meshes, real
rigs).

Each file is a compact GLB made by ``tools/real_characters.py`` from its public source (textures,
materials, UVs, morph targets and animations dropped; the skin kept), listed in
``data_manifest.yaml`` under ``sources: real-characters: files:`` with its licence, origin,
sha256, rig convention and how it was converted. A character whose joint names the rig maps do not
cover ships a joint map beside it (``<name>.joints.yaml``, see
:func:`~retarget_lib.io.rig_maps.load_mapping_file`).

:func:`load_real_character` checks the file's sha256 and reads it with
:func:`~retarget_lib.io.gltf.load_gltf_rig`; :func:`measure_proportions` gives the rest-pose
proportions written to ``data/real_characters/proportions.csv``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ...core.character import Character
from ...core.measures import mesh_standing_height
from ...core.rig import Rig
from ...core.skeleton import J, Skeleton
from ...files import REPO_ROOT, DataError, sha256_file
from ...io.gltf import load_gltf_rig
from ..manifest import source

__all__ = [
    "SOURCE_ID",
    "REAL_DIR",
    "real_character_names",
    "real_character_entry",
    "real_character_path",
    "joint_map_path",
    "load_real_character",
    "measure_proportions",
    "PROPORTION_COLUMNS",
]

SOURCE_ID = "real-characters"
#: where the files are, relative to the repository root
REAL_DIR = REPO_ROOT / "data" / "real_characters"


def _files() -> dict[str, dict]:
    return dict(source(SOURCE_ID)["files"])


def real_character_names() -> list[str]:
    """The characters of the manifest, in its order (the file stems)."""
    return [Path(f).stem for f in _files()]


def real_character_entry(name: str) -> dict:
    """The manifest entry of one character (raises :class:`DataError` naming the known ones)."""
    files = {Path(f).stem: e for f, e in _files().items()}
    if name not in files:
        raise DataError(f"unknown real character {name!r}; known: {sorted(files)}")
    return files[name]


def real_character_path(name: str, verify: bool = True) -> Path:
    """Path of a character's GLB, checked against the manifest's sha256.

    Raises:
        DataError: unknown name, missing file or checksum mismatch.
    """
    entry = real_character_entry(name)
    path = REAL_DIR / f"{name}.glb"
    if not path.is_file():
        raise DataError(
            f"{SOURCE_ID}: {path} is missing (it is part of the repository: restore it with git)"
        )
    if verify and sha256_file(path) != entry["sha256"]:
        raise DataError(
            f"{SOURCE_ID}: {path} does not match its sha256 in data_manifest.yaml; restore it with "
            "git, or rebuild it with tools/real_characters.py and record the new sha256"
        )
    return path


def joint_map_path(name: str) -> Path | None:
    """The joint map shipped beside a character (``<name>.joints.yaml``), or None."""
    entry = real_character_entry(name)
    if not entry.get("joint_map"):
        return None
    path = REAL_DIR / entry["joint_map"]
    if not path.is_file():
        raise DataError(f"{SOURCE_ID}: {name}'s joint map {path} is missing")
    return path


def load_real_character(name: str, verify: bool = True) -> Rig:
    """A real character as a :class:`~retarget_lib.core.rig.Rig` (its own joints; ``.character()``
    is the canonical-22 character), with ``meta["convention"]`` and ``meta["license"]`` from the
    manifest."""
    entry = real_character_entry(name)
    rig = load_gltf_rig(real_character_path(name, verify), joint_map_path(name))
    rig.meta.update(convention=entry["convention"], license=entry["license"])
    return rig


#: the columns of ``proportions.csv`` (lengths are fractions of ``height_m``)
PROPORTION_COLUMNS = (
    "character",
    "convention",
    "height_m",
    "mesh_height_m",
    "leg",
    "thigh",
    "shin",
    "foot",
    "arm",
    "upper_arm",
    "forearm",
    "spine",
    "neck_head",
    "shoulder",
    "shoulder_width",
    "hip_width",
    "arm_angle_deg",
    "rest_pose",
)


def skeleton_proportions(skeleton: Skeleton) -> dict[str, float | str]:
    """Rest-pose proportions of a canonical-22 skeleton (the columns of ``proportions.csv`` but
    the mesh's height).

    ``height_m`` is the library's skeleton height ``H``
    (:meth:`~retarget_lib.core.skeleton.Skeleton.height`: the hips-to-head chain plus the left leg
    chain). Lengths, as fractions of ``H`` (left side): ``leg`` hip-knee-ankle, ``thigh``, ``shin``,
    ``foot`` ankle-toe, ``arm`` shoulder joint-elbow-wrist, ``upper_arm``, ``forearm``, ``spine``
    the Hips-Spine-Spine1-Spine2-Neck chain, ``neck_head`` Neck-Head, ``shoulder``
    Spine2-clavicle-shoulder joint, ``shoulder_width`` between the shoulder joints, ``hip_width``
    between the hip joints. ``arm_angle_deg``: how far the left upper arm hangs below the horizontal
    plane (0 = T-pose, about 45 = A-pose, 90 = arms down); ``rest_pose`` names it (T below 20, A
    below 60, else down).
    """
    p = skeleton.rest_positions()

    def d(a: str, b: str) -> float:
        return float(np.linalg.norm(p[J[a]] - p[J[b]]))

    h = skeleton.height()
    thigh, shin = d("LeftUpLeg", "LeftLeg"), d("LeftLeg", "LeftFoot")
    upper, fore = d("LeftArm", "LeftForeArm"), d("LeftForeArm", "LeftHand")
    spine = d("Hips", "Spine") + d("Spine", "Spine1") + d("Spine1", "Spine2") + d("Spine2", "Neck")
    arm_vec = p[J["LeftForeArm"]] - p[J["LeftArm"]]
    angle = float(np.degrees(np.arcsin(np.clip(-arm_vec[1] / np.linalg.norm(arm_vec), -1, 1))))
    return {
        "height_m": h,
        "leg": (thigh + shin) / h,
        "thigh": thigh / h,
        "shin": shin / h,
        "foot": d("LeftFoot", "LeftToeBase") / h,
        "arm": (upper + fore) / h,
        "upper_arm": upper / h,
        "forearm": fore / h,
        "spine": spine / h,
        "neck_head": d("Neck", "Head") / h,
        "shoulder": (d("Spine2", "LeftShoulder") + d("LeftShoulder", "LeftArm")) / h,
        "shoulder_width": d("LeftArm", "RightArm") / h,
        "hip_width": d("LeftUpLeg", "RightUpLeg") / h,
        "arm_angle_deg": angle,
        "rest_pose": "T" if angle < 20 else "A" if angle < 60 else "arms down",
    }


def measure_proportions(character: Character) -> dict[str, float | str]:
    """:func:`skeleton_proportions` of the character's skeleton, with ``mesh_height_m``, the rest
    mesh's extent along +Y (:func:`~retarget_lib.core.measures.mesh_standing_height`)."""
    return {
        "height_m": character.skeleton.height(),
        "mesh_height_m": mesh_standing_height(character.rest_vertices),
        **skeleton_proportions(character.skeleton),
    }


def check() -> tuple[bool, str]:
    """``(all present and intact, detail)`` for ``retarget data verify``."""
    bad = []
    names = real_character_names()
    for name in names:
        try:
            real_character_path(name)
            joint_map_path(name)
        except DataError as e:
            bad.append(str(e))
    if bad:
        return False, "; ".join(bad)
    return True, f"{len(names)} characters in {REAL_DIR}"
