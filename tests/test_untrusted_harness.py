"""The harness of the untrusted-input tests (``tests/test_untrusted_*.py``), and tests that its
checks fail when they should (a check that cannot fail would prove nothing).

* :func:`run_contained` runs the command line in this process under a memory cap
  (:func:`memory_cap`: ``RLIMIT_AS`` = the address space in use + 2 GiB, so a regression gets a
  ``MemoryError`` instead of eating the machine), records every file opened (an audit hook) and
  snapshots the files of the test's folder before and after.
* :meth:`Run.assert_contained` is what every fuzz example asserts: exit status 0 or 2; on 2
  exactly one stderr line, naming the file, no traceback; no file under the test's folder read
  outside the input's folder (a ``secret/`` folder beside it is the bait); no file changed or
  removed, and none created but the output.
"""

import hashlib
import io
import json
import os
import resource
import struct
import sys
import warnings
from contextlib import contextmanager, redirect_stderr, redirect_stdout
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest
from test_gltf import random_motion

from retarget_lib.cli import main
from retarget_lib.core.rig import Rig
from retarget_lib.data.synthetic.characters import make_character
from retarget_lib.io.gltf_write import save_glb

pytestmark = pytest.mark.tooling  # nothing here depends on the thread count (make unit-threads)

#: the memory a case may take beyond what the process already uses
CAP_BYTES = 2 * 2**30

_OPENED: list[str] | None = None


def _audit(event: str, args: tuple) -> None:
    if _OPENED is not None and event == "open" and isinstance(args[0], (str, bytes, os.PathLike)):
        _OPENED.append(os.path.abspath(os.fsdecode(args[0])))


sys.addaudithook(_audit)


@contextmanager
def watch_opens():
    """The absolute paths of every file opened inside the block (Python-level opens)."""
    global _OPENED
    _OPENED, opened = [], []
    try:
        yield opened
    finally:
        opened.extend(_OPENED)
        _OPENED = None


def _address_space() -> int:
    with open("/proc/self/status") as f:
        return next(int(line.split()[1]) * 1024 for line in f if line.startswith("VmSize:"))


@contextmanager
def memory_cap(extra: int = CAP_BYTES):
    """Limit this process's address space to what it uses now + ``extra`` inside the block."""
    soft, hard = resource.getrlimit(resource.RLIMIT_AS)
    limit = _address_space() + extra
    resource.setrlimit(
        resource.RLIMIT_AS, (limit if hard == resource.RLIM_INFINITY else min(limit, hard), hard)
    )
    try:
        yield
    finally:
        resource.setrlimit(resource.RLIMIT_AS, (soft, hard))


def snapshot(folder: Path) -> dict[str, tuple]:
    """Every file under ``folder``: ``(inode, size, mtime, sha256)`` (symbolic links by their target
    path)."""
    out = {}
    for p in sorted(folder.rglob("*")):
        if p.is_symlink():
            out[str(p)] = ("link", os.readlink(p))
        elif p.is_file():
            st = p.stat()
            out[str(p)] = (
                st.st_ino,
                st.st_size,
                st.st_mtime_ns,
                hashlib.sha256(p.read_bytes()).hexdigest(),
            )
    return out


@dataclass
class Run:
    """One contained command: exit status, stderr lines, opened files, folder before and after."""

    code: int
    err: str
    opened: list[str]
    before: dict
    after: dict
    folder: Path
    out: Path | None = None
    extra_outputs: tuple = field(default_factory=tuple)

    @property
    def lines(self) -> list[str]:
        return self.err.strip().splitlines()

    def assert_error(self, named: str | Path, *fragments: str) -> str:
        """Exit status 2 and one stderr line naming ``named`` (and every fragment)."""
        assert self.code == 2, (self.code, self.err)
        assert len(self.lines) == 1 and "Traceback" not in self.err, self.err
        assert str(named) in self.lines[0], self.lines[0]
        for fragment in fragments:
            assert fragment in self.lines[0], self.lines[0]
        return self.lines[0]

    def assert_contained(self, named: str | Path, inputs: Path) -> None:
        """What every untrusted input must give (module docstring)."""
        assert self.code in (0, 2), (self.code, self.err)
        if self.code == 2:
            self.assert_error(named)
        outside = [
            p
            for p in self.opened
            if p.startswith(str(self.folder))
            and not p.startswith(str(inputs))
            and not (self.out is not None and p.startswith(str(self.out.parent)))
        ]
        assert not outside, f"read outside {inputs}: {outside}"
        assert not any(p.startswith("/etc/") for p in self.opened), self.opened
        changed = {k for k in self.before if self.after.get(k) != self.before[k]}
        assert not changed, f"changed or removed: {changed}"
        created = (
            set(self.after)
            - set(self.before)
            - {str(p) for p in (self.out, *self.extra_outputs) if p}
        )
        assert not created, f"created: {created}"


