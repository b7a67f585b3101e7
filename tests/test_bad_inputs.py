"""The bad-input catalogue (issue 10): every class of bad input gets a clear error, never a
traceback, a silent wrong output, code execution or a destroyed input.

Through the CLI: exit status 2 and one line on stderr naming the file (or key) and the problem.
Through the library: a documented exception type (:mod:`retarget_lib.errors`). The BVH reader
is also fuzzed (``hypothesis``): any mutation of a valid file loads to finite data within the
bounds or raises ``BVHError`` naming a line, within a second.
"""

import os
import re
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest
import torch
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from retarget_lib.cli import main
from retarget_lib.config import ConfigError, load_config
from retarget_lib.core.motion import Motion
from retarget_lib.core.rotations import quat_from_euler
from retarget_lib.core.skeleton import JointSetError, Skeleton
from retarget_lib.data.checkpoints import load_state, resolve_checkpoint
from retarget_lib.data.manifest import checkpoint as shipped_checkpoint
from retarget_lib.data.synthetic.characters import make_character
from retarget_lib.errors import (
    CheckpointError,
    InputFileError,
    LimitError,
    OutputPathError,
    RetargetInputError,
)
from retarget_lib.files import REPO_ROOT, atomic_write, sweep_stale_temps
from retarget_lib.io import BVHError, ShapeError, load_bvh, load_shape_npz, save_bvh, save_shape_npz
from retarget_lib.io.bvh import MAX_FILE_BYTES
from retarget_lib.skeleton import to_canonical22

pytestmark = pytest.mark.tooling  # nothing here depends on the thread count (make unit-threads)

CONFIGS = REPO_ROOT / "configs"


def clip(name="kato", frames=60, fps=60.0, seed=0):
    """A short random-pose clip on a synthetic character (no built data needed)."""
    sk = make_character(name).skeleton
    # small random poses: a plausible body that `retarget retarget` writes (check_posture)
    angles = torch.from_numpy(np.random.default_rng(seed).normal(0.0, 3.0, (frames, 22, 3)))
    rot = quat_from_euler(angles, "ZXY", degrees=True).numpy()
    return Motion(sk, rot, np.tile(sk.offsets[0], (frames, 1)), fps, name=name)


@pytest.fixture
def src(tmp_path):
    path = tmp_path / "src.bvh"
    save_bvh(clip(), path, unit="inch")
    return path


def retarget_args(source, out, target="kato", method="copy", *extra):
    return [
        "retarget",
        "--source",
        str(source),
        "--target",
        str(target),
        "--method",
        method,
        "--out",
        str(out),
        *extra,
    ]


def assert_cli_error(capsys, argv, *fragments):
    """Exit 2 and exactly one stderr line containing every fragment."""
    capsys.readouterr()
    assert main(argv) == 2
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert "Traceback" not in err
    for fragment in fragments:
        assert str(fragment) in lines[0], lines[0]
    return lines[0]


def edit_frame_line(path, column, value, out):
    """``path`` with one value of the first frame replaced."""
    lines = Path(path).read_text().splitlines()
    first = next(i for i, line in enumerate(lines) if line.startswith("Frame Time")) + 1
    row = lines[first].split()
    row[column] = value
    lines[first] = " ".join(row)
    out.write_text("\n".join(lines) + "\n")
    return out, first + 1


# ------------------------------------------------------------------------------ code execution
class _Payload:
    def __reduce__(self):
        return (os.system, (f"touch {Path.cwd() / 'pwned'}",))


def test_a_crafted_checkpoint_is_refused_without_running_code(tmp_path, monkeypatch, capsys, src):
    monkeypatch.chdir(tmp_path)
    evil = tmp_path / "evil.pt"
    torch.save(
        {"config": {}, "modules": {}, "x": _Payload()}, evil
    )  # torch.load(weights_only=False) runs it
    with pytest.raises(CheckpointError, match="evil.pt"):
        load_state(evil)
    assert_cli_error(
        capsys,
        retarget_args(src, tmp_path / "o.bvh", "kato", "tdcn", "--checkpoint", str(evil)),
        "evil.pt",
        "not a readable checkpoint",
    )
    assert not (tmp_path / "pwned").exists()


