"""The retarget pose (retarget_lib.core.retarget_pose): one canonical T-pose for every rig, the
rest alignment built on it, and what reads it (leg length, foot heights)."""

import math

import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st
from skeletons import make_skeleton

from retarget_lib.core.measures import foot_rest_heights, skeleton_leg_length
from retarget_lib.core.retarget_pose import (
    FOOT_SLOPE_DEG,
    TOLERANCE_DEG,
    flatten_soles,
    pose_local_rotations,
    rest_alignment,
    retarget_alignment,
    retarget_pose,
    retarget_pose_rotations,
    retarget_pose_skeleton,
)
from retarget_lib.core.rotations import quat_angle, quat_from_axis_angle, quat_rotate
from retarget_lib.core.skeleton import CANONICAL22, J, JointSetError, Skeleton, canonical22_skeleton

# float64 products of a few unit quaternions: 1e-9 is rounding, far below any pose difference
EXACT = 1e-9

T_POSE = make_skeleton(1.8, arm_deg=0.0)
A_POSE = make_skeleton(1.6, arm_deg=40.0)


def turned(skeleton: Skeleton, axis_angle) -> Skeleton:
    """The same rig with its zero pose turned as a whole (a file whose convention lies it down)."""
    q = quat_from_axis_angle(torch.tensor(axis_angle, dtype=torch.float64))
    return canonical22_skeleton(quat_rotate(q, torch.from_numpy(skeleton.offsets)).numpy())


def along_x_rig() -> Skeleton:
    """A rig whose zero rotations put every bone along +X, the body a straight line lying on its
    side (as some research mocap files rest): the left hip at +Z, the right at -Z."""
    lengths = np.linalg.norm(T_POSE.offsets, axis=-1)
    off = np.zeros((22, 3))
    off[1:, 0] = lengths[1:]
    for side, sz in (("Left", 1.0), ("Right", -1.0)):
        off[J[f"{side}UpLeg"]] = (0.0, 0.0, sz * 0.1)
        off[J[f"{side}Shoulder"]] = (0.1, 0.0, sz * 0.05)
    return canonical22_skeleton(off)


def angles_deg(pose: np.ndarray) -> np.ndarray:
    return np.degrees(quat_angle(torch.as_tensor(pose)).numpy())


def direction(positions: np.ndarray, a: str, b: str) -> np.ndarray:
    d = positions[J[b]] - positions[J[a]]
    return d / np.linalg.norm(d)


def test_a_t_pose_bind_is_its_own_retarget_pose():
    np.testing.assert_allclose(angles_deg(retarget_pose(T_POSE)), 0.0, atol=EXACT)


def test_an_a_pose_gets_its_arms_out_and_nothing_else_moves():
    pose = retarget_pose(A_POSE)
    moved = {CANONICAL22[j] for j in np.flatnonzero(angles_deg(pose) > 1e-6)}
    assert moved == {f"{s}{p}" for s in ("Left", "Right") for p in ("Arm", "ForeArm", "Hand")}
    rest = retarget_pose_skeleton(A_POSE).rest_positions()
    np.testing.assert_allclose(direction(rest, "LeftArm", "LeftForeArm"), [1, 0, 0], atol=EXACT)
    np.testing.assert_allclose(direction(rest, "RightForeArm", "RightHand"), [-1, 0, 0], atol=EXACT)
    np.testing.assert_allclose(
        retarget_pose_skeleton(A_POSE).bone_lengths(), A_POSE.bone_lengths(), atol=EXACT
    )


def drooped(left_deg: float, right_deg: float) -> Skeleton:
    """The T-pose rig with its forearms drooping by these angles below the horizontal."""
    off = T_POSE.offsets.copy()
    for side, sx, deg in (("Left", 1.0, left_deg), ("Right", -1.0, right_deg)):
        a = math.radians(deg)
        off[J[f"{side}Hand"]] = np.linalg.norm(off[J[f"{side}Hand"]]) * np.array(
            [sx * math.cos(a), -math.sin(a), 0.0]
        )
    return canonical22_skeleton(off)