def run_contained(argv: list[str], folder: Path, out: Path | None = None) -> Run:
    """Run ``retarget argv`` in this process, contained (module docstring); ``folder`` is the
    test's folder and ``out`` the one file the command may create."""
    before = snapshot(folder)
    err, stdout = io.StringIO(), io.StringIO()
    with (
        watch_opens() as opened,
        memory_cap(),
        redirect_stderr(err),
        redirect_stdout(stdout),
        warnings.catch_warnings(record=True) as caught,
    ):
        warnings.simplefilter("always")  # a warning is a line on a user's stderr
        code = main(argv)
    shown = "".join(f"{w.category.__name__}: {w.message}\n" for w in caught)
    return Run(code, shown + err.getvalue(), opened, before, snapshot(folder), folder, out)


def retarget_argv(source, out, target="kato", *extra) -> list[str]:
    return [
        "retarget",
        "--source",
        str(source),
        "--target",
        str(target),
        "--method",
        "copy",
        "--out",
        str(out),
        *map(str, extra),
    ]


# ------------------------------------------------------------------------- GLB building blocks
def kato_glb(path: Path, frames: int = 12) -> Path:
    """A valid skinned, animated GLB of the synthetic character ``kato`` (195 KB)."""
    character = make_character("kato")
    save_glb(Rig.from_character(character), path, random_motion(character.skeleton, frames))
    return path


def split_glb(data: bytes) -> tuple[dict, bytes]:
    """``(JSON, binary chunk)`` of a GLB file."""
    json_size = struct.unpack_from("<I", data, 12)[0]
    doc = json.loads(data[20 : 20 + json_size])
    bin_start = 20 + json_size
    bin_size = struct.unpack_from("<I", data, bin_start)[0]
    return doc, data[bin_start + 8 : bin_start + 8 + bin_size]


def pack_glb(doc: dict, blob: bytes, allow_nan: bool = False) -> bytes:
    """A GLB file of ``doc`` (JSON) and ``blob`` (the binary chunk)."""
    text = json.dumps(doc, allow_nan=allow_nan).encode()
    text += b" " * (-len(text) % 4)
    blob += b"\0" * (-len(blob) % 4)
    body = (
        struct.pack("<II", len(text), 0x4E4F534A)
        + text
        + struct.pack("<II", len(blob), 0x004E4942)
        + blob
    )
    return b"glTF" + struct.pack("<II", 2, 12 + len(body)) + body


@pytest.fixture(scope="session")
def kato_parts(tmp_path_factory) -> tuple[dict, bytes]:
    """The JSON and binary chunk of :func:`kato_glb` (each test copies the JSON before editing)."""
    return split_glb(kato_glb(tmp_path_factory.mktemp("kato") / "kato.glb").read_bytes())


# ------------------------------------------------------------------------------ self-tests
def test_the_read_check_fails_on_a_read_outside_the_input_folder(tmp_path):
    (tmp_path / "in").mkdir()
    (tmp_path / "secret").mkdir()
    (tmp_path / "secret" / "passwd").write_text("root:x:0:0")
    before = snapshot(tmp_path)
    with watch_opens() as opened:
        (tmp_path / "secret" / "passwd").read_text()
    run = Run(0, "", opened, before, snapshot(tmp_path), tmp_path)
    with pytest.raises(AssertionError, match="read outside"):
        run.assert_contained("x", tmp_path / "in")


def test_the_file_check_fails_on_a_changed_removed_or_created_file(tmp_path):
    (tmp_path / "a").write_text("a")
    (tmp_path / "b").write_text("b")
    before = snapshot(tmp_path)
    (tmp_path / "a").write_text("changed")
    with pytest.raises(AssertionError, match="changed or removed"):
        Run(0, "", [], before, snapshot(tmp_path), tmp_path).assert_contained("x", tmp_path)
    (tmp_path / "a").write_text("a")
    before = snapshot(tmp_path)
    (tmp_path / "c").write_text("c")
    with pytest.raises(AssertionError, match="created"):
        Run(0, "", [], before, snapshot(tmp_path), tmp_path).assert_contained("x", tmp_path)


def test_a_warning_counts_as_a_line_on_stderr(tmp_path, monkeypatch):
    import retarget_lib.cli.parser

    def warn_then_fail(args):
        warnings.warn("casting discards the imaginary part", RuntimeWarning, stacklevel=2)
        raise ValueError("a.glb: problem")

    monkeypatch.setattr(retarget_lib.cli.parser, "_cmd_data", warn_then_fail)
    run = run_contained(["data", "list"], tmp_path)
    with pytest.raises(AssertionError):
        run.assert_error("a.glb")


def test_the_error_check_fails_on_a_traceback_or_two_lines(tmp_path):
    for code, err in (
        (2, "a.glb: one\na.glb: two\n"),
        (1, "Traceback (most recent call last):\n"),
        (2, "other.glb: problem\n"),
    ):
        with pytest.raises(AssertionError):
            Run(code, err, [], {}, {}, tmp_path).assert_contained("a.glb", tmp_path)
    Run(2, "retarget retarget: error: a.glb: problem\n", [], {}, {}, tmp_path).assert_contained(
        "a.glb", tmp_path
    )


def test_the_memory_cap_turns_a_large_allocation_into_memory_error():
    with memory_cap(), pytest.raises(MemoryError):
        np.ones(3 * 2**30 // 8)
    assert np.ones(2**20).sum() == 2**20  # restored afterwards
