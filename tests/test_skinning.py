"""Linear blend skinning and mesh sub-sampling (retarget_lib.core.skinning)."""

import math

import numpy as np
import pytest
import torch
import trimesh

from retarget_lib.core.kinematics import forward_kinematics
from retarget_lib.core.rotations import (
    quat_from_axis_angle,
    quat_identity,
    quat_normalize,
    quat_rotate,
)
from retarget_lib.core.skinning import linear_blend_skinning, subsample_mesh
from retarget_lib.data.synthetic.characters import make_character


def _random_mesh(nv=50, nj=5, seed=0, dtype=torch.float64):
    g = torch.Generator().manual_seed(seed)
    verts = torch.randn(nv, 3, generator=g, dtype=dtype)
    weights = torch.rand(nv, nj, generator=g, dtype=dtype)
    weights = weights / weights.sum(1, keepdim=True)
    rest_joints = torch.randn(nj, 3, generator=g, dtype=dtype)
    return verts, weights, rest_joints


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_identity_pose_returns_rest_vertices(dtype):
    verts, weights, rest_joints = _random_mesh(dtype=dtype)
    out = linear_blend_skinning(
        verts, weights, rest_joints, quat_identity((5,), dtype), rest_joints
    )
    assert out.dtype == dtype
    torch.testing.assert_close(out, verts)


def test_single_joint_is_a_rigid_transform():
    verts, _, rest_joints = _random_mesh(nj=3)
    weights = torch.zeros(len(verts), 3, dtype=torch.float64)
    weights[:, 1] = 1.0
    q = quat_normalize(torch.tensor([0.3, -0.5, 0.7, 0.2], dtype=torch.float64))
    rot = quat_identity((3,), torch.float64)
    rot[1] = q
    pos = rest_joints + torch.tensor([0.5, -1.0, 2.0], dtype=torch.float64)
    out = linear_blend_skinning(verts, weights, rest_joints, rot, pos)
    expected = quat_rotate(q, verts - rest_joints[1]) + pos[1]
    torch.testing.assert_close(out, expected)


def test_two_joint_half_blend_by_hand():
    # joint 0 at the origin stays; joint 1 at (1, 0, 0) turns 90 deg about +Z and moves up by 1
    rest_joints = torch.tensor([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]], dtype=torch.float64)
    verts = torch.tensor([[2.0, 0.0, 0.0]], dtype=torch.float64)
    weights = torch.tensor([[0.5, 0.5]], dtype=torch.float64)
    rot = torch.stack(
        (
            quat_identity((), torch.float64),
            quat_from_axis_angle(torch.tensor([0.0, 0.0, math.pi / 2], dtype=torch.float64)),
        )
    )
    pos = torch.tensor([[0.0, 0.0, 0.0], [1.0, 1.0, 0.0]], dtype=torch.float64)
    out = linear_blend_skinning(verts, weights, rest_joints, rot, pos)
    # joint 0 keeps (2, 0, 0); joint 1 maps it to (1, 1, 0) + Rz90 (1, 0, 0) = (1, 2, 0)
    torch.testing.assert_close(out, torch.tensor([[1.5, 1.0, 0.0]], dtype=torch.float64))


def test_batched_leading_dims_and_numpy_arguments():
    verts, weights, rest_joints = _random_mesh()
    g = torch.Generator().manual_seed(1)
    rot = quat_normalize(torch.randn(2, 3, 5, 4, generator=g, dtype=torch.float64))
    pos = torch.randn(2, 3, 5, 3, generator=g, dtype=torch.float64)
    out = linear_blend_skinning(verts.numpy(), weights.numpy(), rest_joints.numpy(), rot, pos)
    assert out.shape == (2, 3, 50, 3)
    single = linear_blend_skinning(verts, weights, rest_joints, rot[1, 2], pos[1, 2])
    torch.testing.assert_close(out[1, 2], single)


