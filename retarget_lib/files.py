"""Files: the repository root, the cache folder, SHA-256 checks, atomic writes, and the trust
boundary for the paths of a run (every layer uses them; this module imports only
:mod:`retarget_lib.errors`).

Everything the library downloads or builds lives under :func:`cache_dir` (``$RETARGET_CACHE``,
default ``<repo>/.cache``). Files are written atomically and checked by SHA-256.

**The trust boundary for paths** (``SECURITY.md``); every reader and writer goes through it:

* *A path an input file names* (a ``.gltf`` file's buffer URI) is read with :func:`read_beside`:
  percent-decoded, never absolute, never ``..``, never a URL; then resolved with every symbolic
  link, and the result must lie inside the folder of the file that names it and be a regular file,
  opened without following a final link (so a link beside the file that points at
  ``/etc/passwd`` is refused, as is a FIFO that would block the read).
* *What a run reads*: inside :func:`input_ledger`, every input this module opens for a reader
  (:func:`readable_file`, :func:`read_beside`, :func:`read_yaml`) and every input a command names
  (:func:`check_output`) is recorded by device and inode. :func:`check_output` and
  :func:`atomic_write` refuse an output that is one of them (also through a hard link or a
  symbolic link) unless the run was started with ``force``.
* *Temporary files* are only those this program created: :func:`atomic_write` writes
  ``.retarget-tmp-<pid>-<random>-NAME.tmp`` beside the destination and keeps a record of it (its
  path, device, inode and process) in ``cache_dir("temp-records")`` while it exists. The
  temporary file is removed on any exception, including the ``SystemExit`` that
  :func:`exit_on_signals` turns SIGTERM/SIGINT into; one left by a process killed with SIGKILL
  (or a power cut) is removed by the next write into the same folder, from its record, once its
  process is gone (or the record is older than :data:`STALE_TEMP_SECONDS`) and only if the file
  is still the one recorded (same device and inode, a regular file). Nothing is ever removed
  because its *name* looks like a temporary file.
* *YAML* (configs, joint maps) is read by :func:`read_yaml`: ``safe_load`` semantics, at most
  :data:`MAX_YAML_BYTES`, nested at most :data:`MAX_YAML_DEPTH` deep, at most
  :data:`MAX_YAML_VALUES` values once aliases are expanded (an alias bomb is refused before
  anything prints it), and a key given twice in one mapping is an error, not a silent overwrite.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import secrets
import signal
import stat
import time
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import dataclass, field
from pathlib import Path, PurePosixPath
from typing import Any
from urllib.parse import unquote

import numpy as np
import yaml

from .errors import InputFileError, OutputPathError, RetargetInputError

REPO_ROOT = Path(__file__).resolve().parents[1]
#: a temporary file of an atomic write whose record is older than this is swept even if its
#: process id is alive (process ids are reused; no write of the library takes a day)
STALE_TEMP_SECONDS = 24 * 3600
#: the name every temporary file of :func:`atomic_write` starts with (no user file is expected
#: to; and even one that does is never removed without its record)
TEMP_PREFIX = ".retarget-tmp-"
#: bounds of a YAML file a user gives (a config is ~2 KiB, nested 3 deep; a joint map 1 KiB, 1 deep)
MAX_YAML_BYTES = 1 << 20
MAX_YAML_DEPTH = 32
MAX_YAML_VALUES = 100_000


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
    """Raise :class:`DataError` if ``path``'s SHA-256 differs from ``expected`` (skip if
    ``None``)."""
    if expected is None:
        return
    got = sha256_file(path)
    if got != expected:
        raise DataError(
            f"checksum mismatch for {path}: expected sha256 {expected}, got {got}. "
            "Delete the file and run `retarget data build` to fetch it again."
        )


# ------------------------------------------------------------------------------ what a run reads
@dataclass
class _Ledger:
    """The inputs of one run, by ``(device, inode)``, and whether ``--force`` allows replacing
    them."""

    force: bool
    files: dict[tuple[int, int], str] = field(default_factory=dict)


_LEDGER: ContextVar[_Ledger | None] = ContextVar("retarget_input_ledger", default=None)


@contextmanager
def input_ledger(force: bool = False) -> Iterator[None]:
    """Record every input read inside the block; no :func:`atomic_write` inside replaces one.

    Args:
        force: allow an output to replace an input (``--force``).
    """
    token = _LEDGER.set(_Ledger(force))
    try:
        yield
    finally:
        _LEDGER.reset(token)


def _file_key(st: os.stat_result) -> tuple[int, int]:
    return st.st_dev, st.st_ino


def record_input(path: str | os.PathLike, st: os.stat_result | None = None) -> None:
    """Note ``path`` (its device and inode, ``st`` if already known) as an input of the current
    run (nothing outside :func:`input_ledger`)."""
    ledger = _LEDGER.get()
    if ledger is not None:
        ledger.files.setdefault(_file_key(st or os.stat(path)), str(path))


def refuse_overwriting_inputs(
    out: str | os.PathLike, inputs: Iterable[str | os.PathLike | None] = (), force: bool = False
) -> None:
    """Raise :class:`~retarget_lib.errors.OutputPathError` if ``out`` exists and is one of
    ``inputs`` or of the current run's recorded inputs (same device and inode: hard links and
    symbolic links included), unless ``force`` or the run's ``force``."""
    try:
        key = _file_key(os.stat(out))
    except (FileNotFoundError, NotADirectoryError):
        return
    ledger = _LEDGER.get()
    if force or (ledger is not None and ledger.force):
        return
    known = dict(ledger.files) if ledger is not None else {}
    for src in inputs:
        if src is not None and Path(src).is_file():
            known.setdefault(_file_key(os.stat(src)), str(src))
    if key in known:
        raise OutputPathError(
            f"{out}: is the input {known[key]}; refusing to overwrite an input (use --force)"
        )


