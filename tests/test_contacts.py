"""Contact detection and vertex correspondence (retarget_lib.geometry.contacts; Villegas et al.
2021, Sec. 3.4, App. F)."""

import itertools

import numpy as np
import pytest
from skeletons import make_skeleton

from retarget_lib.core.character import Character
from retarget_lib.core.measures import estimated_standing_height
from retarget_lib.core.skeleton import J, canonical22_skeleton
from retarget_lib.data.synthetic.characters import make_character
from retarget_lib.geometry.contacts import (
    FOOT_JOINTS,
    SelfContacts,
    authored_contact_frames,
    correspondence_features,
    detect_foot_contacts,
    detect_self_contacts,
    fill_contacts,
    frame_precision_recall,
    group_faces,
    transfer_contacts,
    vertex_correspondence,
    vertex_groups,
)


# ----------------------------------------------------------------------------- foot contacts
def _standing_clip(skeleton, frames=8, step=(0.0, 0.0, 0.0), lift=0.0):
    """``(T, 22, 3)`` rest pose translated by ``t * step`` and lifted by ``lift`` metres."""
    rest = skeleton.rest_positions()
    t = np.arange(frames)[:, None, None]
    return rest[None] + t * np.asarray(step) + np.array([0.0, lift, 0.0])


def test_a_still_foot_on_the_ground_is_in_contact_everywhere():
    sk = make_skeleton()
    assert FOOT_JOINTS == ("LeftFoot", "RightFoot", "LeftToeBase", "RightToeBase")
    assert detect_foot_contacts(_standing_clip(sk), sk, character_height=1.8).all()


def test_a_lifted_toe_or_a_moving_foot_is_not_in_contact():
    sk = make_skeleton()
    lifted = detect_foot_contacts(_standing_clip(sk, lift=0.05), sk, character_height=1.8)
    assert lifted[:, :2].all() and not lifted[:, 2:].any()  # heels only need to be still
    sliding = detect_foot_contacts(
        _standing_clip(sk, step=(0.0, 0.0, 0.02)), sk, character_height=1.8
    )
    assert not sliding.any()  # 2 cm per frame > 1 cm


def test_thresholds_scale_with_the_character_height():
    sk = make_skeleton()
    # toe 2.5 cm up: <= 3 cm at 1.80 m, > 2 cm at 1.20 m
    up = _standing_clip(sk, lift=0.025)
    assert detect_foot_contacts(up, sk, character_height=1.8)[:, 2:].all()
    assert not detect_foot_contacts(up, sk, character_height=1.2)[:, 2:].any()
    # 0.8 cm per frame: <= 1 cm at 1.80 m, > 0.667 cm at 1.20 m
    slow = _standing_clip(sk, step=(0.008, 0.0, 0.0))
    assert detect_foot_contacts(slow, sk, character_height=1.8).all()
    assert not detect_foot_contacts(slow, sk, character_height=1.2).any()
    # and at twice the frame rate the same 0.8 cm per frame is twice the speed (0.5 cm allowed)
    assert not detect_foot_contacts(slow, sk, character_height=1.8, fps=60.0).any()


def test_frame_zero_uses_its_displacement_to_frame_one():
    sk = make_skeleton()
    clip = _standing_clip(sk, frames=4)
    clip[0] += [0.05, 0.0, 0.0]  # frame 0 is 5 cm away; frames 1-3 are still
    contacts = detect_foot_contacts(clip, sk, character_height=1.8, window=1)
    # frame 0 -> 1 and frame 1 <- 0 both moved 5 cm; frames 2, 3 did not move
    np.testing.assert_array_equal(contacts[:, 0], [False, False, True, True])


def test_toe_height_is_measured_from_the_toe_rest_height():
    sk = make_skeleton()
    offsets = sk.offsets.copy()
    offsets[0, 1] += 0.04  # a skeleton whose toe joints sit 4 cm above its sole in the rest pose
    high_toes = canonical22_skeleton(offsets)
    assert high_toes.rest_positions()[J["LeftToeBase"], 1] == pytest.approx(0.04)
    # standing still in its rest pose: 4 cm up in absolute terms, 0 cm above its rest height
    assert detect_foot_contacts(_standing_clip(high_toes), high_toes, character_height=1.8).all()


