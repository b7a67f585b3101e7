"""Encoder-space optimisation (retarget_lib.methods.eso) on tiny hand-made problems."""

import numpy as np
import pytest
import torch
from skeletons import make_skeleton

from retarget_lib.core.character import Character
from retarget_lib.core.quantities import MotionQuantities, motion_quantities
from retarget_lib.core.rotations import quat_identity
from retarget_lib.core.skeleton import J
from retarget_lib.core.skinning import linear_blend_skinning
from retarget_lib.data.synthetic.characters import make_character
from retarget_lib.data.synthetic.motions import make_motion
from retarget_lib.geometry.penetration import InterpenetrationEnergy
from retarget_lib.losses.contact import ContactEnergyWeights
from retarget_lib.methods.eso import (
    TERMS,
    encoder_space_optimization,
    eso_source,
    eso_throughput,
    reachable_pairs,
    reached_joints,
)
from retarget_lib.methods.eso import frame as eso_frame
from retarget_lib.methods.eso import step as eso_step
from retarget_lib.models.georet import (
    DecoderState,
    GeometryConditionedRNN,
    motion_features,
    pose_outputs,
)

ONLY_J2J = ContactEnergyWeights(
    lambda_j2j=100.0, beta_int=0.0, gamma_foot=0.0, rho=0.0, omega=0.0, hold=0.0
)


def _point_character(n=800, seed=0):
    """``n`` random points around a 1.8 m skeleton, each rigidly skinned to its nearest joint."""
    skel = make_skeleton()
    rng = np.random.default_rng(seed)
    verts = rng.uniform([-0.9, 0.0, -0.15], [0.9, 1.8, 0.15], size=(n, 3))
    owner = np.linalg.norm(verts[:, None] - skel.rest_positions()[None], axis=-1).argmin(1)
    weights = np.eye(22)[owner]
    faces = np.arange(n - n % 3).reshape(-1, 3)
    return Character("points", skel, verts, faces, weights)


def _model(seed=0, rotation_std=0.0):
    torch.manual_seed(seed)
    model = GeometryConditionedRNN(hidden=32, geometry=16).eval()
    if rotation_std:
        with torch.no_grad():
            model.rotation_head.weight.normal_(std=rotation_std)
    return model


def _rest_source(skel, frames):
    """The skeleton standing still in its rest pose: features and energy quantities."""
    rot = quat_identity((frames, 22))
    root = torch.as_tensor(skel.offsets[0], dtype=torch.float32).repeat(frames, 1)
    feats = motion_features(rot[None], root[None], skel.offsets)
    return feats, motion_quantities(
        rot, root, torch.as_tensor(skel.offsets, dtype=torch.float32), skel.height()
    )


def _initial_vertices(model, character, feats):
    """The network's own output (no ESO) skinned, ``(T, V, 3)``."""
    with torch.no_grad():
        out = model(
            feats,
            torch.as_tensor(character.skeleton.offsets, dtype=torch.float32),
            torch.as_tensor(character.rest_vertices, dtype=torch.float32)[None],
            torch.as_tensor(character.weights, dtype=torch.float32)[None],
            character.height,
        )
        start = torch.as_tensor(character.skeleton.offsets[0], dtype=torch.float32)
        posed = pose_outputs(
            out.rotations, out.root_velocity, character.skeleton.offsets, start=start
        )
        verts = linear_blend_skinning(
            character.rest_vertices,
            character.weights,
            character.skeleton.rest_positions(),
            posed.global_rotations[0],
            posed.positions[0],
        )
    return out, posed, verts


def _pair_at(verts, character, distance):
    """A vertex pair on two unrelated joints whose distance in ``verts (V, 3)`` is closest to
    ``distance``."""
    owner = character.weights.argmax(1)
    parents = character.skeleton.parents
    d = torch.cdist(verts, verts).numpy()
    related = (
        (owner[:, None] == owner[None])
        | (np.array(parents)[owner][:, None] == owner[None])
        | (np.array(parents)[owner][None] == owner[:, None])
    )
    d[related] = np.inf
    i, j = np.unravel_index(np.abs(d - distance).argmin(), d.shape)
    return np.array([[i, j]]), float(d[i, j])


