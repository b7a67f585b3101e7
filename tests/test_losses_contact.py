"""Contact-aware energies (retarget_lib.losses.contact), on hand-made cases computed by hand."""

import math

import numpy as np
import pytest
import torch
from skeletons import make_skeleton

from retarget_lib.core.measures import foot_rest_heights, skeleton_leg_length
from retarget_lib.core.quantities import (
    FOOT_CONTACT_IDS,
    MotionQuantities,
    forward_root_velocity,
    frame_velocities,
    leg_ratio,
    motion_quantities,
)
from retarget_lib.core.rotations import quat_from_axis_angle, quat_identity
from retarget_lib.core.skeleton import J
from retarget_lib.geometry.penetration import InterpenetrationEnergy, interpenetration_energy
from retarget_lib.losses.contact import (
    END_EFFECTORS,
    ESO_FOOT_WEIGHT,
    TABLE3_ROWS,
    ContactEnergyWeights,
    end_effector_energy,
    end_effector_energy_per_frame,
    eso_self_contact_energy,
    foot_contact_energy,
    foot_contact_energy_per_frame,
    full_energy,
    geometry_energy,
    reach_hold_energy,
    self_contact_energy,
    skeleton_energy,
    weak_energy,
)

F64 = torch.float64


def _two_points(gap):
    return torch.tensor([[0.0, 1.0, 0.0], [gap, 1.0, 0.0], [5.0, 5.0, 5.0]], dtype=F64)


# ----------------------------------------------------------------------------- Ej2j (Eq. 3)
def test_two_vertices_3cm_apart_give_ej2j_of_3cm():
    energy = self_contact_energy(_two_points(0.03), np.array([[0, 1]]))
    assert energy.shape == ()
    assert energy.item() == pytest.approx(0.03)


def test_ej2j_is_the_mean_distance_not_its_square():
    v = torch.tensor([[0.0, 0, 0], [0.03, 0, 0], [0.0, 0.1, 0], [0.0, 0.1, 0.05]], dtype=F64)
    assert self_contact_energy(v, [[0, 1], [2, 3]]).item() == pytest.approx((0.03 + 0.05) / 2)


def test_ej2j_gradient_pulls_the_pair_together():
    v = _two_points(0.03).requires_grad_(True)
    self_contact_energy(v, [[0, 1]]).backward()
    torch.testing.assert_close(v.grad[0], torch.tensor([-1.0, 0, 0], dtype=F64))
    torch.testing.assert_close(v.grad[1], torch.tensor([1.0, 0, 0], dtype=F64))


def test_ej2j_batched_with_shared_and_per_element_masked_pairs():
    v = torch.stack([_two_points(0.03), _two_points(0.07)])  # (2, 3, 3)
    torch.testing.assert_close(
        self_contact_energy(v, [[0, 1]]), torch.tensor([0.03, 0.07], dtype=F64)
    )
    pairs = torch.tensor(
        [[[0, 1], [0, 2]], [[0, 1], [0, 0]]]
    )  # second element: one real pair + padding
    mask = torch.tensor([[True, False], [True, False]])
    torch.testing.assert_close(
        self_contact_energy(v, pairs, mask), torch.tensor([0.03, 0.07], dtype=F64)
    )


def test_ej2j_without_pairs_is_zero():
    v = torch.zeros(4, 10, 3, dtype=F64)
    torch.testing.assert_close(
        self_contact_energy(v, np.zeros((0, 2), int)), torch.zeros(4, dtype=F64)
    )
    with pytest.raises(ValueError, match="pairs"):
        self_contact_energy(v, [0, 1, 2])


