"""Inverse kinematics: two-bone limbs, full-body damped least squares, foot planting."""

import numpy as np
import pytest
import torch
from skeletons import make_skeleton

from retarget_lib.core.kinematics import forward_kinematics
from retarget_lib.core.motion import Motion
from retarget_lib.core.rotations import quat_from_axis_angle, quat_mul, quat_rotate
from retarget_lib.core.skeleton import J
from retarget_lib.geometry.ik import (
    apply_foot_contact_ik,
    limb_chain,
    solve_ik,
    two_bone_ik,
    two_bone_positions,
)


def random_pose(sk, T, scale, seed):
    rng = np.random.default_rng(seed)
    rot = quat_from_axis_angle(torch.from_numpy(rng.normal(size=(T, 22, 3)) * scale)).numpy()
    root = sk.offsets[0] + rng.normal(size=(T, 3)) * 0.05
    return rot, root


def bone_lengths(pos, parents):
    return np.stack(
        [
            np.linalg.norm(pos[..., j, :] - pos[..., p, :], axis=-1)
            for j, p in enumerate(parents)
            if p >= 0
        ],
        axis=-1,
    )


@pytest.mark.parametrize("limb", ["left_leg", "right_arm"])
def test_two_bone_reaches_reachable_targets_exactly(limb):
    sk = make_skeleton(arm_deg=40)
    chain = limb_chain(sk, limb)
    rot, root = random_pose(sk, 200, 0.3, seed=0)
    other, _ = random_pose(sk, 200, 0.5, seed=1)
    pos = forward_kinematics(rot, sk.offsets, sk.parents, root).positions
    # a reachable target: where the end joint would be under another pose of the same limb
    probe = rot.copy()
    probe[:, list(chain[:2])] = other[:, list(chain[:2])]
    target = forward_kinematics(probe, sk.offsets, sk.parents, root).positions[:, chain[2]]
    out = two_bone_ik(rot, sk.offsets, sk.parents, root, chain, target)
    new = forward_kinematics(out, sk.offsets, sk.parents, root).positions
    assert np.abs(new[:, chain[2]] - target).max() < 1e-5
    np.testing.assert_allclose(
        bone_lengths(new, sk.parents), bone_lengths(pos, sk.parents), atol=1e-9
    )
    untouched = [j for j in range(22) if j not in chain]
    np.testing.assert_allclose(out[:, untouched], rot[:, untouched])
    # the end joint keeps its local rotation by default
    np.testing.assert_allclose(
        np.abs((out[:, chain[2]] * rot[:, chain[2]]).sum(-1)), 1.0, atol=1e-9
    )


def test_two_bone_knee_bends_towards_pole_and_takes_end_rotation():
    sk = make_skeleton()
    T = 50
    rot = np.tile([1.0, 0.0, 0.0, 0.0], (T, 22, 1))
    root = np.tile(sk.offsets[0], (T, 1))
    chain = limb_chain(sk, "left_leg")
    hip = sk.rest_positions()[J["LeftUpLeg"]]
    target = hip + np.stack(
        [np.zeros(T), -np.linspace(0.5, 0.75, T), np.linspace(-0.2, 0.3, T)], -1
    )
    foot = quat_from_axis_angle(torch.tensor([0.0, 0.3, 0.0])).numpy()
    out = two_bone_ik(
        rot,
        sk.offsets,
        sk.parents,
        root,
        chain,
        target,
        pole=np.array([0.0, 0.0, 1.0]),
        end_rotation=foot,
    )
    pos, grot = forward_kinematics(out, sk.offsets, sk.parents, root)
    np.testing.assert_allclose(pos[:, chain[2]], target, atol=1e-9)
    knee, line_mid = pos[:, chain[1]], 0.5 * (pos[:, chain[0]] + pos[:, chain[2]])
    assert (knee[:, 2] > line_mid[:, 2] + 1e-3).all()  # knee in front of the hip-ankle line
    np.testing.assert_allclose(np.abs((grot[:, chain[2]] * foot).sum(-1)), 1.0, atol=1e-9)


