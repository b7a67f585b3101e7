"""Models: TDCN generator / patch discriminator (Kim et al. 2020) and NKN baselines.

Shapes for any clip length, measured receptive fields, causality, parameter ratios, long clips,
NKN root integration, gradient flow, fusion, and every Table 4 row through ``build_model``.
No timings here (see ``retarget bench``).
"""

import copy

import pytest
import torch

from retarget_lib.core.kinematics import forward_kinematics
from retarget_lib.core.measures import leg_length, nkn_height
from retarget_lib.core.rotations import quat_mul, quat_normalize
from retarget_lib.core.skeleton import CANONICAL22_PARENTS, canonical22_skeleton
from retarget_lib.models import (
    TABLE4_ROWS,
    NKNDiscriminator,
    NKNGenerator,
    PatchDiscriminator,
    TDCNGenerator,
    build_model,
    count_parameters,
)
from retarget_lib.models.features import (
    GENERATOR_LAYOUT,
    FeatureNormalizer,
    discriminator_features,
    discriminator_input_channels,
    from_facing_frame,
    generator_features,
    generator_input_channels,
    hip_facing,
    positions_in_frame,
    source_local_positions,
    split_generator_features,
    to_facing_frame,
)

J = 22
SMALL = 32  # channel width used for fast tests


def _offsets(batch, seed, scale=1.0):
    g = torch.Generator().manual_seed(seed)
    off = torch.randn(batch, J, 3, generator=g) * 0.1 * scale
    off[:, 0] = torch.tensor([0.0, 1.0, 0.0]) * scale
    return off


def _motion(batch, frames, seed=0, dtype=torch.float32):
    g = torch.Generator().manual_seed(seed)
    q = quat_normalize(
        torch.randn(batch, frames, J, 4, generator=g, dtype=dtype) * 0.3
        + torch.tensor([1.0, 0, 0, 0], dtype=dtype)
    )
    r = torch.cumsum(torch.randn(batch, frames, 3, generator=g, dtype=dtype) * 0.01, 1)
    return q, r, _offsets(batch, seed + 1).to(dtype), _offsets(batch, seed + 2, 0.8).to(dtype)


@pytest.fixture(autouse=True)
def _seed_and_one_thread():
    """Seeded, single-threaded: these nets are tiny, and multi-threaded OpenMP regions stall badly
    when the suite runs under ``pytest -n 2`` next to other work."""
    torch.manual_seed(0)
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(threads)


# ----------------------------------------------------------------------------------- features


def test_generator_features_layout_and_roundtrip():
    q, r, oa, ob = _motion(2, 7)
    x = generator_features(q, r, oa, ob)
    assert x.shape == (2, generator_input_channels(), 7) == (2, 223, 7)
    parts = split_generator_features(x)
    assert torch.allclose(parts["q"], q) and torch.allclose(parts["r"], r)
    assert torch.allclose(parts["skeleton"], ob)
    p = source_local_positions(q, oa)
    assert torch.allclose(parts["p"], p)
    assert torch.allclose(p[:, :, 0], torch.zeros(2, 7, 3))  # root at the origin
    # root rotation is applied: p equals global FK minus the root position
    glob = forward_kinematics(q, oa[:, None], CANONICAL22_PARENTS, r).positions
    assert torch.allclose(p, glob - r[..., None, :], atol=1e-5)
    assert GENERATOR_LAYOUT["skeleton"].stop == 223


def test_nkn_height_matches_skeleton_class():
    off = _offsets(3, 5).double()
    h = nkn_height(off)
    for b in range(3):
        assert h[b].item() == pytest.approx(
            canonical22_skeleton(off[b].numpy()).height(), rel=1e-12
        )


def test_discriminator_features_are_eqs_11_18():
    q, r, oa, _ = _motion(2, 9, dtype=torch.float64)
    p = source_local_positions(q, oa)
    f = discriminator_features(p, r, oa)
    assert f.shape == (2, discriminator_input_channels(), 8) == (2, 43, 8)
    h = nkn_height(oa)
    l_expected = (p[:, 1:] - p[:, :-1]).norm(dim=-1)[..., 1:] / h[:, None, None]
    assert torch.allclose(f[:, :21].transpose(1, 2), l_expected)
    assert torch.allclose(f[:, 21], (r[:, 1:] - r[:, :-1]).norm(dim=-1) / h[:, None])
    assert torch.allclose(f[:, 22:, 3], oa[:, 1:].norm(dim=-1))


