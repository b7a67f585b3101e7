"""The residual TDCN and GeoRet variants (ours, not the papers'), their alignment algebra and the
bone-direction term."""

import numpy as np
import pytest
import torch

from retarget_lib.core.kinematics import align_local_rotations, forward_kinematics
from retarget_lib.core.measures import leg_length, skeleton_leg_length
from retarget_lib.core.rotations import quat_normalize
from retarget_lib.core.skeleton import CANONICAL22_PARENTS
from retarget_lib.losses import bone_direction_loss
from retarget_lib.models import build_model

PARENTS = CANONICAL22_PARENTS


def random_quats(*shape, seed=0):
    g = torch.Generator().manual_seed(seed)
    return quat_normalize(torch.randn(*shape, 4, generator=g, dtype=torch.float64))


def test_align_identity_returns_the_rotations():
    q = random_quats(5, 22)
    ident = torch.zeros_like(q)
    ident[..., 0] = 1.0
    # float64 quaternion products of unit quaternions: rounding only
    assert torch.allclose(align_local_rotations(q, ident, PARENTS), q, atol=1e-12)


def test_align_turns_each_global_frame_by_its_own_alignment():
    q, c = random_quats(3, 22, seed=1), random_quats(3, 22, seed=2)
    off = torch.randn(22, 3, dtype=torch.float64)
    g_before = forward_kinematics(q, off, PARENTS, None).rotations
    g_after = forward_kinematics(align_local_rotations(q, c, PARENTS), off, PARENTS, None).rotations
    from retarget_lib.core.rotations import quat_mul

    expected = quat_mul(g_before, c)
    # the same rotation up to the quaternion sign; float64 rounding through 7 levels of products
    dot = (g_after * expected).sum(-1).abs()
    assert torch.allclose(dot, torch.ones_like(dot), atol=1e-10)


def test_bone_direction_loss_hand_values():
    # two bones of a chain: straight up vs. turned by 90 degrees -> |u - u'|^2 = 2 for the turned
    # bone
    parents = (-1, 0, 1)
    p_a = torch.tensor([[0.0, 0, 0], [0, 1, 0], [0, 2, 0]]).view(1, 1, 3, 3)
    p_b = torch.tensor([[0.0, 0, 0], [0, 1, 0], [1, 1, 0]]).view(1, 1, 3, 3)
    assert bone_direction_loss(p_a, p_b, parents).item() == pytest.approx(1.0)  # mean of (0, 2)
    # uniform scaling changes no direction
    assert bone_direction_loss(p_a, 2.5 * p_a, parents).item() == pytest.approx(0.0, abs=1e-12)


def test_leg_length_matches_the_skeleton():
    from retarget_lib.data.synthetic.characters import make_character

    sk = make_character("ada").skeleton
    assert leg_length(torch.as_tensor(sk.offsets)).item() == pytest.approx(
        skeleton_leg_length(sk), rel=1e-12
    )


def _zero_head(linear):
    with torch.no_grad():
        linear.weight.zero_()


def test_untrained_residual_tdcn_is_copy_and_same_skeleton_is_identity():
    gen, _ = build_model({"row": "ours-residual", "profile": "fast"})
    gen.eval()
    _zero_head(gen.head.out)  # the head's bias is the identity: C = 1 exactly
    q = random_quats(2, 30, 22, seed=3).float()
    r = torch.randn(2, 30, 3)
    off_a = torch.randn(22, 3) * 0.1
    off_a[[6, 7, 8, 9, 10, 11, 12, 13], 1] = -0.2  # legs point down: a positive leg length
    off_b = off_a * 1.3
    with torch.no_grad():
        q_hat, r_hat = gen.retarget(q, r, off_a, off_b)
    # float32 quaternion products: rounding only
    assert torch.allclose(q_hat, q, atol=1e-5)
    # the root is the source's times the leg ratio (1.3 for a uniformly scaled skeleton)
    assert torch.allclose(r_hat, r * 1.3, atol=1e-5)


