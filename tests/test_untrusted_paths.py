"""Paths an untrusted file names stay inside its folder; no output replaces a file the run reads;
only the program's own recorded temporary files are ever swept (``retarget_lib.files``)."""

import json
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest
from test_untrusted_harness import kato_glb, kato_parts, retarget_argv, run_contained, split_glb  # noqa: F401

from retarget_lib.errors import GLTFError, OutputPathError
from retarget_lib.files import (
    REPO_ROOT,
    TEMP_PREFIX,
    atomic_write,
    cache_dir,
    input_ledger,
    read_beside,
    sweep_stale_temps,
)
from retarget_lib.io.gltf import load_gltf_rig

pytestmark = pytest.mark.tooling  # nothing here depends on the thread count (make unit-threads)


def gltf_with_buffer(folder: Path, uri: str, blob: bytes, kato_parts) -> Path:  # noqa: F811
    """``folder/a.gltf``: kato's JSON whose one buffer is the file ``uri`` (``blob`` not
    written)."""
    doc = json.loads(json.dumps(kato_parts[0]))
    doc["buffers"] = [{"uri": uri, "byteLength": len(blob)}]
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "a.gltf").write_text(json.dumps(doc))
    return folder / "a.gltf"


@pytest.mark.parametrize("pointing_at", ["secret", "/etc/passwd"])
def test_a_buffer_symlinked_out_of_the_folder_is_refused_and_never_read(
    tmp_path,
    kato_parts,  # noqa: F811
    pointing_at,
):
    secret = tmp_path / "secret" / "passwd"
    secret.parent.mkdir()
    secret.write_bytes(
        kato_parts[1].replace(b"\0\0\0\0", b"ROOT", 1)
    )  # a valid buffer, with a marker
    gltf = gltf_with_buffer(tmp_path / "in", "data.bin", kato_parts[1], kato_parts)
    (tmp_path / "in" / "data.bin").symlink_to(secret if pointing_at == "secret" else pointing_at)
    out = tmp_path / "out" / "o.glb"
    run = run_contained(retarget_argv(gltf, out), tmp_path, out)
    run.assert_error(gltf, "buffer 0 URI 'data.bin' resolves to", "outside the folder")
    run.assert_contained(gltf, tmp_path / "in")
    assert str(secret) not in run.opened and not out.exists()


def test_a_buffer_symlinked_inside_the_folder_is_read(tmp_path, kato_parts):  # noqa: F811
    gltf = gltf_with_buffer(tmp_path / "in", "link.bin", kato_parts[1], kato_parts)
    (tmp_path / "in" / "real.bin").write_bytes(kato_parts[1])
    (tmp_path / "in" / "link.bin").symlink_to("real.bin")
    assert load_gltf_rig(gltf).skeleton.num_joints == 22


@pytest.mark.parametrize(
    "uri",
    [
        "%2e%2e/secret/data.bin",
        "..%2Fsecret%2Fdata.bin",
        "/etc/passwd",
        "file:///etc/passwd",
        "sub\\..\\..\\secret\\data.bin",
    ],
)
def test_a_buffer_uri_that_leaves_the_folder_is_refused(tmp_path, kato_parts, uri):  # noqa: F811
    (tmp_path / "secret").mkdir()
    (tmp_path / "secret" / "data.bin").write_bytes(kato_parts[1])
    gltf = gltf_with_buffer(tmp_path / "in", uri, kato_parts[1], kato_parts)
    with pytest.raises(GLTFError, match="is not a file beside it"):
        load_gltf_rig(gltf)


def test_a_buffer_that_is_a_fifo_is_refused_without_blocking(tmp_path, kato_parts):  # noqa: F811
    gltf = gltf_with_buffer(tmp_path / "in", "data.bin", kato_parts[1], kato_parts)
    os.mkfifo(tmp_path / "in" / "data.bin")
    with pytest.raises(GLTFError, match="is not a regular file"):
        load_gltf_rig(gltf)


def test_read_beside_reads_a_plain_file_and_records_it(tmp_path):
    (tmp_path / "a.gltf").write_text("{}")
    (tmp_path / "b.bin").write_bytes(b"abc")
    with input_ledger():
        assert read_beside(tmp_path / "a.gltf", "b.bin", "buffer 0", 100) == b"abc"
        with pytest.raises(OutputPathError, match="b.bin; refusing to overwrite an input"):
            with atomic_write(tmp_path / "b.bin") as f:
                f.write(b"x")
    assert (tmp_path / "b.bin").read_bytes() == b"abc"


