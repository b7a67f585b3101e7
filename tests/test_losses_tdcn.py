"""TDCN losses (Kim et al. 2020, Eqs. 6-23) against values worked out by hand.

Every expected number below is plain arithmetic written next to the input that produces it;
inputs are tiny (B=1-2, T=1-3, J=1-2) and float64.
"""

import dataclasses
import math

import pytest
import torch

from retarget_lib.core.quantities import discriminator_inputs
from retarget_lib.core.rotations import quat_mul
from retarget_lib.losses import (
    MotionTensors,
    NonFiniteLossError,
    TDCNLossWeights,
    adversarial_loss,
    adversarial_loss_discriminator,
    adversarial_loss_generator,
    bone_axes,
    check_finite,
    cycle_loss,
    height_loss,
    orientation_loss,
    reconstruction_loss,
    regularization_loss,
    root_smoothness_loss,
    sigmoid_ce_discriminator_loss,
    sigmoid_ce_generator_loss,
    smooth_l1,
    total_generator_loss,
    twist_angle,
    twist_loss,
)

D = torch.float64
DEG = math.pi / 180.0  # one degree in radians


def t(x):
    return torch.tensor(x, dtype=D)


def quat_deg(angle_deg, axis):
    """wxyz quaternion of ``angle_deg`` about a unit ``axis`` (input construction only)."""
    h = 0.5 * angle_deg * DEG
    return [math.cos(h)] + [math.sin(h) * a for a in axis]


def approx(value, expected):
    return float(torch.as_tensor(value).detach()) == pytest.approx(expected, rel=1e-9, abs=1e-12)


# ------------------------------------------------------------------------------ Eq. 14


def test_smooth_l1_both_branches():
    # x = 0.5: |x| < 1  -> 0.5 * 0.5**2 = 0.125
    # x = -3 : |x| >= 1 -> 3 - 0.5     = 2.5
    # x = 1  : boundary, 'otherwise' branch -> 1 - 0.5 = 0.5 (= 0.5 * 1**2, continuous)
    assert approx(smooth_l1(t([[0.5]])), 0.125)
    assert approx(smooth_l1(t([[-3.0]])), 2.5)
    assert approx(smooth_l1(t([[1.0]])), 0.5)
    # mean over the two elements: (0.125 + 2.5) / 2 = 1.3125
    assert approx(smooth_l1(t([[0.5, -3.0]])), 1.3125)
    per = smooth_l1(t([[0.5], [-3.0]]), reduction="per_sample")
    assert per.shape == (2,) and approx(per[0], 0.125) and approx(per[1], 2.5)


# --------------------------------------------------------------------------- Eq. 7 / Eq. 21 (A = B)


def motion(p, q, r):
    return MotionTensors(t(p), t(q), t(r))


def test_cycle_loss_by_hand():
    # B=1, T=1, J=1.
    x = motion([[[[0.0, 0.0, 0.0]]]], [[[[1.0, 0.0, 0.0, 0.0]]]], [[[0.0, 0.0, 0.0]]])
    x_hat = motion([[[[0.3, 0.0, 0.4]]]], [[[[0.8, 0.6, 0.0, 0.0]]]], [[[1.0, 2.0, 2.0]]])
    # p: (0.09 + 0 + 0.16) / 3          = 0.083333...
    # q: (0.04 + 0.36 + 0 + 0) / 4      = 0.1
    # r: (1 + 4 + 4) / 3                = 3.0
    expected = 0.25 / 3 + 0.4 / 4 + 9.0 / 3  # 3.18333...
    assert approx(cycle_loss(x, x_hat), expected)
    assert approx(reconstruction_loss(x, x_hat), expected)  # same maths, Eq. 21 second case
    assert approx(cycle_loss(x, x), 0.0)