def test_feature_normalizer_identity_fit_and_checkpoint():
    x = torch.randn(4, 10, 30) * 3 + 5
    x[:, 3] = 2.0  # constant channel: centred, not blown up
    norm = FeatureNormalizer(10)
    assert norm.is_identity and torch.equal(norm(x), x)
    norm.fit([x[:2], x[2:]])
    y = norm(x)
    flat = y.transpose(0, 1).reshape(10, -1)
    keep = [c for c in range(10) if c != 3]
    assert torch.allclose(flat[keep].mean(1), torch.zeros(9), atol=1e-4)
    assert torch.allclose(flat[keep].std(1, unbiased=False), torch.ones(9), atol=1e-3)
    assert torch.allclose(flat[3], torch.zeros_like(flat[3]))
    # statistics travel with the owning model's state dict
    g = TDCNGenerator(channels=SMALL)
    g.normalizer.fit(torch.randn(2, g.in_channels, 20) * 2 + 1)
    g2 = TDCNGenerator(channels=SMALL)
    g2.load_state_dict(g.state_dict())
    assert not g2.normalizer.is_identity
    assert torch.equal(g2.normalizer.mean, g.normalizer.mean)


def test_standardized_root_turns_the_head_output_into_metres_with_the_root_statistics():
    q, r, off_a, off_b = _motion(2, 12, seed=3)
    plain = TDCNGenerator(channels=SMALL).eval()
    zs = TDCNGenerator(channels=SMALL, standardized_root=True).eval()
    zs.load_state_dict(plain.state_dict())
    # unfitted normalizer: mean 0, std 1, so both read the head in metres
    assert torch.equal(
        zs.generate(q, r, off_a, off_b).root_positions,
        plain.generate(q, r, off_a, off_b).root_positions,
    )
    x = generator_features(q, r, off_a, off_b)
    for g in (plain, zs):
        g.normalizer.fit(x * 2.0 + 0.5)
    head = plain.generate(q, r, off_a, off_b).root_positions  # raw head output (z-scores)
    root = GENERATOR_LAYOUT["r"]
    expected = head * zs.normalizer.std[root] + zs.normalizer.mean[root]
    got = zs.generate(q, r, off_a, off_b).root_positions
    torch.testing.assert_close(got, expected)  # float32: one multiply-add apart at most
    assert not torch.allclose(got, head)
    torch.testing.assert_close(zs(x)[1], expected)  # forward agrees with generate
    with pytest.raises(ValueError, match="normalize_inputs"):
        build_model({"kind": "tdcn", "channels": 8, "standardized_root": True})
    with pytest.raises(ValueError, match="paper form"):
        TDCNGenerator(channels=8, residual=True, standardized_root=True)
    g, _ = build_model(
        {"kind": "tdcn", "channels": 8, "standardized_root": True, "normalize_inputs": True}
    )
    assert g.standardized_root


def test_a_residual_tdcn_root_adds_the_head_to_the_sources_leg_scaled_root():
    """root_residual (paper form): the head's root output lands on the source's root times the
    leg ratio; a zero head gives exactly that root (copy's), and the rotations are unchanged."""
    q, r, off_a, off_b = _motion(2, 12, seed=4, dtype=torch.float64)
    plain = TDCNGenerator(channels=SMALL).double().eval()
    res = TDCNGenerator(channels=SMALL, root_residual=True).double().eval()
    res.load_state_dict(plain.state_dict())
    a, b = plain.generate(q, r, off_a, off_b), res.generate(q, r, off_a, off_b)
    ratio = (leg_length(off_b) / leg_length(off_a)).view(2, 1, 1)
    torch.testing.assert_close(b.root_positions, a.root_positions + r * ratio)  # same head
    assert torch.equal(b.rotations, a.rotations)
    with torch.no_grad():
        res.head.out.weight[-3:] = 0.0
        res.head.out.bias[-3:] = 0.0
    torch.testing.assert_close(res.generate(q, r, off_a, off_b).root_positions, r * ratio)
    with pytest.raises(ValueError, match="paper form"):
        TDCNGenerator(channels=8, residual=True, root_residual=True)
    with pytest.raises(ValueError, match="standardized_root"):
        TDCNGenerator(channels=8, standardized_root=True, root_residual=True)
    assert build_model(
        {"kind": "tdcn", "channels": 8, "root_residual": True}
    ).generator.root_residual


