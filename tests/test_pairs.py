"""Ground-truth retargeting, copy baselines and the TDCN test scenarios."""

import numpy as np
import pytest
import torch
from skeletons import contact_runs, make_skeleton

from retarget_lib.core.measures import skeleton_leg_length
from retarget_lib.core.retarget_pose import PRIMARY_CHILD, rest_alignment
from retarget_lib.core.rotations import quat_conjugate, quat_mul
from retarget_lib.core.skeleton import CANONICAL22, FOOT_CONTACT_JOINTS, J, JointSetError, Skeleton
from retarget_lib.core.transfer import (
    change_rest_pose,
    random_rest_rotations,
    retarget_ground_truth,
)
from retarget_lib.data.splits import MotionId, tdcn_splits
from retarget_lib.data.synthetic.motions import MOTION_FAMILIES, make_motion
from retarget_lib.geometry.ik import apply_foot_contact_ik
from retarget_lib.methods.copy import copy_rotations
from retarget_lib.methods.copy_rest import copy_rotations_rest_compensated

A_POSE = make_skeleton(height=1.5, leg_frac=0.45, arm_deg=45.0, spine_curve_deg=6.0)
T_POSE = make_skeleton(height=1.9, leg_frac=0.53, arm_deg=0.0)


@pytest.fixture(scope="module")
def source():
    return make_motion("wave", A_POSE, 0, duration=3.0)


def test_same_skeleton_is_identity(source):
    gt = retarget_ground_truth(source, A_POSE)
    np.testing.assert_allclose(np.abs((gt.rotations * source.rotations).sum(-1)), 1.0, atol=1e-12)
    np.testing.assert_allclose(gt.root_positions, source.root_positions)
    np.testing.assert_allclose(rest_alignment(A_POSE, A_POSE)[:, 0], 1.0)


def test_uniform_scale_gives_the_scaled_motion(source):
    big = A_POSE.scaled(1.3)
    gt = retarget_ground_truth(source, big)
    np.testing.assert_allclose(gt.root_positions, 1.3 * source.root_positions, atol=1e-12)
    np.testing.assert_allclose(gt.global_positions(), 1.3 * source.global_positions(), atol=1e-9)


def test_the_target_performs_the_sources_deltas_from_the_retarget_pose(source):
    gt = retarget_ground_truth(source, T_POSE)
    _, src_rot = source.fk()
    _, gt_rot = gt.fk()
    # G^B_j C_j^-1 = G^A_j: the same world rotation up to the constant rest alignment
    c = torch.from_numpy(rest_alignment(A_POSE, T_POSE))
    undone = quat_mul(torch.from_numpy(gt_rot), quat_conjugate(c)).numpy()
    np.testing.assert_allclose(np.abs((undone * src_rot).sum(-1)), 1.0, atol=1e-9)
    ratio = skeleton_leg_length(T_POSE) / skeleton_leg_length(A_POSE)
    np.testing.assert_allclose(gt.root_positions, ratio * source.root_positions)


def test_apose_to_tpose_arms_point_the_same_way_but_copy_does_not(source):
    arms = [(J["LeftArm"], J["LeftForeArm"]), (J["RightForeArm"], J["RightHand"])]

    def arm_dirs(m):
        pos = m.global_positions()
        d = np.stack([pos[:, b] - pos[:, a] for a, b in arms], axis=1)
        return d / np.linalg.norm(d, axis=-1, keepdims=True)

    want = arm_dirs(source)
    np.testing.assert_allclose(arm_dirs(retarget_ground_truth(source, T_POSE)), want, atol=1e-6)
    copied = arm_dirs(copy_rotations(source, T_POSE))
    error = np.degrees(np.arccos(np.clip((copied * want).sum(-1), -1, 1)))
    assert error.mean() > 30.0  # copying local rotations raises the arms by the A/T difference


def test_two_t_pose_binds_of_different_shape_retarget_by_copying(source):
    """Mixamo's rule: characters bound in one T-pose convention copy their local rotations, and
    each keeps its own shape (a drooping forearm stays drooped)."""
    droop = T_POSE.offsets.copy()
    angle = np.radians(8.0)  # within the retarget pose's tolerance: shape, not convention
    droop[J["LeftHand"]] = np.linalg.norm(droop[J["LeftHand"]]) * np.array(
        [np.cos(angle), -np.sin(angle), 0.0]
    )
    drooped = Skeleton(T_POSE.joint_names, T_POSE.parents, droop)
    on_t = retarget_ground_truth(source, T_POSE)
    onto = retarget_ground_truth(on_t, drooped)
    np.testing.assert_allclose(onto.rotations, on_t.rotations, atol=1e-12)
    np.testing.assert_allclose(rest_alignment(T_POSE, drooped)[:, 0], 1.0)
    rest = drooped.rest_positions()
    forearm = rest[J["LeftHand"]] - rest[J["LeftForeArm"]]
    assert forearm[1] < 0  # the rest droop is kept: the zero pose's hand is below the elbow
    np.testing.assert_array_equal(
        copy_rotations_rest_compensated(on_t, drooped).rotations, onto.rotations
    )


def test_round_trip_returns_the_source(source):
    back = retarget_ground_truth(retarget_ground_truth(source, T_POSE), A_POSE)
    np.testing.assert_allclose(np.abs((back.rotations * source.rotations).sum(-1)), 1.0, atol=1e-9)
    np.testing.assert_allclose(back.root_positions, source.root_positions, atol=1e-12)