def test_a_shipped_id_never_resolves_to_a_file_of_that_name(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "tdcn-ours-fast").write_bytes(b"not the shipped file")
    assert resolve_checkpoint("tdcn-ours-fast") == shipped_checkpoint("tdcn-ours-fast").path


# ----------------------------------------------------------------------------- inputs destroyed
@pytest.mark.parametrize("which", ["source", "target"])
def test_out_equal_to_an_input_is_refused(tmp_path, capsys, src, which):
    target = tmp_path / "target.bvh"
    save_bvh(clip("gus", frames=2), target)
    before = {p: p.read_bytes() for p in (src, target)}
    out = src if which == "source" else target
    assert_cli_error(
        capsys,
        retarget_args(src, out, target),
        str(out),
        "refusing to overwrite an input",
        "--force",
    )
    assert all(p.read_bytes() == b for p, b in before.items())
    with pytest.raises(OutputPathError):
        from retarget_lib.methods.retarget import retarget_file

        retarget_file(src, str(target), "copy", out)
    assert main(retarget_args(src, out, target, "copy", "--force")) == 0  # allowed when asked for


def test_only_recorded_temp_files_of_gone_processes_are_swept(tmp_path):
    """Files that merely look like temporary files (a user's ``.notes.tmp``, the old
    ``.NAME.<pid>.<random>.tmp`` pattern of a dead process) are never removed; the temporary file
    of a write whose process is gone is, from its record (tests/test_untrusted_paths.py:
    SIGKILL)."""
    dead = tmp_path / ".out.bvh.999999999.abcd1234.tmp"  # pid beyond pid_max: its process is gone
    legacy = tmp_path / ".out.bvh.abcd1234.tmp"  # before temp names carried a pid
    notes = tmp_path / ".notes.tmp"
    for p in (dead, legacy, notes):
        p.write_bytes(b"x" * 100)
    two_hours_ago = time.time() - 7200
    os.utime(legacy, (two_hours_ago, two_hours_ago))
    os.utime(notes, (two_hours_ago, two_hours_ago))
    with atomic_write(tmp_path / "out.bvh", "w") as f:
        f.write("data")
    assert sweep_stale_temps(tmp_path) == []
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(
        [dead.name, legacy.name, notes.name, "out.bvh"]
    )


@pytest.mark.parametrize("signame", ["SIGTERM", "SIGINT"])
def test_a_killed_write_leaves_no_temp_file(tmp_path, signame):
    script = textwrap.dedent(f"""
        import os, signal
        from retarget_lib.files import atomic_write, exit_on_signals
        exit_on_signals()
        with atomic_write({str(tmp_path / "big.bin")!r}) as f:
            f.write(b"x" * 1000)
            os.kill(os.getpid(), signal.{signame})
            f.write(b"never")
    """)
    env = dict(os.environ, PYTHONPATH=str(REPO_ROOT))
    proc = subprocess.run(
        [sys.executable, "-c", script], env=env, capture_output=True, text=True, timeout=60
    )
    assert proc.returncode == 128 + {"SIGTERM": 15, "SIGINT": 2}[signame], proc.stderr
    assert list(tmp_path.iterdir()) == []


# ------------------------------------------------------------------------- silent wrong outputs
@pytest.mark.parametrize("frame_time", ["100", "1e-12", "-0.1", "nan"])
def test_frame_time_outside_its_bounds(tmp_path, capsys, src, frame_time):
    bad = tmp_path / "ft.bvh"
    text = src.read_text()
    line = (
        text.splitlines().index(next(ln for ln in text.splitlines() if ln.startswith("Frame Time")))
        + 1
    )
    bad.write_text(
        "\n".join(
            f"Frame Time: {frame_time}" if ln.startswith("Frame Time") else ln
            for ln in text.splitlines()
        )
    )
    with pytest.raises(
        BVHError, match=f"line {line}: frame time must be positive and within the limits 0.001-1 s"
    ):
        load_bvh(bad)
    assert_cli_error(
        capsys, retarget_args(bad, tmp_path / "o.bvh"), "ft.bvh", f"line {line}", "0.001-1 s"
    )


