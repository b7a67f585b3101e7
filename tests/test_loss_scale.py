"""The authors' loss scale (losses/tdcn.py, "Reductions"): per-frame sums and standardised
positions."""

import pytest
import torch

from retarget_lib.config import load_config
from retarget_lib.losses.tdcn import (
    CODE_END_EFFECTOR_IDS,
    MotionTensors,
    PositionScale,
    adversarial_loss,
    cycle_loss,
    height_loss,
    per_sample,
    reconstruction_loss,
    twist_loss,
)


def test_frame_sum_sums_each_frame_and_averages_frames_by_hand():
    # two frames of 2 joints x 3 channels: per-frame sums 6 and 12 -> mean 9; the mean is 1.5
    p = torch.tensor(
        [[[[1.0, 1, 1], [1, 1, 1]], [[2.0, 2, 2], [2, 2, 2]]]]
    ).sqrt()  # squared -> 1s and 2s
    zero = torch.zeros_like(p)
    q, r = torch.zeros(1, 2, 2, 4), torch.zeros(1, 2, 3)
    a, b = MotionTensors(p, q, r), MotionTensors(zero, q, r)
    assert cycle_loss(a, b, "mean").item() == pytest.approx(1.5)
    assert cycle_loss(a, b, "frame_sum").item() == pytest.approx(9.0)
    assert cycle_loss(a, b, "per_sample_frame_sum").shape == (1,)


def test_one_value_per_frame_is_the_same_under_both_reductions():
    # the root term of Lh has one value per frame: it must not change with the reduction, while the
    # per-joint term is multiplied by the joint count when every joint has the same error
    p_a = torch.zeros(1, 3, 4, 3)
    p_b = torch.zeros(1, 3, 4, 3)
    p_b[:, 1:, :, 0] = torch.tensor([0.1, 0.2])[
        None, :, None
    ]  # every joint moves 0.1 then 0.1 (per H = 1)
    r_a, r_b = torch.zeros(1, 3, 3), torch.zeros(1, 3, 3)
    r_b[:, :, 0] = 0.3
    mean = height_loss(p_a, p_b, r_a, r_b, 1.0, 1.0, lambda_g=0.0, reduction="mean")
    summed = height_loss(p_a, p_b, r_a, r_b, 1.0, 1.0, lambda_g=0.0, reduction="frame_sum")
    assert summed.item() == pytest.approx(4 * mean.item())  # 4 joints, equal errors
    root_mean = height_loss(p_a, p_a, r_a, r_b, 1.0, 1.0, lambda_g=1.0, reduction="mean")
    root_sum = height_loss(p_a, p_a, r_a, r_b, 1.0, 1.0, lambda_g=1.0, reduction="frame_sum")
    assert root_sum.item() == pytest.approx(root_mean.item()) and root_mean.item() == pytest.approx(
        0.5 * 0.3**2
    )


def test_twist_frame_sum_counts_every_joint():
    half = torch.deg2rad(torch.tensor(75.0))
    q = torch.zeros(2, 5, 22, 4)
    q[..., 0], q[..., 1] = (
        torch.cos(half),
        torch.sin(half),
    )  # 150 degrees about x: beyond alpha = 100
    mean = twist_loss(q, alpha_deg=100.0, reduction="mean")
    assert mean.item() > 0
    assert twist_loss(q, alpha_deg=100.0, reduction="frame_sum").item() == pytest.approx(
        22 * mean.item(), rel=1e-6
    )


def test_adversarial_loss_uses_the_per_sample_form_of_its_reduction():
    assert per_sample("mean") == "per_sample" and per_sample("frame_sum") == "per_sample_frame_sum"
    p = torch.ones(2, 3, 4, 3)
    x = MotionTensors(p, torch.zeros(2, 3, 4, 4), torch.zeros(2, 3, 3))
    y = MotionTensors(torch.zeros_like(p), x.q, x.r)
    same = torch.tensor([True, True])
    h = torch.zeros(2, 3)
    assert adversarial_loss(h, x, y, same).item() == pytest.approx(1.0)
    assert adversarial_loss(h, x, y, same, reduction="frame_sum").item() == pytest.approx(
        12.0
    )  # 4 joints x 3
    with pytest.raises(ValueError, match="reduction"):
        adversarial_loss(h, x, y, same, reduction="per_sample")


def test_position_scale_z_scores_and_floors_the_std():
    g = torch.Generator().manual_seed(0)
    p = (
        torch.randn(8, 10, 3, 3, generator=g) * torch.tensor([0.0, 0.5, 2.0])[None, None, :, None]
        + 1.0
    )
    r = torch.randn(8, 10, 3, generator=g) * 3.0
    scale = PositionScale.fit(p, r)
    z = scale.apply(MotionTensors(p, torch.zeros(8, 10, 3, 4), r))
    flat = z.p.reshape(-1, 3, 3)
    assert torch.allclose(
        flat[:, 0], torch.zeros(80, 3)
    )  # a still joint: std floored at 1 cm, mean removed
    assert torch.allclose(
        flat[:, 1:].std(0), torch.ones(2, 3), atol=1e-5
    )  # float32 over 80 samples
    assert torch.allclose(z.r.reshape(-1, 3).mean(0), torch.zeros(3), atol=1e-5)


def test_the_code_scale_config_is_a_small_delta_over_the_paper_config():
    base = load_config("configs/tdcn_paper.yaml", profile="fast")
    code = load_config("configs/tdcn_paper_code_scale.yaml", profile="fast")
    assert code["loss"]["reduction"] == "frame_sum" and code["loss"]["standardize"] is True
    assert {k: v for k, v in code["loss"].items() if k not in ("reduction", "standardize")} == base[
        "loss"
    ]