def test_matches_forward_kinematics_on_joint_positions():
    """A vertex placed on a joint and bound to it follows that joint exactly."""
    offsets = torch.tensor([[0.0, 1.0, 0.0], [0.0, 0.5, 0.0], [0.3, 0.0, 0.0]], dtype=torch.float64)
    parents = (-1, 0, 1)
    rest = torch.tensor([[0.0, 1.0, 0.0], [0.0, 1.5, 0.0], [0.3, 1.5, 0.0]], dtype=torch.float64)
    rot = quat_normalize(
        torch.randn(4, 3, 4, generator=torch.Generator().manual_seed(2), dtype=torch.float64)
    )
    pos, grot = forward_kinematics(rot, offsets, parents, torch.zeros(4, 3, dtype=torch.float64))
    verts = rest[[2, 2]]  # two vertices on joint 2 ...
    weights = torch.eye(3, dtype=torch.float64)[[1, 2]]  # ... bound to joint 1 and to joint 2
    out = linear_blend_skinning(verts, weights, rest, grot, pos)
    torch.testing.assert_close(out[:, 0], pos[:, 2])  # joint 1 carries its child's offset rigidly
    torch.testing.assert_close(out[:, 1], pos[:, 2])  # joint 2's own vertex stays on it


def test_gradcheck_float64():
    verts, weights, rest_joints = _random_mesh(nv=6, nj=3)
    g = torch.Generator().manual_seed(3)
    rot = quat_normalize(torch.randn(2, 3, 4, generator=g, dtype=torch.float64)).requires_grad_()
    pos = torch.randn(2, 3, 3, generator=g, dtype=torch.float64).requires_grad_()
    verts.requires_grad_()
    weights.requires_grad_()
    assert torch.autograd.gradcheck(
        lambda v, w, r, p: linear_blend_skinning(v, w, rest_joints, r, p),
        (verts, weights, rot, pos),
    )


def test_shape_mismatch_raises():
    verts, weights, rest_joints = _random_mesh()
    with pytest.raises(ValueError, match="rest_vertices"):
        linear_blend_skinning(
            verts[:10], weights, rest_joints, quat_identity((5,), torch.float64), rest_joints
        )


def test_subsample_mesh_keeps_a_closed_skinned_surface():
    sphere = trimesh.creation.icosphere(subdivisions=4)  # 2562 vertices
    verts = np.asarray(sphere.vertices)
    weights = np.stack((0.5 + 0.5 * verts[:, 1], 0.5 - 0.5 * verts[:, 1]), axis=1)  # top/bottom
    v, f, w = subsample_mesh(verts, sphere.faces, weights, n=500)
    assert 450 <= len(v) <= 550
    mesh = trimesh.Trimesh(v, f, process=False)
    assert mesh.is_watertight
    np.testing.assert_allclose(np.linalg.norm(v, axis=1), 1.0, atol=0.03)
    np.testing.assert_allclose(w.sum(1), 1.0)
    # weights travel with their vertices: cluster means of a linear field stay close to it
    np.testing.assert_allclose(w[:, 0], 0.5 + 0.5 * v[:, 1], atol=0.06)


def test_subsample_mesh_small_input_unchanged():
    box = trimesh.creation.box()
    w = np.ones((len(box.vertices), 1))
    v, f, w2 = subsample_mesh(box.vertices, box.faces, w, n=100)
    np.testing.assert_array_equal(v, box.vertices)
    np.testing.assert_array_equal(f, box.faces)


def test_a_decimated_character_keeps_its_skeleton_and_leaves_the_original_alone():
    character = make_character("otto")
    small = character.decimated(1000)
    assert 900 <= small.num_vertices <= 1100 and character.num_vertices > 2000
    np.testing.assert_array_equal(small.skeleton.offsets, character.skeleton.offsets)
    np.testing.assert_allclose(small.weights.sum(1), 1.0)
    assert small.faces.max() < small.num_vertices
    lo, hi = (
        character.rest_vertices.min(0),
        character.rest_vertices.max(0),
    )  # the same body, smaller
    np.testing.assert_allclose(small.rest_vertices.min(0), lo, atol=0.03)
    np.testing.assert_allclose(small.rest_vertices.max(0), hi, atol=0.03)
    assert character.num_vertices == len(character.weights) > 2000  # untouched