def _georet_inputs(frames, seed):
    """A random source clip for the geometry-conditioned RNN: rotations ``(1, T, 22, 4)``, its
    features, rest offsets, a base root velocity, and a 50-vertex mesh with skinning weights."""
    from retarget_lib.models.georet import motion_features

    q = random_quats(1, frames, 22, seed=seed).float()
    root = torch.cumsum(torch.randn(1, frames, 3) * 0.01, 1)
    off = torch.randn(22, 3) * 0.1
    vel = torch.randn(1, frames, 3) * 0.01
    verts, weights = torch.randn(1, 50, 3), torch.softmax(torch.randn(1, 50, 22), -1)
    return q, motion_features(q, root, off), off, vel, verts, weights


def test_residual_georet_starts_at_the_source_rotations():
    from retarget_lib.models.georet import GeometryConditionedRNN, ResidualBase

    model = GeometryConditionedRNN(hidden=32, geometry=16, residual=True).eval()  # as initialised
    assert not model.rotation_head.weight.any() and not model.velocity_head.weight.any()
    q, feats, off, vel, verts, weights = _georet_inputs(8, seed=4)
    with torch.no_grad():
        out = model(feats, off, verts, weights, base=ResidualBase(q, vel))
    from retarget_lib.core.rotations import quat_to_matrix

    # same rotation (sign-free comparison as matrices), float32 rounding
    assert torch.allclose(quat_to_matrix(out.rotations), quat_to_matrix(q), atol=1e-5)
    assert torch.allclose(out.root_velocity, vel, atol=1e-6)
    with pytest.raises(ValueError, match="ResidualBase"):
        model(feats, off, verts, weights)


def test_residual_tdcn_on_its_own_skeleton_is_the_identity_for_any_weights():
    torch.manual_seed(0)
    gen, _ = build_model({"row": "ours-residual", "profile": "fast"})
    gen.eval()
    with torch.no_grad():
        gen.head.out.weight.normal_(std=0.5)  # far from the identity initialisation
    q = random_quats(2, 40, 22, seed=5).float()
    r = torch.randn(2, 40, 3)
    off = torch.randn(2, 22, 3) * 0.1
    off[:, [6, 7, 8, 9, 10, 11, 12, 13], 1] = -0.2
    with torch.no_grad():
        q_hat, r_hat = gen.retarget(q, r, off, off)
        q_other, _ = gen.retarget(q, r, off, off * torch.tensor([1.2, 0.9, 1.0]))
    from retarget_lib.core.rotations import quat_to_matrix

    # float32 products of a few unit quaternions: rounding only
    assert torch.allclose(quat_to_matrix(q_hat), quat_to_matrix(q), atol=1e-4)
    assert torch.allclose(r_hat, r, atol=1e-5)
    assert not torch.allclose(
        quat_to_matrix(q_other), quat_to_matrix(q), atol=1e-2
    )  # another target: a change


def test_untrained_residual_tdcn_is_copy_rest_between_rest_conventions():
    """The residual network's base is the rest alignment of the two retarget poses: untrained
    (correction 1), an A-pose source onto a T-pose target is exactly the ``copy-rest`` method."""
    from skeletons import make_skeleton

    from retarget_lib.core.transfer import transfer_rotations

    gen, _ = build_model({"row": "ours-residual", "profile": "fast"})
    gen.eval()
    _zero_head(gen.head.out)
    a_pose, t_pose = make_skeleton(1.5, arm_deg=45.0), make_skeleton(1.8, arm_deg=0.0)
    q = random_quats(1, 20, 22, seed=9)
    r = torch.randn(1, 20, 3)
    off_a, off_b = (torch.as_tensor(s.offsets, dtype=torch.float32) for s in (a_pose, t_pose))
    with torch.no_grad():
        q_hat, _ = gen.retarget(q.float(), r, off_a, off_b)
    want = torch.from_numpy(transfer_rotations(q[0].numpy(), a_pose, t_pose))
    from retarget_lib.core.rotations import quat_to_matrix

    # float32 network path against the float64 method: rounding only
    assert torch.allclose(quat_to_matrix(q_hat[0].double()), quat_to_matrix(want), atol=1e-5)
    copied = quat_to_matrix(q[0])
    assert not torch.allclose(quat_to_matrix(want), copied, atol=1e-2)  # the arms are aligned