def test_cycle_loss_is_a_mean_over_frames():
    # Two frames, the second one exact: every part's mean halves -> 3.18333 / 2.
    x = motion(
        [[[[0.0, 0.0, 0.0]], [[1.0, 1.0, 1.0]]]],
        [[[[1.0, 0.0, 0.0, 0.0]], [[1.0, 0.0, 0.0, 0.0]]]],
        [[[0.0, 0.0, 0.0], [5.0, 0.0, 0.0]]],
    )
    x_hat = motion(
        [[[[0.3, 0.0, 0.4]], [[1.0, 1.0, 1.0]]]],
        [[[[0.8, 0.6, 0.0, 0.0]], [[1.0, 0.0, 0.0, 0.0]]]],
        [[[1.0, 2.0, 2.0], [5.0, 0.0, 0.0]]],
    )
    assert approx(cycle_loss(x, x_hat), (0.25 / 3 + 0.4 / 4 + 9.0 / 3) / 2)


# ------------------------------------------------------------------------------ Eq. 8


Q120 = quat_deg(120.0, (0.0, 1.0, 0.0))
Q80 = quat_deg(80.0, (1.0, 0.0, 0.0))
QID = [1.0, 0.0, 0.0, 0.0]
EXCESS20 = (20 * math.pi / 180) ** 2  # (20° in rad)^2 = 0.3490658503988659^2 = 0.12184696791...


def test_twist_loss_120_vs_alpha_100():
    q_b = t([[[Q120]]])  # (1,1,1,4): a 120° joint
    q_a = t([[[Q80]]])  # an 80° joint: below α, free
    # intended: max(0, 120° - 100°)^2 + max(0, 80° - 100°)^2 = (20°)^2 + 0, in rad^2
    assert approx(twist_loss(q_b, q_a, alpha_deg=100.0), EXCESS20)
    # the network's unnormalised output gives the same angle
    assert approx(twist_loss(2.0 * q_b, q_a), EXCESS20)
    # J = 2 joints (120°, 0°): mean over joints -> 0.1218.../2
    assert approx(twist_loss(t([[[Q120, QID]]])), EXCESS20 / 2)
    # root excluded (authors' code): only the 0° joint is left -> 0
    assert approx(twist_loss(t([[[Q120, QID]]]), exclude_root=True), 0.0)


def test_twist_loss_literal_reading_differs():
    q_b, q_a = t([[[Q120]]]), t([[[Q80]]])
    # printed Eq. 8: |120-100|^2 + |80-100|^2 = 2 * (20°)^2
    assert approx(twist_loss(q_b, q_a, reading="literal"), 2 * EXCESS20)
    assert approx(twist_loss(q_b, q_a, reading="intended"), EXCESS20)
    # an identity joint: intended 0, literal (100°)^2 = 1.7453292519943295^2 = 3.04617...
    ident = t([[[QID]]])
    assert approx(twist_loss(ident, ident), 0.0)
    assert approx(twist_loss(ident, None, reading="literal"), (100 * math.pi / 180) ** 2)


def test_twist_about_the_bone_leaves_a_bending_elbow_free():
    x = t([1.0, 0.0, 0.0])
    # 120° about the bone (x): all twist; 120° about y swings the bone: no twist about x
    assert approx(twist_angle(t(quat_deg(120.0, (1.0, 0.0, 0.0))), x), math.radians(120.0))
    assert approx(twist_angle(t(Q120), x), 0.0)
    # a swing of 90° about y after a twist of 30° about x: the twist is still 30°
    q = quat_mul(t(quat_deg(90.0, (0.0, 1.0, 0.0))), t(quat_deg(30.0, (1.0, 0.0, 0.0))))
    assert approx(twist_angle(q, x), math.radians(30.0))
    # the double cover: -q is the same rotation
    assert approx(twist_angle(-q, x), math.radians(30.0))
    # Eq. 8 on the twist: a 120° elbow bend (about y, the bone along x) costs nothing, a 120°
    # twist about the bone costs (20°)^2 as the whole-angle reading does
    bend, spin = t([[[Q120]]]), t([[[quat_deg(120.0, (1.0, 0.0, 0.0))]]])
    along_x = t([[[1.0, 0.0, 0.0]]])  # (B, J, 3)
    assert approx(twist_loss(bend, None, axes_b=along_x), 0.0)
    assert approx(twist_loss(spin, None, axes_b=along_x), EXCESS20)
    assert approx(twist_loss(bend, None), EXCESS20)
    with pytest.raises(ValueError, match="both skeletons"):
        twist_loss(bend, bend, axes_b=along_x)


