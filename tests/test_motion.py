"""Motion container: windows, resampling, mirroring, root normalisation."""

import numpy as np
import pytest
import torch

from retarget_lib.core.motion import Motion
from retarget_lib.core.rotations import quat_from_axis_angle
from retarget_lib.core.skeleton import CANONICAL22, MIRROR22, canonical22_skeleton


def random_motion(T=50, fps=30.0, seed=0):
    rng = np.random.default_rng(seed)
    off = rng.normal(size=(22, 3)) * 0.1
    rot = rng.normal(size=(T, 22, 4))
    rot /= np.linalg.norm(rot, axis=-1, keepdims=True)
    root = np.cumsum(rng.normal(size=(T, 3)) * 0.01, axis=0)
    return Motion(canonical22_skeleton(off), rot, root, fps, name="rand")


def test_rejects_nan_and_bad_shapes():
    m = random_motion()
    bad = m.rotations.copy()
    bad[3, 4, 0] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        Motion(m.skeleton, bad, m.root_positions, 30)
    with pytest.raises(ValueError, match="rotations must be"):
        Motion(m.skeleton, m.rotations[:, :5], m.root_positions, 30)


def test_windows_cover_and_pad():
    m = random_motion(T=100)
    w = m.windows(30)
    assert [x.num_frames for x in w] == [30, 30, 30]
    np.testing.assert_array_equal(w[1].rotations, m.rotations[30:60])
    w = m.windows(30, pad_last=True)
    assert len(w) == 4 and np.array_equal(w[-1].rotations, m.rotations[70:100])
    short = m.slice(0, 10).windows(30, pad_last=True)
    assert len(short) == 1 and short[0].num_frames == 30
    np.testing.assert_array_equal(short[0].rotations[20], m.rotations[9])


def test_resample_120_to_30_keeps_samples_and_duration():
    T = 121
    t = np.arange(T) / 120.0
    root = np.stack([t, np.zeros(T), 2 * t], -1)
    angles = np.zeros((T, 22, 3))
    angles[:, 5, 1] = t  # head yaw grows linearly in time
    rot = quat_from_axis_angle(torch.from_numpy(angles)).numpy()
    m = Motion(canonical22_skeleton(np.ones((22, 3)) * 0.1), rot, root, 120.0)
    r = m.resample(30.0)
    assert r.num_frames == 31 and r.fps == 30.0
    np.testing.assert_allclose(r.root_positions, root[::4], atol=1e-12)
    np.testing.assert_allclose(r.rotations, rot[::4], atol=1e-12)
    # half-way samples are interpolated (slerp of a linear yaw is linear)
    h = m.resample(240.0)
    np.testing.assert_allclose(
        h.rotations[1, 5],
        quat_from_axis_angle(torch.tensor([0.0, 0.5 / 120.0, 0.0], dtype=torch.float64)).numpy(),
        atol=1e-12,
    )


def test_mirror_reflects_world_positions_and_swaps_sides():
    m = random_motion()
    p = m.global_positions()
    pm = m.mirror().global_positions()
    expected = p[:, list(MIRROR22)] * np.array([-1.0, 1.0, 1.0])
    np.testing.assert_allclose(pm, expected, atol=1e-12)
    assert CANONICAL22[MIRROR22[CANONICAL22.index("LeftHand")]] == "RightHand"


def test_normalize_root_faces_plus_z_at_origin_on_ground():
    m = random_motion(T=40)
    n = m.normalize_root()
    f0 = n.facing()[0]
    np.testing.assert_allclose(f0, [0.0, 0.0, 1.0], atol=1e-9)
    np.testing.assert_allclose(n.root_positions[0, [0, 2]], 0.0, atol=1e-12)
    assert abs(n.global_positions()[:30, :, 1].min()) < 1e-12
    # a rigid motion of the whole clip: bone lengths and the relative trajectory are unchanged
    d_old = np.linalg.norm(np.diff(m.root_positions, axis=0), axis=-1)
    d_new = np.linalg.norm(np.diff(n.root_positions, axis=0), axis=-1)
    np.testing.assert_allclose(d_old, d_new, atol=1e-12)