# ----------------------------------------------------------------------------- ESO relaxed Ej2j
def test_eso_self_contact_starts_at_blend_times_the_gap_and_vanishes_at_the_relaxed_targets():
    v0 = _two_points(0.05)
    assert eso_self_contact_energy(v0, [[0, 1]], v0, blend=0.3).item() == pytest.approx(0.3 * 0.05)
    assert eso_self_contact_energy(v0, [[0, 1]], v0, blend=1.0).item() == pytest.approx(
        self_contact_energy(v0, [[0, 1]]).item()
    )
    moved = v0.clone()
    moved[0, 0] = 0.3 * 0.05  # 0.7 of its own start + 0.3 of its partner
    moved[1, 0] = 0.7 * 0.05  # and the partner likewise
    assert eso_self_contact_energy(moved, [[0, 1]], v0, blend=0.3).item() == pytest.approx(
        0.0, abs=1e-15
    )
    # a masked (padding) pair counts for nothing: ESO's compiled step pads to fixed minimum sizes
    mask = torch.tensor([1.0, 0.0], dtype=F64)
    assert eso_self_contact_energy(v0, [[0, 1], [1, 0]], v0, 0.3, mask).item() == pytest.approx(
        0.3 * 0.05
    )
    assert eso_self_contact_energy(v0, [[0, 1], [0, 1]], v0, 0.3, mask * 0).item() == 0.0


def test_eso_self_contact_rejects_bad_blend():
    v0 = _two_points(0.05)
    with pytest.raises(ValueError, match="blend"):
        eso_self_contact_energy(v0, [[0, 1]], v0, blend=1.5)


def test_reach_hold_is_the_mean_drift_of_the_held_joints():
    g0 = torch.zeros(22, 3, dtype=F64)
    g = g0.clone()
    g[J["Head"], 1] = 0.02
    g[J["Hips"], 0] = 0.04
    assert reach_hold_energy(g, g0, [J["Head"], J["Hips"]]).item() == pytest.approx(0.03)
    assert reach_hold_energy(g, g0, []).item() == 0.0
    held = torch.zeros(22, dtype=F64)
    held[[J["Head"], J["Hips"]]] = 1.0  # the same as a (22,) mask
    assert reach_hold_energy(g, g0, held).item() == pytest.approx(0.03)
    assert reach_hold_energy(g, g0, held * 0).item() == 0.0


# ----------------------------------------------------------------------------- Efoot (Eq. 6)
def _still_feet(frames, ground):
    pos = torch.zeros(frames, 22, 3, dtype=F64)
    pos[:, list(FOOT_CONTACT_IDS), 1] = torch.as_tensor(ground, dtype=F64)
    return pos


def test_still_foot_on_its_rest_height_costs_nothing():
    ground = np.array([0.08, 0.08, 0.02, 0.02])
    contacts = np.ones((4, 4), dtype=bool)
    assert foot_contact_energy(
        _still_feet(4, ground), contacts, ground, 1.5
    ).item() == pytest.approx(0.0)


def test_foot_2cm_up_sliding_1cm_per_frame_by_hand():
    ground = np.array([0.08, 0.08, 0.02, 0.02])
    pos = _still_feet(3, ground)
    left_heel = J["LeftFoot"]
    pos[:, left_heel, 1] += 0.02
    pos[:, left_heel, 0] = torch.tensor([0.0, 0.01, 0.02], dtype=F64)
    contacts = np.zeros((3, 4), dtype=bool)
    contacts[:, 0] = True  # LeftFoot in contact; the others would cost 0 anyway
    h = 1.5
    # frame 0: no velocity, 0.02^2 height; frames 1, 2: 0.01^2 + 0.02^2
    per_frame = foot_contact_energy_per_frame(pos, contacts, ground, h)
    torch.testing.assert_close(per_frame, torch.tensor([4e-4, 5e-4, 5e-4], dtype=F64) / h)
    assert foot_contact_energy(pos, contacts, ground, h).item() == pytest.approx(14e-4 / 3 / h)
    contacts[:] = False
    assert foot_contact_energy(pos, contacts, ground, h).item() == 0.0


