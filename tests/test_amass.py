"""SMPL-X / AMASS motion .npz files (issue 12): skeleton from the betas, axes, round trips, bad
files."""

import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st
from mannequin import Mannequin

from retarget_lib.core.rotations import (
    quat_from_axis_angle,
    quat_mul,
    quat_rotate,
    quat_to_axis_angle,
)
from retarget_lib.data.synthetic.amass_clip import (
    AMASS_CLIP_BETAS,
    AMASS_CLIP_PATH,
    make_amass_clip,
)
from retarget_lib.errors import AMASSError, RetargetInputError
from retarget_lib.io import load_bvh, save_bvh
from retarget_lib.io.amass import SMPLX_TO_CANONICAL as ORDER
from retarget_lib.io.amass import _pelvis_rest, load_amass, save_amass, smplx_skeleton
from retarget_lib.io.joint_maps import to_canonical22


@settings(max_examples=10, deadline=None)
@given(st.lists(st.floats(-3, 3), min_size=10, max_size=10))
def test_skeleton_from_betas_matches_mannequin_x(betas):
    """The rest joints equal mannequin-x's own SMPL-X skeleton (its public forward_skeleton) up to
    the floor shift, for any shape within +-3 standard deviations."""
    betas = np.array(betas)
    body = Mannequin("convex", shape=betas)
    theirs = body.joint_transforms(body.rest_pose())[:22, :3, 3][list(ORDER)]
    ours = smplx_skeleton(betas).rest_positions()
    shift = theirs - ours
    np.testing.assert_allclose(shift - shift[0], 0.0, atol=1e-6)  # float32 package arithmetic
    np.testing.assert_allclose(shift[0, [0, 2]], 0.0, atol=1e-6)  # only the height is shifted


def test_shipped_clip_is_reproducible_and_round_trips_through_bvh(tmp_path):
    again = tmp_path / "walk.npz"
    make_amass_clip(again)
    shipped, made = np.load(AMASS_CLIP_PATH), np.load(again)
    for key in ("betas", "mocap_frame_rate"):
        np.testing.assert_array_equal(shipped[key], made[key])  # copied, not recomputed: exact
    # float64 regenerated (trig, quaternion products, a betas matmul): last-bit differences between
    # CPUs (2.2e-16 m measured). trans = root - J_0 cancels metre-sized terms, so the error is
    # absolute (1.1e-16 m at |trans| = 0.06 m, 16 of its ulps); poses are then rounded to float32,
    # which that can flip by one ulp
    np.testing.assert_allclose(made["trans"], shipped["trans"], rtol=0, atol=1e-15)
    np.testing.assert_allclose(
        made["poses"], shipped["poses"], rtol=np.finfo(np.float32).eps, atol=1e-15
    )
    assert shipped["poses"].shape == (120, 165) and shipped["betas"].shape == (16,)
    motion = load_amass(AMASS_CLIP_PATH)
    assert motion.meta["up"] == "z" and motion.fps == 30.0 and motion.skeleton.is_canonical22()
    np.testing.assert_allclose(motion.meta["betas"][:10], AMASS_CLIP_BETAS)
    # a walk on the floor: feet touch y = 0 (the soles' rest height), the body faces +Z and walks
    # forward
    pos = motion.global_positions()
    assert pos[:, :, 1].min() > -0.02 and pos[:, [8, 12], 1].min() < 0.12
    assert motion.root_positions[-1, 2] - motion.root_positions[0, 2] > 0.5
    bvh = tmp_path / "walk.bvh"
    save_bvh(motion, bvh)
    np.testing.assert_allclose(
        to_canonical22(load_bvh(bvh)).global_positions(), pos, atol=1e-4
    )  # BVH text: 6 decimals


def test_write_read_is_exact_to_float32_and_y_up_files_are_detected(tmp_path):
    motion = load_amass(AMASS_CLIP_PATH)
    out = tmp_path / "again.npz"
    save_amass(motion, out, motion.meta["betas"])
    back = load_amass(out)
    np.testing.assert_allclose(
        back.global_positions(), motion.global_positions(), atol=1e-5
    )  # float32 poses
    # the same clip stored Y-up: root orientation and pelvis turned -90 degrees about X
    data = dict(np.load(out))
    turn = torch.tensor(
        [np.cos(np.pi / 4), -np.sin(np.pi / 4), 0.0, 0.0], dtype=torch.float64
    ).expand(120, 4)
    root = quat_from_axis_angle(torch.from_numpy(data["poses"][:, :3].astype(np.float64)))
    data["poses"][:, :3] = quat_to_axis_angle(quat_mul(turn, root)).numpy()
    j0 = _pelvis_rest(data["betas"])  # the pelvis is at J_0 + trans
    data["trans"] = quat_rotate(turn, torch.from_numpy(data["trans"] + j0)).numpy() - j0
    y_up = tmp_path / "yup.npz"
    np.savez(y_up, **data)
    read = load_amass(y_up)
    assert read.meta["up"] == "y"
    np.testing.assert_allclose(read.global_positions(), back.global_positions(), atol=1e-5)


def _without(tmp_path, drop=(), **changes):
    data = dict(np.load(AMASS_CLIP_PATH))
    for k in drop:
        data.pop(k)
    data.update(changes)
    path = tmp_path / "bad.npz"
    np.savez(path, **data)
    return path


@pytest.mark.parametrize(
    "drop, changes, message",
    [
        (("betas",), {}, "no 'betas': the skeleton's bone lengths come from the body shape"),
        (("poses",), {}, "no 'poses'"),
        (("trans",), {}, "no 'trans'"),
        (("mocap_frame_rate",), {}, "no frame rate"),
        ((), {"poses": np.zeros((120, 30))}, r"poses must be \(T, >=66\)"),
        ((), {"trans": np.zeros((59, 3))}, r"trans must be \(120, 3\)"),
        ((), {"betas": np.full(16, np.nan)}, "betas holds NaN"),
        ((), {"betas": np.full(16, 50.0)}, "beyond the bound 10"),
        ((), {"mocap_frame_rate": np.float64(0.0)}, "frame rate 0.0 is outside"),
    ],
)
def test_bad_files_give_one_clear_error(tmp_path, drop, changes, message):
    with pytest.raises(AMASSError, match=message):
        load_amass(_without(tmp_path, drop, **changes))


def test_pickled_and_corrupt_files(tmp_path):
    pickled = tmp_path / "pickled.npz"
    data = dict(np.load(AMASS_CLIP_PATH))
    data["betas"] = np.array([list(range(10))], dtype=object)
    np.savez(pickled, **data)
    with pytest.raises(AMASSError, match="pickled object array"):
        load_amass(pickled)
    truncated = tmp_path / "truncated.npz"
    truncated.write_bytes(AMASS_CLIP_PATH.read_bytes()[:3000])
    with pytest.raises(RetargetInputError, match="not a readable .npz"):
        load_amass(truncated)