# ------------------------------------------------------------------------------------ inputs
def readable_file(path: str | os.PathLike, what: str, max_bytes: int | None = None) -> Path:
    """``path`` as a :class:`~pathlib.Path` after checking it is a readable, non-empty regular
    file (recorded as an input of the current run, :func:`input_ledger`).

    Args:
        path: the input.
        what: what the file should be, for the message (e.g. ``"BVH file"``).
        max_bytes: refuse a larger file (:class:`~retarget_lib.errors.InputFileError` naming the
            limit) before reading any of it.

    Raises:
        InputFileError: missing, a directory, not a regular file, unreadable, empty or larger
            than ``max_bytes``.
    """
    path = Path(path)
    if not path.exists():
        raise InputFileError(f"{path}: no such {what}")
    if not path.is_file():
        raise InputFileError(
            f"{path}: is a directory, not a {what}"
            if path.is_dir()
            else f"{path}: not a regular file"
        )
    if not os.access(path, os.R_OK):
        raise InputFileError(f"{path}: permission denied (cannot read the {what})")
    st = path.stat()
    _check_size(path, st.st_size, what, max_bytes)
    record_input(path, st)
    return path


def _check_size(path: str | os.PathLike, size: int, what: str, max_bytes: int | None) -> None:
    if size == 0:
        raise InputFileError(f"{path}: empty file (expected a {what})")
    if max_bytes is not None and size > max_bytes:
        raise InputFileError(
            f"{path}: {size / 2**20:.0f} MiB exceeds the {max_bytes / 2**20:.0f} MiB limit for a "
            f"{what}"
        )