def test_foot_energy_batched_heights_and_bad_contacts():
    ground = np.zeros(4)
    pos = _still_feet(2, ground).repeat(2, 1, 1, 1)
    pos[:, :, J["RightToeBase"], 1] = 0.1
    contacts = np.ones((2, 2, 4), dtype=bool)
    out = foot_contact_energy(pos, contacts, ground, torch.tensor([1.0, 2.0], dtype=F64))
    torch.testing.assert_close(out, torch.tensor([0.01, 0.005], dtype=F64))
    with pytest.raises(ValueError, match="contacts"):
        foot_contact_energy(pos, np.ones((2, 3, 4), bool), ground, 1.0)


def test_foot_rest_heights_are_the_rest_heights_of_heels_and_toes():
    skel = make_skeleton()
    rest = skel.rest_positions()
    expected = [rest[J[n], 1] for n in ("LeftFoot", "RightFoot", "LeftToeBase", "RightToeBase")]
    np.testing.assert_allclose(foot_rest_heights(skel), expected, atol=1e-12)
    assert foot_rest_heights(skel)[2] == pytest.approx(0.0)


# ----------------------------------------------------------------------------- Eweak (Eq. 8)
def test_weak_energy_of_identical_motions_is_zero():
    g = torch.Generator().manual_seed(0)
    rot = torch.nn.functional.normalize(torch.randn(5, 22, 4, generator=g, dtype=F64), dim=-1)
    vel = torch.randn(5, 3, generator=g, dtype=F64)
    torch.testing.assert_close(
        weak_energy(rot, rot, vel, vel, 1.0, 1000.0), torch.zeros(5, dtype=F64)
    )


def test_weak_energy_of_one_joint_rotated_90_degrees_is_rho_times_4():
    rot_a = quat_identity((22,), F64)
    rot_b = rot_a.clone()
    rot_b[J["LeftArm"]] = quat_from_axis_angle(torch.tensor([0.0, 0.0, math.pi / 2], dtype=F64))
    zero = torch.zeros(3, dtype=F64)
    # ||R - I||_F^2 = 2 * (2 - 2 cos 90°) = 4
    assert weak_energy(rot_b, rot_a, zero, zero, 1.0, 1000.0).item() == pytest.approx(4000.0)


def test_weak_energy_scales_the_source_root_velocity_by_the_leg_ratio():
    rot = quat_identity((22,), F64)
    o_a = torch.tensor([0.01, 0.0, 0.0], dtype=F64)
    o_b = torch.tensor([0.02, 0.0, 0.0], dtype=F64)
    assert weak_energy(rot, rot, o_b, o_a, 2.0, 1000.0).item() == pytest.approx(0.0)
    assert weak_energy(rot, rot, o_b, o_a, 1.0, 1000.0).item() == pytest.approx(1e-4)


def test_leg_length_and_leg_ratio_by_hand():
    skel = make_skeleton(height=1.8, leg_frac=0.5)
    # hips at 0.06 + thigh + shin + ankle (= 0.94 + 0.06 of the 0.9 m leg); toes on the ground
    assert skeleton_leg_length(skel) == pytest.approx(0.06 + 0.9)
    assert leg_ratio(skel, skel.scaled(1.25)) == pytest.approx(1.25)


def test_forward_root_velocity_by_hand():
    root = torch.tensor([[0.0, 1, 0], [0.1, 1, 0], [0.3, 1, 0]], dtype=F64)
    expected = torch.tensor([[0.1, 0, 0], [0.2, 0, 0], [0.2, 0, 0]], dtype=F64)
    torch.testing.assert_close(forward_root_velocity(root), expected)
    torch.testing.assert_close(forward_root_velocity(root[:1]), torch.zeros(1, 3, dtype=F64))


