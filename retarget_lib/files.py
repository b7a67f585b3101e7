"""Files: the repository root, the cache folder, input and output path checks, atomic writes and
SHA-256 checks (every layer uses them; this module imports only :mod:`retarget_lib.errors`).

Everything the library downloads or builds lives under :func:`cache_dir` (``$RETARGET_CACHE``,
default ``<repo>/.cache``). Files are written atomically and checked by SHA-256.

Atomic writes go to a hidden temporary file beside the destination, ``.NAME.<pid>.<random>.tmp``,
renamed over the destination when complete. The temporary file is removed on any exception,
including the ``SystemExit`` that :func:`exit_on_signals` turns SIGTERM/SIGINT into; one left by a
process killed with SIGKILL (or a power cut) is swept by the next write into the same folder once
its process is gone (or it is older than :data:`STALE_TEMP_SECONDS`).
"""

from __future__ import annotations

import hashlib
import os
import signal
import tempfile
import time
from contextlib import contextmanager
from pathlib import Path
from typing import Iterable, Iterator

import numpy as np

from .errors import InputFileError, OutputPathError

REPO_ROOT = Path(__file__).resolve().parents[1]
#: a temporary file of an atomic write older than this is swept even if its process id is alive
#: (process ids are reused; no write of the library takes a day)
STALE_TEMP_SECONDS = 24 * 3600


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


def quantised_sha256(arrays: Iterable[tuple[str, np.ndarray]], per_unit: float) -> str:
    """Hex SHA-256 of named arrays, floats rounded to ``1 / per_unit`` first, so that last-bit float
    differences between CPUs do not change it while any real change does.

    Args:
        arrays: ``(name, array)`` pairs, hashed in the order given (names too).
        per_unit: quantisation steps per unit (``1e4``: 0.1 mm for metres).
    """
    h = hashlib.sha256()
    for name, a in arrays:
        a = np.asarray(a)
        if a.dtype.kind == "f":
            a = np.round(a.astype(np.float64) * per_unit).astype(np.int64)
        h.update(name.encode())
        h.update(np.ascontiguousarray(a).tobytes() if a.dtype.kind != "U" else str(a).encode())
    return h.hexdigest()


def check_sha256(path: str | os.PathLike, expected: str | None) -> None:
    """Raise :class:`DataError` if ``path``'s SHA-256 differs from ``expected`` (skip if ``None``)."""
    if expected is None:
        return
    got = sha256_file(path)
    if got != expected:
        raise DataError(f"checksum mismatch for {path}: expected sha256 {expected}, got {got}. "
                        "Delete the file and run `retarget data build` to fetch it again.")


def readable_file(path: str | os.PathLike, what: str, max_bytes: int | None = None) -> Path:
    """``path`` as a :class:`~pathlib.Path` after checking it is a readable, non-empty file.

    Args:
        path: the input.
        what: what the file should be, for the message (e.g. ``"BVH file"``).
        max_bytes: refuse a larger file (:class:`~retarget_lib.errors.InputFileError` naming the
            limit) before reading any of it.

    Raises:
        InputFileError: missing, a directory, unreadable, empty or larger than ``max_bytes``.
    """
    path = Path(path)
    if not path.exists():
        raise InputFileError(f"{path}: no such {what}")
    if not path.is_file():
        raise InputFileError(f"{path}: is a directory, not a {what}" if path.is_dir() else f"{path}: not a regular file")
    if not os.access(path, os.R_OK):
        raise InputFileError(f"{path}: permission denied (cannot read the {what})")
    size = path.stat().st_size
    if size == 0:
        raise InputFileError(f"{path}: empty file (expected a {what})")
    if max_bytes is not None and size > max_bytes:
        raise InputFileError(f"{path}: {size / 2**20:.0f} MiB exceeds the {max_bytes / 2**20:.0f} MiB limit for a "
                             f"{what}")
    return path