def test_bone_axes_point_along_each_joints_bone():
    from retarget_lib.core.skeleton import J
    from retarget_lib.data.synthetic.characters import make_character

    off = torch.from_numpy(make_character("ada").skeleton.offsets)
    axes = bone_axes(off)
    assert axes.shape == (22, 3)
    assert torch.allclose(axes.norm(dim=-1), torch.ones(22, dtype=axes.dtype))
    # the elbow's bone is the forearm: it points at the hand
    forearm = off[J["LeftHand"]] / off[J["LeftHand"]].norm()
    assert torch.allclose(axes[J["LeftForeArm"]], forearm)
    # a leaf (the hand) takes its own bone
    assert torch.allclose(axes[J["LeftHand"]], forearm)


def test_gan_weight_scales_only_the_gan_case():
    x_a = motion([[[[0.0, 0, 0]]]] * 2, [[[[1.0, 0, 0, 0]]]] * 2, [[[0.0, 0, 0]]] * 2)
    x_b = motion([[[[0.0, 0, 0]]]] * 2, [[[[1.0, 0, 0, 0]]]] * 2, [[[3.0, 0, 0]], [[0.0, 0.3, 0]]])
    same = torch.tensor([False, True])
    h_fake = t([[0.25], [0.0]])
    # NKN's code weight 0.001: (0.001 * 0.5625 + 0.03) / 2
    got = adversarial_loss(h_fake, x_a, x_b, same, gan_weight=0.001)
    assert approx(got, (0.001 * 0.5625 + 0.03) / 2)


# ------------------------------------------------------------------------------ Eqs. 9-17


def height_case(step_b, r_b2):
    # B=1, T=2, J=2 (joint 0 = root, always at the origin of p; joint 1 moves along +X).
    p_a = t([[[[0, 0, 0], [0.1, 0.9, 0]], [[0, 0, 0], [0.13, 0.9, 0]]]])  # moves 3 cm
    p_b = t([[[[0, 0, 0], [0.1, 1.2, 0]], [[0, 0, 0], [0.1 + step_b, 1.2, 0]]]])
    # frame 1 of r is far off on purpose: Eq. 17 uses frames 2..T only.
    r_a = t([[[10.0, 0, 0], [0.3, 0, 0.4]]])  # |r_2| = 0.5
    r_b = t([[[-7.0, 0, 0], r_b2]])
    return p_a, p_b, r_a, r_b


def test_height_loss_3cm_on_1p5m_equals_4cm_on_2m():
    # l^A = 0.03 / 1.5 = 0.02, l^B = 0.04 / 2 = 0.02; m^A = 0.5/1.5 = 1/3, m^B = (2/3)/2 = 1/3
    p_a, p_b, r_a, r_b = height_case(0.04, [0.0, 0.0, 2.0 / 3.0])
    assert approx(height_loss(p_a, p_b, r_a, r_b, 1.5, 2.0), 0.0)
    assert approx(height_loss(p_a, p_b, r_a, r_b, t([1.5]), t([2.0])), 0.0)