def test_two_bone_unreachable_target_gives_straight_limb_towards_it():
    sk = make_skeleton()
    rot, root = random_pose(sk, 20, 0.3, seed=2)
    chain = limb_chain(sk, "right_leg")
    pos = forward_kinematics(rot, sk.offsets, sk.parents, root).positions
    a = pos[:, chain[0]]
    direction = np.random.default_rng(3).normal(size=(20, 3))
    direction /= np.linalg.norm(direction, axis=-1, keepdims=True)
    reach = np.linalg.norm(sk.offsets[chain[1]]) + np.linalg.norm(sk.offsets[chain[2]])
    target = a + 3.0 * reach * direction
    out = two_bone_ik(rot, sk.offsets, sk.parents, root, chain, target)
    new = forward_kinematics(out, sk.offsets, sk.parents, root).positions
    np.testing.assert_allclose(new[:, chain[2]], a + reach * direction, atol=1e-6)


def test_two_bone_torch_batched_matches_numpy_and_positions_helper():
    sk = make_skeleton(arm_deg=45)
    rot, root = random_pose(sk, 12, 0.3, seed=4)
    chain = limb_chain(sk, "left_arm")
    pos = forward_kinematics(rot, sk.offsets, sk.parents, root).positions
    target = pos[:, chain[2]] + np.random.default_rng(5).normal(size=(12, 3)) * 0.1
    ref = two_bone_ik(rot, sk.offsets, sk.parents, root, chain, target)
    batched = two_bone_ik(
        torch.from_numpy(rot).reshape(3, 4, 22, 4),
        torch.from_numpy(sk.offsets),
        sk.parents,
        torch.from_numpy(root).reshape(3, 4, 3),
        chain,
        torch.from_numpy(target).reshape(3, 4, 3),
    )
    assert isinstance(batched, torch.Tensor)
    np.testing.assert_allclose(batched.reshape(12, 22, 4).numpy(), ref, atol=1e-10)
    b_new, c_new = two_bone_positions(*(pos[:, k] for k in chain), target)
    new = forward_kinematics(ref, sk.offsets, sk.parents, root).positions
    np.testing.assert_allclose(new[:, chain[1]], b_new, atol=1e-9)
    np.testing.assert_allclose(new[:, chain[2]], c_new, atol=1e-9)


def test_solve_ik_reaches_several_targets_and_keeps_other_joints():
    sk = make_skeleton()
    rot, root = random_pose(sk, 100, 0.2, seed=6)
    other = quat_mul(
        torch.from_numpy(rot),
        quat_from_axis_angle(
            torch.from_numpy(np.random.default_rng(7).normal(size=(100, 22, 3)) * 0.15)
        ),
    ).numpy()
    goal = forward_kinematics(other, sk.offsets, sk.parents, root + 0.03).positions
    targets = {j: goal[:, j] for j in (J["LeftHand"], J["RightHand"], J["LeftFoot"], J["Head"])}
    free = [j for j in range(22) if j not in (J["LeftToeBase"], J["RightLeg"])]
    out, out_root = solve_ik(rot, sk.offsets, sk.parents, root, targets, free_joints=free)
    pos = forward_kinematics(out, sk.offsets, sk.parents, out_root).positions
    for j, t in targets.items():
        assert np.abs(pos[:, j] - t).max() < 1e-5
    np.testing.assert_allclose(
        out[:, [J["LeftToeBase"], J["RightLeg"]]],
        rot[:, [J["LeftToeBase"], J["RightLeg"]]],
        atol=1e-12,
    )


def test_solve_ik_targets_already_met_leave_pose_unchanged():
    sk = make_skeleton()
    rot, root = random_pose(sk, 10, 0.3, seed=8)
    pos = forward_kinematics(rot, sk.offsets, sk.parents, root).positions
    out, out_root = solve_ik(
        rot, sk.offsets, sk.parents, root, {J["LeftHand"]: pos[:, J["LeftHand"]]}
    )
    np.testing.assert_allclose(np.abs((out * rot).sum(-1)), 1.0, atol=1e-9)
    np.testing.assert_allclose(out_root, root, atol=1e-9)


def stepping_motion(sk, T=120):
    """Legs swinging under a slowly moving root: the feet slide without IK."""
    t = np.arange(T) / 30.0
    aa = np.zeros((T, 22, 3))
    wave = 0.2 * np.sin(2 * np.pi * t)
    aa[:, J["LeftUpLeg"], 0], aa[:, J["RightUpLeg"], 0] = -0.3 + wave, -0.3 - wave
    aa[:, J["LeftLeg"], 0], aa[:, J["RightLeg"], 0] = 0.6 + wave, 0.6 - wave
    rot = quat_from_axis_angle(torch.from_numpy(aa)).numpy()
    root = np.stack([np.zeros(T), 0.8 + 0.02 * np.sin(4 * np.pi * t), 0.1 * t], -1)
    return Motion(sk, rot, root, 30.0)