# ----------------------------------------------------------------------------- Eee (Eq. 9)
def test_end_effector_energy_with_hand_made_velocities():
    assert END_EFFECTORS == ("LeftHand", "RightHand", "LeftFoot", "RightFoot")
    t = torch.arange(3, dtype=F64)
    pos_a = torch.zeros(3, 22, 3, dtype=F64)
    pos_b = torch.zeros(3, 22, 3, dtype=F64)
    pos_a[:, J["LeftHand"], 0] = 0.01 * t  # 1 cm/frame on a 1 m character -> 0.01 / frame
    pos_b[:, J["LeftHand"], 0] = 0.03 * t  # 3 cm/frame on a 1.5 m one     -> 0.02 / frame
    pos_b[:, J["Head"], 2] = 0.5 * t  # not an end effector: ignored
    per_frame = end_effector_energy_per_frame(pos_b, pos_a, 1.5, 1.0)
    torch.testing.assert_close(per_frame, torch.tensor([0.0, 1e-4, 1e-4], dtype=F64))
    assert end_effector_energy(pos_b, pos_a, 1.5, 1.0).item() == pytest.approx(2e-4 / 3)
    assert end_effector_energy(pos_a * 1.5, pos_a, 1.5, 1.0).item() == pytest.approx(0.0)


def test_frame_velocities_start_at_zero():
    pos = torch.arange(6, dtype=F64).reshape(2, 1, 3)
    torch.testing.assert_close(
        frame_velocities(pos), torch.tensor([[[0.0, 0, 0]], [[3.0, 3, 3]]], dtype=F64)
    )


# ----------------------------------------------------------------------------- weights
def test_weights_training_eso_and_table3_rows():
    w = ContactEnergyWeights()
    assert (w.lambda_j2j, w.beta_int, w.gamma_foot, w.rho, w.omega) == (1000, 100, 0.1, 1000, 1000)
    e = ContactEnergyWeights.eso()
    assert (e.lambda_j2j, e.beta_int, e.rho, e.omega, e.hold) == (100, 1, 10, 1000, 100)  # App. B.1
    # the paper's gamma in ESO: four planted foot joints slipping 1 cm in a frame on a 1.7 m body
    # cost ~2e-3
    slip = torch.zeros(1, 2, 22, 3)
    slip[0, 1, list(FOOT_CONTACT_IDS), 0] = 0.01
    foot = foot_contact_energy_per_frame(
        slip, torch.ones(1, 2, 4, dtype=torch.bool), torch.zeros(4), 1.7
    )[0, 1]
    assert e.gamma_foot == ESO_FOOT_WEIGHT == 0.1
    assert e.gamma_foot * float(e.in_units("foot", foot)) == pytest.approx(4 * 0.1 / 170)
    assert list(TABLE3_ROWS) == [
        "Eskel",
        "Eskel+Efoot",
        "Eskel+Efoot+Eint w/o w",
        "Eskel+Efoot+Eint",
        "Efull",
    ]
    skel = ContactEnergyWeights.row("Eskel")
    assert (skel.j2j_weight, skel.int_weight, skel.foot_weight) == (0, 0, 0)
    no_w = ContactEnergyWeights.row("Eskel+Efoot+Eint w/o w")
    assert no_w.use_int and not no_w.use_j2j and not no_w.geodesic_weights
    assert ContactEnergyWeights.row("Efull") == ContactEnergyWeights()
    assert ContactEnergyWeights.row("Eskel+Efoot").relaxed().use_int is False
    assert (
        ContactEnergyWeights(gamma_foot=7.0).relaxed().gamma_foot == 7.0
    )  # App. B.1 leaves gamma alone
    assert ContactEnergyWeights().with_foot_ramp(1, 10).gamma_foot == pytest.approx(0.01)
    with pytest.raises(ValueError, match="Table 3"):
        ContactEnergyWeights.row("Efull+IK")
    with pytest.raises(ValueError, match="length_unit"):
        ContactEnergyWeights(length_unit=0.0)


