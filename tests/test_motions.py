"""Synthetic motion library: every family on very different characters, physically consistent."""

import numpy as np
import pytest
import torch
from skeletons import contact_runs, make_skeleton

from retarget_lib.core.measures import skeleton_leg_length
from retarget_lib.core.rotations import quat_rotate
from retarget_lib.core.skeleton import FOOT_CONTACT_JOINTS, J
from retarget_lib.data.synthetic.motions import (
    DURATION_RANGES,
    FPS,
    MOTION_FAMILIES,
    default_body_radii,
    make_motion,
    motion_library,
)

SKELETONS = {
    "short_apose": make_skeleton(height=1.3, leg_frac=0.42, arm_deg=45.0),
    "tall_tpose": make_skeleton(height=2.0, leg_frac=0.55, arm_deg=0.0, spine_curve_deg=8.0),
}
FEET = [J[n] for n in FOOT_CONTACT_JOINTS]


@pytest.fixture(scope="module")
def clips():
    """Seed 0 of every family on both skeletons (built once)."""
    return {(f, k): make_motion(f, sk, 0) for f in MOTION_FAMILIES for k, sk in SKELETONS.items()}


@pytest.mark.parametrize("family", MOTION_FAMILIES)
def test_family_is_well_formed_on_both_characters(clips, family):
    for key in SKELETONS:
        m = clips[family, key]
        lo, hi = DURATION_RANGES[family]
        assert m.fps == FPS and lo - 1e-9 <= m.duration <= hi + 1 / FPS and 2.0 <= lo and hi <= 40.0
        assert np.isfinite(m.rotations).all() and np.isfinite(m.root_positions).all()
        np.testing.assert_allclose(np.linalg.norm(m.rotations, axis=-1), 1.0, atol=1e-9)
        np.testing.assert_allclose(m.root_positions[0, [0, 2]], 0.0, atol=1e-9)
        facing = m.facing()[0]
        assert facing[2] > np.cos(np.radians(2.0))  # starts facing +Z
        assert m.meta["family"] == family and m.meta["seed"] == 0
        assert m.meta["joint_contacts"].shape == (m.num_frames, 4)
        np.testing.assert_array_equal(
            m.meta["foot_contacts"],
            m.meta["joint_contacts"][:, :2] & m.meta["joint_contacts"][:, 2:],
        )


@pytest.mark.parametrize("family", MOTION_FAMILIES)
def test_feet_planted_without_sliding_and_never_under_the_floor(clips, family):
    for key in SKELETONS:
        m = clips[family, key]
        pos = m.global_positions()
        contacts = m.meta["joint_contacts"]
        assert contacts[0].all() and contacts.any(axis=0).all()  # starts standing
        assert pos[:, FEET, 1].min() > -0.01
        for k, joint in enumerate(FEET):
            for a, b in contact_runs(contacts[:, k]):
                slide = np.linalg.norm(np.diff(pos[a:b, joint], axis=0), axis=-1).sum()
                assert slide < 0.01, (key, FOOT_CONTACT_JOINTS[k], a, b, slide)
        flat = m.meta["foot_contacts"]
        for side in (0, 1):  # a flat planted foot rests on the floor: its lowest joint at y = 0
            low = pos[flat[:, side]][:, [FEET[side], FEET[side + 2]], 1].min(axis=-1)
            np.testing.assert_allclose(low, 0.0, atol=0.01)


@pytest.mark.parametrize("family", ["walk", "run", "squat", "kick", "jump"])
def test_knees_bend_forward_only(clips, family):
    for key in SKELETONS:
        pos = clips[family, key].global_positions()
        left = pos[:, J["LeftUpLeg"]] - pos[:, J["RightUpLeg"]]
        left /= np.linalg.norm(left, axis=-1, keepdims=True)
        for side in ("Left", "Right"):
            thigh = pos[:, J[f"{side}Leg"]] - pos[:, J[f"{side}UpLeg"]]
            shin = pos[:, J[f"{side}Foot"]] - pos[:, J[f"{side}Leg"]]
            hinge = (np.cross(thigh, shin) * left).sum(-1)
            scale = np.linalg.norm(thigh, axis=-1) * np.linalg.norm(shin, axis=-1)
            assert (hinge > -1e-3 * scale).all(), (key, side)