@pytest.mark.parametrize(
    "pattern, expected",
    [
        ("11011", "11111"),  # a one-frame gap is filled
        ("110011", "111111"),  # a two-frame gap: 3 of 5 around each missing frame
        ("1100011", "1100011"),  # a three-frame gap is not
        ("00100", "00100"),  # fill only: an isolated contact frame stays, nothing is added
        ("011000", "111000"),  # clip edge: frame 0 sees frames 0-2 and 2 of them are contact
        ("000110", "000111"),  # last frame sees frames 3-5: 2 of 3
    ],
)
def test_five_frame_window_fill(pattern, expected):
    mask = np.array([c == "1" for c in pattern])
    np.testing.assert_array_equal(fill_contacts(mask, 5), [c == "1" for c in expected])


def test_fill_works_per_column_and_checks_its_window():
    mask = np.array([[1, 0], [1, 0], [0, 1], [1, 0], [1, 0]], dtype=bool)
    np.testing.assert_array_equal(fill_contacts(mask), [[1, 0], [1, 0], [1, 1], [1, 0], [1, 0]])
    np.testing.assert_array_equal(fill_contacts(mask, 1), mask)
    with pytest.raises(ValueError, match="odd"):
        fill_contacts(mask, 4)


def test_foot_contacts_reject_bad_shapes():
    sk = make_skeleton()
    with pytest.raises(ValueError, match="positions must be"):
        detect_foot_contacts(np.zeros((1, 22, 3)), sk, 1.8)
    with pytest.raises(ValueError, match="positions must be"):
        detect_foot_contacts(np.zeros((5, 21, 3)), sk, 1.8)


@pytest.mark.data
def test_foot_contacts_match_a_synthetic_walk(synthetic):
    clip = synthetic.clip("walk_000")
    detected = detect_foot_contacts(
        clip.motion.global_positions(),
        clip.motion.skeleton,
        estimated_standing_height(clip.motion.skeleton),
    )
    # toes match closely; a heel also reads "still" in the first frames of its slow lift-off
    # (the paper's heel rule has no height test), so its precision is lower (measured 0.74-0.80)
    for k, least_precision in enumerate((0.7, 0.7, 0.95, 0.95)):
        precision, recall = frame_precision_recall(detected[:, k], clip.joint_contacts[:, k])
        assert precision > least_precision and recall > 0.95, (FOOT_JOINTS[k], precision, recall)


# ----------------------------------------------------------------------------- vertex groups
def test_vertex_groups_and_their_faces_by_hand():
    weights = np.array(
        [[0.6, 0.4, 0.0], [0.5, 0.5, 0.0], [0.2, 0.3, 0.5], [0.0, 0.0, 1.0], [0.4, 0.3, 0.3]]
    )
    groups = vertex_groups(weights)
    assert [g.tolist() for g in groups] == [[0, 1], [1], [2, 3]]  # vertex 4 has no weight >= 0.5
    faces = np.array([[0, 1, 2], [0, 1, 1], [2, 3, 2], [1, 2, 3]])
    assert [f.tolist() for f in group_faces(faces, groups, 5)] == [[1], [], [2]]
    assert [g.tolist() for g in vertex_groups(weights, threshold=0.6)] == [[0], [], [3]]


# ----------------------------------------------------------------------------- self-contacts
def _cube(origin, size):
    """8 corners in ``itertools.product`` order (x slowest) and 12 outward triangles."""
    corners = np.array(list(itertools.product((0.0, 1.0), repeat=3)))
    faces = np.array(
        [
            [0, 1, 3],
            [0, 3, 2],
            [4, 6, 7],
            [4, 7, 5],  # x = 0, x = 1
            [0, 4, 5],
            [0, 5, 1],
            [2, 3, 7],
            [2, 7, 6],  # y = 0, y = 1
            [0, 2, 6],
            [0, 6, 4],
            [1, 5, 7],
            [1, 7, 3],
        ]
    )  # z = 0, z = 1
    return np.asarray(origin) + size * corners, faces