def test_the_tdcn_method_commutes_with_a_mirror_and_keeps_identity():
    """``mirror_averaged`` (what the ``tdcn`` method runs for a residual generator): the mirror
    image of a clip onto the mirror image of a character is the mirror image of the result, for a
    network whose own answer breaks the symmetry; a clip onto its own skeleton comes back."""
    from retarget_lib.core.motion import Motion
    from retarget_lib.data.synthetic.characters import make_character
    from retarget_lib.methods.tdcn import mirror_averaged

    torch.manual_seed(0)
    gen, _ = build_model({"row": "ours-residual", "profile": "fast"})
    gen.eval()
    with torch.no_grad():
        gen.head.out.weight.normal_(std=0.5)  # alignments far from the identity, not symmetric
    source_skeleton = make_character("gus").skeleton  # symmetric
    clip = Motion(
        source_skeleton,
        random_quats(40, 22, seed=11).numpy(),
        np.cumsum(np.random.default_rng(2).normal(scale=0.01, size=(40, 3)), axis=0)
        + [0.0, 0.9, 0.0],
        30.0,
    )
    target = source_skeleton.scaled(1.1)
    target.offsets[source_skeleton.index("LeftUpLeg")] *= [1.3, 1.0, 1.0]  # not symmetric itself
    with torch.no_grad():
        q, r = mirror_averaged(gen, clip, target)
        q_m, r_m = mirror_averaged(gen, clip.mirror(), target.mirror())
        plain_m, _ = gen.retarget(
            *(x[None] for x in clip.mirror().torch()[:2]),
            torch.as_tensor(clip.mirror().skeleton.offsets, dtype=torch.float32),
            torch.as_tensor(target.mirror().offsets, dtype=torch.float32),
        )
        q_same, r_same = mirror_averaged(gen, clip, source_skeleton)
    result = clip.copy(skeleton=target, rotations=q.double().numpy(), root_positions=r.numpy())
    mirrored = result.mirror()
    # float32 network passes composed with a few unit quaternions: rounding only
    np.testing.assert_allclose(
        clip.copy(
            skeleton=target.mirror(), rotations=q_m.double().numpy(), root_positions=r_m.numpy()
        ).global_positions(),
        mirrored.global_positions(),
        atol=1e-4,
    )
    one_pass = clip.copy(
        skeleton=target.mirror(), rotations=plain_m[0].double().numpy(), root_positions=r_m.numpy()
    )
    assert np.abs(one_pass.global_positions() - mirrored.global_positions()).max() > 1e-2
    np.testing.assert_allclose(
        clip.copy(
            rotations=q_same.double().numpy(), root_positions=r_same.numpy()
        ).global_positions(),
        clip.global_positions(),
        atol=1e-4,
    )  # identity: both passes return the input (float32)


def _far_from_identity(model, seed=0):
    torch.manual_seed(seed)
    with torch.no_grad():
        model.rotation_head.weight.normal_(std=0.5)
        model.velocity_head.weight.normal_(std=0.5)
    return model


def test_lower_body_from_base_keeps_the_bases_hips_legs_and_root_path_for_any_weights():
    from retarget_lib.core.rotations import quat_to_matrix
    from retarget_lib.models.georet import GeometryConditionedRNN, ResidualBase
    from retarget_lib.models.georet.model import LOWER_BODY

    q, feats, off, vel, verts, weights = _georet_inputs(6, seed=7)
    outs = {}
    for kept in (False, True):
        model = GeometryConditionedRNN(
            hidden=32, geometry=16, residual=True, lower_body_from_base=kept
        ).eval()
        _far_from_identity(model)
        with torch.no_grad():
            outs[kept] = model(feats, off, verts, weights, base=ResidualBase(q, vel))
    lower, upper = list(LOWER_BODY), [j for j in range(22) if j not in LOWER_BODY]
    m = {k: quat_to_matrix(o.rotations) for k, o in outs.items()}
    base = quat_to_matrix(q)
    # float32 products of unit quaternions: rounding only
    assert torch.allclose(m[True][:, :, lower], base[:, :, lower], atol=1e-5)
    assert torch.allclose(outs[True].root_velocity, vel, atol=1e-6)
    # the same weights with the lower body free change it, and the upper body changes either way
    assert not torch.allclose(m[False][:, :, lower], base[:, :, lower], atol=1e-2)
    assert not torch.allclose(outs[False].root_velocity, vel, atol=1e-3)
    assert not torch.allclose(m[True][:, :, upper], base[:, :, upper], atol=1e-2)
    with pytest.raises(ValueError, match="residual"):
        GeometryConditionedRNN(hidden=32, geometry=16, lower_body_from_base=True)


