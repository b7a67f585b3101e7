"""Malformed and hostile SMPL-X/AMASS ``.npz`` files (and shape ``.npz`` targets): one clear error
naming the file, or a correct result, without inflating what the budget refuses
(``retarget_lib.io.amass``, ``retarget_lib.io.untrusted.read_npz``)."""

import io
import zipfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from test_untrusted_harness import memory_cap, retarget_argv, run_contained

from retarget_lib.data.synthetic.amass_clip import AMASS_CLIP_PATH
from retarget_lib.errors import AMASSError, LimitError
from retarget_lib.io.amass import load_amass

pytestmark = pytest.mark.tooling  # nothing here depends on the thread count (make unit-threads)


def clip_arrays() -> dict[str, np.ndarray]:
    with np.load(AMASS_CLIP_PATH) as data:
        return {k: data[k] for k in data.files}


def npz(path: Path, **arrays) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez(path, **arrays)
    return path


def npz_bomb(path: Path, rows: int, cols: int, **others) -> Path:
    """An ``.npz`` whose ``poses`` member is ``rows x cols`` float32 zeros, deflated while streamed
    (the test never holds the array), beside ``others``."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED, compresslevel=1) as zf:
        for key, value in others.items():
            out = io.BytesIO()
            np.lib.format.write_array(out, np.asarray(value))
            zf.writestr(f"{key}.npy", out.getvalue())
        with zf.open("poses.npy", "w", force_zip64=True) as f:
            np.lib.format.write_array_header_1_0(
                f, {"descr": "<f4", "fortran_order": False, "shape": (rows, cols)}
            )
            left, chunk = rows * cols * 4, bytes(2**24)
            while left:
                f.write(chunk[: min(left, len(chunk))])
                left -= min(left, len(chunk))
    return path


def source_run(tmp_path, path: Path):
    out = tmp_path / "out" / "o.bvh"
    run = run_contained(retarget_argv(path, out), tmp_path, out)
    run.assert_contained(path, path.parent)
    return run


def test_an_empty_frame_rate(tmp_path):
    path = npz(
        tmp_path / "in" / "empty_rate.npz", **(clip_arrays() | {"mocap_frame_rate": np.array([])})
    )
    source_run(tmp_path, path).assert_error(
        path, "mocap_frame_rate must be one number (frames per second), got float64 of shape (0,)"
    )


@pytest.mark.parametrize("value", [np.array("30"), np.array([30.0, 60.0])])
def test_a_frame_rate_that_is_not_one_number(tmp_path, value):
    path = npz(tmp_path / "in" / "rate.npz", **(clip_arrays() | {"mocap_frame_rate": value}))
    source_run(tmp_path, path).assert_error(path, "mocap_frame_rate must be one number")


def test_no_frame_rate_gives_no_advice_that_cannot_help(tmp_path):
    arrays = clip_arrays()
    del arrays["mocap_frame_rate"]
    path = npz(tmp_path / "in" / "no_rate.npz", **arrays)
    line = source_run(tmp_path, path).assert_error(path, "no frame rate", "mocap_frame_rate")
    assert "--fps" not in line


@pytest.mark.parametrize("role", ["source", "target"])
def test_a_npy_named_npz(tmp_path, role):
    path = tmp_path / "in" / "poses.npz"
    path.parent.mkdir()
    np.save(path.with_suffix(""), clip_arrays()["poses"])  # np.save appends .npy
    path.with_suffix(".npy").rename(path)
    valid = npz(tmp_path / "in" / "valid.npz", **clip_arrays())
    out = tmp_path / "out" / "o.bvh"
    argv = retarget_argv(path, out) if role == "source" else retarget_argv(valid, out, path)
    run = run_contained(argv, tmp_path, out)
    run.assert_error(path, "a single .npy array, not an .npz archive of named arrays")
    run.assert_contained(path, tmp_path / "in")


def test_poses_that_would_inflate_beyond_the_budget(tmp_path):
    arrays = clip_arrays()
    path = npz_bomb(
        tmp_path / "in" / "bomb.npz",
        2_000_000,
        165,
        **{k: arrays[k] for k in ("betas", "trans", "mocap_frame_rate")},
    )
    assert path.stat().st_size < 8 * 2**20
    run = source_run(tmp_path, path)
    run.assert_error(
        path, "array 'poses' (2,000,000 x 165) would take 1.2 GiB, beyond the 1 GiB budget"
    )


def test_a_header_that_declares_more_than_its_member_holds(tmp_path):
    path = npz(tmp_path / "in" / "liar.npz", **clip_arrays())
    with zipfile.ZipFile(path) as zf:
        members = {n: zf.read(n) for n in zf.namelist()}
    assert b"(120, 165), }" in members["poses.npy"][:128]
    members["poses.npy"] = members["poses.npy"].replace(
        b"(120, 165), }", b"(99999, 165)}", 1
    )  # same length
    with zipfile.ZipFile(path, "w") as zf:
        for name, data in members.items():
            zf.writestr(name, data)
    with (
        memory_cap(),
        pytest.raises(
            AMASSError, match=r"liar.npz: array 'poses' declares \(99999, 165\) of float32"
        ),
    ):
        load_amass(path)


@pytest.mark.parametrize(
    "shape,problem",
    [
        ((200_000, 66), "200,000 frames x 22 joints"),
        ((10, 5000), "5,000 pose columns exceed the limit of 330"),
        ((1_000_001, 0), "1,000,001 frames of poses exceed the limit"),
    ],
)
def test_sizes_beyond_the_bounds_are_refused_from_the_header(tmp_path, shape, problem):
    arrays = clip_arrays()
    others = {k: arrays[k] for k in ("betas", "trans", "mocap_frame_rate")}
    path = npz_bomb(tmp_path / "in" / "big.npz", *shape, **others)
    with memory_cap(), pytest.raises(LimitError, match=problem):
        load_amass(path)


def test_pickled_poses_are_refused_without_unpickling(tmp_path):
    arrays = clip_arrays()
    arrays["poses"] = np.array([{"a": 1}], dtype=object)
    path = tmp_path / "in" / "pickled.npz"
    path.parent.mkdir()
    np.savez(path, **arrays)
    source_run(tmp_path, path).assert_error(path, "key 'poses' is a pickled object array")


# --------------------------------------------------------------------------------------- fuzz
_KEYS = [
    "poses",
    "root_orient",
    "pose_body",
    "betas",
    "trans",
    "mocap_frame_rate",
    "mocap_framerate",
    "gender",
    "x",
]
_DTYPES = ["<f4", "<f8", "<i4", "|b1", "<U3", "|u1", "<c8"]


@st.composite
def hostile_arrays(draw) -> dict[str, np.ndarray]:
    """The shipped clip's arrays with keys dropped, replaced by arrays of other shapes and dtypes
    (values from NaN to 1e300), or added."""
    arrays = clip_arrays()
    for _ in range(draw(st.integers(1, 4))):
        key = draw(st.sampled_from(_KEYS))
        if draw(st.booleans()) and key in arrays:
            del arrays[key]
            continue
        shape = tuple(
            draw(st.lists(st.sampled_from([0, 1, 2, 3, 22, 63, 66, 120, 165]), max_size=3))
        )
        dtype = np.dtype(draw(st.sampled_from(_DTYPES)))
        fill = draw(st.sampled_from([0.0, 1.0, -1.0, np.nan, np.inf, 1e300, 30.0, 120.0]))
        with np.errstate(over="ignore", invalid="ignore"):
            arrays[key] = (
                np.full(shape, fill).astype(dtype) if dtype.kind in "fc" else np.zeros(shape, dtype)
            )
    return arrays


@settings(
    max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(arrays=hostile_arrays(), layout=st.sampled_from(["npz", "npy", "truncated"]))
def test_fuzz_amass_npz(tmp_path_factory, arrays, layout):
    root = tmp_path_factory.mktemp("fuzz")
    path = npz(root / "in" / "fuzz.npz", **arrays)
    if layout == "npy":
        np.save(root / "in" / "fuzz.npy", arrays.get("poses", np.zeros(3)))
        (root / "in" / "fuzz.npy").replace(path)
    elif layout == "truncated":
        path.write_bytes(path.read_bytes()[: len(path.read_bytes()) // 2])
    out = root / "out" / "o.bvh"
    run = run_contained(retarget_argv(path, out), root, out)
    run.assert_contained(path, root / "in")