def test_a_bone_within_the_tolerance_keeps_its_own_direction_and_one_beyond_turns():
    for droop, turns in ((TOLERANCE_DEG - 3, False), (TOLERANCE_DEG + 3, True)):
        pose = retarget_pose(drooped(droop, droop))
        assert (angles_deg(pose)[J["LeftForeArm"]] > 1.0) == turns
        assert (angles_deg(pose)[J["RightForeArm"]] > 1.0) == turns
        assert angles_deg(pose)[J["LeftArm"]] < EXACT  # the chain's root stays


def test_left_and_right_turn_together_by_their_mean_angle():
    """A convention is symmetric: a rig is never turned on one side alone (it would stand
    crooked); the two sides decide by the mean of their angles."""
    for left, right, turns in ((TOLERANCE_DEG + 4, TOLERANCE_DEG - 2, True), (20.0, 0.0, False)):
        angles = angles_deg(retarget_pose(drooped(left, right)))
        assert angles[J["LeftForeArm"]] > 1.0 if turns else angles[J["LeftForeArm"]] < EXACT
        assert angles[J["RightForeArm"]] > 1.0 if turns else angles[J["RightForeArm"]] < EXACT


@pytest.mark.parametrize(
    "axis_angle", [(0.0, 0.0, math.pi / 2), (math.pi / 2, 0.0, 0.0), (0.0, math.pi, 0.0)]
)
def test_a_rig_lying_or_facing_away_stands_up_like_the_upright_one(axis_angle):
    upright = retarget_pose_skeleton(A_POSE).rest_positions()
    lying = retarget_pose_skeleton(turned(A_POSE, axis_angle)).rest_positions()
    np.testing.assert_allclose(lying - lying[0], upright - upright[0], atol=EXACT)


@settings(max_examples=25, deadline=None)
@given(
    st.tuples(*[st.floats(-1.0, 1.0)] * 3).filter(lambda v: np.linalg.norm(v) > 0.1),
    st.floats(TOLERANCE_DEG + 1.0, 179.0),
    st.sampled_from(["t", "a", "bent"]),
)
def test_any_turn_of_a_rig_beyond_the_tolerance_has_the_same_retarget_pose(axis, angle, which):
    """A whole rig turned beyond the tolerance is a convention: it stands up as the upright rig.
    (One turned less is read as the rig's own lean, like a spine's tilt, and kept.)"""
    rig = {"t": T_POSE, "a": A_POSE, "bent": make_skeleton(1.7, arm_deg=25, spine_curve_deg=5)}
    sk = rig[which]
    axis_angle = np.asarray(axis) / np.linalg.norm(axis) * math.radians(angle)
    want = retarget_pose_skeleton(sk).rest_positions()
    got = retarget_pose_skeleton(turned(sk, tuple(axis_angle))).rest_positions()
    np.testing.assert_allclose(got - got[0], want - want[0], atol=1e-7)


def test_a_rig_whose_bones_all_lie_along_x_stands_in_the_canonical_t_pose():
    rest = retarget_pose_skeleton(along_x_rig()).rest_positions()
    for a, b, want in (
        ("Hips", "Spine1", [0, 1, 0]),
        ("Spine2", "Head", [0, 1, 0]),
        ("LeftUpLeg", "LeftLeg", [0, -1, 0]),
        ("RightLeg", "RightFoot", [0, -1, 0]),
        ("LeftArm", "LeftHand", [1, 0, 0]),
        ("RightArm", "RightHand", [-1, 0, 0]),
    ):
        np.testing.assert_allclose(direction(rest, a, b), want, atol=1e-7, err_msg=f"{a}->{b}")
    assert rest[J["LeftUpLeg"], 0] > rest[J["RightUpLeg"], 0]  # left at +X: facing +Z
    s = math.radians(FOOT_SLOPE_DEG)
    for side in ("Left", "Right"):  # a foot along its shin is turned flat, forward
        np.testing.assert_allclose(
            direction(rest, f"{side}Foot", f"{side}ToeBase"),
            [0, -math.sin(s), math.cos(s)],
            atol=1e-7,
        )