def test_foot_contact_ik_pins_feet_and_blends_smoothly():
    sk = make_skeleton()
    m = stepping_motion(sk)
    contacts = np.zeros((m.num_frames, 2), bool)
    contacts[10:30, 0] = contacts[70:100, 0] = contacts[40:60, 1] = True
    before = m.global_positions()
    out = apply_foot_contact_ik(m, contacts)
    pos = out.global_positions()
    for side, runs in ((0, [(10, 30), (70, 100)]), (1, [(40, 60)])):
        for joint in (("LeftFoot", "LeftToeBase"), ("RightFoot", "RightToeBase"))[side]:
            j = J[joint]
            assert np.abs(before[10:30, j] - before[10, j]).max() > 0.01  # it did slide before
            for s, e in runs:
                assert np.abs(pos[s:e, j] - pos[s, j]).max() < 1e-6
    # blending spreads the catch-up over several frames instead of one jump
    jump = apply_foot_contact_ik(m, contacts, blend_frames=0).global_positions()
    speed = lambda p: np.linalg.norm(  # noqa: E731
        np.diff(p[:, [J["LeftFoot"], J["RightFoot"]]], axis=0), axis=-1
    )
    assert speed(pos).max() < 0.7 * speed(jump).max()
    np.testing.assert_allclose(out.root_positions, m.root_positions)
    np.testing.assert_allclose(pos[:, :6], before[:, :6], atol=1e-9)  # upper body untouched
    far = slice(110, 120)  # more than 5 frames after the last contact run
    np.testing.assert_allclose(pos[far], before[far], atol=1e-9)


def test_foot_contact_ik_toe_only_contact_pins_toe():
    sk = make_skeleton()
    m = stepping_motion(sk)
    contacts = np.zeros((m.num_frames, 4), bool)
    contacts[10:30, 2] = True  # left toe only
    pos = apply_foot_contact_ik(m, contacts).global_positions()
    assert np.abs(pos[10:30, J["LeftToeBase"]] - pos[10, J["LeftToeBase"]]).max() < 1e-3
    assert np.abs(pos[10:30, J["LeftFoot"]] - pos[10, J["LeftFoot"]]).max() > 1e-3  # heel free
    with pytest.raises(ValueError, match="contacts"):
        apply_foot_contact_ik(m, contacts[:, :3])


def test_a_nearly_straight_leg_turns_without_twisting_its_thigh():
    """A rest thigh leaning 3 degrees outwards (mannequin-x's SMPL-X calibration) bends the
    straight leg in the frontal plane; a knee sent forward must not twist the thigh about its bone
    (it did by 110 degrees: the frontal plane carried onto the sagittal one)."""
    sk = make_skeleton()
    for side, sx in (("Left", 1.0), ("Right", -1.0)):
        thigh = sk.offsets[J[f"{side}Leg"]]
        length = np.linalg.norm(thigh)
        lean = np.radians(3.0)
        sk.offsets[J[f"{side}Leg"]] = length * np.array([sx * np.sin(lean), -np.cos(lean), 0.0])
    q = np.zeros((1, 22, 4))
    q[..., 0] = 1.0
    root = np.array([[0.0, sk.offsets[0, 1], 0.0]])
    pos = forward_kinematics(q, sk.offsets, sk.parents, root).positions
    chain = limb_chain(sk, "left_leg")
    hip, ankle = pos[0, chain[0]], pos[0, chain[2]]
    target = (ankle + 0.12 * (hip - ankle))[None]  # the ankle raised: the knee bends ~40 degrees
    out = two_bone_ik(q, sk.offsets, sk.parents, root, chain, target, np.array([[0.0, 0.0, 1.0]]))
    g = forward_kinematics(out, sk.offsets, sk.parents, root)
    kneecap = quat_rotate(torch.from_numpy(g.rotations[0, chain[0]]), torch.tensor([0.0, 0, 1]))
    bone = g.positions[0, chain[1]] - g.positions[0, chain[0]]
    bone /= np.linalg.norm(bone)
    kneecap = kneecap.numpy() - (kneecap.numpy() @ bone) * bone
    # the kneecap (the thigh's rest +Z) stays forward: within the knee's forward swing, far from 110
    twist = np.degrees(np.arctan2(kneecap[0], kneecap[2]))
    assert abs(twist) < 5.0, twist
    np.testing.assert_allclose(g.positions[0, chain[2]], target[0], atol=1e-9)  # and it reaches