def test_locomotion_travels_and_legs_alternate(clips):
    for key, sk in SKELETONS.items():
        speeds = {}
        for family in ("walk", "run"):
            m = clips[family, key]
            airborne = ~m.meta["joint_contacts"].any(axis=1)
            assert airborne.any() == (family == "run")  # flight phases only when running
            path = np.linalg.norm(np.diff(m.root_positions[:, [0, 2]], axis=0), axis=-1).sum()
            speeds[family] = path / m.duration / skeleton_leg_length(sk)  # leg lengths per second
            flat = m.meta["foot_contacts"]
            assert len(contact_runs(flat[:, 0])) >= 3 and len(contact_runs(flat[:, 1])) >= 3
        assert 0.3 < speeds["walk"] < 1.6 and 1.0 < speeds["run"] < 4.5


def test_clap_and_pray_palms_meet(clips):
    for family in ("clap", "pray"):
        for key, sk in SKELETONS.items():
            m = clips[family, key]
            pos, grot = m.fk()
            touches = m.meta["hand_contacts"]
            assert touches and {c.hand for c in touches} == {"LeftHand", "RightHand"}
            frames = np.concatenate([np.arange(c.start, c.stop) for c in touches])
            gap = np.linalg.norm(pos[frames, J["LeftHand"]] - pos[frames, J["RightHand"]], axis=-1)
            assert gap.max() < 0.02
            # palms face each other (rest palm normal: down, perpendicular to the forearm)
            rest = sk.rest_positions()
            along = rest[J["LeftHand"]] - rest[J["LeftForeArm"]]
            down = np.array([0.0, -1.0, 0.0]) - along * (-along[1]) / (along @ along)
            palm = quat_rotate(
                torch.from_numpy(grot[frames, J["LeftHand"]]), torch.from_numpy(down)
            ).numpy()
            toward = pos[frames, J["RightHand"]] - pos[frames, J["LeftHand"]]
            cos = (
                (palm * toward).sum(-1)
                / np.linalg.norm(palm, axis=-1)
                / np.linalg.norm(toward, axis=-1)
            )
            assert cos.min() > 0.9


def test_hands_rest_on_the_hips_surface(clips):
    for key, _sk in SKELETONS.items():
        m = clips["hands_on_hips", key]
        r = m.meta["body_radii"]
        pos = m.global_positions()
        touches = m.meta["hand_contacts"]
        assert {(c.hand, c.part) for c in touches} == {
            ("LeftHand", "LeftHip"),
            ("RightHand", "RightHip"),
        }
        for c in touches:
            hand = pos[c.start : c.stop, J[c.hand]]
            hips = pos[c.start : c.stop, J["Hips"]]
            across = np.linalg.norm((hand - hips)[:, [0, 2]], axis=-1)
            np.testing.assert_allclose(across, r["hip"] + r["hand"], atol=0.03)
            assert (np.abs(hand[:, 1] - hips[:, 1]) < 0.15).all()
            assert (np.sign(hand[:, 0] - hips[:, 0]) == (1 if c.hand == "LeftHand" else -1)).all()


def test_touch_head_hand_on_top_of_the_head(clips):
    for key in SKELETONS:
        m = clips["touch_head", key]
        r = m.meta["body_radii"]
        pos = m.global_positions()
        assert m.meta["hand_contacts"]
        for c in m.meta["hand_contacts"]:
            assert c.part == "HeadTop"
            hand = pos[c.start : c.stop, J[c.hand]]
            head = pos[c.start : c.stop, J["Head"]]
            centre = head + np.array([0.0, 0.9 * r["head"], 0.0])
            d = np.linalg.norm(hand - centre, axis=-1)
            assert ((d > 0.8 * r["head"]) & (d < r["head"] + r["hand"] + 0.03)).all()
            assert (hand[:, 1] > head[:, 1] + 1.3 * r["head"]).all()


