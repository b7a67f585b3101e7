"""Table 1's metrics on the Mixamo-convention characters
(retarget_lib/evaluation/contact_mixamo_convention.py)."""

from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest

from retarget_lib.data.splits import MotionId, ScenarioPair
from retarget_lib.data.synthetic.mixamo_convention import generate
from retarget_lib.evaluation import contact_mixamo_convention as mcc
from retarget_lib.evaluation.results import load_result


@pytest.fixture(scope="module")
def small_profile():
    """Three characters, a clap and a walk authored on each, and a split with repeated and
    same-character pairs (which the cases must leave out)."""
    data = generate(count=3, clip_ids=[("clap", 1), ("walk", 0), ("kick", 0)])
    pairs = [
        ScenarioPair("tp01", "tp02", MotionId("clap", 1)),
        ScenarioPair("tp01", "tp02", MotionId("clap", 1)),
        ScenarioPair("tp03", "tp03", MotionId("walk", 0)),
        ScenarioPair("tp03", "tp01", MotionId("walk", 0)),
        ScenarioPair("tp02", "tp03", MotionId("walk", 0)),
        ScenarioPair("tp02", "tp01", MotionId("kick", 0)),
    ]
    return data, SimpleNamespace(scenarios={1: pairs[:3], 2: pairs[3:]})


@pytest.fixture
def patched(small_profile, monkeypatch):
    data, split = small_profile
    monkeypatch.setattr(mcc, "mixamo_convention_versions", lambda pairs: data)
    monkeypatch.setattr(mcc, "mixamo_convention_split", lambda: split)
    monkeypatch.setattr(mcc, "PAIRS_PER_FAMILY", 1)
    return data


def test_cases_are_the_targets_own_versions_with_the_sources_contacts(patched):
    cases = mcc.mixamo_convention_contact_cases("fast")
    # kick is not a family of the fast profile; the repeated clap pair, tp03 onto itself and the
    # second walk pair (one pair per family here) are left out
    assert [(c.clip, c.source_character.name, c.target.name) for c in cases] == [
        ("clap_001", "tp01", "tp02"),
        ("walk_000", "tp03", "tp01"),
    ]
    for c in cases:
        own = patched.clips[c.clip][c.target.name]
        assert c.source.num_frames == c.truth.num_frames == min(60, own.num_frames)
        assert np.array_equal(
            c.truth.global_positions(), own.slice(0, c.truth.num_frames).global_positions()
        )
        assert np.array_equal(
            c.source.rotations, patched.clips[c.clip][c.source_character.name].rotations[:60]
        )
        assert c.foot_contacts.shape == (c.source.num_frames, 4)
    clap = cases[0]
    assert (
        clap.contact_rich and len(clap.contacts) > 0
    )  # the clap's hand contacts, carried to tp02's mesh
    assert max(int(np.max(clap.contacts.at(f))) for f in clap.contacts.frames) < len(
        clap.target.rest_vertices
    )


def test_the_table_puts_each_rows_error_beside_copys(patched, tmp_path, monkeypatch):
    monkeypatch.setattr(mcc, "ROWS", ("copy", "copy-rest"))
    table = mcc.run_mixamo_convention_contact_evaluation(tmp_path, "fast", command="cmd")
    # one T-pose rest with identity rotations: the rest-compensated copy is the copy, to the last
    # digit
    assert table.loc["copy", "ours global position MSE / copy's"] == 1.0
    assert table.loc["copy-rest", "ours global position MSE / copy's"] == pytest.approx(
        1.0, abs=1e-12
    )
    assert table.loc["copy", "ours global position MSE"] > 0  # copy is not the target's own version
    assert not any(c.startswith("paper") for c in table.columns)
    per_case = pd.read_csv(tmp_path / "contact_mixamo_convention_cases.csv")
    assert set(per_case["source"]) == {"tp01", "tp03"} and len(per_case) == 4
    assert (tmp_path / "contact_mixamo_convention.md").read_text().startswith("Table 1's metrics")
    stored = load_result("contact_mixamo_convention_cases", rows={}, results_dir=tmp_path)
    assert stored.provenance["command"] == "cmd"
