"""Quaternion math: round trips in float64 against independent references."""

import math

import numpy as np
import pytest
import torch

from retarget_lib.core import rotations as R

ORDERS = ["XYZ", "XZY", "YXZ", "YZX", "ZXY", "ZYX"]


@pytest.fixture
def quats():
    torch.manual_seed(0)
    return R.quat_normalize(torch.randn(500, 4, dtype=torch.float64))


def axis_matrix(axis, a):
    c, s = math.cos(a), math.sin(a)
    return {
        "X": np.array([[1, 0, 0], [0, c, -s], [0, s, c]]),
        "Y": np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]]),
        "Z": np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]]),
    }[axis]


def same_rotation(a, b, tol=1e-10):
    return torch.minimum((a - b).abs().amax(-1), (a + b).abs().amax(-1)).max().item() < tol


@pytest.mark.parametrize("order", ORDERS)
def test_euler_matches_hand_built_matrix_product(order):
    angles = np.array([0.3, -1.1, 2.4])
    q = R.quat_from_euler(torch.tensor(angles, dtype=torch.float64), order)
    expected = (
        axis_matrix(order[0], angles[0])
        @ axis_matrix(order[1], angles[1])
        @ axis_matrix(order[2], angles[2])
    )
    np.testing.assert_allclose(R.quat_to_matrix(q).numpy(), expected, atol=1e-12)


@pytest.mark.parametrize("order", ORDERS)
def test_euler_round_trip(quats, order):
    e = R.quat_to_euler(quats, order, degrees=True)
    assert same_rotation(R.quat_from_euler(e, order, degrees=True), quats)
    assert e[:, 1].abs().max() <= 90.0 + 1e-9


def test_euler_gimbal_lock_round_trip():
    e = torch.tensor([[30.0, 90.0, 0.0], [-70.0, -90.0, 0.0]], dtype=torch.float64)
    q = R.quat_from_euler(e, "ZXY", degrees=True)
    assert same_rotation(R.quat_from_euler(R.quat_to_euler(q, "ZXY", True), "ZXY", True), q)


def test_matrix_round_trip_and_orthonormal(quats):
    m = R.quat_to_matrix(quats)
    eye = torch.eye(3, dtype=torch.float64).expand_as(m)
    assert torch.allclose(m @ m.transpose(-1, -2), eye, atol=1e-12)
    assert torch.allclose(torch.det(m), torch.ones(len(m), dtype=torch.float64))
    assert same_rotation(R.matrix_to_quat(m), quats, 1e-12)


def test_mul_matches_matrix_product_and_inverse(quats):
    a, b = quats[:250], quats[250:]
    ab = R.quat_mul(a, b)
    assert torch.allclose(
        R.quat_to_matrix(ab), R.quat_to_matrix(a) @ R.quat_to_matrix(b), atol=1e-12
    )
    ident = R.quat_mul(a, R.quat_inverse(a))
    assert same_rotation(ident, R.quat_identity((250,), torch.float64), 1e-12)


def test_rotate_matches_matrix(quats):
    v = torch.randn(500, 3, dtype=torch.float64)
    expected = (R.quat_to_matrix(quats) @ v.unsqueeze(-1)).squeeze(-1)
    assert torch.allclose(R.quat_rotate(quats, v), expected, atol=1e-12)


def test_axis_angle_round_trip_and_known_value(quats):
    assert same_rotation(R.quat_from_axis_angle(R.quat_to_axis_angle(quats)), quats, 1e-12)
    q = R.quat_from_axis_angle(torch.tensor([0.0, 0.0, math.pi / 2], dtype=torch.float64))
    assert torch.allclose(
        R.quat_rotate(q, torch.tensor([1.0, 0, 0], dtype=torch.float64)),
        torch.tensor([0.0, 1.0, 0.0], dtype=torch.float64),
        atol=1e-12,
    )
    # smooth at zero: the gradient exists and is finite
    aa = torch.zeros(3, dtype=torch.float64, requires_grad=True)
    R.quat_from_axis_angle(aa).sum().backward()
    assert torch.isfinite(aa.grad).all()


def test_6d_round_trip(quats):
    assert same_rotation(R.quat_from_6d(R.quat_to_6d(quats)), quats, 1e-12)


def test_angle_known_values():
    q = R.quat_from_axis_angle(
        torch.tensor([[0.0, 0.0, 0.0], [0.0, 1.0, 0.0], [3.0, 0.0, 0.0]], dtype=torch.float64)
    )
    assert torch.allclose(R.quat_angle(q), torch.tensor([0.0, 1.0, 3.0], dtype=torch.float64))
    assert torch.allclose(R.quat_angle(-q), R.quat_angle(q))


def test_slerp_endpoints_midpoint_and_constant_speed():
    a = R.quat_identity((), torch.float64)
    b = R.quat_from_axis_angle(torch.tensor([0.0, 2.0, 0.0], dtype=torch.float64))
    assert same_rotation(R.quat_slerp(a, b, 0.0), a) and same_rotation(R.quat_slerp(a, b, 1.0), b)
    ts = torch.linspace(0, 1, 5, dtype=torch.float64)
    angles = R.quat_angle(R.quat_slerp(a.expand(5, 4), b.expand(5, 4), ts))
    assert torch.allclose(angles, 2.0 * ts, atol=1e-12)
    # shorter arc: -b is the same rotation
    assert same_rotation(R.quat_slerp(a, -b, 0.5), R.quat_slerp(a, b, 0.5))


def test_between_and_swing_twist():
    u = torch.randn(100, 3, dtype=torch.float64)
    v = torch.randn(100, 3, dtype=torch.float64)
    q = R.quat_between(u, v)
    un, vn = u / u.norm(dim=-1, keepdim=True), v / v.norm(dim=-1, keepdim=True)
    assert torch.allclose(R.quat_rotate(q, un), vn, atol=1e-12)
    assert torch.allclose(R.quat_rotate(R.quat_between(u, -u), un), -un, atol=1e-12)
    axis = torch.tensor([0.0, 1.0, 0.0], dtype=torch.float64)
    qs = R.quat_normalize(torch.randn(100, 4, dtype=torch.float64))
    swing, twist = R.quat_swing_twist(qs, axis)
    assert same_rotation(R.quat_mul(swing, twist), qs, 1e-12)
    assert torch.allclose(
        R.quat_rotate(twist, axis.expand(100, 3)), axis.expand(100, 3), atol=1e-12
    )


def test_float32_supported():
    q = R.quat_normalize(torch.randn(10, 4))
    assert R.quat_to_matrix(q).dtype == torch.float32
    assert R.quat_from_euler(torch.zeros(3), "ZXY").dtype == torch.float32