def test_eso_moves_neither_the_root_nor_the_legs_of_a_lower_body_from_base_network():
    from retarget_lib.core.rotations import quat_to_matrix
    from retarget_lib.data.synthetic.characters import make_character
    from retarget_lib.data.synthetic.motions import make_motion
    from retarget_lib.geometry.penetration import InterpenetrationEnergy
    from retarget_lib.methods.contact import retarget_with_eso
    from retarget_lib.models.georet import GeometryConditionedRNN
    from retarget_lib.models.georet.model import LOWER_BODY

    character = make_character("ada")
    motion = make_motion("clap", character.skeleton, 0).slice(0, 4)
    eint = InterpenetrationEnergy(character.faces, character.rest_vertices)
    eso = {"iterations": 3, "lr": 0.05, "reach": 0.15, "blend": 0.3}
    results = {}
    for kept in (False, True):
        model = GeometryConditionedRNN(
            hidden=32, geometry=16, residual=True, lower_body_from_base=kept
        ).eval()
        _far_from_identity(model, seed=1)
        results[kept] = retarget_with_eso(model, eso, motion, character, None, eint, compile=False)
    lower = list(LOWER_BODY)
    kept = results[True]
    # onto its own skeleton the base is the source itself (leg ratio 1)
    np.testing.assert_allclose(kept.root_positions, motion.root_positions, atol=1e-5)
    a = quat_to_matrix(torch.as_tensor(kept.rotations[:, lower]))
    b = quat_to_matrix(torch.as_tensor(motion.rotations[:, lower]))
    assert torch.allclose(a, b.to(a.dtype), atol=1e-4)  # float32 network, float64 source
    assert np.abs(results[False].root_positions - motion.root_positions).max() > 1e-3


def test_eso_takes_its_rotation_and_interpenetration_weights_from_the_config(monkeypatch):
    """``eso.rho`` / ``eso.beta_int`` of a checkpoint's config reach ESO's energy; without them
    ESO keeps App. B.1's relaxed 10 and 1."""
    from retarget_lib.data.synthetic.characters import make_character
    from retarget_lib.data.synthetic.motions import make_motion
    from retarget_lib.geometry.penetration import InterpenetrationEnergy
    from retarget_lib.methods import contact
    from retarget_lib.models.georet import GeometryConditionedRNN

    seen = []
    run = contact.encoder_space_optimization

    def spy(*args, **kwargs):
        seen.append(kwargs["weights"])
        return run(*args, **kwargs)

    monkeypatch.setattr(contact, "encoder_space_optimization", spy)
    character = make_character("ada")
    motion = make_motion("clap", character.skeleton, 0).slice(0, 2)
    eint = InterpenetrationEnergy(character.faces, character.rest_vertices)
    model = GeometryConditionedRNN(hidden=16, geometry=8, residual=True).eval()
    eso = {"iterations": 1, "lr": 0.01, "reach": 0.15, "blend": 0.3}
    for config in (eso, {**eso, "rho": 1000.0, "beta_int": 10.0}):
        contact.retarget_with_eso(model, config, motion, character, None, eint, compile=False)
    assert (seen[0].rho, seen[0].beta_int, seen[0].lambda_j2j) == (10.0, 1.0, 100.0)
    assert (seen[1].rho, seen[1].beta_int, seen[1].lambda_j2j) == (1000.0, 10.0, 100.0)