# ----------------------------------------------------------------------------------- TDCN


@pytest.mark.parametrize("kwargs", [{}, {"causal": True}, {"dense": True}])
@pytest.mark.parametrize("frames", [1, 5, 81, 200])
def test_tdcn_one_output_per_input_frame(kwargs, frames):
    g = TDCNGenerator(channels=SMALL, **kwargs)
    q, r, oa, ob = _motion(2, frames)
    out = g.generate(q, r, oa, ob)  # train mode
    assert out.rotations.shape == (2, frames, J, 4) and out.root_positions.shape == (2, frames, 3)
    g.eval()
    with torch.no_grad():
        qn, rn = g.retarget(q[:1], r[:1], oa[:1], ob[:1])  # batch size 1, eval
    assert qn.shape == (1, frames, J, 4) and rn.shape == (1, frames, 3)
    assert torch.allclose(qn.norm(dim=-1), torch.ones(1, frames, J), atol=1e-5)


def _changed_outputs(model_fn, features, frame):
    with torch.no_grad():
        base = model_fn(features)
        pert = features.clone()
        pert[..., frame] += 10.0
        moved = model_fn(pert)
    diff = (moved - base).abs().reshape(base.shape[0], base.shape[1], -1).amax(-1)[0]
    return torch.nonzero(diff > 0).flatten().tolist()


def _tdcn_out(g):
    def fn(x):
        q, r = g(x)
        return torch.cat([q.flatten(2), r], -1)  # (B, T, 91)

    return fn


@pytest.mark.parametrize("dense", [False, True])
def test_tdcn_receptive_field_is_81_frames(dense):
    g = TDCNGenerator(channels=SMALL, dense=dense).double().eval()
    assert g.receptive_field == 81
    x = torch.randn(1, g.in_channels, 200, dtype=torch.float64)
    assert _changed_outputs(_tdcn_out(g), x, 100) == list(range(60, 141))
    # at the clip edge the padding copies frame 0: outputs 0..40 see it
    assert _changed_outputs(_tdcn_out(g), x, 0) == list(range(0, 41))


def test_causal_tdcn_sees_only_the_past():
    g = TDCNGenerator(channels=SMALL, causal=True).double().eval()
    assert g.receptive_field == 81
    x = torch.randn(1, g.in_channels, 200, dtype=torch.float64)
    assert _changed_outputs(_tdcn_out(g), x, 100) == list(range(100, 181))
    # output t never depends on inputs after t (truncating the future changes nothing)
    with torch.no_grad():
        full = _tdcn_out(g)(x)
        part = _tdcn_out(g)(x[..., :120])
    # equal up to float64 rounding: the convolution's summation order depends on the clip length
    # (1 ulp, 2.2e-16, measured with torch 2.13 on this CPU)
    torch.testing.assert_close(part, full[:, :120], rtol=0.0, atol=1e-12)


def test_dense_variant_has_more_parameters():
    ratios = {}
    for c in (SMALL, 256, 1024):
        dilated = count_parameters(TDCNGenerator(channels=c))
        dense = count_parameters(TDCNGenerator(channels=c, dense=True))
        ratios[c] = dense / dilated
    print("A1 dense / dilated parameter ratio:", {c: round(v, 2) for c, v in ratios.items()})
    assert all(v > 1 for v in ratios.values())
    assert 6.0 < ratios[1024] < 7.0  # the paper: "6.5 times more parameters"


def test_long_clip_in_eval_mode_plain_and_fused():
    g = TDCNGenerator(channels=64).eval()
    q, r, oa, ob = _motion(1, 2000)
    with torch.inference_mode():
        qn, rn = g.retarget(q, r, oa, ob)
        gf = copy.deepcopy(g).fuse_for_inference()
        qf, rf = gf.retarget(q, r, oa, ob)
    assert qn.shape == (1, 2000, J, 4) and rn.shape == (1, 2000, 3)
    assert torch.isfinite(qn).all() and torch.isfinite(rn).all()
    assert torch.allclose(qn, qf, atol=1e-4) and torch.allclose(rn, rf, atol=1e-4)