def test_eso_leaves_an_output_that_already_equals_the_source_unchanged():
    character = _point_character()
    model = _model(rotation_std=0.1)
    feats = torch.randn(1, 4, 267, generator=torch.Generator().manual_seed(1))
    out, posed, _ = _initial_vertices(model, character, feats)
    source = MotionQuantities(
        out.rotations[0], out.root_velocity[0], posed.positions[0], character.height
    )
    only_weak = ContactEnergyWeights(
        lambda_j2j=0.0, beta_int=0.0, gamma_foot=0.0, rho=10.0, omega=0.0, hold=0.0
    )
    result = encoder_space_optimization(
        model, feats, character, source, np.zeros((4, 4), bool), 1.0, weights=only_weak
    )
    assert result.energies.shape == (4, 31)
    # Eweak at its minimum, every iteration: the same decode_step kernels on the same values in one
    # process give exactly the source's rotations (and exact 0 matters: Adam's step hardly shrinks
    # with the gradient)
    assert result.energies.abs().max().item() == 0.0
    torch.testing.assert_close(result.rotations, out.rotations[0])
    torch.testing.assert_close(result.root_positions, posed.root_positions[0])
    torch.testing.assert_close(result.positions, posed.positions[0])


def test_eso_closes_a_reachable_5cm_contact():
    character = _point_character()
    model = _model(rotation_std=0.1)
    feats, source = _rest_source(character.skeleton, 1)
    _, _, verts = _initial_vertices(model, character, feats)
    pairs, gap = _pair_at(verts[0], character, 0.05)
    assert gap == pytest.approx(0.05, abs=0.002)
    result = encoder_space_optimization(
        model,
        feats,
        character,
        source,
        np.zeros((1, 4), bool),
        1.0,
        contacts=[pairs],
        weights=ONLY_J2J,
    )
    assert result.energies.shape == (1, 31)
    assert set(result.terms) == set(TERMS)
    assert result.active_contacts.tolist() == [1]
    relaxed, distance = result.terms["j2j"][0], result.terms["j2j_distance"][0]
    assert relaxed[0].item() == pytest.approx(
        100 * 0.3 * gap / 0.01, rel=1e-4
    )  # λ · 0.3 · gap, in cm
    assert distance[0].item() == pytest.approx(gap, rel=1e-4)
    assert relaxed[-1] < 0.4 * relaxed[0]  # a clear factor
    assert distance[-1] < 0.5 * gap  # 5 cm -> about 2 cm (0.4 of it at best)
    assert distance[-1] > 0.35 * gap  # ... not beyond the relaxed targets
    rises = (distance[1:] > distance[:-1] * 1.02).sum().item()  # Adam wobbles a little at most
    assert rises <= 3
    final = linear_blend_skinning(
        character.rest_vertices,
        character.weights,
        character.skeleton.rest_positions(),
        _global_rotations(result, character),
        result.positions,
    )[0]
    assert (final[pairs[0, 0]] - final[pairs[0, 1]]).norm().item() == pytest.approx(
        distance[-1].item(), rel=1e-3
    )


def _global_rotations(result, character):
    from retarget_lib.core.kinematics import forward_kinematics

    return forward_kinematics(
        result.rotations,
        torch.as_tensor(character.skeleton.offsets, dtype=torch.float32),
        character.skeleton.parents,
        result.root_positions,
    ).rotations


def test_eso_ignores_a_contact_beyond_reach():
    character = _point_character()
    model = _model(rotation_std=0.3)
    feats, source = _rest_source(character.skeleton, 2)
    _, _, verts = _initial_vertices(model, character, feats)
    pairs, gap = _pair_at(verts[0], character, 0.5)
    assert gap == pytest.approx(0.5, abs=0.01)
    far = encoder_space_optimization(
        model,
        feats,
        character,
        source,
        np.zeros((2, 4), bool),
        1.0,
        contacts=[pairs, pairs],
        weights=ONLY_J2J,
        iterations=5,
    )
    none = encoder_space_optimization(
        model,
        feats,
        character,
        source,
        np.zeros((2, 4), bool),
        1.0,
        contacts=None,
        weights=ONLY_J2J,
        iterations=5,
    )
    assert far.active_contacts.tolist() == [0, 0]
    assert far.energies.shape == (2, 6)
    assert far.terms["j2j"].abs().max().item() == 0.0
    torch.testing.assert_close(far.rotations, none.rotations)
    wide = encoder_space_optimization(
        model,
        feats,
        character,
        source,
        np.zeros((2, 4), bool),
        1.0,
        contacts=[pairs, pairs],
        weights=ONLY_J2J,
        iterations=5,
        reach=10.0,
    )
    assert wide.active_contacts.tolist() == [1, 1]