def test_height_loss_by_hand_small_branch():
    # B moves 6 cm: l^B = 0.06 / 2 = 0.03; l^A - l^B = -0.01 -> 0.5 * 0.0001 = 0.00005
    #   mean over J=2 (the root joint's l is 0 for both)   -> 0.000025
    # r^B_2 = (0,0,1): m^B = 1/2; m^A - m^B = 1/3 - 1/2 = -1/6 -> 0.5 / 36 = 0.013888...
    #   times λg = 5                                        -> 0.069444...
    p_a, p_b, r_a, r_b = height_case(0.06, [0.0, 0.0, 1.0])
    expected = 0.000025 + 5 * 0.5 / 36  # 0.06946944...
    assert approx(height_loss(p_a, p_b, r_a, r_b, 1.5, 2.0, lambda_g=5.0), expected)
    assert approx(height_loss(p_a, p_b, r_a, r_b, 1.5, 2.0, lambda_g=0.0), 0.000025)


def test_height_loss_large_branch():
    # H^A = H^B = 1, no joint motion; root at 3 m vs 0 m: m diff 3 -> 3 - 0.5 = 2.5; x λg 5 = 12.5
    p = torch.zeros(1, 2, 2, 3, dtype=D)
    r_a = t([[[0.0, 0, 0], [3.0, 0, 0]]])
    r_b = torch.zeros(1, 2, 3, dtype=D)
    assert approx(height_loss(p, p, r_a, r_b, 1.0, 1.0), 12.5)


def test_discriminator_inputs_by_hand():
    # B=1, T=3, J=2, H=2. Joint 1 moves 0.3 then 0.4 -> l = [0, 0.15], [0, 0.2]
    p = t([[[[0, 0, 0], [0, 1, 0]], [[0, 0, 0], [0, 1, 0.3]], [[0, 0, 0], [0.4, 1, 0.3]]]])
    # root steps (0,0,1) then (1.2,0,1.6) (length 2) -> δ = [1/2, 2/2]
    r = t([[[0.0, 0, 0], [0.0, 0, 1.0], [1.2, 0, 2.6]]])
    offsets = t([[0.0, 1.0, 0.0], [0.3, 0.0, 0.4]])  # bone lengths 1, 0.5
    lv, delta, bones = discriminator_inputs(p, r, offsets, 2.0)
    assert lv.shape == (1, 2, 2) and delta.shape == (1, 2) and bones.shape == (1, 2)
    assert torch.allclose(lv, t([[[0.0, 0.15], [0.0, 0.2]]]))
    assert torch.allclose(delta, t([[0.5, 1.0]]))
    assert torch.allclose(bones, t([[1.0, 0.5]]))
    # per-sample offsets and heights
    l2, d2, b2 = discriminator_inputs(
        p.repeat(2, 1, 1, 1), r.repeat(2, 1, 1), offsets.repeat(2, 1, 1), t([2.0, 4.0])
    )
    assert torch.allclose(l2[1], t([[0.0, 0.075], [0.0, 0.1]]))
    assert torch.allclose(d2[1], t([0.25, 0.5]))
    assert torch.allclose(b2, t([[1.0, 0.5], [1.0, 0.5]]))


# ------------------------------------------------------------------------------ Eq. 21


def test_lsgan_scores_quarter_and_three_quarters():
    h_real = t([[0.75]]).requires_grad_()
    h_fake = t([[0.25]]).requires_grad_()
    # D: (0.75 - 1)^2 + 0.25^2 = 0.0625 + 0.0625 = 0.125
    d_loss = adversarial_loss_discriminator(h_real, h_fake)
    assert approx(d_loss, 0.125)
    # descent on D raises the real score and lowers the fake one:
    # d/dh_real = 2 (0.75 - 1) = -0.5,  d/dh_fake = 2 * 0.25 = 0.5
    d_loss.backward()
    assert approx(h_real.grad, -0.5) and approx(h_fake.grad, 0.5)
    # G: (0.25 - 1)^2 = 0.5625 — the G-dependent part (1 - h^B)^2 of the printed Eq. 21,
    # whose full printed value (0.75)^2 + (1 - 0.25)^2 = 1.125 is what D would *maximise*.
    assert approx(adversarial_loss_generator(t([[0.25]])), 0.5625)
    assert approx(adversarial_loss_generator(t([[1.0]])), 0.0)
    assert approx(adversarial_loss_discriminator(t([[1.0]]), t([[0.0]])), 0.0)


