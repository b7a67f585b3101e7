"""``mixamo-local``: a reviewer's own Mixamo download.

Layout (``$RETARGET_MIXAMO``, default ``data/mixamo``; see ``data_manifest.yaml``)::

    <root>/<Character>/shape.npz        rest_vertices, rest_faces, skinning_weights, skeleton, joint_names
    <root>/<Character>/<Motion>.bvh     Blender-exported, `mixamorig:` prefix, fingers, *_End sites, cm
    <root>/<Character>/<Character>.dae  optional Collada export

:mod:`retarget_lib.data.sources.mixamo_fixture` writes synthetic characters in exactly that layout.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, field
from pathlib import Path

from ...core.canonical import to_canonical22
from ...core.character import Character
from ...core.motion import Motion
from ...files import DataError, sha256_file
from ...io.bvh import load_bvh
from ...io.shape import load_shape_npz

SHAPE_FILE = "shape.npz"


@dataclass
class MixamoCharacterFolder:
    """One character folder found by :func:`scan_mixamo_folder`.

    Attributes:
        name: folder name (the character).
        shape: path of ``shape.npz`` or ``None`` if absent.
        motions: motion name -> BVH path.
        collada: path of a ``.dae`` file or ``None``.
    """

    name: str
    shape: Path | None
    motions: dict[str, Path] = field(default_factory=dict)
    collada: Path | None = None


def scan_mixamo_folder(root: str | Path) -> list[MixamoCharacterFolder]:
    """List the characters and motions in a ``mixamo-local`` folder.

    Raises:
        DataError: if ``root`` is missing or holds no character folder with BVH files.
    """
    root = Path(root)
    if not root.is_dir():
        raise DataError(f"mixamo-local folder {root} does not exist; set RETARGET_MIXAMO "
                        "(layout: <Character>/shape.npz + <Character>/<Motion>.bvh)")
    found = []
    for folder in sorted(p for p in root.iterdir() if p.is_dir()):
        bvhs = sorted(folder.glob("*.bvh"))
        if not bvhs:
            continue
        shape = folder / SHAPE_FILE
        dae = sorted(folder.glob("*.dae"))
        found.append(MixamoCharacterFolder(folder.name, shape if shape.exists() else None,
                                           {p.stem: p for p in bvhs}, dae[0] if dae else None))
    if not found:
        raise DataError(f"no <Character>/<Motion>.bvh found under {root}")
    return found


def load_mixamo_motion(path: str | Path, fps: float | None = 30.0) -> Motion:
    """Load a Mixamo BVH (any prefix, fingers, end sites) folded to the canonical 22 joints.

    Args:
        path: the BVH file.
        fps: resample to this rate (``None``: keep the file's own rate).
    """
    motion = to_canonical22(load_bvh(path), "mixamo")
    return motion if fps is None else motion.resample(fps)


@dataclass
class MixamoFolder:
    """Every clip of a ``mixamo-local`` folder, loaded at the files' own frame rates.

    Attributes:
        root: the folder.
        characters: the :class:`MixamoCharacterFolder` entries (sorted by name).
        clips: ``(character, motion) -> Motion`` on the canonical 22 joints, metres, native fps.
    """

    root: Path
    characters: list[MixamoCharacterFolder]
    clips: dict[tuple[str, str], Motion]

    def performers(self) -> dict[str, set[str]]:
        """``motion -> {characters that perform it}``, motions sorted by name."""
        out: dict[str, set[str]] = {}
        for character, motion in sorted(self.clips, key=lambda k: k[1]):
            out.setdefault(motion, set()).add(character)
        return out

    def fingerprint(self, character: str, motion: str) -> str:
        """16 hex digits of the sha256 of a clip's BVH and its character's ``shape.npz`` (cache keys)."""
        entry = next(c for c in self.characters if c.name == character)
        parts = [sha256_file(entry.motions[motion])] + ([sha256_file(entry.shape)] if entry.shape else [])
        return hashlib.sha256("".join(parts).encode()).hexdigest()[:16]

    def character(self, name: str) -> Character | None:
        """The character's ``shape.npz`` as a :class:`Character` named ``name`` (``None`` without one)."""
        folder = next((c for c in self.characters if c.name == name), None)
        if folder is None or folder.shape is None:
            return None
        character = load_shape_npz(folder.shape)
        character.name = name
        return character


def load_mixamo_folder(root: str | Path) -> MixamoFolder:
    """Scan (:func:`scan_mixamo_folder`) and load every BVH of a ``mixamo-local`` folder.

    Raises:
        DataError: no such folder or no BVH in it.
        BVHError: a malformed BVH (names the file and line).
        JointSetError: a BVH whose joints do not fold onto the canonical 22 (names the file's joints).
    """
    characters = scan_mixamo_folder(root)
    clips = {(c.name, motion): load_mixamo_motion(path, fps=None)
             for c in characters for motion, path in c.motions.items()}
    return MixamoFolder(Path(root), characters, clips)