def test_the_arm_drop_augmentation_lowers_both_upper_arms_by_the_same_drawn_angle():
    from retarget_lib.core.skeleton import J
    from retarget_lib.core.transfer import change_rest_pose
    from retarget_lib.data.synthetic.characters import make_character
    from retarget_lib.training.tdcn_data import WindowSampler

    offsets = torch.as_tensor(make_character("kato").skeleton.offsets, dtype=torch.float32)[
        None
    ].repeat(64, 1, 1)
    sampler = WindowSampler.__new__(WindowSampler)  # only the rest turns are exercised
    sampler.rest_jitter_deg, sampler.rest_arm_drop_deg = 0.0, 70.0
    turns = sampler._rest_turns(offsets, torch.Generator().manual_seed(0))
    q = torch.zeros(64, 1, 22, 4)
    q[..., 0] = 1.0
    _, turned = change_rest_pose(q, offsets, turns)

    def below_horizontal(bone):  # degrees
        return torch.rad2deg(torch.asin(-bone[:, 1] / bone.norm(dim=-1)))

    rest = below_horizontal(offsets[:, J["LeftForeArm"]])
    left, right = (
        below_horizontal(turned[:, J["LeftForeArm"]]),
        below_horizontal(turned[:, J["RightForeArm"]]),
    )
    drop = left - rest
    assert torch.allclose(left, right, atol=1e-3)  # symmetric (float32 rotations)
    assert (drop >= -1e-3).all() and drop.max() <= 70.0 + 1e-3 and drop.max() > 35.0
    assert 10 < int((drop.abs() < 1e-3).sum()) < 54  # about half the skeletons keep their rest


def test_the_authors_code_weighting_of_the_reconstruction_and_cycle_terms_by_hand():
    # one frame, 22 joints: every position off by 1 in x, every quaternion off by 0.5 in w,
    # the root off by 2 in y. frame sums: p 22 (all joints) or 5 (the code's end effectors),
    # q 22 x 0.25 = 5.5, r 4.
    p = torch.zeros(1, 1, 22, 3)
    q = torch.zeros(1, 1, 22, 4)
    r = torch.zeros(1, 1, 3)
    x = MotionTensors(p, q, r)
    dp, dq, dr = p.clone(), q.clone(), r.clone()
    dp[..., 0], dq[..., 0], dr[..., 1] = 1.0, 0.5, 2.0
    y = MotionTensors(dp, dq, dr)
    assert cycle_loss(x, y, "frame_sum").item() == pytest.approx(22 + 5.5 + 4)
    assert cycle_loss(x, y, "frame_sum", 10.0).item() == pytest.approx(22 + 55 + 4)
    code = dict(quaternion_weight=10.0, joints=CODE_END_EFFECTOR_IDS)
    assert cycle_loss(x, y, "frame_sum", **code).item() == pytest.approx(5 + 55 + 4)
    assert reconstruction_loss(x, y, "frame_sum", **code).item() == pytest.approx(5 + 55 + 4)
    same = torch.tensor([True])
    h = torch.zeros(1, 1)
    assert adversarial_loss(h, x, y, same, reduction="frame_sum", **code).item() == pytest.approx(
        64.0
    )
    # a position error away from the end effectors is not seen by the code's comparison
    spine = MotionTensors(p.clone(), q, r)
    spine.p[0, 0, 1, 0] = 3.0
    assert cycle_loss(x, spine, "frame_sum", **code).item() == 0.0
    assert cycle_loss(x, spine, "frame_sum").item() == pytest.approx(9.0)


def test_the_code_losses_config_is_a_small_delta_over_the_mixamo_convention_row():
    base = load_config("configs/tdcn_ours_mixamo_convention.yaml", profile="fast")
    code = load_config("configs/tdcn_ours_mixamo_convention_code_losses.yaml", profile="fast")
    assert code["loss"]["quaternion_weight"] == 10.0
    assert code["loss"]["position_joints"] == "end_effectors"
    delta = ("quaternion_weight", "position_joints")
    assert {k: v for k, v in code["loss"].items() if k not in delta} == base["loss"]
    assert {k: v for k, v in code.items() if k not in ("loss", "name", "config_path")} == {
        k: v for k, v in base.items() if k not in ("loss", "name", "config_path")
    }


def test_the_root_term_can_be_normalised_by_leg_length_by_hand():
    # two frames, the root 1 m up on A, 0.5 m up on B; both 2 m tall (H), legs 1 m and 0.5 m.
    # By H (Eqs. 15-16): m = 0.5 against 0.25, smoothL1(0.25) = 0.03125, times lambda_g = 5.
    # By leg length: m = 1 against 1: nothing (the leg-scaled root is what the term asks for).
    p = torch.zeros(1, 2, 2, 3)
    r_a = torch.tensor([[[0.0, 1.0, 0.0], [0.0, 1.0, 0.0]]])
    r_b = r_a * 0.5
    h = torch.tensor([2.0])
    by_height = height_loss(p, p, r_a, r_b, h, h, 5.0)
    assert by_height.item() == pytest.approx(5.0 * 0.5 * 0.25**2)
    by_leg = height_loss(p, p, r_a, r_b, h, h, 5.0, root_scales=(torch.tensor([1.0]), 0.5))
    assert by_leg.item() == 0.0