def test_lsgan_discriminator_fake_mask():
    # fakes 0.25 (counted) and 0.9 (A = B, masked): 0.0625 + 0.25^2 = 0.125
    h_real, h_fake = t([[0.75], [0.75]]), t([[0.25], [0.9]])
    assert approx(adversarial_loss_discriminator(h_real, h_fake, t([1.0, 0.0]).bool()), 0.125)
    # nothing selected -> only the real term 0.0625
    assert approx(
        adversarial_loss_discriminator(h_real, h_fake, torch.zeros(2, dtype=torch.bool)), 0.0625
    )


def test_adversarial_loss_picks_case_per_sample():
    # sample 0: A != B, score 0.25 -> (0.25 - 1)^2 = 0.5625 (its reconstruction error, 3.0, unused)
    # sample 1: A == B, r off by 0.3 in one coordinate -> 0.09 / 3 = 0.03 (its score 0 -> 1.0
    # unused)
    x_a = motion([[[[0.0, 0, 0]]]] * 2, [[[[1.0, 0, 0, 0]]]] * 2, [[[0.0, 0, 0]]] * 2)
    x_b = motion([[[[0.0, 0, 0]]]] * 2, [[[[1.0, 0, 0, 0]]]] * 2, [[[3.0, 0, 0]], [[0.0, 0.3, 0]]])
    same = torch.tensor([False, True])
    h_fake = t([[0.25], [0.0]])
    # batch mean: (0.5625 + 0.03) / 2 = 0.29625
    assert approx(adversarial_loss(h_fake, x_a, x_b, same), 0.29625)
    # NKN flavour: sample 0 logit 0 -> -log σ(0) = ln 2 = 0.693147...; (0.6931471805599453 + 0.03) /
    # 2
    h_logit = t([[0.0], [5.0]])
    assert approx(
        adversarial_loss(h_logit, x_a, x_b, same, gan="sigmoid_ce"), (0.6931471805599453 + 0.03) / 2
    )


def test_sigmoid_ce_losses_by_hand():
    ln2 = 0.6931471805599453
    assert approx(sigmoid_ce_generator_loss(t([[0.0]])), ln2)  # -log(1/2)
    assert approx(sigmoid_ce_discriminator_loss(t([[0.0]]), t([[0.0]])), 2 * ln2)
    # logits ln 3 (σ = 0.75) and ln(1/3) (σ = 0.25): D = -ln 0.75 - ln(1 - 0.25) = 2 * 0.28768207...
    ln3 = 1.0986122886681098
    assert approx(sigmoid_ce_discriminator_loss(t([[ln3]]), t([[-ln3]])), 2 * 0.2876820724517809)
    # G at σ = 0.25: -ln 0.25 = 1.3862943611198906
    assert approx(sigmoid_ce_generator_loss(t([[-ln3]])), 1.3862943611198906)


# ------------------------------------------------------------------------------ Eq. 22


def test_regularization_norm_1p2():
    q_b = t([[[[0.72, 0.96, 0.0, 0.0]]]])  # norm sqrt(0.5184 + 0.9216) = 1.2 -> (1 - 1.2)^2 = 0.04
    q_a = t([[[[0.9, 0.0, 0.0, 0.0]]]])  # norm 0.9 -> 0.01
    assert approx(regularization_loss(q_b), 0.04)
    assert approx(regularization_loss(q_b, q_a), 0.05)
    unit = t([[[QID, Q120]]])
    assert approx(regularization_loss(unit, unit), 0.0)


# ------------------------------------------------------------------------------ Eq. 23