def test_eso_default_weights_log_every_term_and_keep_the_model():
    character = _point_character()
    model = _model(rotation_std=0.1).train()
    before = [p.detach().clone() for p in model.parameters()]
    threads = torch.get_num_threads()
    feats, source = _rest_source(character.skeleton, 3)
    contacts = np.ones((3, 4), bool)
    result = encoder_space_optimization(
        model, feats[0], character, source, contacts, 1.0, iterations=4
    )
    assert torch.get_num_threads() == threads
    assert result.energies.shape == (3, 5)
    torch.testing.assert_close(
        result.energies, sum(result.terms[k] for k in TERMS if k != "j2j_distance")
    )
    assert (result.terms["weak"] > 0).all() and (result.terms["foot"] > 0).any()
    assert model.training and all(p.requires_grad for p in model.parameters())
    for p, q in zip(model.parameters(), before, strict=False):
        torch.testing.assert_close(p, q)
    assert result.frames_per_second > 0
    with pytest.raises(ValueError, match="foot_contacts"):
        encoder_space_optimization(model, feats, character, source, contacts[:2], 1.0)


@pytest.mark.parametrize("redetect_every", [0, 10])
def test_eso_with_only_eint_lowers_the_penetration(redetect_every):
    character = _point_character(n=300)  # its "faces" join random points: hundreds of crossings
    eint = InterpenetrationEnergy(character.faces, character.rest_vertices, geodesic_weights=False)
    model = _model(rotation_std=0.1)
    feats, source = _rest_source(character.skeleton, 1)
    only_int = ContactEnergyWeights(
        lambda_j2j=0.0, beta_int=1.0, gamma_foot=0.0, rho=0.0, omega=0.0, hold=0.0
    )
    result = encoder_space_optimization(
        model,
        feats,
        character,
        source,
        np.zeros((1, 4), bool),
        1.0,
        interpenetration=eint,
        weights=only_int,
        redetect_every=redetect_every,
    )
    assert result.colliding_pairs[0] > 100
    _, _, verts = _initial_vertices(model, character, feats)
    assert result.terms["int"][0, 0].item() == pytest.approx(
        eint(verts[0]).item() / 0.01**2, rel=1e-4
    )
    assert result.terms["int"][0, -1] < 0.99 * result.terms["int"][0, 0]
    torch.testing.assert_close(
        result.energies, result.terms["int"] + result.terms["weak"]
    )  # + root term


def test_eso_skinning_only_the_vertices_it_reads_gives_the_whole_mesh_result(monkeypatch):
    # each step skins the colliding faces' vertices and their neighbours only; forcing the whole
    # mesh must give the same optimisation (float32 sums in another order: 1e-5)
    character = _point_character(n=300)
    eint = InterpenetrationEnergy(character.faces, character.rest_vertices)
    model = _model(rotation_std=0.1)
    feats, source = _rest_source(character.skeleton, 2)
    only_int = ContactEnergyWeights(
        lambda_j2j=0.0, beta_int=1.0, gamma_foot=0.0, rho=1.0, omega=0.0, hold=0.0
    )
    run = lambda: encoder_space_optimization(  # noqa: E731
        model,
        feats,
        character,
        source,
        np.zeros((2, 4), bool),
        1.0,  # noqa: E731
        interpenetration=eint,
        weights=only_int,
        iterations=5,
    )
    subset = run()
    monkeypatch.setattr(
        eso_frame.Frame,
        "mesh_vertices",
        lambda self, pairs, collisions: np.arange(len(character.rest_vertices)),
    )
    whole = run()
    assert (
        subset.colliding_pairs[0] > 100 and subset.terms["int"][0, -1] < subset.terms["int"][0, 0]
    )
    torch.testing.assert_close(subset.energies, whole.energies, rtol=1e-5, atol=1e-6)
    torch.testing.assert_close(subset.rotations, whole.rotations, rtol=1e-5, atol=1e-6)


def test_reachable_pairs_and_reached_joints_by_hand():
    verts = torch.tensor([[0.0, 0, 0], [0.1, 0, 0], [0.0, 0.5, 0], [0.3, 0, 0]])
    pairs = np.array([[0, 1], [0, 2], [1, 3]])
    np.testing.assert_array_equal(reachable_pairs(pairs, verts, 0.15), [[0, 1]])
    np.testing.assert_array_equal(reachable_pairs(pairs, verts, 0.25), [[0, 1], [1, 3]])
    weights = np.zeros((4, 22))
    weights[0, J["LeftHand"]] = 0.8
    weights[0, J["LeftForeArm"]] = 0.2
    weights[1, J["Head"]] = 1.0
    weights[2, J["RightHand"]] = 1.0
    weights[3, J["Spine2"]] = 1.0
    assert reached_joints(pairs, weights) == [J["Head"]]  # (0, 2) is hand-hand: nothing held
    assert reached_joints(np.array([[1, 3]]), weights) == []  # no hand involved