def test_body_size_hint_moves_contacts_to_the_surface():
    sk = SKELETONS["tall_tpose"]
    radii = dict(default_body_radii(sk), hip=0.25, hand=0.02)
    m = make_motion("hands_on_hips", sk, 3, body_radii=radii)
    pos = m.global_positions()
    c = m.meta["hand_contacts"][0]
    across = np.linalg.norm(
        (pos[c.start : c.stop, J[c.hand]] - pos[c.start : c.stop, 0])[:, [0, 2]], axis=-1
    )
    np.testing.assert_allclose(across, 0.27, atol=0.03)
    assert m.meta["body_radii"]["hip"] == 0.25


def test_deterministic_by_seed_and_varied_across_seeds():
    sk = SKELETONS["short_apose"]
    for family in ("walk", "clap", "kick"):
        a, b = make_motion(family, sk, 5), make_motion(family, sk, 5)
        np.testing.assert_array_equal(
            a.rotations, b.rotations
        )  # the same code twice in one process: exact
        np.testing.assert_array_equal(a.root_positions, b.root_positions)
        others = [make_motion(family, sk, s) for s in (6, 7)]
        assert len({a.num_frames} | {o.num_frames for o in others}) > 1 or all(
            not np.allclose(a.rotations, o.rotations) for o in others
        )
        assert a.meta["style"] != others[0].meta["style"]


def test_duration_override_and_range():
    sk = SKELETONS["tall_tpose"]
    assert make_motion("squat", sk, 1, duration=10.0).num_frames == 300
    for seed in range(6):
        m = make_motion("walk", sk, seed)
        assert DURATION_RANGES["walk"][0] <= m.duration <= DURATION_RANGES["walk"][1] + 1 / FPS
    with pytest.raises(ValueError, match="unknown motion family"):
        make_motion("dance", sk, 0)


def test_motion_library_covers_every_family():
    lib = motion_library(
        SKELETONS["short_apose"], seeds_per_family=2, seed=3, families=("wave", "turn", "jump")
    )
    assert [m.meta["family"] for m in lib] == ["wave", "wave", "turn", "turn", "jump", "jump"]
    assert [m.meta["seed"] for m in lib] == [3, 4] * 3
    assert len({m.name for m in lib}) == 6


def test_generation_is_fast():
    import time

    sk = SKELETONS["tall_tpose"]
    make_motion("run", sk, 0, duration=2.0)
    start = time.perf_counter()
    make_motion("run", sk, 1, duration=10.0)
    assert time.perf_counter() - start < 1.0


def test_a_character_standing_on_the_floor_keeps_its_soles_on_it():
    """A character whose rest pose stands on ``y = 0`` (soles there, toe joints above) plants its
    feet at their rest heights, so its mesh stands on the floor, not 3 cm into it (Efoot's ḡ, Eq.
    6)."""
    from retarget_lib.core.measures import foot_rest_heights
    from retarget_lib.core.quantities import FOOT_CONTACT_IDS
    from retarget_lib.data.synthetic.characters import make_character

    c = make_character("ada")
    assert c.rest_vertices[:, 1].min() == pytest.approx(0.0, abs=1e-6)
    m = make_motion("walk", c.skeleton, 0)
    pos = m.global_positions()[:, list(FOOT_CONTACT_IDS), 1]
    contacts = m.meta["joint_contacts"]
    flat = np.tile(
        m.meta["foot_contacts"], 2
    )  # heel and toe (FOOT_CONTACT_JOINTS order) of a flat foot
    lift = (pos - foot_rest_heights(c.skeleton))[flat & contacts]
    np.testing.assert_allclose(lift, 0.0, atol=0.005)  # 5 mm: the IK solve's residual
    lowest = c.skinned(m.rotations, m.root_positions)[..., 1].min(axis=1)
    both_flat = m.meta["foot_contacts"].all(axis=1)
    np.testing.assert_allclose(lowest[both_flat], 0.0, atol=0.005)