def test_orientation_30_vs_50_degrees_of_yaw():
    yaw = (0.0, 1.0, 0.0)
    a = t([[quat_deg(30, yaw)]])
    b = t([[quat_deg(50, yaw)]])
    # 20° = 0.3490658503988659 rad < 1 -> 0.5 * 0.3490658503988659^2 = 0.06092348395734...
    assert approx(orientation_loss(a, b), 0.5 * EXCESS20)
    assert approx(orientation_loss(a, a), 0.0)


def test_orientation_both_branches_and_angle_only():
    yaw = (0.0, 1.0, 0.0)
    # frame 1: 30° vs 50° -> 0.0609234839...; frame 2: 10° vs 170° -> 160° = 2.792526803190927 rad,
    # >= 1 -> 2.792526803190927 - 0.5 = 2.292526803190927; mean over T = 2
    a = t([[quat_deg(30, yaw), quat_deg(10, yaw)]])
    b = t([[quat_deg(50, yaw), quat_deg(170, yaw)]])
    assert approx(orientation_loss(a, b), (0.5 * EXCESS20 + 2.292526803190927) / 2)
    # as printed, E(.) keeps only the angle: a 30° yaw vs a 30° roll costs nothing
    assert approx(orientation_loss(t([[quat_deg(30, yaw)]]), t([[quat_deg(30, (0, 0, 1.0))]])), 0.0)


# ------------------------------------------------------------------------------ Ls (NKN code)


def test_root_smoothness_hand_values():
    # steps (m/frame) of one sample: (0.01, 0, 0) -> (0.03, 0, 0) -> (0.03, 0.02, 0)
    # changes: (0.02, 0, 0), (0, 0.02, 0): squared sums 0.0004 per frame pair
    v_b = t([[[0.01, 0.0, 0.0], [0.03, 0.0, 0.0], [0.03, 0.02, 0.0]]])
    # frame_sum (the authors' code): channels summed, mean over the 2 pairs = 0.0004
    assert approx(root_smoothness_loss(v_b, reduction="frame_sum"), 0.0004)
    # mean: over 2 pairs x 3 channels = 0.0008 / 6
    assert approx(root_smoothness_loss(v_b), 0.0008 / 6)
    # a constant velocity costs nothing; with the cycle output the two means are averaged
    still = t([[[0.02, 0.0, 0.01]] * 3])
    assert approx(root_smoothness_loss(still, still, "frame_sum"), 0.0)
    assert approx(root_smoothness_loss(v_b, still, "frame_sum"), 0.5 * 0.0004)
    with pytest.raises(ValueError, match="v_b_hat must have 3 dims ending in 3"):
        root_smoothness_loss(t([[0.0, 0.0, 0.0]]))


# ------------------------------------------------------------------------------ Eq. 6


TERMS = {"Lc": 1.0, "Lt": 0.5, "Lh": 0.2, "La": 0.3, "Lr": 2.0, "Lo": 0.4}


def test_paper_weights():
    w = TDCNLossWeights()
    assert (w.lambda_t, w.lambda_h, w.lambda_a, w.lambda_r, w.lambda_o, w.lambda_g) == (
        10.0,
        10.0,
        1.0,
        0.1,
        1.0,
        5.0,
    )
    assert w.lambda_c == 1.0


def test_total_is_weighted_sum():
    terms = {k: t(v).requires_grad_() for k, v in TERMS.items()}
    total, log = total_generator_loss(terms)
    # 1 + 10*0.5 + 10*0.2 + 1*0.3 + 0.1*2 + 1*0.4 = 1 + 5 + 2 + 0.3 + 0.2 + 0.4 = 8.9
    assert approx(total, 8.9)
    assert log == pytest.approx({**TERMS, "total": 8.9})
    assert all(isinstance(v, float) for v in log.values())
    total.backward()
    assert approx(terms["Lh"].grad, 10.0) and approx(terms["Lr"].grad, 0.1)