def test_fusion_matches_batchnorm_statistics_and_blocks_training():
    g = TDCNGenerator(channels=SMALL, skip_projection=True)
    q, r, oa, ob = _motion(3, 40)
    for _ in range(3):  # non-trivial running statistics
        g.generate(q, r, oa, ob)
    g.eval()
    with torch.no_grad():
        a = g(generator_features(q, r, oa, ob))
        gf = copy.deepcopy(g).fuse_for_inference()
        b = gf(generator_features(q, r, oa, ob))
    assert torch.allclose(a[0], b[0], atol=1e-5) and torch.allclose(a[1], b[1], atol=1e-5)
    with pytest.raises(RuntimeError):
        gf.train()


def test_raw_quaternions_start_near_identity():
    g = TDCNGenerator(channels=SMALL).eval()
    q, r, oa, ob = _motion(1, 10)
    with torch.no_grad():
        out = g.generate(q, r, oa, ob)
    assert torch.allclose(
        out.rotations, torch.tensor([1.0, 0, 0, 0]).expand_as(out.rotations), atol=0.2
    )


# ----------------------------------------------------------------------------- discriminator


@pytest.mark.parametrize("rf", [31, 81])
def test_patch_discriminator_receptive_field(rf):
    d = PatchDiscriminator(channels=SMALL, receptive_field=rf).double().eval()
    assert d.receptive_field == rf
    x = torch.randn(2, discriminator_input_channels(), 200, dtype=torch.float64)
    with torch.no_grad():
        assert d(x).shape == (2, 200 - rf + 1)
    changed = _changed_outputs(lambda f: d(f).unsqueeze(-1), x, 100)
    assert changed == list(range(100 - rf + 1, 101))  # score i sees input frames i .. i+rf-1


def test_patch_discriminator_short_clip_gets_one_score():
    d = PatchDiscriminator(channels=SMALL, receptive_field=81)
    q, r, oa, _ = _motion(4, 81)
    f = d.features(source_local_positions(q, oa), r, oa)  # 80 feature frames < 81
    assert d(f).shape == (4, 1)


# ----------------------------------------------------------------------------------- NKN


@pytest.mark.parametrize("backbone", ["gru", "dense", "dilated"])
@pytest.mark.parametrize("frames", [1, 5, 81])
def test_nkn_shapes(backbone, frames):
    g = NKNGenerator(hidden=SMALL, backbone=backbone)
    q, r, oa, ob = _motion(2, frames)
    out = g(q, r, oa, ob)
    assert out.rotations.shape == (2, frames, J, 4)
    assert out.root_positions.shape == out.root_velocities.shape == (2, frames, 3)
    g.eval()
    with torch.no_grad():
        qn, rn = g.retarget(q[:1], r[:1], oa[:1], ob[:1])
    assert qn.shape == (1, frames, J, 4) and rn.shape == (1, frames, 3)


@pytest.mark.parametrize("normalize_root", [False, True])
def test_nkn_root_is_cumulative_sum_of_velocities(normalize_root):
    g = NKNGenerator(hidden=SMALL, normalize_root=normalize_root).eval()
    q, r, oa, ob = _motion(2, 50, dtype=torch.float64)
    g.double()
    with torch.no_grad():
        out = g(q, r, oa, ob)
    start = r[:, 0] * (leg_length(ob) / leg_length(oa))[:, None]
    expected = start[:, None] + torch.cumsum(out.root_velocities, 1)
    assert torch.allclose(out.root_positions, expected, atol=1e-12)
    assert torch.allclose(out.root_positions.diff(dim=1), out.root_velocities[:, 1:], atol=1e-12)


def test_facing_frame_round_trip_and_the_hips_rule():
    g = torch.Generator().manual_seed(3)
    v = torch.randn(5, 7, 3, generator=g, dtype=torch.float64)
    yaw = torch.rand(5, 7, generator=g, dtype=torch.float64) * 6.283
    facing = torch.stack((yaw.sin(), yaw.cos()), -1)
    back = from_facing_frame(to_facing_frame(v, facing), facing)
    assert torch.allclose(back, v, atol=1e-12)  # an orthonormal map and its transpose
    # a step along the facing direction is pure +z in the facing frame, lengths kept
    step = torch.cat((facing[..., :1], torch.zeros_like(yaw)[..., None], facing[..., 1:]), -1)
    local = to_facing_frame(step, facing)
    assert torch.allclose(local, torch.tensor([0.0, 0.0, 1.0], dtype=torch.float64), atol=1e-12)
    # the hips' rule: the rest pose faces +z (left hip at +x); a quarter turn left faces +x
    p = torch.zeros(J, 3)
    p[6], p[10] = (
        torch.tensor([0.1, -0.05, 0.0]),
        torch.tensor([-0.1, -0.05, 0.0]),
    )  # Left/RightUpLeg
    assert torch.allclose(hip_facing(p), torch.tensor([0.0, 1.0]), atol=1e-6)
    turn = torch.tensor([[0.0, 0, 1], [0, 1, 0], [-1, 0, 0]])  # +90 degrees about +Y: +z -> +x
    assert torch.allclose(hip_facing(p @ turn.T), torch.tensor([1.0, 0.0]), atol=1e-6)