def test_bent_knees_straighten_and_the_feet_stay_flat():
    off = T_POSE.offsets.copy()
    knee = math.radians(25.0)
    for side in ("Left", "Right"):
        thigh, shin = (np.linalg.norm(off[J[f"{side}{p}"]]) for p in ("Leg", "Foot"))
        off[J[f"{side}Leg"]] = thigh * np.array([0, -math.cos(knee), math.sin(knee)])
        off[J[f"{side}Foot"]] = shin * np.array([0, -math.cos(knee), -math.sin(knee)])
    feet = [J[n] for n in ("LeftFoot", "RightFoot", "LeftToeBase", "RightToeBase")]
    drop = canonical22_skeleton(off).rest_positions()[feet, 1].min()
    off[0, 1] -= drop - T_POSE.rest_positions()[feet, 1].min()  # standing on the same floor
    bent = canonical22_skeleton(off)
    pose = retarget_pose(bent)
    rest = retarget_pose_skeleton(bent).rest_positions()
    np.testing.assert_allclose(direction(rest, "LeftUpLeg", "LeftFoot"), [0, -1, 0], atol=EXACT)
    # the feet keep their world orientation (the rig stood on flat feet)
    assert angles_deg(pose)[J["LeftFoot"]] < EXACT and angles_deg(pose)[J["RightToeBase"]] < EXACT
    np.testing.assert_allclose(foot_rest_heights(bent), foot_rest_heights(T_POSE), atol=EXACT)
    # the same bones as the T-pose rig, straightened: its leg length (whose thigh and shin lean
    # 1.2 degrees, about 0.1 mm shorter vertically than straight)
    assert skeleton_leg_length(bent) == pytest.approx(skeleton_leg_length(T_POSE), abs=1e-3)
    assert skeleton_leg_length(bent) > bent.rest_positions()[0, 1] - drop  # more than bent


def test_leg_length_and_foot_heights_do_not_depend_on_the_rigs_convention():
    lying = turned(T_POSE, (0.0, 0.0, math.pi / 2))
    assert skeleton_leg_length(lying) == pytest.approx(skeleton_leg_length(T_POSE), abs=EXACT)
    # the lying rig has no sole to measure at rest: its lowest foot joint reads 0
    upright = foot_rest_heights(T_POSE)
    np.testing.assert_allclose(foot_rest_heights(lying), upright - upright.min(), atol=EXACT)


@pytest.mark.parametrize("rig", ["t", "a", "x"])
def test_the_retarget_pose_of_a_rig_in_its_retarget_pose_is_the_identity(rig):
    sk = {"t": T_POSE, "a": A_POSE, "x": along_x_rig()}[rig]
    np.testing.assert_allclose(
        angles_deg(retarget_pose(retarget_pose_skeleton(sk))), 0.0, atol=1e-5
    )


def test_the_local_rotations_of_the_pose_put_the_mesh_frame_in_it():
    from retarget_lib.core.kinematics import forward_kinematics

    pose = retarget_pose(A_POSE)
    local = pose_local_rotations(torch.from_numpy(pose)).numpy()
    pos, _ = forward_kinematics(
        local[None], A_POSE.offsets, A_POSE.parents, A_POSE.offsets[0][None]
    )
    np.testing.assert_allclose(
        np.asarray(pos[0]), retarget_pose_skeleton(A_POSE).rest_positions(), atol=EXACT
    )


def test_rest_alignment_removes_the_convention_and_keeps_the_shape():
    c = rest_alignment(A_POSE, T_POSE)
    assert angles_deg(c)[J["LeftArm"]] == pytest.approx(40.0, abs=1e-6)
    np.testing.assert_allclose(
        angles_deg(rest_alignment(T_POSE, T_POSE.scaled(1.3))), 0, atol=EXACT
    )
    batch = retarget_alignment(
        torch.from_numpy(np.stack([A_POSE.offsets, T_POSE.offsets])),
        torch.from_numpy(np.stack([T_POSE.offsets, A_POSE.offsets])),
    ).numpy()
    np.testing.assert_allclose(np.abs((batch[0] * c).sum(-1)), 1.0, atol=EXACT)
    np.testing.assert_allclose(
        np.abs((batch[1] * rest_alignment(T_POSE, A_POSE)).sum(-1)), 1.0, atol=EXACT
    )