@pytest.mark.parametrize(
    "column,value,problem",
    [
        (5, "1e308", "rotation beyond |a| <= 100000 degrees"),
        (0, "1e300", "position beyond |x| <= 1e+06 file units"),
    ],
)
def test_huge_rotations_and_positions(tmp_path, capsys, src, column, value, problem):
    bad, line = edit_frame_line(src, column, value, tmp_path / "huge.bvh")
    with pytest.raises(
        BVHError, match=f"line {line}: .*" + problem.replace("|", r"\|").replace("+", r"\+")
    ):
        load_bvh(bad)
    assert_cli_error(
        capsys, retarget_args(bad, tmp_path / "o.bvh"), "huge.bvh", f"line {line}", problem
    )


def test_huge_offset(tmp_path):
    text = (
        "HIERARCHY\nROOT Hips\n{\n  OFFSET 0 1e300 0\n  CHANNELS 3 Zrotation Xrotation "
        "Yrotation\n}\n"
        "MOTION\nFrames: 1\nFrame Time: 0.033\n0 0 0\n"
    )
    (tmp_path / "off.bvh").write_text(text)
    with pytest.raises(BVHError, match=r"line 4: OFFSET value beyond the limit \|x\| <= 1e\+06"):
        load_bvh(tmp_path / "off.bvh")


def test_a_resampled_clip_beyond_the_frame_limit(src):
    with pytest.raises(LimitError, match="beyond the limit of 1000000"):
        load_bvh(src).resample(2e7)


@pytest.mark.parametrize(
    "name,problem",
    [
        ("nan", "non-finite (NaN or inf) rotations"),
        ("fps", "cannot write frame rate -30 fps"),
        ("huge", "root positions beyond the limit"),
    ],
)
def test_save_bvh_refuses_what_load_bvh_would_reject(tmp_path, name, problem):
    m = clip(frames=3)
    if name == "nan":
        m.rotations[1, 2, 0] = np.nan
    elif name == "fps":
        m = m.copy(fps=-30.0)
    else:
        m.root_positions[0, 0] = 1e9
    with pytest.raises(BVHError, match=re.escape(problem)):
        save_bvh(m, tmp_path / "x.bvh")
    assert list(tmp_path.iterdir()) == []


def _scaled_checkpoint(tmp_path, factor=None, nan=False):
    state = torch.load(shipped_checkpoint("tdcn-ours-fast").path, weights_only=True)
    weights = state["modules"]["generator"]
    name = next(k for k, v in weights.items() if v.is_floating_point() and v.abs().max() > 0.1)
    weights[name] = (
        weights[name].float() * factor if factor else weights[name].float().fill_(float("nan"))
    )
    path = tmp_path / "bad.pt"
    torch.save(state, path)
    return path, name


@pytest.mark.parametrize("nan", [False, True])
def test_corrupted_checkpoint_weights(tmp_path, capsys, src, nan):
    path, name = _scaled_checkpoint(tmp_path, None if nan else 1e6, nan)
    problem = "NaN or inf weights" if nan else "weights beyond the limit"
    with pytest.raises(CheckpointError, match=problem):
        load_state(path)
    assert_cli_error(
        capsys,
        retarget_args(src, tmp_path / "o.bvh", "kato", "tdcn", "--checkpoint", str(path)),
        "bad.pt",
        name,
        problem,
    )