def test_a3_without_height_loss():
    a3 = dataclasses.replace(TDCNLossWeights(), lambda_h=0.0)
    terms = {k: t(v) for k, v in TERMS.items()}
    # 8.9 - 10*0.2 = 6.9, whether Lh is given, omitted, or even NaN
    assert approx(total_generator_loss(terms, a3)[0], 6.9)
    no_h = {k: v for k, v in terms.items() if k != "Lh"}
    total, log = total_generator_loss(no_h, a3)
    assert approx(total, 6.9) and "Lh" not in log
    total, log = total_generator_loss({**terms, "Lh": t(float("nan"))}, a3)
    assert approx(total, 6.9) and math.isnan(log["Lh"])


def test_total_rejects_missing_or_unknown_terms():
    terms = {k: t(v) for k, v in TERMS.items()}
    with pytest.raises(KeyError, match="Lt"):
        total_generator_loss({k: v for k, v in terms.items() if k != "Lt"})
    with pytest.raises(KeyError, match="Lx"):
        total_generator_loss({**terms, "Lx": t(1.0)})


def test_check_finite_names_the_term():
    x = t([1.0, 2.0])
    assert check_finite("Lc", x) is x
    with pytest.raises(NonFiniteLossError, match="'Lh'.*1 NaN"):
        check_finite("Lh", t([1.0, float("nan")]))
    with pytest.raises(NonFiniteLossError, match="'Lo'.*1 inf"):
        check_finite("Lo", t(float("inf")))
    terms = {k: t(v) for k, v in TERMS.items()}
    with pytest.raises(NonFiniteLossError, match="'Lt'"):
        total_generator_loss({**terms, "Lt": t(float("inf"))})


# ------------------------------------------------------------------------------ gradients


def test_gradients_are_finite_at_awkward_points():
    g = torch.Generator().manual_seed(0)
    B, T, J = 2, 4, 3

    def rnd(*shape):
        return torch.randn(*shape, generator=g, dtype=D)

    p_a = rnd(B, T, J, 3)
    p_a[:, :, 0] = 0.0  # root joint never moves in p: zero displacement, ‖0‖
    r_a = rnd(B, T, 3)
    q_a = rnd(B, T, J, 4)
    q_a[:, :, 0] = t(QID)  # identity: angle 0
    q_a[0, 0, 1] = t([0.0, 1.0, 0.0, 0.0])  # 180°: w = 0
    leaves = [x.clone().requires_grad_() for x in (rnd(B, T, J, 3), rnd(B, T, 3), q_a.clone())]
    p_b, r_b, q_b = leaves
    p_b_static = p_b * torch.cat(
        [torch.zeros(B, T, 1, 1, dtype=D), torch.ones(B, T, J - 1, 1, dtype=D)], 2
    )
    x_a = MotionTensors(p_a, q_a, r_a)
    x_b = MotionTensors(p_b_static, q_b, r_b)
    h_fake = (p_b**2).sum(dim=(2, 3))[:, 1:]  # any differentiable score
    terms = {
        "Lc": cycle_loss(x_a, x_b),
        "Lt": twist_loss(q_b, q_b),
        "Lh": height_loss(p_a, p_b_static, r_a, r_b, t([1.5, 1.7]), t([2.0, 1.2])),
        "La": adversarial_loss(h_fake, x_a, x_b, torch.tensor([True, False])),
        "Lr": regularization_loss(q_b, q_b),
        "Lo": orientation_loss(q_a[:, :, 0], q_b[:, :, 0]),
    }
    total, _ = total_generator_loss(terms)
    total.backward()
    for leaf in leaves:
        assert leaf.grad is not None and torch.isfinite(leaf.grad).all()
    # D side too
    h = rnd(B, T - 1).requires_grad_()
    (adversarial_loss_discriminator(h, h) + sigmoid_ce_discriminator_loss(h, h)).backward()
    assert torch.isfinite(h.grad).all()
    li = discriminator_inputs(p_b_static, r_b, rnd(J, 3), 1.5)
    assert all(torch.isfinite(x).all() for x in li)