def _yawed(q, angle):
    """``q`` with every root rotation turned by ``angle`` radians about +Y (wxyz)."""
    half = torch.tensor(angle / 2)
    turn = torch.tensor([half.cos(), 0.0, half.sin(), 0.0])
    out = q.clone()
    out[..., 0, :] = quat_mul(turn.expand_as(q[..., 0, :]), q[..., 0, :])
    return out


def test_positions_in_the_root_and_facing_frames():
    """``"root"`` is FK with the root's rotation set to identity (the authors' TDCN input);
    ``"facing"`` turns every frame to face +z, so a yaw of the whole motion leaves it unchanged
    (the authors' NKN input); ``"world"`` is Eq. 1's ``p`` itself. float32 FK: 1e-5 m."""
    q, _, oa, _ = _motion(2, 9)
    p = source_local_positions(q, oa)
    unrooted = q.clone()
    unrooted[..., 0, :] = torch.tensor([1.0, 0.0, 0.0, 0.0])
    assert torch.allclose(
        positions_in_frame(p, "root", q[..., 0, :]), source_local_positions(unrooted, oa), atol=1e-5
    )
    assert positions_in_frame(p, "world") is p
    facing = positions_in_frame(p, "facing")
    assert torch.allclose(hip_facing(facing), torch.tensor([0.0, 1.0]).expand(2, 9, 2), atol=1e-5)
    turned = source_local_positions(_yawed(q, 1.3), oa)
    assert not torch.allclose(turned, p, atol=1e-2)  # the yaw moves world-axis positions...
    assert torch.allclose(positions_in_frame(turned, "facing"), facing, atol=1e-5)  # not these
    with pytest.raises(ValueError, match="needs the root rotations"):
        positions_in_frame(p, "root")
    with pytest.raises(ValueError, match="frame must be one of"):
        positions_in_frame(p, "hips")


def test_each_network_reads_positions_in_its_frame():
    """A root-frame TDCN's input (and so the features its normaliser is fitted on) has the
    root-frame ``p``; a facing-frame NKN's encoder input and fed-back pose are facing-frame, so a
    yawed source gives it the same encoder input; the residual TDCN refuses the option."""
    q, r, oa, ob = _motion(2, 12)
    tdcn = TDCNGenerator(channels=SMALL, positions_frame="root")
    x = split_generator_features(tdcn.input_features(q, r, oa, ob))
    expected = positions_in_frame(source_local_positions(q, oa), "root", q[..., 0, :])
    assert torch.allclose(x["p"], expected, atol=1e-6)
    world = split_generator_features(TDCNGenerator(channels=SMALL).input_features(q, r, oa, ob))
    assert torch.equal(world["p"], split_generator_features(generator_features(q, r, oa, ob))["p"])
    nkn = NKNGenerator(hidden=SMALL, positions_frame="facing")
    p, p_turned = source_local_positions(q, oa), source_local_positions(_yawed(q, 0.7), oa)
    still = r * torch.tensor([0.0, 1.0, 0.0])  # no root steps: the yaw changes only p
    a = nkn.source_features(p, still, oa)[:, : 3 * J]
    assert torch.allclose(a, nkn.source_features(p_turned, still, oa)[:, : 3 * J], atol=1e-5)
    assert not torch.allclose(
        a, NKNGenerator(hidden=SMALL).source_features(p_turned, still, oa)[:, : 3 * J], atol=1e-3
    )
    world_nkn = NKNGenerator(hidden=SMALL)
    facings = []
    for model in (nkn, world_nkn):  # the head's root: a quarter turn about +Y, whatever its input
        with torch.no_grad():
            model.out.weight[:4] = 0.0
            model.out.bias[:4] = torch.tensor([0.5**0.5, 0.0, 0.5**0.5, 0.0])
            enc, skel = torch.zeros(2, SMALL), ob.reshape(2, 3 * J)
            states, prev = [torch.zeros(2, SMALL)], torch.zeros(2, 3 * J + 3)
            _, _, fed_back, _ = model.decode_step(enc, skel, prev, states, ob)
        facings.append(hip_facing(fed_back[:, : 3 * J].reshape(2, J, 3)))
    assert torch.allclose(facings[0], torch.tensor([0.0, 1.0]).expand(2, 2), atol=1e-5)
    rest = hip_facing(ob)  # the up-legs hang from the root: their rest offsets give the facing
    turned = torch.stack((rest[:, 1], -rest[:, 0]), -1)  # a quarter turn about +Y: +z -> +x
    assert torch.allclose(facings[1], turned, atol=1e-5) and not torch.allclose(
        facings[1], facings[0], atol=0.1
    )
    with pytest.raises(ValueError, match="paper form"):
        TDCNGenerator(channels=SMALL, residual=True, positions_frame="root")
    with pytest.raises(ValueError, match="world or facing"):
        NKNGenerator(hidden=SMALL, positions_frame="root")


