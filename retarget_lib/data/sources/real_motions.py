"""The ``real-motions`` source: real motion capture shipped in the repository
(``data/real_motions``), a second public mocap source beside CMU's
(:mod:`~retarget_lib.data.sources.cmu`).

* ``motion_capture_rom.bvh``: the range-of-motion capture of assimp's test models (a 3ds Max Biped
  performer with German bone names, 45 s, keys at 6 per second; "Free for any purpose"), converted
  by ``tools/real_motions.py``. Its joint map beside it names the canonical joints.

Each file is checked against the manifest's sha256 before it is read; the manifest gives each
file's length unit (BVH has none). Used for testing, never for training.
"""

from __future__ import annotations

from pathlib import Path

from ...core.motion import Motion
from ...files import REPO_ROOT, DataError, sha256_file
from ...io.bvh import load_bvh
from ...io.joint_maps import to_canonical22
from ..manifest import source

__all__ = [
    "SOURCE_ID",
    "MOTIONS_DIR",
    "real_motion_names",
    "real_motion_path",
    "load_real_motion",
    "check",
]

SOURCE_ID = "real-motions"
#: where the files are
MOTIONS_DIR = REPO_ROOT / "data" / "real_motions"


def _files() -> dict[str, dict]:
    return {Path(f).stem: dict(e) for f, e in source(SOURCE_ID)["files"].items()}


def real_motion_names() -> list[str]:
    """The clips of the manifest, in its order (the file stems)."""
    return list(_files())


def _entry(name: str) -> dict:
    files = _files()
    if name not in files:
        raise DataError(f"unknown real motion {name!r}; known: {sorted(files)}")
    return files[name]


def real_motion_path(name: str) -> Path:
    """Path of a clip's BVH, checked against the manifest's sha256 (:class:`DataError` if unknown,
    missing or changed)."""
    entry, path = _entry(name), MOTIONS_DIR / f"{name}.bvh"
    if not path.is_file():
        raise DataError(
            f"{SOURCE_ID}: {path} is missing (it is part of the repository: restore it with git)"
        )
    if sha256_file(path) != entry["sha256"]:
        raise DataError(
            f"{SOURCE_ID}: {path} does not match its sha256 in data_manifest.yaml; restore it with "
            "git, "
            "or rebuild it with tools/real_motions.py and record the new sha256"
        )
    return path


def load_real_motion(name: str, fps: float | None = 30, normalize: bool = True) -> Motion:
    """One clip on the canonical 22 joints (through its joint map), in metres.

    Args:
        name: one of :func:`real_motion_names`.
        fps: resample to this rate (``None`` keeps the file's).
        normalize: :meth:`~retarget_lib.core.motion.Motion.normalize_root` (frame 0 at ``x = z =
            0``, facing +Z, feet on ``y = 0``).
    """
    entry, path = _entry(name), real_motion_path(name)
    raw = load_bvh(path, unit=entry["unit"])
    mapping = MOTIONS_DIR / entry["joint_map"]
    motion = to_canonical22(raw, mapping=mapping, what=str(path))
    if fps is not None:
        motion = motion.resample(fps)
    if normalize:
        motion = motion.normalize_root()
    motion.name = name
    motion.meta["source"] = SOURCE_ID
    return motion


def check() -> tuple[bool, str]:
    """``(all present and intact, detail)`` for ``retarget data verify``."""
    bad = []
    for name in real_motion_names():
        try:
            real_motion_path(name)
        except DataError as e:
            bad.append(str(e))
    return (
        (False, "; ".join(bad))
        if bad
        else (True, f"{len(real_motion_names())} clip(s) in {MOTIONS_DIR}")
    )