def test_eso_weights_from_a_config_section_replace_only_what_it_sets():
    """A checkpoint config's ``eso`` section sets rho and beta (configs/contact_residual.yaml);
    what it leaves out keeps App. B.1's relaxed value, and the other weights never move."""
    paper = ContactEnergyWeights.eso()
    assert ContactEnergyWeights.from_eso_config({"iterations": 30, "reach": 0.15}) == paper
    only_rho = ContactEnergyWeights.from_eso_config({"rho": 1000})
    assert (only_rho.rho, only_rho.beta_int) == (1000.0, 1.0)
    both = ContactEnergyWeights.from_eso_config({"rho": 1000, "beta_int": 10})
    assert (both.rho, both.beta_int) == (1000.0, 10.0)
    assert (both.lambda_j2j, both.hold, both.gamma_foot) == (
        paper.lambda_j2j,
        paper.hold,
        paper.gamma_foot,
    )


# ----------------------------------------------------------------------------- combinations
def _motion(skel, frames=3, seed=0):
    g = torch.Generator().manual_seed(seed)
    rot = torch.nn.functional.normalize(
        quat_identity((frames, 22), F64) + 0.1 * torch.randn(frames, 22, 4, generator=g, dtype=F64),
        dim=-1,
    )
    root = (
        torch.tensor([0.0, 0.96, 0.0], dtype=F64) + 0.02 * torch.arange(frames, dtype=F64)[:, None]
    )
    return motion_quantities(rot, root, skel.offsets, skel.height())


def test_motion_quantities_hold_fk_positions_and_forward_root_velocity():
    skel = make_skeleton()
    q = _motion(skel)
    torch.testing.assert_close(
        q.positions[:, 0],
        torch.tensor([0.0, 0.96, 0.0], dtype=F64) + 0.02 * torch.arange(3, dtype=F64)[:, None],
    )
    torch.testing.assert_close(q.root_velocity, torch.full((3, 3), 0.02, dtype=F64))


def test_skeleton_energy_weights_terms_and_converts_lengths():
    skel = make_skeleton()
    a, b = _motion(skel, seed=0), _motion(skel, seed=1)
    w = ContactEnergyWeights(length_unit=1.0)
    terms = skeleton_energy(b, a, 1.0, w)
    assert set(terms) == {"weak", "ee", "total"}
    weak = weak_energy(
        b.rotations, a.rotations, b.root_velocity, a.root_velocity, 1.0, w.rho
    ).mean()
    torch.testing.assert_close(terms["weak"], weak)
    torch.testing.assert_close(
        terms["ee"], w.omega * end_effector_energy(b.positions, a.positions, b.height, a.height)
    )
    torch.testing.assert_close(terms["total"], terms["weak"] + terms["ee"])
    # the root term is a squared length: in centimetres it is 10^4 times larger; rotations, Eee
    # unchanged
    faster = b._replace(root_velocity=b.root_velocity + 0.01)
    extra_m = skeleton_energy(faster, a, 1.0, w)["weak"] - terms["weak"]
    extra_cm = (
        skeleton_energy(faster, a, 1.0, ContactEnergyWeights())["weak"]
        - skeleton_energy(b, a, 1.0, ContactEnergyWeights())["weak"]
    )
    assert extra_cm.item() == pytest.approx(1e4 * extra_m.item())


def test_skeleton_energy_ee_on_the_leg_scale():
    """``ee_scale="legs"``: Eee asks for the source's end-effector speed times the leg ratio, the
    speed Eweak asks of the root; as printed (``"height"``) it asks for ``h_B / h_A`` times it."""
    skel = make_skeleton()
    a = _motion(skel, seed=0)
    legs, h_b = 2.0, 1.5 * float(a.height)
    on_legs = a._replace(positions=a.positions * legs, height=h_b)  # every velocity x leg ratio
    on_height = a._replace(positions=a.positions * 1.5, height=h_b)  # every velocity x h_B/h_A
    legs_w = ContactEnergyWeights(ee_scale="legs")
    printed = ContactEnergyWeights()

    def ee(output, weights):
        return skeleton_energy(output, a, legs, weights)["ee"].item()

    assert ee(on_legs, legs_w) == pytest.approx(0.0, abs=1e-12)
    assert ee(on_legs, printed) > 1e-3
    assert ee(on_height, printed) == pytest.approx(0.0, abs=1e-12)
    assert legs_w.ee_source_height(1.5, 1.0, 2.0) == 0.75  # h_B / leg ratio
    with pytest.raises(ValueError, match="ee_scale"):
        ContactEnergyWeights(ee_scale="arms")