def test_a_facing_frame_nkn_steps_along_the_sources_heading():
    """A head that outputs one forward step a frame walks wherever the source faces."""
    g = NKNGenerator(hidden=SMALL, backbone="dilated", root_frame="facing").eval()
    with torch.no_grad():
        g.out.weight[-3:] = 0.0
        g.out.bias[-3:] = torch.tensor([0.0, 0.0, 0.01])
    q, r, oa, ob = _motion(2, 40)
    with torch.no_grad():
        out = g(q, r, oa, ob)
    f = hip_facing(source_local_positions(q, oa))
    expected = 0.01 * torch.stack((f[..., 0], torch.zeros_like(f[..., 0]), f[..., 1]), -1)
    assert torch.allclose(out.root_velocities, expected, atol=1e-6)
    with pytest.raises(ValueError, match="root_frame"):
        NKNGenerator(hidden=SMALL, root_frame="heading")


def test_a_floor_height_nkn_scales_the_sources_hip_height_and_cannot_drift():
    """root_height="floor": a zero vertical output gives the source's hip height times the leg
    ratio in every frame (the ground truth's root height), and a constant vertical output lifts
    every frame by the same amount instead of climbing frame after frame as an integrated step."""
    g = NKNGenerator(hidden=SMALL, backbone="dilated", root_height="floor").eval().double()
    q, r, oa, ob = _motion(2, 40, dtype=torch.float64)
    r = r.clone()
    r[..., 1] = 0.9 + 0.1 * torch.linspace(0, 6.283, 40, dtype=torch.float64).sin()  # a bob
    ratio = (leg_length(ob) / leg_length(oa))[:, None]
    with torch.no_grad():
        g.out.weight[-3:] = 0.0
        g.out.bias[-3:] = 0.0
        zero = g(q, r, oa, ob)
        g.out.bias[-2] = 0.05  # five hundredths of a leg length, every frame
        lifted = g(q, r, oa, ob)
    assert torch.allclose(zero.root_positions[..., 1], r[..., 1] * ratio, atol=1e-12)
    lift = lifted.root_positions[..., 1] - zero.root_positions[..., 1]
    assert torch.allclose(lift, 0.05 * leg_length(ob)[:, None].expand_as(lift), atol=1e-12)
    # the returned steps are the path's vertical steps (0 at the first frame)
    assert torch.allclose(zero.root_velocities[:, 1:, 1], zero.root_positions[..., 1].diff(dim=1))
    assert (zero.root_velocities[:, 0, 1] == 0).all()
    # and the source's height enters the encoder in place of its vertical step
    x = g.source_features(source_local_positions(q, oa), r, oa)
    assert torch.allclose(x[:, -2], r[..., 1] / leg_length(oa)[:, None], atol=1e-12)
    with pytest.raises(ValueError, match="root_height"):
        NKNGenerator(hidden=SMALL, root_height="absolute")