def _two_cubes(
    gap, frames=3, velocity_a=(0.0, 0.0, 0.0), velocity_b=(0.0, 0.0, 0.0), joint_b="Hips"
):
    """A 4 cm cube skinned to LeftHand (vertices 0-7) and one to ``joint_b`` (8-15), ``gap``
    metres to its +x side, each moving by its velocity (metres per frame)."""
    va, fa = _cube((0.0, 1.0, 0.0), 0.04)
    vb, fb = _cube((0.04 + gap, 1.0, 0.0), 0.04)
    t = np.arange(frames)[:, None, None]
    vertices = np.concatenate(
        [va + t * np.asarray(velocity_a), vb + t * np.asarray(velocity_b)], axis=1
    )
    weights = np.zeros((16, 22))
    weights[:8, J["LeftHand"]] = 1.0
    weights[8:, J[joint_b]] = 1.0
    return vertices, np.concatenate([fa, fb + 8]), weights


def test_touching_cubes_give_their_three_closest_vertex_pairs():
    # 1 mm apart at the paper's 138 cm scale: nearest vertices < 0.2 cm
    contacts = detect_self_contacts(*_two_cubes(0.001), character_height=1.38)
    assert contacts.num_frames == 3 and contacts.frame_mask().all()
    # the x = 1 face of cube A (corners 4-7) faces the x = 0 face of cube B (8-11); the
    # four pairs are equally close, ties go to the lower hand vertex
    np.testing.assert_array_equal(contacts.at(1), [[4, 8], [5, 9], [6, 10]])
    np.testing.assert_array_equal(contacts.groups, np.tile([J["LeftHand"], J["Hips"]], (9, 1)))
    np.testing.assert_array_equal(contacts.frames, np.repeat([0, 1, 2], 3))


def test_cubes_apart_give_no_contact():
    contacts = detect_self_contacts(*_two_cubes(0.05), character_height=1.38)
    assert len(contacts) == 0 and not contacts.frame_mask().any()
    assert contacts.at(0).shape == (0, 2)


def test_cubes_moving_together_are_a_contact_by_the_cosine_rule():
    # 5 mm apart: inside the 1 cm margin but not within 0.2 cm, so only the velocity rule can fire
    together = detect_self_contacts(
        *_two_cubes(0.005, velocity_a=(0, 0.01, 0), velocity_b=(0, 0.01, 0)), character_height=1.38
    )
    assert together.frame_mask().all()
    opposite = detect_self_contacts(
        *_two_cubes(0.005, velocity_a=(0, 0.01, 0), velocity_b=(0, -0.01, 0)), character_height=1.38
    )
    assert len(opposite) == 0
    # the margin is scaled with the height too: 5.8 mm at 0.8 m, 4.3 mm at 0.6 m (still cubes
    # count as moving together)
    assert detect_self_contacts(*_two_cubes(0.005), character_height=0.8).frame_mask().all()
    assert len(detect_self_contacts(*_two_cubes(0.005), character_height=0.6)) == 0


def test_the_hands_own_forearm_is_skipped_but_the_other_hand_is_not():
    assert (
        len(detect_self_contacts(*_two_cubes(0.001, joint_b="LeftForeArm"), character_height=1.38))
        == 0
    )
    hands = detect_self_contacts(*_two_cubes(0.001, joint_b="RightHand"), character_height=1.38)
    np.testing.assert_array_equal(
        np.unique(hands.groups, axis=0), [[J["LeftHand"], J["RightHand"]]]
    )
    assert hands.frame_mask("RightHand").all() and not hands.frame_mask("Hips").any()


def test_self_contacts_reject_bad_input():
    vertices, faces, weights = _two_cubes(0.001)
    with pytest.raises(ValueError, match="weights must be"):
        detect_self_contacts(vertices, faces, weights[:, :21], 1.38)
    with pytest.raises(ValueError, match="vertices must be"):
        detect_self_contacts(vertices[:1], faces, weights, 1.38)


def test_remap_maps_vertices_and_drops_duplicates_and_empty_pairs():
    contacts = SelfContacts(
        4,
        frames=[1, 1, 1, 1, 3],
        pairs=[[0, 2], [1, 2], [0, 3], [3, 2], [1, 3]],
        groups=[[17, 0]] * 5,
    )
    mapped = contacts.remap(np.array([5, 6, 7, 5]))
    # (0,3) -> (5,5) is empty; (3,2) -> (5,7) repeats (0,2) in frame 1
    np.testing.assert_array_equal(mapped.frames, [1, 1, 3])
    np.testing.assert_array_equal(mapped.pairs, [[5, 7], [6, 7], [6, 5]])
    np.testing.assert_array_equal(mapped.groups, [[17, 0]] * 3)
    with pytest.raises(ValueError, match="correspondence"):
        contacts.remap(np.arange(3))