def test_eso_source_and_throughput_on_a_synthetic_character():
    character = make_character("ada")
    motion = make_motion("clap", character.skeleton, 0)
    src = eso_source(motion, character)
    assert src.features.shape == (1, motion.num_frames, 267)
    assert src.foot_contacts.shape == (motion.num_frames, 4) and src.foot_contacts.any()
    assert src.leg_ratio == pytest.approx(1.0)
    row = eso_throughput(_model(), motion, character, frames=2, iterations=2)
    assert row["frames"] == 2 and row["vertices"] == len(character.rest_vertices)
    assert row["frames_per_second"] > 0
    with pytest.raises(ValueError, match="frames"):
        eso_throughput(_model(), motion, character, frames=motion.num_frames + 1)


def test_eso_keeps_every_iterate_on_request():
    character = _point_character()
    model = _model(rotation_std=0.1)
    feats, source = _rest_source(character.skeleton, 2)
    out, posed, verts = _initial_vertices(model, character, feats)
    pairs, _ = _pair_at(verts[0], character, 0.05)
    kwargs = dict(contacts=[pairs, pairs], weights=ONLY_J2J, iterations=6)
    plain = encoder_space_optimization(
        model, feats, character, source, np.zeros((2, 4), bool), 1.0, **kwargs
    )
    assert plain.iterate_rotations is None and plain.iterate_roots is None
    result = encoder_space_optimization(
        model, feats, character, source, np.zeros((2, 4), bool), 1.0, keep_iterates=True, **kwargs
    )
    assert result.iterate_rotations.shape == (2, 7, 22, 4) and result.iterate_roots.shape == (
        2,
        7,
        3,
    )
    torch.testing.assert_close(
        result.iterate_rotations[:, -1], result.rotations
    )  # n = N is the kept pose
    torch.testing.assert_close(result.iterate_roots[:, -1], result.root_positions)
    torch.testing.assert_close(
        result.iterate_rotations[0, 0], out.rotations[0, 0]
    )  # frame 0 before any step
    torch.testing.assert_close(result.rotations, plain.rotations)  # keeping them changes nothing
    assert (
        result.iterate_rotations[0, 1:] - result.iterate_rotations[0, :1]
    ).abs().max() > 0  # it moved


@pytest.mark.slow
def test_compiled_steps_optimise_as_the_eager_ones():
    # the same energy compiled (torch.compile, sizes dynamic, pairs padded with zero weight): frames
    # with and without colliding pairs, contact pairs on some frames only; float32 fused in another
    # order, so agreement to 1e-4 relative over 3 frames x 8 steps
    character = _point_character(n=300)
    eint = InterpenetrationEnergy(character.faces, character.rest_vertices)
    model = _model(rotation_std=0.1)
    feats, source = _rest_source(character.skeleton, 3)
    _, _, verts = _initial_vertices(model, character, feats)
    pairs, _ = _pair_at(verts[0], character, 0.05)
    run = (  # noqa: E731
        lambda compile: encoder_space_optimization(  # noqa: E731
            model,
            feats,
            character,
            source,
            np.zeros((3, 4), bool),
            1.0,
            contacts=[pairs, pairs[:0], pairs[:1]],
            interpenetration=eint,
            iterations=8,
            compile=compile,
        )
    )
    eager, compiled = run(False), run(True)
    assert (
        eager.colliding_pairs.min() > 0
        and eager.terms["j2j"][0, 0] > 0
        and eager.terms["int"][0, 0] > 0
    )
    torch.testing.assert_close(compiled.energies, eager.energies, rtol=1e-4, atol=1e-6)
    torch.testing.assert_close(compiled.rotations, eager.rotations, rtol=1e-4, atol=1e-5)
    # each term of the first evaluation (the same energy on the same input, summed in another
    # order): 1e-3. Later steps are not compared term by term: Eint (2.8e6 here) dominates the
    # gradient, and Adam carries its reordering into the small terms (measured on an AMD EPYC:
    # Eweak 7.28 eager against 7.96 compiled at step 2, while the totals agree to 2e-6 and the
    # rotations to 1e-4)
    for name in TERMS:
        torch.testing.assert_close(
            compiled.terms[name][:, 0], eager.terms[name][:, 0], rtol=1e-3, atol=1e-5
        )


