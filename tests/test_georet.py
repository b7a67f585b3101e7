"""The geometry-conditioned RNN (retarget_lib.models.georet)."""

import numpy as np
import pytest
import torch
from skeletons import make_skeleton

from retarget_lib.core.kinematics import forward_kinematics
from retarget_lib.core.rotations import quat_identity
from retarget_lib.core.skeleton import CANONICAL22_PARENTS
from retarget_lib.models.georet import (
    MOTION_FEATURE_LAYOUT,
    MOTION_FEATURES,
    GeometryConditionedRNN,
    PointNetEncoder,
    ResidualBase,
    batch_meshes,
    motion_features,
    normalize_rest_vertices,
    pose_outputs,
)


def _small_model(seed=0, **kw):
    torch.manual_seed(seed)
    return GeometryConditionedRNN(**{"hidden": 32, "geometry": 16, **kw})


def _mesh(nv, batch=1, seed=0):
    g = torch.Generator().manual_seed(seed)
    verts = torch.rand(batch, nv, 3, generator=g) * torch.tensor([0.5, 1.7, 0.3])
    weights = torch.softmax(4 * torch.randn(batch, nv, 22, generator=g), -1)
    return verts, weights


def _inputs(batch, frames, nv=50, seed=0):
    g = torch.Generator().manual_seed(seed)
    skel = make_skeleton()
    offsets = torch.as_tensor(skel.offsets, dtype=torch.float32).expand(batch, 22, 3)
    source = torch.randn(batch, frames, MOTION_FEATURES, generator=g)
    verts, weights = _mesh(nv, batch, seed)
    return source, offsets, verts, weights


# ----------------------------------------------------------------------------- PointNet (Eq. 19)
def test_geometry_embedding_ignores_vertex_order_and_duplicates():
    enc = PointNetEncoder(hidden=64)
    verts, weights = _mesh(50)
    e = enc(verts, weights)
    assert e.shape == (1, 64)
    perm = torch.randperm(50)
    torch.testing.assert_close(enc(verts[:, perm], weights[:, perm]), e)
    dup = torch.arange(3000) % 50  # the same 50 points, 3000 vertices
    torch.testing.assert_close(enc(verts[:, dup], weights[:, dup]), e)


def test_geometry_embedding_is_invariant_to_translation_and_scale():
    enc = PointNetEncoder(hidden=64)
    verts, weights = _mesh(80)
    moved = verts * 1.3 + torch.tensor([2.0, 0.5, -1.0])
    torch.testing.assert_close(enc(moved, weights), enc(verts, weights), atol=1e-5, rtol=1e-5)


def test_normalized_rest_vertices_span_zero_to_one_in_height():
    verts, _ = _mesh(200)
    n = normalize_rest_vertices(verts)
    assert n[..., 1].min().item() == pytest.approx(0.0, abs=1e-7)
    assert n[..., 1].max().item() == pytest.approx(1.0)
    assert (n[..., 0].max() + n[..., 0].min()).item() == pytest.approx(0.0, abs=1e-6)


def test_batch_meshes_keeps_each_embedding():
    enc = PointNetEncoder(hidden=32)
    (va, wa), (vb, wb) = _mesh(30, seed=1), _mesh(70, seed=2)
    verts, weights = batch_meshes([va[0], vb[0]], [wa[0], wb[0]])
    assert verts.shape == (2, 70, 3) and weights.shape == (2, 70, 22)
    e = enc(verts, weights)
    torch.testing.assert_close(e[0], enc(va, wa)[0])
    torch.testing.assert_close(e[1], enc(vb, wb)[0])
    with pytest.raises(ValueError, match="weight rows"):
        batch_meshes([va[0]], [wb[0]])


def test_pointnet_rejects_bad_shapes():
    enc = PointNetEncoder()
    with pytest.raises(ValueError, match="skinning weights"):
        enc(torch.zeros(1, 5, 3), torch.zeros(1, 5, 20))
    with pytest.raises(ValueError, match=r"\(B, V, 3\)"):
        enc(torch.zeros(5, 3), torch.zeros(5, 22))


# ----------------------------------------------------------------------------- the RNN
@pytest.mark.parametrize("frames, nv", [(1, 50), (100, 3000)])
def test_output_shapes_and_unit_quaternions(frames, nv):
    model = _small_model().eval()
    out = model(*_inputs(2, frames, nv))
    assert out.rotations.shape == (2, frames, 22, 4)
    assert out.root_velocity.shape == (2, frames, 3)
    assert out.local_positions.shape == (2, frames, 22, 3)
    assert out.geometry.shape == (2, 16)
    torch.testing.assert_close(out.rotations.norm(dim=-1), torch.ones(2, frames, 22))
    assert (out.rotations[..., 0] >= 0).all()


