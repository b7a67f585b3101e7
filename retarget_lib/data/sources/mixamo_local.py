"""``mixamo-local``: a reviewer's own Mixamo download.

Layout (``$RETARGET_MIXAMO``, default ``data/mixamo``; see ``data_manifest.yaml``)::

    <root>/<Character>/shape.npz        rest_vertices, rest_faces, skinning_weights, skeleton, joint_names
    <root>/<Character>/<Motion>.bvh     Blender-exported, `mixamorig:` prefix, fingers, *_End sites, cm
    <root>/<Character>/<Character>.dae  optional Collada export

The tests write a synthetic character in exactly that layout (``tests/mixamo_fixture.py``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from ...core.motion import Motion
from ...files import DataError
from ...io.bvh import load_canonical_bvh

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


def load_mixamo_motion(path: str | Path, fps: float = 30.0) -> Motion:
    """Load a Mixamo BVH and fold it to the canonical 22 joints at ``fps``."""
    return load_canonical_bvh(path, fps, convention="mixamo")