@pytest.mark.parametrize("how", ["same", "hard link", "symlink"])
def test_out_equal_to_an_external_buffer_is_refused(tmp_path, kato_parts, how):  # noqa: F811
    folder = tmp_path / "in"
    gltf = gltf_with_buffer(folder, "buffer.glb", kato_parts[1], kato_parts)
    (folder / "buffer.glb").write_bytes(kato_parts[1])
    out = folder / "buffer.glb"
    if how == "hard link":
        out = tmp_path / "hard.glb"
        os.link(folder / "buffer.glb", out)
    elif how == "symlink":
        out = tmp_path / "soft.glb"
        out.symlink_to(folder / "buffer.glb")
    run = run_contained(retarget_argv(gltf, out, gltf), tmp_path, out)
    run.assert_error(out, "buffer.glb; refusing to overwrite an input (use --force)")
    assert (folder / "buffer.glb").read_bytes() == kato_parts[1]
    assert run.after == run.before


def test_out_equal_to_an_external_buffer_is_written_with_force(tmp_path, kato_parts):  # noqa: F811
    gltf = gltf_with_buffer(tmp_path, "buffer.glb", kato_parts[1], kato_parts)
    (tmp_path / "buffer.glb").write_bytes(kato_parts[1])
    run = run_contained(retarget_argv(gltf, tmp_path / "buffer.glb", gltf, "--force"), tmp_path)
    assert run.code == 0, run.err
    assert (tmp_path / "buffer.glb").read_bytes()[:4] == b"glTF"


@pytest.mark.parametrize("which", ["--joint-map", "--checkpoint"])
def test_out_equal_to_another_input_is_refused(tmp_path, kato_parts, which):  # noqa: F811
    target = kato_glb(tmp_path / "kato.glb")
    other = tmp_path / "other.glb"
    other.write_text("Head: Head\n")
    argv = retarget_argv(target, other, target, which, other)
    if which == "--checkpoint":
        argv[argv.index("copy")] = "tdcn"
    run = run_contained(argv, tmp_path, other)
    run.assert_error(other, "refusing to overwrite an input")
    assert other.read_text() == "Head: Head\n"


# ---------------------------------------------------------------------------- temporary files
def test_the_sweep_keeps_a_users_tmp_file_and_a_look_alike_input(tmp_path):
    target = kato_glb(tmp_path / "kato.glb")
    notes = tmp_path / ".notes.tmp"
    notes.write_text("my notes")
    two_hours_ago = time.time() - 7200
    os.utime(notes, (two_hours_ago, two_hours_ago))
    joint_map = (
        tmp_path / ".map.yaml.999999999.abcd1234.tmp"
    )  # a dead process's temp name, by the old pattern
    joint_map.write_text("Head: Head\n")
    old = (
        tmp_path / f"{TEMP_PREFIX}999999999-abcd-o.bvh.tmp"
    )  # even our own prefix, without a record
    old.write_text("x")
    out = tmp_path / "o.bvh"
    run = run_contained(retarget_argv(target, out, target, "--joint-map", joint_map), tmp_path, out)
    assert run.code == 0, run.err
    assert (
        notes.read_text() == "my notes" and joint_map.read_text() == "Head: Head\n" and old.exists()
    )
    run.assert_contained(target, tmp_path)
    assert sweep_stale_temps(tmp_path) == []


def _killed_write(folder: Path) -> None:
    """A child process that dies by SIGKILL in the middle of an atomic write into ``folder``."""
    script = textwrap.dedent(f"""
        import os, signal
        from retarget_lib.files import atomic_write
        with atomic_write({str(folder / "big.bin")!r}) as f:
            f.write(b"x" * 1000)
            f.flush()
            os.kill(os.getpid(), signal.SIGKILL)
    """)
    env = dict(os.environ, PYTHONPATH=str(REPO_ROOT))
    proc = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True, timeout=120)
    assert proc.returncode == -signal.SIGKILL, proc.stderr


def test_a_killed_writes_temp_file_is_swept_from_its_record(tmp_path):
    _killed_write(tmp_path)
    left = [p for p in tmp_path.iterdir() if p.name.startswith(TEMP_PREFIX)]
    assert len(left) == 1 and not (tmp_path / "big.bin").exists()
    with atomic_write(tmp_path / "other.bin") as f:
        f.write(b"data")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["other.bin"]
    assert not [
        r for r in cache_dir("temp-records").glob("*.json") if str(tmp_path) in r.read_text()
    ]


def test_a_recorded_temp_replaced_by_a_users_file_is_kept(tmp_path):
    _killed_write(tmp_path)
    left = next(p for p in tmp_path.iterdir() if p.name.startswith(TEMP_PREFIX))
    mine = tmp_path / "mine"
    mine.write_text("the user's own file, same name, another inode")
    os.replace(mine, left)
    assert sweep_stale_temps(tmp_path) == []
    assert left.read_text().startswith("the user's own file")


def test_a_live_writes_temp_file_is_kept(tmp_path):
    with atomic_write(tmp_path / "out.bin") as f:
        f.write(b"partial")
        assert sweep_stale_temps(tmp_path) == []
        assert len([p for p in tmp_path.iterdir() if p.name.startswith(TEMP_PREFIX)]) == 1
    assert [p.name for p in tmp_path.iterdir()] == ["out.bin"]
