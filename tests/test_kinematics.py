"""Forward kinematics against hand-computed chains and a naive per-joint loop."""

import math

import numpy as np
import torch

from retarget_lib.core.kinematics import forward_kinematics, local_positions
from retarget_lib.core.rotations import (
    quat_from_axis_angle,
    quat_identity,
    quat_mul,
    quat_normalize,
    quat_rotate,
)
from retarget_lib.core.skeleton import CANONICAL22_PARENTS

D = torch.float64


def test_three_joint_chain_by_hand():
    # root at (1,0,0); joint1 offset (0,1,0); joint2 offset (0,1,0).
    # root rotated 90° about Z: +Y -> -X. joint1 rotated 90° about Z again: +Y -> +Y rotated 180° =
    # -Y.
    parents = (-1, 0, 1)
    offsets = torch.tensor([[5.0, 5.0, 5.0], [0.0, 1.0, 0.0], [0.0, 1.0, 0.0]], dtype=D)
    qz = quat_from_axis_angle(torch.tensor([0.0, 0.0, math.pi / 2], dtype=D))
    rot = torch.stack([qz, qz, quat_identity((), D)])
    pos, grot = forward_kinematics(rot, offsets, parents, torch.tensor([1.0, 0.0, 0.0], dtype=D))
    expected = torch.tensor([[1.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, -1.0, 0.0]], dtype=D)
    assert torch.allclose(pos, expected, atol=1e-12)
    # global rotation of joint 2 = 180° about Z
    assert torch.allclose(
        quat_rotate(grot[2], torch.tensor([1.0, 0, 0], dtype=D)),
        torch.tensor([-1.0, 0, 0], dtype=D),
        atol=1e-12,
    )


def naive_fk(rot, off, parents, root):
    gq, gp = [None] * len(parents), [None] * len(parents)
    gq[0], gp[0] = rot[..., 0, :], root
    for j in range(1, len(parents)):
        p = parents[j]
        gq[j] = quat_mul(gq[p], rot[..., j, :])
        gp[j] = gp[p] + quat_rotate(gq[p], off[..., j, :])
    return torch.stack(gp, -2), torch.stack(gq, -2)


def test_matches_naive_loop_batched_with_per_sample_offsets():
    torch.manual_seed(1)
    rot = quat_normalize(torch.randn(3, 7, 22, 4, dtype=D))
    off = torch.randn(3, 1, 22, 3, dtype=D)
    root = torch.randn(3, 7, 3, dtype=D)
    pos, grot = forward_kinematics(rot, off, CANONICAL22_PARENTS, root)
    npos, nrot = naive_fk(rot, off, CANONICAL22_PARENTS, root)
    assert pos.shape == (3, 7, 22, 3) and grot.shape == (3, 7, 22, 4)
    assert torch.allclose(pos, npos, atol=1e-12) and torch.allclose(grot, nrot, atol=1e-12)


def test_numpy_in_numpy_out_and_local_positions():
    rng = np.random.default_rng(0)
    rot = rng.normal(size=(5, 22, 4))
    rot /= np.linalg.norm(rot, axis=-1, keepdims=True)
    off = rng.normal(size=(22, 3))
    root = rng.normal(size=(5, 3))
    pos, _ = forward_kinematics(rot, off, CANONICAL22_PARENTS, root)
    assert isinstance(pos, np.ndarray) and pos.dtype == np.float64
    local = local_positions(torch.from_numpy(rot), torch.from_numpy(off), CANONICAL22_PARENTS)
    np.testing.assert_allclose(local.numpy() + root[:, None], pos, atol=1e-12)


def test_differentiable_gradcheck():
    torch.manual_seed(2)
    parents = (-1, 0, 1, 1, 3)
    rot = quat_normalize(torch.randn(2, 5, 4, dtype=D)).requires_grad_()
    off = torch.randn(5, 3, dtype=D, requires_grad=True)
    root = torch.randn(2, 3, dtype=D, requires_grad=True)
    assert torch.autograd.gradcheck(
        lambda r, o, t: forward_kinematics(r, o, parents, t), (rot, off, root)
    )


def test_bone_lengths_preserved():
    torch.manual_seed(3)
    off = torch.randn(22, 3, dtype=D)
    rot = quat_normalize(torch.randn(10, 22, 4, dtype=D))
    pos = forward_kinematics(rot, off, CANONICAL22_PARENTS).positions
    par = torch.tensor(CANONICAL22_PARENTS[1:])
    lengths = (pos[:, 1:] - pos[:, par]).norm(dim=-1)
    assert torch.allclose(lengths, off[1:].norm(dim=-1).expand_as(lengths), atol=1e-12)