def test_bit_flipped_checkpoint(tmp_path, capsys, src):
    data = bytearray(shipped_checkpoint("tdcn-ours-fast").path.read_bytes())
    for k in np.random.default_rng(1).integers(1000, len(data) - 1000, 2000):
        data[k] ^= 0xFF
    (tmp_path / "flip.pt").write_bytes(bytes(data))
    assert_cli_error(
        capsys,
        retarget_args(
            src, tmp_path / "o.bvh", "kato", "tdcn", "--checkpoint", str(tmp_path / "flip.pt")
        ),
        "flip.pt",
    )
    assert not (tmp_path / "o.bvh").exists()


@pytest.mark.parametrize(
    "delta,key",
    [
        ("trian: {steps: 3}", "unknown key 'trian'"),
        ("train: {stesp: 3}", "unknown key 'train.stesp'; allowed in 'train': batch, betas"),
        ("loss: {lambda_hh: 3}", "unknown key 'loss.lambda_hh'"),
        ("train: {steps: abc}", "train.steps = 'abc' is invalid: must be an integer > 0"),
        ("model: {channels: -4}", "model.channels = -4 is invalid: must be an integer > 0"),
        ("train: [unclosed", "line 3 malformed YAML"),
    ],
)
def test_config_file_errors_stop_before_any_work(tmp_path, capsys, delta, key):
    cfg = tmp_path / "bad.yaml"
    cfg.write_text(f"base: {CONFIGS / 'tdcn_paper.yaml'}\n{delta}\n")
    with pytest.raises(ConfigError, match=key.replace("[", r"\[")):
        load_config(cfg)
    assert_cli_error(
        capsys, ["train", "--config", str(cfg), "--out", str(tmp_path / "run")], "bad.yaml", key
    )
    assert not (tmp_path / "run").exists()


def test_contact_config_typo(tmp_path):
    cfg = tmp_path / "c.yaml"
    cfg.write_text(f"base: {CONFIGS / 'contact_paper.yaml'}\ndata: {{windw: 30}}\n")
    with pytest.raises(
        ConfigError, match="unknown key 'data.windw'; allowed in 'data': held_out_seed"
    ):
        load_config(cfg)


@pytest.mark.parametrize(
    "override,problem",
    [
        ("model.channels=-4", "model.channels = -4 is invalid: must be an integer > 0"),
        ("train.lr=abc", "train.lr = 'abc' is invalid"),
        ("train.stesp=3", "unknown key 'train.stesp'; allowed in 'train': batch"),
    ],
)
def test_config_override_errors(tmp_path, capsys, override, problem):
    assert_cli_error(
        capsys,
        [
            "train",
            "--config",
            str(CONFIGS / "tdcn_paper.yaml"),
            override,
            "--out",
            str(tmp_path / "run"),
        ],
        problem,
    )
    assert not (tmp_path / "run").exists()


def test_every_shipped_config_is_valid():
    for path in sorted(CONFIGS.glob("*.yaml")):
        for profile in ("fast", "paper"):
            load_config(path, profile=profile)


def test_a_mesh_for_a_skeleton_only_method_is_refused(tmp_path, capsys, src):
    assert_cli_error(
        capsys,
        retarget_args(src, tmp_path / "o.bvh", "kato", "copy", "--target-mesh", "x.npz"),
        "x.npz",
        "--target-mesh is only used by methods that need meshes",
        "--method copy",
    )


def test_no_eso_for_a_method_without_eso_is_refused(tmp_path, capsys, src):
    assert_cli_error(
        capsys,
        retarget_args(src, tmp_path / "o.bvh", "kato", "tdcn", "--no-eso"),
        "--no-eso is only used by --method contact",
        "--method tdcn",
    )
    assert not (tmp_path / "o.bvh").exists()