def test_a_fresh_model_outputs_the_rest_pose_and_no_root_motion():
    model = GeometryConditionedRNN().eval()
    out = model(*_inputs(1, 4))
    torch.testing.assert_close(out.rotations, quat_identity((1, 4, 22)), atol=0.05, rtol=0)
    assert out.root_velocity.abs().max() < 0.05


def test_a_root_residual_network_adds_its_velocity_to_the_sources_leg_scaled_one():
    """root_residual (paper form, ours): same weights and decoder state, the step's velocity is
    the paper form's plus the base's o^(A→B) of that frame, the rotations unchanged; it needs the
    base. (Over a sequence the two differ later: the velocity is fed back to the decoder.)"""
    source, offsets, verts, weights = _inputs(2, 5)
    paper = _small_model(seed=3).eval()
    rooted = _small_model(seed=3, root_residual=True).eval()
    rooted.load_state_dict(paper.state_dict())
    o_ab = torch.randn(2, 5, 3, generator=torch.Generator().manual_seed(1)) * 0.02
    base = ResidualBase(quat_identity((2, 5, 22)), o_ab)
    with torch.no_grad():
        h_enc = paper.encode(source)
        context = paper.target_context(offsets, verts, weights)
        state = paper.initial_state(context)
        for t in range(5):
            rot_a, vel_a, after = paper.decode_step(h_enc[:, t], state, context, base.frame(t))
            rot_b, vel_b, _ = rooted.decode_step(h_enc[:, t], state, context, base.frame(t))
            torch.testing.assert_close(rot_b, rot_a)
            torch.testing.assert_close(vel_b, vel_a + o_ab[:, t])
            state = after
        with pytest.raises(ValueError, match="base"):
            rooted(source, offsets, verts, weights)
    with pytest.raises(ValueError, match="paper form"):
        _small_model(residual=True, root_residual=True)


def test_forward_equals_step_by_step_decoding():
    model = _small_model().eval()
    source, offsets, verts, weights = _inputs(2, 7)
    out = model(source, offsets, verts, weights)
    h_enc = model.encode(source)
    assert h_enc.shape == (2, 7, 32)
    context = model.target_context(offsets, verts, weights)
    state = model.initial_state(context)
    for t in range(7):
        rot, vel, state = model.decode_step(h_enc[:, t], state, context)
        torch.testing.assert_close(rot, out.rotations[:, t])
        torch.testing.assert_close(vel, out.root_velocity[:, t])
        torch.testing.assert_close(state.local_positions, out.local_positions[:, t])


def test_decoder_step_is_two_torch_gru_cells():
    """decode_step's GRU update from gate products is nn.GRUCell's formula (float32 rounding
    only)."""
    model = _small_model().eval()
    source, offsets, verts, weights = _inputs(2, 1)
    context = model.target_context(offsets, verts, weights)
    g = torch.Generator().manual_seed(3)
    state = model.initial_state(context)._replace(
        hidden=torch.randn(2, 2, 32, generator=g),
        root_velocity=0.01 * torch.randn(2, 3, generator=g),
    )
    h_enc = model.encode(source)[:, 0]
    h = context.height.view(2, 1)
    x = torch.cat(
        (
            h_enc,
            state.local_positions.reshape(2, -1) / h,
            state.root_velocity / h,
            context.skeleton,
            context.geometry,
        ),
        dim=-1,
    )
    expected = []
    for i, cell in enumerate(model.decoder):
        x = cell(x, state.hidden[i])
        expected.append(x)
    _, _, after = model.decode_step(h_enc, state, context)
    torch.testing.assert_close(after.hidden, torch.stack(expected), atol=1e-6, rtol=0)


def test_decoder_gates_do_not_depend_on_the_optimised_inputs():
    """ESO computes the gates once per frame and then changes h_enc and o_(t-1) (Eq. 11): the step
    with kept gates equals the step that computes them, for any h_enc and o."""
    model = _small_model().eval()
    source, offsets, verts, weights = _inputs(1, 2)
    context = model.target_context(offsets, verts, weights)
    state = model.initial_state(context)
    gates = model.decoder_gates(state, context)
    for t, velocity in enumerate(
        (torch.tensor([[0.02, 0.0, -0.01]]), torch.tensor([[-0.3, 0.1, 0.2]]))
    ):
        moved = state._replace(root_velocity=velocity)
        h_enc = model.encode(source)[:, t]
        kept = model.decode_step(h_enc, moved, context, None, gates)
        fresh = model.decode_step(h_enc, moved, context)
        for a, b in zip(kept[:2] + tuple(kept[2]), fresh[:2] + tuple(fresh[2]), strict=False):
            torch.testing.assert_close(a, b)
    # and they do depend on what they hold: another previous hidden state changes them
    other = model.decoder_gates(state._replace(hidden=state.hidden + 1.0), context)
    assert (other.hidden - gates.hidden).abs().max() > 1e-3