def check_output(out: str | os.PathLike, inputs: list[str | os.PathLike | None], suffixes: tuple[str, ...],
                 force: bool = False) -> Path:
    """Check an output path before any work is done.

    Args:
        out: the output path.
        inputs: the command's input paths (``None`` and non-existing entries are skipped).
        suffixes: the extensions that can be written (lower case, with the dot).
        force: allow ``out`` to be one of ``inputs``.

    Raises:
        OutputPathError: wrong extension, a directory, a parent that is a file, not writable, or
            (without ``force``) the same file as an input.
    """
    out = Path(out)
    if out.is_dir():
        raise OutputPathError(f"{out}: is a directory; give a file name")
    if out.suffix.lower() not in suffixes:
        raise OutputPathError(f"{out}: cannot write a {out.suffix or 'suffix-less'} file; supported: "
                              f"{', '.join(suffixes)}")
    parent = next((p for p in out.absolute().parents if p.exists()), None)
    if parent is not None and not parent.is_dir():
        raise OutputPathError(f"{out}: cannot create it, {parent} is a file")
    if parent is not None and not os.access(parent, os.W_OK):
        raise OutputPathError(f"{out}: permission denied (cannot write into {parent})")
    if not force and out.exists():
        for src in inputs:
            if src is not None and Path(src).exists() and out.samefile(src):
                raise OutputPathError(f"{out}: is the input {src}; refusing to overwrite an input (use --force)")
    return out


def _temp_is_stale(tmp: Path, now: float) -> bool:
    """A temporary file of :func:`atomic_write` whose process is gone or that is too old."""
    parts = tmp.name[: -len(".tmp")].rsplit(".", 2)
    try:
        age = now - tmp.stat().st_mtime
    except FileNotFoundError:
        return False
    if age > STALE_TEMP_SECONDS:
        return True
    if len(parts) != 3 or not parts[1].isdigit():
        return age > 3600  # written before temp names carried a process id
    pid = int(parts[1])
    if pid == os.getpid():
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return True
    except PermissionError:  # alive, another user's
        return False
    return False


def sweep_stale_temps(folder: str | os.PathLike) -> list[Path]:
    """Remove the temporary files that interrupted atomic writes left in ``folder``.

    Returns:
        the removed paths.
    """
    now, removed = time.time(), []
    for tmp in Path(folder).glob(".*.tmp"):
        if _temp_is_stale(tmp, now):
            try:
                tmp.unlink()
                removed.append(tmp)
            except FileNotFoundError:
                pass
    return removed


def exit_on_signals() -> None:
    """Turn SIGTERM and SIGINT into ``SystemExit(128 + signal)`` in the main thread, so every
    :func:`atomic_write` in progress removes its temporary file (the command line calls this)."""

    def _exit(signum, frame):  # noqa: ARG001 (signal handler signature)
        raise SystemExit(128 + signum)

    for sig in (signal.SIGTERM, signal.SIGINT):
        signal.signal(sig, _exit)


@contextmanager
def atomic_write(path: str | os.PathLike, mode: str = "wb") -> Iterator:
    """Open a temporary file beside ``path``; on success rename it over ``path`` (atomic).

    A crash or exception leaves any previous ``path`` untouched and removes the temporary file;
    stale temporary files of killed writes in the same folder are swept first
    (:func:`sweep_stale_temps`).

    Args:
        path: destination.
        mode: ``"wb"`` or ``"w"``.

    Raises:
        OutputPathError: ``path`` is a directory or a parent of it is a file.
    """
    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except (FileExistsError, NotADirectoryError):
        raise OutputPathError(f"{path}: cannot create it, a parent folder is a file") from None
    if path.is_dir():
        raise OutputPathError(f"{path}: is a directory; give a file name")
    sweep_stale_temps(path.parent)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.{os.getpid()}.", suffix=".tmp", dir=path.parent)
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
