"""Shared test helpers: a parametric canonical-22 test character and contact-run splitting."""

import numpy as np

from retarget_lib.core.skeleton import J, canonical22_skeleton


def make_skeleton(height=1.8, leg_frac=0.5, arm_deg=0.0, spine_curve_deg=0.0):
    """A canonical-22 test character standing on ``y = 0``.

    Args:
        height: rough stature in metres.
        leg_frac: hip height as a fraction of ``height``.
        arm_deg: arms lowered from a T-pose by this angle (45 = A-pose).
        spine_curve_deg: forward bend per spine joint in the rest pose.
    """
    s = height / 1.8
    leg = leg_frac * height
    thigh, shin, ankle_h = 0.47 * leg, 0.47 * leg, 0.06 * leg
    seg = (height - leg - 0.22 * s) / 4.0
    off = np.zeros((22, 3))
    off[J["Hips"]] = (0.0, 0.06 * s + thigh + shin + ankle_h, 0.0)
    bend = np.radians(spine_curve_deg)
    for k, name in enumerate(("Spine", "Spine1", "Spine2", "Neck")):
        off[J[name]] = seg * np.array([0.0, np.cos(bend * (k - 1.5)), np.sin(bend * (k - 1.5))])
    off[J["Head"]] = (0.0, 0.1 * s, 0.01 * s)
    arm = np.radians(arm_deg)
    for side, sx in (("Left", 1.0), ("Right", -1.0)):
        off[J[f"{side}UpLeg"]] = (sx * 0.09 * s, -0.06 * s, 0.0)
        off[J[f"{side}Leg"]] = (0.0, -thigh, 0.01 * s)
        off[J[f"{side}Foot"]] = (0.0, -shin, -0.01 * s)
        off[J[f"{side}ToeBase"]] = (sx * 0.01 * s, -ankle_h, 0.14 * s)
        off[J[f"{side}Shoulder"]] = (sx * 0.05 * s, 0.1 * s, 0.0)
        off[J[f"{side}Arm"]] = (sx * 0.12 * s, 0.0, 0.0)
        direction = np.array([sx * np.cos(arm), -np.sin(arm), 0.0])
        off[J[f"{side}ForeArm"]] = 0.29 * s * direction
        off[J[f"{side}Hand"]] = 0.26 * s * direction
    return canonical22_skeleton(off)


def contact_runs(mask):
    """``(start, stop)`` index pairs of the runs of ``True`` in a 1-D bool ``mask``."""
    m = np.concatenate(([False], mask, [False]))
    e = np.flatnonzero(m[1:] != m[:-1])
    return list(zip(e[::2], e[1::2], strict=False))


def assert_same_up_to_floor_shift(actual, expected, atol, max_shift=0.3):
    """``(T, J, 3)`` positions equal but for one vertical shift per frame (the ground rule of
    ``retarget retarget``, :func:`retarget_lib.core.ground.floor_offset`), at most ``max_shift``
    metres (a source whose floor is not the target's: 15-21 cm measured between CMU and Mixamo
    proportions)."""
    actual, expected = np.asarray(actual), np.asarray(expected)
    np.testing.assert_allclose(actual[..., [0, 2]], expected[..., [0, 2]], atol=atol)
    dy = actual[..., 1] - expected[..., 1]  # (T, J)
    np.testing.assert_allclose(dy, np.broadcast_to(dy[:, :1], dy.shape), atol=atol)
    assert np.abs(dy).max() <= max_shift, f"shifted {np.abs(dy).max():.3f} m"