def test_the_batched_pose_matches_one_skeleton_at_a_time():
    rigs = [T_POSE, A_POSE, along_x_rig(), turned(A_POSE, (0.4, -1.0, 0.2))]
    batch = retarget_pose_rotations(torch.from_numpy(np.stack([r.offsets for r in rigs])))
    for k, rig in enumerate(rigs):
        np.testing.assert_allclose(
            np.abs((batch[k].numpy() * retarget_pose(rig)).sum(-1)), 1.0, atol=EXACT
        )


def test_zero_length_bones_are_left_alone():
    off = T_POSE.offsets.copy()
    off[J["Neck"]] = 0.0  # CMU's neck joint sits on the chest joint
    off[J["LeftShoulder"]] = 0.0
    pose = retarget_pose(canonical22_skeleton(off))
    assert np.isfinite(pose).all()
    np.testing.assert_allclose(angles_deg(pose), 0.0, atol=EXACT)


def test_the_retarget_pose_needs_the_canonical_joints():
    with pytest.raises(JointSetError, match="canonical 22"):
        retarget_pose(Skeleton(("Hips", "Spine"), (-1, 0), np.ones((2, 3))))


def _foot_mesh(skeleton: Skeleton, pitch_deg: float) -> tuple[np.ndarray, np.ndarray]:
    """A box sole under each foot, from heel to ball, pitched ``pitch_deg`` (toe end down)."""
    rest = skeleton.rest_positions()
    verts, weights = [], []
    for side in ("Left", "Right"):
        ankle, ball = rest[J[f"{side}Foot"]], rest[J[f"{side}ToeBase"]]
        a = math.radians(pitch_deg)
        for u in np.linspace(-0.05, 0.2, 11):  # along the foot, metres from the ankle
            for x in (-0.04, 0.0, 0.04):
                for h in (0.0, 0.06):
                    p = np.array(
                        [ankle[0] + x, h + 0.0 - u * math.sin(a), ankle[2] + u * math.cos(a)]
                    )
                    verts.append(p)
                    w = np.zeros(22)
                    w[J[f"{side}Foot"] if u < ball[2] - ankle[2] else J[f"{side}ToeBase"]] = 1.0
                    weights.append(w)
    return np.array(verts), np.array(weights)


def test_a_mesh_with_sloping_soles_gets_its_feet_pitched_flat():
    pose = retarget_pose(T_POSE)
    for pitch, turns in ((30.0, True), (-30.0, True), (5.0, False)):
        verts, weights = _foot_mesh(T_POSE, pitch)
        flat = flatten_soles(T_POSE, pose, verts, weights)
        foot = angles_deg(flat)[J["LeftFoot"]]
        if turns:
            assert foot == pytest.approx(abs(pitch), abs=0.5)
            # the sole is level after the turn: lowest heel and ball points at one height
            q = torch.from_numpy(flat[J["LeftFoot"]])
            ankle = T_POSE.rest_positions()[J["LeftFoot"]]
            left = weights[:, J["LeftFoot"]] + weights[:, J["LeftToeBase"]] > 0.5
            posed = quat_rotate(q, torch.from_numpy(verts[left] - ankle)).numpy()
            bottom = posed[np.isclose(verts[left][:, 1] + 0, verts[left][:, 1].min(), atol=0.2)]
            heel, ball = (
                bottom[:, 2] < np.median(bottom[:, 2]),
                bottom[:, 2] >= np.median(bottom[:, 2]),
            )
            assert abs(posed[heel, 1].min() - posed[ball, 1].min()) < 0.02
        else:
            assert foot < EXACT