def test_no_eso_runs_the_contact_network_without_optimising(tmp_path, monkeypatch):
    """``--no-eso`` writes the network's output: with ESO made to fail, the same command fails
    without the flag and succeeds with it, and its pose is the network's."""
    import retarget_lib.methods.contact as contact
    from retarget_lib.methods.registry import get_method

    source = clip("kato", frames=20, fps=30.0)  # the methods' rate: no resampling
    src = tmp_path / "src.bvh"
    save_bvh(source, src)

    def no_eso(*args, **kwargs):
        raise AssertionError("ESO ran")

    monkeypatch.setattr(contact, "encoder_space_optimization", no_eso)
    with pytest.raises(AssertionError, match="ESO ran"):
        main(retarget_args(src, tmp_path / "eso.bvh", "bram", "contact"))
    out = tmp_path / "net.bvh"
    assert main(retarget_args(src, out, "bram", "contact", "--no-eso")) == 0
    model, _ = contact.load_contact_model(get_method("contact").default_checkpoint())
    network = contact.retarget_with_network(model, source, make_character("bram"))
    written = to_canonical22(load_bvh(out)).global_positions()
    expected = network.global_positions()
    # root-relative (the ground rule may lift the root); 0.1 mm: BVH text and float32 network
    np.testing.assert_allclose(written - written[:, :1], expected - expected[:, :1], atol=1e-4)


def test_a_mesh_of_another_character_is_refused(tmp_path, capsys, src):
    save_shape_npz(make_character("kato"), tmp_path / "kato.npz")
    target = tmp_path / "gus.bvh"
    save_bvh(clip("gus", frames=2), target)
    assert_cli_error(
        capsys,
        retarget_args(
            src, tmp_path / "o.bvh", target, "contact", "--target-mesh", str(tmp_path / "kato.npz")
        ),
        "kato.npz",
        "differs from the target",
    )


@pytest.mark.parametrize("name", ["out.obj", "out.txt", "out"])
def test_output_formats_that_cannot_be_written(tmp_path, capsys, src, name):
    assert_cli_error(
        capsys, retarget_args(src, tmp_path / name), name, "supported: .bvh, .glb, .fbx"
    )
    assert not (tmp_path / name).exists()


# ----------------------------------------------------------------------------------- tracebacks
@pytest.mark.parametrize("role", ["--source", "--target", "--out"])
def test_a_directory_as_a_path(tmp_path, capsys, src, role):
    folder = tmp_path / "folder.bvh"
    folder.mkdir()
    paths = {"--source": src, "--target": "kato", "--out": tmp_path / "o.bvh", role: folder}
    assert_cli_error(
        capsys,
        retarget_args(paths["--source"], paths["--out"], paths["--target"]),
        "folder.bvh",
        "is a directory",
    )


def test_missing_source(tmp_path, capsys):
    with pytest.raises(InputFileError, match="no such BVH file"):
        load_bvh(tmp_path / "nope.bvh")
    assert_cli_error(
        capsys, retarget_args(tmp_path / "nope.bvh", tmp_path / "o.bvh"), "nope.bvh", "no such"
    )


@pytest.mark.skipif(os.geteuid() == 0, reason="root reads files whatever their mode")
def test_unreadable_source(tmp_path, capsys, src):
    src.chmod(0)
    assert_cli_error(capsys, retarget_args(src, tmp_path / "o.bvh"), "src.bvh", "permission denied")


def test_out_whose_parent_is_a_file(tmp_path, capsys, src):
    (tmp_path / "afile").write_text("x")
    with pytest.raises(OutputPathError, match="is a file"):
        save_bvh(clip(frames=2), tmp_path / "afile" / "o.bvh")
    assert_cli_error(
        capsys, retarget_args(src, tmp_path / "afile" / "o.bvh"), "o.bvh", "afile is a file"
    )


