"""`retarget evaluate --table real`: measures without ground truth, on cases with known answers."""

import numpy as np
import pytest

from retarget_lib.core.motion import Motion
from retarget_lib.data.sources.real_characters import load_real_character
from retarget_lib.data.synthetic.characters import make_character
from retarget_lib.evaluation.real import (
    MEASURES,
    RealClip,
    _methods,
    evaluate_real,
    real_measures,
    real_table,
    welded,
)
from retarget_lib.methods.retarget import on_the_ground

pytestmark = pytest.mark.data


def _still(skeleton, frames=30) -> Motion:
    """The rest pose held still, feet on y = 0."""
    q = np.zeros((frames, 22, 4))
    q[..., 0] = 1.0
    root = np.repeat(skeleton.offsets[:1], frames, axis=0)
    return Motion(skeleton.copy(), q, root, 30.0, name="still")


@pytest.fixture(scope="module")
def character():
    return welded(load_real_character("quaternius_male_casual").character())


def test_a_still_source_held_still_scores_zero_and_a_slide_scores_its_speed(character):
    source = make_character("ada")
    clip = RealClip("still", _still(source.skeleton), source, None)
    result = on_the_ground(_still(character.skeleton), clip.motion, character, source)
    m = real_measures(result, clip, character)
    h = character.skeleton.height()
    assert m["skate_pct_per_s"] == pytest.approx(0.0, abs=1e-9)
    assert m["under_floor_pct"] == pytest.approx(
        0.0, abs=1e-6
    )  # the ground rule puts the soles on y = 0
    assert m["float_pct"] == pytest.approx(
        0.0, abs=0.05
    )  # the toe joints' rest heights differ by < 1 mm
    slid = result.copy()
    slid.root_positions[:, 0] += 0.3 * np.arange(30) / 30.0  # 0.3 m/s sideways
    assert real_measures(slid, clip, character)["skate_pct_per_s"] == pytest.approx(
        100 * 0.3 / h, rel=1e-6
    )
    sunk = result.copy()
    sunk.root_positions[:, 1] -= 0.05
    assert real_measures(sunk, clip, character)["under_floor_pct"] == pytest.approx(
        100 * 0.05 / h, rel=0.02
    )
    assert np.isnan(m["hand_gap_pct"])  # no labelled hand contacts
    assert (
        m["foot_contact_mismatch"] == 0.0
    )  # both stand still: every heel and toe in contact on both
    fast = result.copy()
    fast.root_positions[:, 0] += (
        0.9 * np.arange(30) / 30.0
    )  # 3 cm a frame, thrice Sec. 3.4's 1 cm: no contact kept
    assert real_measures(fast, clip, character)["foot_contact_mismatch"] > 0.9


def test_arms_pushed_into_the_body_raise_the_penetration(character):
    source = make_character("ada")
    clip = RealClip("still", _still(source.skeleton), source, None)
    rest = on_the_ground(_still(character.skeleton), clip.motion, character, source)
    inward = rest.copy()
    arm = character.skeleton.index("LeftArm")
    # the character's rest arms hang down at its side (+X); turn the left upper arm 60 degrees
    # about -Z: the arm swings in, through the torso
    half = np.deg2rad(-30.0)
    inward.rotations[:, arm] = [np.cos(half), 0.0, 0.0, np.sin(half)]
    before = real_measures(rest, clip, character)["arm_penetration"]
    after = real_measures(inward, clip, character)["arm_penetration"]
    assert after > before + 0.05


def test_the_table_has_every_measure_and_identity_is_exact_for_the_rest_compensated_copy():
    source = make_character("ada")
    clip = RealClip("still", _still(source.skeleton, 12), source, None)
    per_case = evaluate_real(
        _methods(["copy", "copy-rest"], None), [clip], ["quaternius_male_casual"]
    )
    assert list(per_case["method"]) == ["copy", "copy-rest"]
    table = real_table(per_case)
    assert list(table.columns) == list(MEASURES)
    assert table.loc["copy-rest", "identity_pct"] == pytest.approx(0.0, abs=1e-9)


def test_welding_joins_split_vertices_without_moving_the_surface():
    raw = load_real_character("quaternius_male_casual").character()
    joined = welded(raw)
    assert (
        len(joined.rest_vertices) < len(raw.rest_vertices) / 2
    )  # flat-shaded export: 3-6 copies a vertex
    lo, hi = raw.rest_vertices.min(0), raw.rest_vertices.max(0)
    assert joined.rest_vertices.min(0) == pytest.approx(lo) and joined.rest_vertices.max(
        0
    ) == pytest.approx(hi)
    assert joined.weights.sum(1) == pytest.approx(np.ones(len(joined.weights)))


def test_jitter_is_zero_for_the_source_smoothness_and_symmetric_in_the_log(character):
    # a source swaying 2 cm at 2 Hz; the result sways the same in proportion to its height (0),
    # twice as much (ln 2) or half as much (also ln 2: smoothing a motion away is no better than
    # shaking it)
    source = make_character("ada")
    t = np.arange(30) / 30.0
    sway = np.sin(2 * np.pi * 2 * t)
    src = _still(source.skeleton)
    src.root_positions[:, 0] += 0.02 * sway
    clip = RealClip("sway", src, source, None)
    scale = character.skeleton.height() / source.skeleton.height()
    for factor, expected in ((1.0, 0.0), (2.0, np.log(2)), (0.5, np.log(2))):
        result = _still(character.skeleton)
        result.root_positions[:, 0] += factor * 0.02 * scale * sway
        assert real_measures(result, clip, character)["jitter_log_ratio"] == pytest.approx(
            expected, abs=1e-9
        )