def read_beside(
    container: str | os.PathLike,
    reference: str,
    what: str,
    max_bytes: int,
    error: type[RetargetInputError] = InputFileError,
) -> bytes:
    """The bytes of a file that an input file names (a ``.gltf`` buffer URI), under the rules of
    the module docstring: a relative reference, resolved with its symbolic links to a regular
    file inside the folder of ``container``.

    Args:
        container: the input file that names it.
        reference: the relative URI as written in the file (percent-encoded).
        what: what the named file is, for messages (``"buffer 0"``).
        max_bytes: refuse a larger file before reading it.
        error: the exception type for a reference that breaks the rules.

    Raises:
        error: an absolute path, ``..``, a URL, or a path that resolves outside the folder.
        InputFileError: missing, not a regular file, empty or too large.
    """
    container = Path(container)
    name = unquote(reference)
    rel = PurePosixPath(name)
    if (
        not name
        or "\x00" in name
        or "\\" in name
        or ":" in name
        or rel.is_absolute()
        or ".." in rel.parts
    ):
        raise error(
            f"{container}: {what} URI {reference!r} is not a file beside it (absolute paths, '..' "
            "and URLs "
            "are refused)"
        )
    folder = os.path.realpath(container.absolute().parent)
    real = os.path.realpath(os.path.join(folder, *rel.parts))
    if os.path.commonpath([real, folder]) != folder:
        raise error(
            f"{container}: {what} URI {reference!r} resolves to {real}, outside the folder "
            f"{folder} (a "
            "symbolic link?); a file may only name files beside it"
        )
    try:
        fd = os.open(real, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK | os.O_CLOEXEC)
    except FileNotFoundError:
        raise InputFileError(f"{container}: {what} file {name!r} not found beside it") from None
    except PermissionError:
        raise InputFileError(
            f"{real}: permission denied (cannot read {what} of {container})"
        ) from None
    with os.fdopen(fd, "rb") as f:
        st = os.fstat(f.fileno())
        if not stat.S_ISREG(st.st_mode):
            raise error(f"{container}: {what} URI {reference!r} is not a regular file")
        _check_size(real, st.st_size, f"{what} of {container}", max_bytes)
        record_input(real, st)
        return f.read(max_bytes)


def check_output(
    out: str | os.PathLike,
    inputs: list[str | os.PathLike | None],
    suffixes: tuple[str, ...],
    force: bool = False,
) -> Path:
    """Check an output path before any work is done.

    Args:
        out: the output path.
        inputs: the command's input paths (``None`` and non-existing entries are skipped); inside
            :func:`input_ledger` they are recorded as the run's inputs.
        suffixes: the extensions that can be written (lower case, with the dot).
        force: allow ``out`` to be one of ``inputs``.

    Raises:
        OutputPathError: wrong extension, a directory, a parent that is a file, not writable, or
            (without ``force``) the same file as an input or as a recorded input of the run.
    """
    out = Path(out)
    if out.is_dir():
        raise OutputPathError(f"{out}: is a directory; give a file name")
    if out.suffix.lower() not in suffixes:
        raise OutputPathError(
            f"{out}: cannot write a {out.suffix or 'suffix-less'} file; supported: "
            f"{', '.join(suffixes)}"
        )
    parent = next((p for p in out.absolute().parents if p.exists()), None)
    if parent is not None and not parent.is_dir():
        raise OutputPathError(f"{out}: cannot create it, {parent} is a file")
    if parent is not None and not os.access(parent, os.W_OK):
        raise OutputPathError(f"{out}: permission denied (cannot write into {parent})")
    for src in inputs:
        if src is not None and Path(src).is_file():
            record_input(src)
    refuse_overwriting_inputs(out, inputs, force)
    return out