@pytest.mark.parametrize(
    "content,problem",
    [
        (b"", "empty file"),
        (b"hello, not a checkpoint", "not a readable checkpoint"),
        ("truncated", "not a readable checkpoint"),
        ("state-only", "expected a mapping with 'config' and 'modules'"),
    ],
)
def test_unreadable_checkpoints(tmp_path, capsys, src, content, problem):
    path = tmp_path / "c.pt"
    if content == "truncated":
        path.write_bytes(shipped_checkpoint("tdcn-ours-fast").path.read_bytes()[:5000])
    elif content == "state-only":
        torch.save({"weight": torch.zeros(3)}, path)
    else:
        path.write_bytes(content)
    with pytest.raises(RetargetInputError, match=problem):
        load_state(path)
    assert_cli_error(
        capsys,
        retarget_args(src, tmp_path / "o.bvh", "kato", "tdcn", "--checkpoint", str(path)),
        "c.pt",
        problem,
    )


def test_a_checkpoint_of_another_model(tmp_path, capsys, src):
    state = torch.load(shipped_checkpoint("tdcn-ours-fast").path, weights_only=True)
    state["modules"]["generator"] = {
        k: v[..., :1] if v.dim() else v for k, v in state["modules"]["generator"].items()
    }
    torch.save(state, tmp_path / "small.pt")
    assert_cli_error(
        capsys,
        retarget_args(
            src, tmp_path / "o.bvh", "kato", "tdcn", "--checkpoint", str(tmp_path / "small.pt")
        ),
        "small.pt",
        "not a valid tdcn checkpoint",
    )


@pytest.mark.parametrize("cut", [0.5, 0.9])
def test_truncated_mesh(tmp_path, capsys, src, cut):
    save_shape_npz(make_character("kato"), tmp_path / "full.npz")
    data = (tmp_path / "full.npz").read_bytes()
    (tmp_path / "cut.npz").write_bytes(data[: int(len(data) * cut)])
    with pytest.raises(ShapeError, match="cut.npz: not a readable .npz file"):
        load_shape_npz(tmp_path / "cut.npz")
    assert_cli_error(
        capsys,
        retarget_args(
            src, tmp_path / "o.bvh", "kato", "contact", "--target-mesh", str(tmp_path / "cut.npz")
        ),
        "cut.npz",
        "not a readable .npz",
    )


def nested(depth):
    joints = "".join(
        f"JOINT j{k}\n{{\nOFFSET 0 1 0\nCHANNELS 3 Zrotation Xrotation Yrotation\n"
        for k in range(depth)
    )
    return (
        "HIERARCHY\nROOT r\n{\nOFFSET 0 0 0\nCHANNELS 3 Zrotation Xrotation Yrotation\n"
        + joints
        + "}\n" * (depth + 1)
        + "MOTION\nFrames: 1\nFrame Time: 0.0333\n"
        + " ".join(["0"] * (3 * (depth + 1)))
    )


def test_deep_nesting(tmp_path, capsys):
    (tmp_path / "deep.bvh").write_text(nested(3000))
    with pytest.raises(BVHError, match="line 402: joints nested more than 100 deep"):
        load_bvh(tmp_path / "deep.bvh")
    assert_cli_error(
        capsys, retarget_args(tmp_path / "deep.bvh", tmp_path / "o.bvh"), "deep.bvh", "nested"
    )


def test_unknown_convention():
    sk = Skeleton(["root", "tip"], [-1, 0], np.array([[0.0, 1.0, 0.0], [0.0, 0.5, 0.0]]))
    motion = Motion(sk, np.tile([1.0, 0, 0, 0], (2, 2, 1)), np.zeros((2, 3)), 30.0)
    with pytest.raises(
        JointSetError, match="m.bvh: unknown joint-name convention 'martian'; known: mixamo, cmu"
    ):
        to_canonical22(motion, "martian", what="m.bvh")