def test_self_contacts_container_checks_its_arrays():
    with pytest.raises(ValueError, match="frames must lie"):
        SelfContacts(2, frames=[2], pairs=[[0, 1]], groups=[[17, 0]])
    with pytest.raises(ValueError, match="2 frames, 1 pairs"):
        SelfContacts(3, frames=[0, 1], pairs=[[0, 1]], groups=[[17, 0]])


# ----------------------------------------------------------------------------- correspondence
@pytest.fixture(scope="module")
def ada() -> Character:
    return make_character("ada")


def test_correspondence_features_by_hand_on_one_vertex(ada):
    features = correspondence_features(ada, canonical_pose=False)
    v = 123
    joint = int(ada.weights[v].argmax())
    expected = (ada.rest_joint_positions()[joint] - ada.rest_vertices[v]) / ada.height
    np.testing.assert_allclose(features[v, :22], ada.weights[v])
    np.testing.assert_allclose(features[v, 22:], expected)
    np.testing.assert_allclose(
        correspondence_features(ada, 2.0, canonical_pose=False)[v, 22:], 2 * expected
    )


@pytest.mark.parametrize("canonical_pose", [True, False])
def test_correspondence_to_itself_is_the_identity(ada, canonical_pose):
    corr = vertex_correspondence(ada, ada, canonical_pose=canonical_pose)
    np.testing.assert_array_equal(corr, np.arange(ada.num_vertices))


def test_correspondence_to_a_scaled_copy_is_nearly_the_identity(ada):
    big = Character(
        "ada-x1.2", ada.skeleton.scaled(1.2), 1.2 * ada.rest_vertices, ada.faces, ada.weights
    )
    corr = vertex_correspondence(ada, big)
    assert (corr == np.arange(ada.num_vertices)).mean() > 0.99


def test_transfer_contacts_goes_through_the_correspondence(ada):
    contacts = SelfContacts(
        2, frames=[0, 1], pairs=[[10, 20], [30, 40]], groups=[[17, 0], [17, 21]]
    )
    moved = transfer_contacts(contacts, ada, ada)
    np.testing.assert_array_equal(moved.pairs, contacts.pairs)
    np.testing.assert_array_equal(moved.groups, contacts.groups)


# ----------------------------------------------------------------------------- synthetic clips
@pytest.fixture(scope="module")
def synthetic():
    from retarget_lib.data.synthetic.dataset import load_synthetic

    return load_synthetic()


@pytest.mark.data
@pytest.mark.parametrize("name", ["clap_000", "pray_001"])
def test_hand_hand_contacts_of_a_synthetic_clip_on_its_performer(synthetic, name):
    clip = synthetic.clip(name)
    performer = synthetic.characters[clip.performer]
    vertices = performer.skinned(clip.motion.rotations, clip.motion.root_positions)
    contacts = detect_self_contacts(
        vertices, performer.faces, performer.weights, estimated_standing_height(performer.skeleton)
    )
    detected = contacts.frame_mask("RightHand") & contacts.frame_mask("LeftHand")
    expected = authored_contact_frames(clip.hand_contacts, len(vertices), "LeftHand")
    precision, recall = frame_precision_recall(detected, expected)
    assert precision > 0.6 and recall > 0.6, (precision, recall)
    hand_hand = [J["LeftHand"], J["RightHand"]]
    assert (contacts.groups == hand_hand).all(axis=1).any()


def test_precision_recall_and_authored_frames_by_hand():
    class Run:
        def __init__(self, start, stop, hand):
            self.start, self.stop, self.hand = start, stop, hand

    expected = authored_contact_frames([Run(1, 3, "LeftHand"), Run(5, 6, "RightHand")], 7)
    np.testing.assert_array_equal(expected, [0, 1, 1, 0, 0, 1, 0])
    assert authored_contact_frames([Run(5, 6, "RightHand")], 7, "LeftHand").sum() == 0
    detected = np.array([0, 1, 0, 1, 0, 1, 0], bool)
    assert frame_precision_recall(detected, expected) == pytest.approx((2 / 3, 2 / 3))