def test_copy_baselines(source):
    ratio = skeleton_leg_length(T_POSE) / skeleton_leg_length(A_POSE)
    copied = copy_rotations(source, T_POSE)
    np.testing.assert_array_equal(copied.rotations, source.rotations)
    np.testing.assert_allclose(copied.root_positions, ratio * source.root_positions)
    np.testing.assert_array_equal(copied.skeleton.offsets, T_POSE.offsets)
    compensated = copy_rotations_rest_compensated(source, T_POSE)
    gt = retarget_ground_truth(source, T_POSE)
    np.testing.assert_allclose(compensated.rotations, gt.rotations)
    assert compensated.meta["retargeted"] == "copy_rest_compensated" != gt.meta["retargeted"]


def test_a_changed_rest_pose_moves_no_joint_in_any_frame(source):
    offsets = torch.from_numpy(source.skeleton.offsets)[None]
    turns = random_rest_rotations(offsets, 30.0, torch.Generator().manual_seed(3)).double()
    q, moved = change_rest_pose(torch.from_numpy(source.rotations)[None], offsets, turns)
    changed = source.copy(
        skeleton=Skeleton(list(CANONICAL22), source.skeleton.parents, moved[0].numpy()),
        rotations=q[0].numpy(),
    )
    # float64 quaternion products: 1e-9 m is far below any rounding that would matter
    np.testing.assert_allclose(changed.global_positions(), source.global_positions(), atol=1e-9)
    # the rest pose really changed: bones swing, lengths do not, leaves keep their frame
    rest_old, rest_new = source.skeleton.rest_positions(), changed.skeleton.rest_positions()
    assert np.abs(rest_new - rest_old).max() > 0.05
    np.testing.assert_allclose(
        np.linalg.norm(moved[0], axis=-1), np.linalg.norm(offsets[0], axis=-1), atol=1e-12
    )
    for leaf in (J["Head"], J["LeftHand"], J["LeftToeBase"]):
        assert turns[0, leaf, 0] == 1.0  # a zero rotation vector: cos(0) = 1 exactly on any CPU
    # the swing of a bone is perpendicular to it: the bone's angle is at most the 30° drawn
    for _j, c in enumerate(PRIMARY_CHILD):
        if c >= 0:
            a, b = offsets[0, c].numpy(), moved[0, c].numpy()
            angle = np.degrees(
                np.arccos(np.clip(a @ b / np.linalg.norm(a) / np.linalg.norm(b), -1, 1))
            )
            assert angle <= 30.0 + 1e-6


def test_rest_alignment_needs_canonical_joints():
    other = Skeleton(CANONICAL22[:3], (-1, 0, 1), np.ones((3, 3)))
    with pytest.raises(JointSetError, match="canonical 22"):
        rest_alignment(other, A_POSE)


NAMES = tuple(f"char{k:02d}" for k in range(16))


def test_tdcn_splits_are_disjoint_and_scenarios_follow_table3():
    sp = tdcn_splits(NAMES, MOTION_FAMILIES, seed=1, pairs_per_scenario=6)
    assert set(sp.train_characters).isdisjoint(sp.test_characters)
    assert set(sp.train_characters) | set(sp.test_characters) == set(NAMES)
    assert len(sp.test_characters) == 5
    assert set(sp.train_motions).isdisjoint(sp.test_motions)
    assert len(sp.test_families) == 2 and not {m.family for m in sp.train_motions} & set(
        sp.test_families
    )
    assert {m.family for m in sp.test_motions} == set(MOTION_FAMILIES)  # held-out seeds + families
    seen, unseen = set(sp.train_characters), set(sp.test_characters)
    rules = {
        1: (seen, seen, True),
        2: (seen, unseen, True),
        3: (unseen, seen, False),
        4: (unseen, unseen, False),
    }
    for k, (src_set, tgt_set, motion_seen) in rules.items():
        rows = sp.scenarios[k]
        assert len(rows) == 6
        for row in rows:
            assert row.source in src_set and row.target in tgt_set and row.source != row.target
            assert (row.motion in sp.train_motions) == motion_seen
            assert (
                isinstance(row.motion, MotionId)
                and str(row.motion) == f"{row.motion.family}/{row.motion.seed}"
            )
    for a, b in ((1, 2), (3, 4)):  # same inputs, only the target's novelty changes
        assert [(r.source, r.motion) for r in sp.scenarios[a]] == [
            (r.source, r.motion) for r in sp.scenarios[b]
        ]


def test_tdcn_splits_deterministic_and_seed_dependent():
    a = tdcn_splits(NAMES, MOTION_FAMILIES, seed=0)
    assert a == tdcn_splits(NAMES, MOTION_FAMILIES, seed=0)
    b = tdcn_splits(NAMES, MOTION_FAMILIES, seed=5)
    assert (a.test_characters, a.test_families) != (b.test_characters, b.test_families)
    with pytest.raises(ValueError, match="unseen"):
        tdcn_splits(NAMES[:3], MOTION_FAMILIES)


def test_foot_contact_ik_removes_the_ground_truths_foot_sliding():
    """Different limb proportions make the ground truth slide; the SAN-style IK pins it again."""
    off = T_POSE.offsets.copy()
    for side in ("Left", "Right"):
        off[J[f"{side}Leg"]] *= 0.85  # shorter thigh
        off[J[f"{side}Foot"]] *= 1.25  # longer shin
    target = Skeleton(T_POSE.joint_names, T_POSE.parents, off)
    src = make_motion("walk", A_POSE, 2)
    contacts = src.meta["joint_contacts"]

    def worst_slide(m):
        pos = m.global_positions()
        out = 0.0
        for k, name in enumerate(FOOT_CONTACT_JOINTS):
            for a, b in contact_runs(contacts[:, k]):
                out = max(out, np.linalg.norm(np.diff(pos[a:b, J[name]], axis=0), axis=-1).sum())
        return out

    gt = retarget_ground_truth(src, target)
    assert worst_slide(gt) > 0.02
    assert worst_slide(apply_foot_contact_ik(gt, contacts)) < 0.002