# -------------------------------------------------------------------------------------- YAML
class _BoundedLoader(yaml.SafeLoader):
    """``yaml.SafeLoader`` that refuses nesting beyond :data:`MAX_YAML_DEPTH` (composing is
    recursive) and a key given twice in one mapping."""

    def __init__(self, stream) -> None:
        super().__init__(stream)
        self._depth = 0

    def compose_node(self, parent, index):
        self._depth += 1
        try:
            if self._depth > MAX_YAML_DEPTH:
                raise yaml.composer.ComposerError(
                    None,
                    None,
                    f"nested more than {MAX_YAML_DEPTH} deep (the limit)",
                    self.peek_event().start_mark,
                )
            return super().compose_node(parent, index)
        finally:
            self._depth -= 1

    def construct_mapping(self, node, deep=False):
        first: dict[Any, yaml.Mark] = {}
        for key_node, _ in node.value if isinstance(node, yaml.MappingNode) else ():
            if isinstance(key_node, yaml.ScalarNode) and key_node.tag != "tag:yaml.org,2002:merge":
                if key_node.value in first:
                    raise yaml.constructor.ConstructorError(
                        None,
                        None,
                        f"key {key_node.value!r} is given twice (first on line "
                        f"{first[key_node.value].line + 1}); each key may appear once",
                        key_node.start_mark,
                    )
                first[key_node.value] = key_node.start_mark
        return super().construct_mapping(node, deep=deep)


# YAML 1.2's exponent floats: PyYAML (YAML 1.1) reads ``1e-3`` (no dot) as a string, so
# ``train.lr=1e-3`` or ``lr: 1e-4`` would be refused as "not a number"; this resolver adds only the
# exponent forms (dotted floats, ``.inf`` and ``.nan`` PyYAML already reads).
_BoundedLoader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"^[-+]?(?:[0-9][0-9_]*(?:\.[0-9_]*)?|\.[0-9_]+)[eE][-+]?[0-9]+$"),
    list("-+0123456789."),
)


def _expands_beyond(data: Any, limit: int) -> bool:
    """Whether ``data`` holds more than ``limit`` values once shared (aliased) parts are counted
    every time they appear; stops counting at ``limit``."""
    stack, count = [data], 0
    while stack:
        value = stack.pop()
        count += 1
        if count > limit:
            return True
        if isinstance(value, dict):
            stack.extend(value.keys())
            stack.extend(value.values())
        elif isinstance(value, (list, tuple, set)):
            stack.extend(value)
    return False


def load_yaml(text: str, where: str, error: type[RetargetInputError]) -> Any:
    """Parse untrusted YAML text within the bounds of the module docstring.

    Args:
        text: the document.
        where: the file (or option) it comes from, for messages.
        error: the exception type to raise.

    Raises:
        error: malformed YAML (naming the line), nested too deep, a duplicate key, or more than
            :data:`MAX_YAML_VALUES` values after expanding aliases.
    """
    loader = None
    try:
        loader = _BoundedLoader(text)  # its reader already refuses non-printable characters
        data = loader.get_single_data()
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None)
        line = f" line {mark.line + 1}" if mark is not None else ""
        problem = getattr(e, "problem", None) or " ".join(str(e).split())
        raise error(f"{where}:{line} malformed YAML: {problem}") from None
    finally:
        if loader is not None:
            loader.dispose()
    if _expands_beyond(data, MAX_YAML_VALUES):
        raise error(
            f"{where}: holds more than {MAX_YAML_VALUES} values once its aliases are expanded (the "
            "limit; "
            "a YAML alias bomb?)"
        )
    return data


def read_yaml(path: str | os.PathLike, what: str, error: type[RetargetInputError]) -> Any:
    """Read a YAML file a user gives (recorded as an input of the run), within the bounds of
    :func:`load_yaml` and at most :data:`MAX_YAML_BYTES`.

    Raises:
        error: not UTF-8 text, or what :func:`load_yaml` raises.
        InputFileError: missing, a directory, unreadable, empty or too large.
    """
    path = readable_file(path, what, MAX_YAML_BYTES)
    try:
        text = path.read_bytes()[:MAX_YAML_BYTES].decode("utf-8")
    except UnicodeDecodeError:
        raise error(f"{path}: not a UTF-8 text file (expected a {what})") from None
    return load_yaml(text, str(path), error)