def _crossing_triangles():
    """Two triangles, no shared vertex, crossing each other."""
    verts = (
        np.array(
            [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0.2, 0.2, -0.5], [0.3, 0.2, 0.5], [0.2, 0.3, 0.5]],
            dtype=float,
        )
        * 0.1
    )
    return verts, np.array([[0, 1, 2], [3, 4, 5]])


def test_geometry_and_full_energy_terms_switches_and_units():
    skel = make_skeleton()
    a, b = _motion(skel, seed=0), _motion(skel, seed=1)
    verts, faces = _crossing_triangles()
    eint = InterpenetrationEnergy(faces, verts, geodesic_weights=False)
    v = torch.as_tensor(verts)
    pairs = np.array([[0, 3]])
    contacts = np.ones((3, 4), bool)
    ground = foot_rest_heights(skel)
    w = ContactEnergyWeights()
    terms = full_energy(b, a, v, pairs, contacts, ground, 1.0, w, eint)
    assert set(terms) == {"weak", "ee", "j2j", "int", "foot", "total"}
    gap = np.linalg.norm(verts[0] - verts[3])
    assert terms["j2j"].item() == pytest.approx(1000 * gap / 0.01)
    e_int = interpenetration_energy(v, faces, eint.pairs(verts))
    assert e_int.item() > 0
    assert terms["int"].item() == pytest.approx(100 * e_int.item() / 0.01**2)
    foot = foot_contact_energy(b.positions, contacts, ground, b.height)
    assert terms["foot"].item() == pytest.approx(0.1 * foot.item() / 0.01)
    total = sum(terms[k] for k in ("weak", "ee", "j2j", "int", "foot"))
    torch.testing.assert_close(terms["total"], total)

    only_skel = full_energy(
        b, a, v, pairs, contacts, ground, 1.0, ContactEnergyWeights.row("Eskel")
    )
    assert set(only_skel) == {"weak", "ee", "total"}
    geo = geometry_energy(
        v, None, b.positions, contacts, ground, b.height, ContactEnergyWeights.row("Eskel")
    )
    assert set(geo) == {"total"} and geo["total"].item() == 0.0
    with pytest.raises(ValueError, match="interpenetration"):
        geometry_energy(v, pairs, b.positions, contacts, ground, b.height, w)


def test_full_energy_is_differentiable_in_the_output_motion():
    skel = make_skeleton()
    a = _motion(skel, seed=0)
    rot = _motion(skel, seed=1).rotations.clone().requires_grad_(True)
    root = torch.tensor([0.0, 0.97, 0.0], dtype=F64).repeat(3, 1).requires_grad_(True)
    b = motion_quantities(rot, root, skel.offsets, skel.height())
    terms = full_energy(
        b,
        a,
        b.positions[0],
        [[J["LeftHand"], J["Head"]]],
        np.ones((3, 4), bool),
        foot_rest_heights(skel),
        leg_ratio(skel, skel),
        ContactEnergyWeights.row("Eskel+Efoot"),
    )
    terms["total"].backward()
    assert torch.isfinite(rot.grad).all() and rot.grad.abs().sum() > 0
    assert root.grad.abs().sum() > 0
    assert isinstance(b, MotionQuantities)


def test_foot_rest_heights_measure_from_the_rest_ground():
    from retarget_lib.data.synthetic.characters import make_character

    sk = make_character("ada").skeleton
    on_floor = foot_rest_heights(sk)
    lowered = sk.copy()
    lowered.offsets[0] = lowered.offsets[0] - [
        0.0,
        1.0,
        0.0,
    ]  # root at the origin-ish: feet below 0
    np.testing.assert_allclose(foot_rest_heights(lowered), on_floor - on_floor.min(), atol=1e-12)
    assert on_floor.min() >= 0
