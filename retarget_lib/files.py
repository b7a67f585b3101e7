"""Files: the repository root, the cache folder, atomic writes and SHA-256 checks (every layer
uses them; this module imports nothing of the library).

Everything the library downloads or builds lives under :func:`cache_dir` (``$RETARGET_CACHE``,
default ``<repo>/.cache``). Files are written atomically and checked by SHA-256.
"""

from __future__ import annotations

import hashlib
import os
import tempfile
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator

REPO_ROOT = Path(__file__).resolve().parents[1]


class DataError(RuntimeError):
    """A data source is missing, corrupt or cannot be fetched (the message says how to get it)."""


def cache_dir(*parts: str) -> Path:
    """The cache folder (created on demand), or a sub-folder of it.

    Args:
        *parts: optional sub-path components.
    """
    root = Path(os.environ.get("RETARGET_CACHE", REPO_ROOT / ".cache"))
    path = root.joinpath(*parts)
    path.mkdir(parents=True, exist_ok=True)
    return path


def sha256_file(path: str | os.PathLike) -> str:
    """Hex SHA-256 of a file's bytes."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def check_sha256(path: str | os.PathLike, expected: str | None) -> None:
    """Raise :class:`DataError` if ``path``'s SHA-256 differs from ``expected`` (skip if ``None``)."""
    if expected is None:
        return
    got = sha256_file(path)
    if got != expected:
        raise DataError(f"checksum mismatch for {path}: expected sha256 {expected}, got {got}. "
                        "Delete the file and run `retarget data build` to fetch it again.")


@contextmanager
def atomic_write(path: str | os.PathLike, mode: str = "wb") -> Iterator:
    """Open a temporary file beside ``path``; on success rename it over ``path`` (atomic).

    A crash or exception leaves any previous ``path`` untouched and removes the temporary file.

    Args:
        path: destination.
        mode: ``"wb"`` or ``"w"``.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, mode) as f:
            yield f
            f.flush()
            os.fsync(f.fileno())
        os.chmod(tmp, 0o644)
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        raise