def test_a_standardized_nkn_root_head_outputs_z_scores_of_the_root_channels():
    """standardized_root: a head bias of 1 on the three root channels gives one input std of each
    (here a facing-frame step of 2 cm forward, 1 cm sideways), and an unfitted normalizer (std 1)
    leaves metres as they were."""
    g = NKNGenerator(
        hidden=SMALL, backbone="dilated", root_frame="facing", standardized_root=True
    ).eval()
    q, r, oa, ob = _motion(1, 20)
    with torch.no_grad():
        g.out.weight[-3:] = 0.0
        g.out.bias[-3:] = torch.tensor([1.0, 0.0, 1.0])
        g.normalizer.std[-3:] = torch.tensor([0.01, 0.5, 0.02])
        out = g(q, r, oa, ob)
    f = hip_facing(source_local_positions(q, oa))
    fx, fz = f[..., 0], f[..., 1]
    expected = torch.stack((0.01 * fz + 0.02 * fx, torch.zeros_like(fx), 0.02 * fz - 0.01 * fx), -1)
    assert torch.allclose(out.root_velocities, expected, atol=1e-6)


@pytest.mark.parametrize("root_frame", ["world", "facing"])
def test_a_residual_nkn_root_gives_the_sources_path_times_the_leg_ratio(root_frame):
    """root_residual: a zero root head gives the source's root path scaled by the leg ratio from
    the scaled start (the ground truth's rule), horizontally with a floor height; a constant head
    output adds a step of its size in every frame."""
    q, r, oa, ob = _motion(2, 30, dtype=torch.float64)
    r = r.clone()
    r[..., 0] = torch.linspace(0.0, 0.6, 30, dtype=torch.float64)  # a walk along x
    r[..., 1] = 0.9
    ratio = (leg_length(ob) / leg_length(oa)).view(2, 1, 1)
    for height in ("step", "floor"):
        g = (
            NKNGenerator(
                hidden=SMALL,
                backbone="dilated",
                root_frame=root_frame,
                root_height=height,
                root_residual=True,
            )
            .eval()
            .double()
        )
        with torch.no_grad():
            g.out.weight[-3:] = 0.0
            g.out.bias[-3:] = 0.0
            out = g(q, r, oa, ob)
        assert torch.allclose(out.root_positions, r * ratio, atol=1e-9), height
    with torch.no_grad():
        g.out.bias[-3:] = torch.tensor([0.0, 0.0, 0.01], dtype=torch.float64)  # 1 cm a frame
        moved = g(q, r, oa, ob)
    extra = (moved.root_velocities - out.root_velocities)[..., [0, 2]].norm(dim=-1)
    assert torch.allclose(extra, torch.full_like(extra, 0.01), atol=1e-9)
    assert build_model(
        {"kind": "nkn", "channels": SMALL, "root_residual": True}
    ).generator.root_residual


def test_nkn_gru_decoder_is_online():
    """The GRU baseline is causal: later source frames do not change earlier outputs."""
    g = NKNGenerator(hidden=SMALL).eval()
    q, r, oa, ob = _motion(1, 30)
    with torch.no_grad():
        full = g(q, r, oa, ob)
        part = g(q[:, :20], r[:, :20], oa, ob)
    assert torch.allclose(full.rotations[:, :20], part.rotations, atol=1e-6)


@pytest.mark.slow  # torch.compile of the GRU step: ~1 min of CPU
def test_a_compiled_nkn_decoder_computes_the_eager_outputs_and_gradients():
    eager = NKNGenerator(hidden=SMALL)  # dropout 0 (NKN's GRU default): both draw no random masks
    compiled = NKNGenerator(hidden=SMALL)
    compiled.load_state_dict(eager.state_dict())
    compiled.compile_decoder()
    q, r, oa, ob = _motion(2, 6)
    outs = [g(q, r, oa, ob) for g in (eager, compiled)]
    # fused kernels sum in another order: float32 rounding, carried through 6 recurrent frames
    torch.testing.assert_close(outs[1].rotations, outs[0].rotations, rtol=1e-4, atol=1e-5)
    torch.testing.assert_close(outs[1].root_positions, outs[0].root_positions, rtol=1e-4, atol=1e-5)
    for _g, out in zip((eager, compiled), outs, strict=False):
        (out.rotations.square().sum() + out.root_positions.square().sum()).backward()
    for (name, a), b in zip(eager.named_parameters(), compiled.parameters(), strict=False):
        torch.testing.assert_close(b.grad, a.grad, rtol=1e-3, atol=1e-5, msg=name)
    assert (
        NKNGenerator(hidden=SMALL, backbone="dense").compile_decoder() is None
    )  # no per-frame loop: a no-op