# --------------------------------------------------------------------------------------- hangs
def test_many_joints_fail_fast_and_loading_is_linear(tmp_path, capsys):
    def wide(n):
        return (
            "HIERARCHY\nROOT r\n{\nOFFSET 0 0 0\nCHANNELS 3 Zrotation Xrotation Yrotation\n"
            + "".join(f"JOINT j{k}\n{{\nOFFSET 0 1 0\n}}\n" for k in range(n))
            + "}\nMOTION\nFrames: 1\nFrame Time: 0.0333\n0 0 0\n"
        )

    (tmp_path / "wide.bvh").write_text(wide(40_000))
    start = time.perf_counter()
    assert_cli_error(
        capsys,
        retarget_args(tmp_path / "wide.bvh", tmp_path / "o.bvh"),
        "wide.bvh",
        "more than 1000 joints",
    )
    assert time.perf_counter() - start < 5.0  # measured 0.2 s; quadratic loading took > 18 s
    # at the limit: 999 joints load in well under a second
    (tmp_path / "limit.bvh").write_text(wide(999))
    start = time.perf_counter()
    assert load_bvh(tmp_path / "limit.bvh").skeleton.num_joints == 1000
    assert time.perf_counter() - start < 5.0


def test_garbage_and_oversized_files_fail_before_being_read(tmp_path, capsys):
    garbage = tmp_path / "garbage.bvh"
    garbage.write_bytes(b"lorem ipsum " * 500_000)  # 6 MB on one line
    start = time.perf_counter()
    with pytest.raises(BVHError, match="line 1: expected HIERARCHY"):
        load_bvh(garbage)
    assert time.perf_counter() - start < 2.0
    huge = tmp_path / "huge.bvh"
    with open(huge, "wb") as f:  # sparse: no disk used
        f.truncate(MAX_FILE_BYTES + 1)
    assert_cli_error(
        capsys, retarget_args(huge, tmp_path / "o.bvh"), "huge.bvh", "exceeds the 64 MiB limit"
    )


# ------------------------------------------------------------------------------ units and fps
def test_output_keeps_the_sources_frame_rate_and_unit(tmp_path, src):
    out = tmp_path / "o.bvh"
    assert main(retarget_args(src, out)) == 0
    written = load_bvh(out)
    assert (
        written.fps == 60 and written.num_frames == 60
    )  # every source frame (31 at 30 fps in between)
    assert written.meta["unit"] == "inch" and "Frame Time: 0.01666667" in out.read_text()
    assert main(retarget_args(src, out, "kato", "copy", "--fps", "24")) == 0
    resampled = load_bvh(out)  # 59 / 60 s at 24 fps: floor(23.6) + 1 frames
    assert resampled.fps == 24 and resampled.num_frames == 24


@pytest.mark.slow
def test_every_method_writes_a_named_target_in_the_sources_unit(tmp_path, src):
    for method in ("copy", "tdcn", "contact"):
        out = tmp_path / f"{method}.bvh"
        assert main(retarget_args(src, out, "kato", method)) == 0
        assert load_bvh(out).meta["unit"] == "inch", method


# ------------------------------------------------------------------------------- BVH reader fuzz
FUZZ_BASE = """HIERARCHY
ROOT Hips
{
  OFFSET 0 90 0
  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
  JOINT Spine
  {
    OFFSET 0 10 0
    CHANNELS 3 Zrotation Xrotation Yrotation
    End Site
    {
      OFFSET 0 10 0
    }
  }
}
MOTION
Frames: 2
Frame Time: 0.0333333
0 90 0 10 20 30 1 2 3
1 91 0 11 21 31 2 3 4
"""
_FUZZ_TOKENS = [
    "{",
    "}",
    "ROOT",
    "JOINT",
    "End",
    "Site",
    "OFFSET",
    "CHANNELS",
    "MOTION",
    "Frames:",
    "Frame",
    "Time:",
    "3",
    "-1",
    "0",
    "1e308",
    "nan",
    "inf",
    "1e-12",
    "100",
    "Xrotation",
    "Zposition",
    "",
    "\t",
    "99999999999",
    "é",
    "\x00",
]