# --------------------------------------------------------------------------- temporary files
def _records() -> Path | None:
    """The folder of temporary-file records, or ``None`` when the cache cannot be written."""
    try:
        return cache_dir("temp-records")
    except OSError:
        return None


def _record_temp(tmp: Path, fd: int) -> Path | None:
    """Write the record of a new temporary file; its path (``None`` if it could not be written:
    the file is then still removed on any exception, only a SIGKILL would leave it)."""
    folder = _records()
    if folder is None:
        return None
    st = os.fstat(fd)
    record = folder / f"{os.getpid()}-{secrets.token_hex(8)}.json"
    entry = dict(
        path=str(tmp),
        folder=str(tmp.parent),
        dev=st.st_dev,
        ino=st.st_ino,
        pid=os.getpid(),
        created=time.time(),
    )
    try:
        with open(record, "x") as f:
            json.dump(entry, f)
    except OSError:
        return None
    return record


def _process_gone(pid: int) -> bool:
    if pid == os.getpid():
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return True
    except PermissionError:  # alive, another user's
        return False
    return False


def _sweep_record(record: Path, folder: str, now: float) -> Path | None:
    """Act on one record: remove its temporary file (if stale, in ``folder`` and still the
    recorded file) and the record; return the removed file."""
    try:
        entry = json.loads(record.read_text())
        path, pid, created = Path(entry["path"]), int(entry["pid"]), float(entry["created"])
        key, where = (int(entry["dev"]), int(entry["ino"])), str(entry["folder"])
    except (OSError, ValueError, KeyError, TypeError):
        return None  # not a record this module wrote: left alone
    if where != folder or not (now - created > STALE_TEMP_SECONDS or _process_gone(pid)):
        return None
    removed = None
    try:
        st = os.lstat(path)
        ledger = _LEDGER.get()
        is_input = ledger is not None and _file_key(st) in ledger.files
        if (
            stat.S_ISREG(st.st_mode)
            and _file_key(st) == key
            and path.name.startswith(TEMP_PREFIX)
            and not is_input
        ):
            path.unlink()
            removed = path
    except FileNotFoundError:
        pass
    record.unlink(missing_ok=True)
    return removed


def sweep_stale_temps(folder: str | os.PathLike) -> list[Path]:
    """Remove the temporary files that interrupted :func:`atomic_write` calls of this program left
    in ``folder``, from their records (module docstring): never a file by its name alone.

    Returns:
        the removed paths.
    """
    records = _records()
    if records is None:
        return []
    where, now = str(Path(folder).absolute()), time.time()
    removed = [_sweep_record(r, where, now) for r in sorted(records.glob("*.json"))]
    return [r for r in removed if r is not None]


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
    temporary files of this program's killed writes into the same folder are swept first
    (:func:`sweep_stale_temps`). Inside :func:`input_ledger`, ``path`` must not be an input of
    the run.

    Args:
        path: destination.
        mode: ``"wb"`` or ``"w"``.

    Raises:
        OutputPathError: ``path`` is a directory, a parent of it is a file, its folder cannot be
            written, or it is an input of the current run.
    """
    path = Path(path)
    refuse_overwriting_inputs(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except (FileExistsError, NotADirectoryError):
        raise OutputPathError(f"{path}: cannot create it, a parent folder is a file") from None
    if path.is_dir():
        raise OutputPathError(f"{path}: is a directory; give a file name")
    sweep_stale_temps(path.parent)
    tmp = (
        path.absolute().parent
        / f"{TEMP_PREFIX}{os.getpid()}-{secrets.token_hex(6)}-{path.name[:40]}.tmp"
    )
    try:
        fd = os.open(
            tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW | os.O_CLOEXEC, 0o600
        )
    except PermissionError:  # name the output the user gave, not the temporary file
        raise OutputPathError(
            f"{path}: cannot write into {path.parent} (permission denied)"
        ) from None
    record = None
    try:
        record = _record_temp(tmp, fd)
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
    finally:
        if record is not None:
            record.unlink(missing_ok=True)