def test_nkn_discriminator_scores_whole_clip():
    d = NKNDiscriminator()
    for frames in (2, 9, 120):
        q, r, oa, _ = _motion(3, frames)
        f = d.features(source_local_positions(q, oa), r, oa)
        assert f.shape == (3, d.in_channels, frames - 1)
        assert d(f).shape == (3, 1)


# ------------------------------------------------------------------------------- gradients


def _assert_all_grads(module):
    missing = [
        n for n, p in module.named_parameters() if p.grad is None or not p.grad.abs().sum() > 0
    ]
    assert not missing, f"no gradient reaches {missing}"


@pytest.mark.parametrize(
    "row", ["ours", "A1", "A5", "Baseline", "Baseline-dense", "Baseline-dilated", "Baseline-height"]
)
def test_gradient_reaches_every_generator_parameter(row):
    gen, _ = build_model({"row": row, "channels": 16})
    gen.train()
    q, r, oa, ob = _motion(2, 12)
    out = gen.generate(q, r, oa, ob)
    w = torch.randn_like(out.rotations)
    (out.rotations * w).sum().backward(retain_graph=True)
    (out.root_positions * torch.randn_like(out.root_positions)).sum().backward()
    _assert_all_grads(gen)


@pytest.mark.parametrize("row", ["ours", "A4", "Baseline"])
def test_gradient_reaches_every_discriminator_parameter(row):
    gen, disc = build_model({"row": row, "channels": 16, "disc_channels": 16})
    disc.train()
    q, r, oa, _ = _motion(3, 100)
    f = disc.features(source_local_positions(q, oa), r, oa).requires_grad_(True)
    score = disc(f)
    (score * torch.randn_like(score)).sum().backward()
    _assert_all_grads(disc)
    assert f.grad is not None and f.grad.abs().sum() > 0


# ------------------------------------------------------------------------------- factory


def test_build_model_builds_every_table4_row():
    expect = {
        "Baseline": (NKNGenerator, dict(backbone="gru", normalize_root=False, height_loss=False)),
        "Baseline-dense": (NKNGenerator, dict(backbone="dense")),
        "Baseline-dilated": (NKNGenerator, dict(backbone="dilated")),
        "Baseline-height": (
            NKNGenerator,
            dict(backbone="gru", normalize_root=True, height_loss=True),
        ),
        "ours": (TDCNGenerator, dict(causal=False)),
        "A1": (TDCNGenerator, dict(causal=False)),
        "A2": (TDCNGenerator, dict(causal=False)),
        "A3": (TDCNGenerator, dict(causal=False)),
        "A4": (TDCNGenerator, dict(causal=False)),
        "A5": (TDCNGenerator, dict(causal=True)),
        "ours-residual": (
            TDCNGenerator,
            dict(causal=False, residual=True),
        ),  # our variant, not a paper row
    }
    assert set(expect) == set(TABLE4_ROWS)
    q, r, oa, ob = _motion(1, 6)
    for row, (cls, attrs) in expect.items():
        gen, disc = build_model(
            {"row": row, "profile": "fast", "channels": 16, "disc_channels": 16}
        )
        assert isinstance(gen, cls), row
        for k, v in attrs.items():
            assert getattr(gen, k) == v, (row, k)
        assert gen.config["row"] == row
        gen.eval()
        with torch.no_grad():
            qn, rn = gen.retarget(q, r, oa, ob)
        assert qn.shape == (1, 6, J, 4) and rn.shape == (1, 6, 3)
        if cls is TDCNGenerator:
            assert gen.receptive_field == 81
            assert gen.body.dense == (row == "A1")
            assert isinstance(disc, PatchDiscriminator)
            assert disc.receptive_field == (81 if row == "A4" else 31)
        else:
            assert isinstance(disc, NKNDiscriminator)


def test_build_model_profiles_and_errors():
    g, d = build_model({"kind": "tdcn", "profile": "paper"})
    assert g.body.channels == 1024 and g.config["channels"] == 1024
    g, _ = build_model({"kind": "nkn", "profile": "paper"})
    assert g.hidden == 512
    g, _ = build_model({"model": {"kind": "tdcn", "variant": "causal", "channels": 8}})
    assert g.causal and g.body.channels == 8
    with pytest.raises(ValueError):
        build_model({"kind": "tdcn", "chanels": 8})
    with pytest.raises(ValueError):
        build_model({"kind": "tdcn", "variant": "height"})
    with pytest.raises(ValueError):
        build_model({"row": "A9"})