def test_compiling_is_chosen_for_long_clips_and_never_without_a_compiler(monkeypatch):
    monkeypatch.setattr(eso_step, "_have_compiler", lambda: True)
    monkeypatch.setattr(eso_step, "_compiled_in_process", lambda: False)
    assert not eso_step.use_compiled(60) and eso_step.use_compiled(eso_step.COMPILE_FROM_FRAMES)
    assert eso_step.use_compiled(60, compile=True) and not eso_step.use_compiled(
        10_000, compile=False
    )
    monkeypatch.setattr(eso_step, "_have_compiler", lambda: False)
    with pytest.warns(UserWarning, match="C\\+\\+ compiler"):
        assert not eso_step.use_compiled(10_000)
    monkeypatch.setattr(eso_step, "_have_compiler", lambda: True)
    monkeypatch.setattr(
        eso_step, "_compiled_in_process", lambda: True
    )  # compiled already: reuse it
    assert eso_step.use_compiled(60)


def test_an_eso_step_is_torch_adam_on_the_frame_energy(monkeypatch):
    # adam_step writes Adam's arithmetic out (so a compiled step fuses it): on a known energy,
    # 6 steps from the same start follow torch.optim.Adam with ESO's betas and epsilon (float32
    # rounding in another order: ~1e-6; a missing bias correction or moment errs by ~lr = 0.05)
    target_h, target_o = torch.linspace(-1.0, 1.0, 8)[None], torch.tensor([[0.3, -0.2, 0.1]])

    def quadratic(model, weights, blend, cone, constants, frame, h_enc, o_prev):
        total = ((h_enc - target_h) ** 2).sum() + 3.0 * ((o_prev - target_o) ** 2).sum()
        state = DecoderState(*(o_prev * 1.0 for _ in range(5)))
        return torch.stack([total] * (len(TERMS) + 1)), eso_frame.Pose(
            o_prev * 1.0, state, o_prev * 2.0, None
        )

    monkeypatch.setattr(eso_step, "frame_terms", quadratic)
    start = (torch.zeros(1, 8), torch.zeros(1, 3))
    variables, adam, lr = start, eso_step.AdamState.start(start), torch.tensor(0.05)
    reference = [x.clone().requires_grad_(True) for x in start]
    optimiser = torch.optim.Adam(
        reference, lr=0.05, betas=eso_step.ADAM_BETAS, eps=eso_step.ADAM_EPS
    )
    for _ in range(6):
        variables, adam, values, _ = eso_step.adam_step(
            None, None, 0.0, {}, None, None, variables, adam, lr
        )
        optimiser.zero_grad()
        quadratic(*[None] * 6, *reference)[0][-1].backward()
        optimiser.step()
        for ours, theirs in zip(variables, reference, strict=False):
            torch.testing.assert_close(ours, theirs.detach(), rtol=0, atol=1e-5)
    assert (variables[0] - start[0]).abs().max() > 0.2  # it moved towards the minimum


def test_eso_takes_the_step_it_is_given():
    # a notebook's own step (exercise 07b.1) runs in place of the library's: called once per
    # iteration and once more per frame for the final terms, and the library's step given by hand
    # changes nothing
    character = _point_character()
    model = _model(rotation_std=0.1)
    feats, source = _rest_source(character.skeleton, 2)
    _, _, verts = _initial_vertices(model, character, feats)
    pairs, _ = _pair_at(verts[0], character, 0.05)
    calls = []

    def counted(*args):
        calls.append(1)
        return eso_step.adam_step(*args)

    kwargs = dict(contacts=[pairs, pairs], weights=ONLY_J2J, iterations=4)
    plain = encoder_space_optimization(
        model, feats, character, source, np.zeros((2, 4), bool), 1.0, **kwargs
    )
    given = encoder_space_optimization(
        model, feats, character, source, np.zeros((2, 4), bool), 1.0, step=counted, **kwargs
    )
    assert len(calls) == 2 * (4 + 1)
    torch.testing.assert_close(given.rotations, plain.rotations, rtol=0, atol=0)
    torch.testing.assert_close(given.energies, plain.energies, rtol=0, atol=0)