def test_step_state_integrates_the_root_from_the_start():
    model = _small_model().eval()
    source, offsets, verts, weights = _inputs(1, 3)
    context = model.target_context(offsets, verts, weights)
    start = torch.tensor([0.5, 0.9, -0.2])
    state = model.initial_state(context, start)
    torch.testing.assert_close(state.root_velocity, torch.zeros(1, 3))
    rot, vel, state = model.decode_step(model.encode(source)[:, 0], state, context)
    torch.testing.assert_close(state.root_position, start[None])  # frame 0 sits at the start
    _, _, state = model.decode_step(model.encode(source)[:, 1], state, context)
    torch.testing.assert_close(state.root_position, start[None] + vel)  # Eq. 18


def test_gradients_reach_every_parameter():
    model = _small_model(dropout=0.0).train()
    out = model(*_inputs(2, 5))
    loss = (
        (out.rotations[..., 1:] ** 2).sum()
        + out.root_velocity.pow(2).sum()
        + out.local_positions.sum()
    )
    loss.backward()
    for name, p in model.named_parameters():
        assert p.grad is not None and p.grad.abs().sum() > 0, name


def test_default_sizes_match_appendix_b():
    model = GeometryConditionedRNN()
    assert model.encoder.hidden_size == 512 and model.encoder.num_layers == 2
    assert len(model.decoder) == 2 and model.decoder[0].hidden_size == 512
    assert model.decoder[0].input_size == 512 + 66 + 3 + 66 + 256
    assert [m.out_features for m in model.pointnet.mlp if isinstance(m, torch.nn.Linear)] == [
        256,
        256,
    ]
    n = sum(p.numel() for p in model.parameters())
    print(f"GeometryConditionedRNN parameters: {n:,}")
    assert n == 6_669_703


def test_encode_rejects_bad_features():
    with pytest.raises(ValueError, match="267"):
        _small_model().encode(torch.zeros(1, 4, 223))


# ----------------------------------------------------------------------------- features and FK
def test_motion_features_of_a_rest_pose_walking_forward_by_hand():
    skel = make_skeleton()
    h = skel.height()
    rot = quat_identity((1, 3, 22))
    root = torch.tensor([[0.0, 0.96, 0.0], [0.0, 0.96, 0.03], [0.0, 0.96, 0.06]])[None]
    m = motion_features(rot, root, skel.offsets, CANONICAL22_PARENTS)
    assert m.shape == (1, 3, 267)
    rest = skel.rest_positions() - skel.rest_positions()[0]
    np.testing.assert_allclose(
        m[0, 1, MOTION_FEATURE_LAYOUT["positions"]].numpy(), rest.reshape(-1) / h, atol=1e-6
    )
    np.testing.assert_allclose(
        m[0, 2, MOTION_FEATURE_LAYOUT["rotations"]].numpy(), np.tile(np.eye(3).ravel(), 22)
    )
    np.testing.assert_allclose(
        m[0, :, MOTION_FEATURE_LAYOUT["root_velocity"]].numpy(),
        np.tile([0.0, 0.0, 0.03 / h], (3, 1)),
        atol=1e-7,
    )
    with pytest.raises(ValueError, match="rotations"):
        motion_features(rot[0], root[0], skel.offsets)


def test_pose_outputs_integrate_root_velocities_by_hand():
    skel = make_skeleton()
    rot = quat_identity((1, 3, 22))
    vel = torch.tensor([[[0.1, 0.0, 0.0]] * 3])
    posed = pose_outputs(rot, vel, skel.offsets, start=torch.tensor([0.0, 1.0, 0.0]))
    torch.testing.assert_close(
        posed.root_positions[0], torch.tensor([[0.0, 1, 0], [0.1, 1, 0], [0.2, 1, 0]])
    )
    expected = forward_kinematics(
        rot,
        torch.as_tensor(skel.offsets, dtype=torch.float32),
        CANONICAL22_PARENTS,
        posed.root_positions,
    ).positions
    torch.testing.assert_close(posed.positions, expected)
    assert posed.global_rotations.shape == (1, 3, 22, 4)