@st.composite
def mutated_bvh(draw):
    """The valid file above with one to three mutations: a token replaced or inserted, a line
    deleted or duplicated, the text truncated."""
    lines = FUZZ_BASE.splitlines()
    for _ in range(draw(st.integers(1, 3))):
        kind = draw(st.sampled_from(["replace", "insert", "delete", "duplicate", "truncate"]))
        i = draw(st.integers(0, len(lines) - 1))
        words = lines[i].split()
        token = draw(st.sampled_from(_FUZZ_TOKENS) | st.text(max_size=6))
        if kind == "replace" and words:
            words[draw(st.integers(0, len(words) - 1))] = token
            lines[i] = " ".join(words)
        elif kind == "insert":
            words.insert(draw(st.integers(0, len(words))), token)
            lines[i] = " ".join(words)
        elif kind == "delete" and len(lines) > 1:
            del lines[i]
        elif kind == "duplicate":
            lines.insert(i, lines[i])
        elif kind == "truncate":
            lines = lines[: i + 1]
    return "\n".join(lines) + "\n"


@settings(
    max_examples=300, deadline=1000, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(text=mutated_bvh())
def test_any_mutation_loads_within_bounds_or_names_a_line(tmp_path, text):
    path = tmp_path / "fuzz.bvh"
    path.write_text(text, encoding="utf-8", errors="surrogatepass")
    try:
        m = load_bvh(path)
    except BVHError as e:
        assert re.search(r"fuzz\.bvh: line \d+: ", str(e)), str(e)
        assert "\n" not in str(e)
        return
    except InputFileError as e:  # an empty file after truncation
        assert "empty file" in str(e)
        return
    assert np.isfinite(m.rotations).all() and np.isfinite(m.root_positions).all()
    assert np.isfinite(m.skeleton.offsets).all()
    assert np.abs(m.root_positions).max() <= 1e6 * m.meta["unit_scale"]
    assert 1 <= m.fps <= 1000 and 1 <= m.num_frames <= 1_000_000
    np.testing.assert_allclose(
        np.linalg.norm(m.rotations, axis=-1), 1.0, atol=1e-9
    )  # unit quaternions


# -------------------------------------------------------------------------------- data verify
def test_data_verify_names_truncated_empty_and_bit_flipped_cache_files(
    tmp_path, monkeypatch, capsys
):
    from retarget_lib.data.status import check_cache

    monkeypatch.setenv("RETARGET_CACHE", str(tmp_path))
    folder = tmp_path / "contact_training"
    folder.mkdir()
    np.savez(folder / "good.npz", a=np.arange(1000.0))
    data = (folder / "good.npz").read_bytes()
    (folder / "cut.npz").write_bytes(data[: len(data) // 2])
    (folder / "empty.npz").write_bytes(b"")
    flipped = bytearray(data)
    flipped[len(data) // 2] ^= 0xFF  # inside the array's bytes: the zip CRC fails
    (folder / "flip.npz").write_bytes(bytes(flipped))
    status = check_cache()
    assert status.state == "BAD" and "3 bad file(s)" in status.detail
    for name in (
        "cut.npz: truncated or corrupt",
        "empty.npz: empty file",
        "flip.npz: truncated or corrupt",
    ):
        assert name in status.detail
    assert "good.npz" not in status.detail
    assert_cli_error(
        capsys, ["data", "verify"], "data verification failed", "flip.npz", "cut.npz", "empty.npz"
    )


def test_an_output_folder_that_cannot_be_written_names_the_output(
    tmp_path, capsys, src, monkeypatch
):
    """A read-only folder (simulated: the suite runs as root, which writes anywhere): the error
    names the --out file, not the temporary file beside it."""
    import retarget_lib.files as files

    real_open = files.os.open

    def refuse_temps(path, *args, **kw):
        if Path(path).name.startswith(files.TEMP_PREFIX):
            raise PermissionError(13, "Permission denied", str(path))
        return real_open(path, *args, **kw)

    monkeypatch.setattr(files.os, "open", refuse_temps)
    capsys.readouterr()
    assert main(retarget_args(src, tmp_path / "o.bvh")) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert (
        len(err) == 1
        and f"{tmp_path / 'o.bvh'}: cannot write into" in err[0]
        and ".tmp" not in err[0]
    ), err
