"""TDCN evaluation: the normalised MSE on cases with known answers, the scenario protocol."""

import numpy as np
import pandas as pd
import pytest

from retarget_lib.core.motion import Motion
from retarget_lib.core.skeleton import canonical22_skeleton
from retarget_lib.core.transfer import retarget_ground_truth
from retarget_lib.data.manifest import table_checkpoints
from retarget_lib.data.synthetic.characters import make_character
from retarget_lib.data.synthetic.mixamo_convention import generate
from retarget_lib.evaluation.paper import PAPER_TABLE4, TABLE4_COLUMNS
from retarget_lib.evaluation.tdcn import (
    markdown_table,
    normalized_mse,
    ordering_checks,
    paper_comparison,
    tdcn_cases,
    tdcn_table,
    write_table,
)
from retarget_lib.evaluation.tdcn.cases import EvalCase, evaluate_case, short_chunks
from retarget_lib.methods.copy import copy_rotations, copy_unscaled


def test_normalized_mse_known_values():
    truth = np.zeros((10, 22, 3))
    pred = truth + np.array([0.03, 0.04, 0.0])  # every joint 5 cm off: 25 cm² per joint and frame
    # H = 1.5 m = 150 cm: 25 cm² / 150 cm = 1/6 cm; H² variant: 0.0025 m² / 2.25 m² = 1/900
    assert normalized_mse(pred, truth, 1.5) == pytest.approx(25 / 150)
    assert normalized_mse(pred, truth, 1.5, squared_height=True) == pytest.approx(1 / 900)
    half = truth.copy()
    half[:5] += [0.1, 0.0, 0.0]  # half the frames 10 cm off: mean 50 cm²
    assert normalized_mse(half, truth, 2.0) == pytest.approx(50 / 200)
    with pytest.raises(ValueError, match="differ"):
        normalized_mse(pred[:3], truth, 1.5)


def _half_size_case(root_z_cm: np.ndarray) -> EvalCase:
    """A source of ``H`` = 160 cm standing still in its rest pose while its root moves along +z
    by ``root_z_cm``, and a target with every bone half as long (``H`` = 80 cm) whose ground
    truth is the same motion at half the size."""
    template = make_character("ada").skeleton
    source = canonical22_skeleton(template.offsets * (1.6 / template.height()))
    target = canonical22_skeleton(source.offsets * 0.5)
    frames = len(root_z_cm)
    rotations = np.tile([1.0, 0.0, 0.0, 0.0], (frames, 22, 1))
    root = np.zeros((frames, 3))
    root[:, 1] = source.offsets[0, 1]
    root[:, 2] = root_z_cm / 100.0
    motion = Motion(source, rotations, root, 30.0)
    truth = Motion(target, rotations, root * 0.5, 30.0)
    return EvalCase(1, "a", "b", "hand", motion, target, truth)


def test_the_papers_copy_row_on_a_hand_case():
    """NKN's copy moves a half-size target as far as the source: off by (1 - s) v t at every
    joint, so short = (1 - s)^2 v^2 (T - 1)(2T - 1) / (6 H) with s = 1/2, v = 1 cm per frame,
    H = 80 cm (T = 120: 14.8130; the whole 250 frames: 64.7141); the leg-scaled copy is exact."""
    case = _half_size_case(np.arange(250.0))
    assert case.target.height() == pytest.approx(0.8)
    got = evaluate_case(copy_unscaled, case)
    assert got["long"] == pytest.approx(0.25 * 249 * 499 / 6 / 80, rel=1e-9)
    assert got["long"] == pytest.approx(64.7141, abs=1e-4)
    short = evaluate_case(copy_unscaled, _half_size_case(np.arange(120.0)))["short"]
    assert short == pytest.approx(14.8130, abs=1e-4)
    assert evaluate_case(copy_rotations, case)["long"] == pytest.approx(0.0, abs=1e-12)


def test_short_windows_are_the_authors():
    """The authors' code adds an overlapping last window where 120 does not divide the clip:
    [0, 120), [120, 240), [130, 250) for 250 frames; a root that moves only after frame 200 then
    scores (0 + 0.53490 + 1.05273) / 3 = 0.52921 short (dropping the remainder: 0.26745)."""
    assert short_chunks(250) == [(0, 120), (120, 240), (130, 250)]
    assert short_chunks(240) == [(0, 120), (120, 240)]
    assert short_chunks(60) == [(0, 60)]
    case = _half_size_case(np.maximum(0.0, np.arange(250.0) - 200.0))
    got = evaluate_case(copy_unscaled, case)
    assert got["short"] == pytest.approx(0.52921, abs=1e-5)
    assert got["long"] == pytest.approx(0.50531, abs=1e-5)


@pytest.fixture(scope="module")
def cases():
    return tdcn_cases()


@pytest.mark.data
def test_cases_cover_the_four_scenarios(cases):
    assert sorted({c.scenario for c in cases}) == [1, 2, 3, 4]
    assert all(c.source_name != c.target_name for c in cases)
    assert all(
        c.truth.skeleton is not None and c.truth.num_frames == c.source.num_frames for c in cases
    )


@pytest.mark.data
def test_ground_truth_method_scores_zero_and_copy_does_not(cases, tmp_path):
    table, per_case = tdcn_table(
        {"copy-rest": retarget_ground_truth, "copy": copy_rotations}, cases[::4]
    )
    ours = [f"ours {c}" for c in TABLE4_COLUMNS]
    assert np.allclose(table.loc["copy-rest", ours].astype(float), 0.0, atol=1e-9)
    assert (per_case.query("method == 'copy'")["long"] > 0).all()
    csv_path, md_path = write_table(table, tmp_path, "t4", note="test")
    assert csv_path.exists() and md_path.read_text().startswith("test")
    assert "| copy |" in md_path.read_text()


def test_paper_numbers_and_markdown():
    assert PAPER_TABLE4["ours"][4] == 2.45 and PAPER_TABLE4["ours"][9] == 2.48
    assert all(len(v) == len(TABLE4_COLUMNS) for v in PAPER_TABLE4.values())
    import pandas as pd

    md = markdown_table(pd.DataFrame({"a": [1.234, np.nan]}, index=["x", "y"]))
    assert md.splitlines()[2] == "| x | 1.23 |" and md.splitlines()[3] == "| y |  |"


@pytest.mark.data
def test_cli_evaluate_writes_every_table4_row_with_provenance(tmp_path, capsys, monkeypatch):
    from retarget_lib.cli import main
    from retarget_lib.evaluation import tdcn
    from retarget_lib.evaluation.results import load_result
    from retarget_lib.evaluation.tdcn import tables  # where `retarget evaluate` looks the cases up

    # every row on a subset of the cases (the full run is `make tables`, ~10 min): the first pair of
    # every scenario, one CMU clip onto one target
    every, real = tdcn.tdcn_cases(), tdcn.cmu_cases()[:1]
    monkeypatch.setattr(tables, "tdcn_cases", lambda: tdcn.rerun_subset(every))
    monkeypatch.setattr(tables, "cmu_cases", lambda: real)
    # the Mixamo-convention profile: one pair of two of its characters in every scenario, authored
    # here (the whole profile is built on first use by `make tables`, 3.5 min)
    two = generate(count=2, clip_ids=[("walk", 8)])
    walk = two.clips["walk_008"]
    mc = [
        tdcn.EvalCase(
            s,
            "tp01",
            "tp02",
            "walk_008",
            walk["tp01"],
            two.characters["tp02"].skeleton,
            walk["tp02"],
        )
        for s in (1, 2, 3, 4)
    ]
    monkeypatch.setattr(tables, "mixamo_convention_cases", lambda: mc)
    assert main(["evaluate", "--table", "tdcn", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "no trained checkpoint yet for:" not in out  # every Table 4 row ships a checkpoint
    for name in (
        "table4.csv",
        "table4.md",
        "table4_h2.csv",
        "table4_cases.csv",
        "table4_cmu_cases.csv",
        "table4_windowed_cases.csv",
        "table4_mixamo_convention.md",
        "table4_mixamo_convention_cases.csv",
    ):
        assert (tmp_path / name).exists()
    t = pd.read_csv(tmp_path / "table4.csv", index_col=0)
    assert set(PAPER_TABLE4) <= set(t.index), set(PAPER_TABLE4) - set(t.index)
    assert t.loc["ours", "paper short avg"] == 2.45 and t.loc["ours", "ours long avg"] > 0
    # the provenance names every row's checkpoint, and a fresh result is not stale
    stored = load_result("table4_cases", rows=table_checkpoints("tdcn"), results_dir=tmp_path)
    assert stored.stale == [], stored.stale
    assert set(stored.provenance["checkpoints"]) == set(table_checkpoints("tdcn"))
    assert len(stored.frame) == 4 * len(t) and set(stored.frame["scenario"]) == {1, 2, 3, 4}
    assert load_result("table4_cmu_cases", results_dir=tmp_path).frame["clip"].nunique() == 1
    windowed = load_result("table4_windowed_cases", results_dir=tmp_path)
    assert list(windowed.provenance["checkpoints"]) == [tdcn.WINDOWED_ROW]
    mc_stored = load_result(
        "table4_mixamo_convention_cases",
        rows=tdcn.mixamo_convention_checkpoints(),
        results_dir=tmp_path,
    )
    assert mc_stored.stale == [] and {"copy", "copy-rest", "ours", "ours-residual"} <= set(
        mc_stored.frame["method"]
    )


def test_contact_rows_can_be_recomputed_alone_only_for_the_contact_tables(tmp_path, capsys):
    from retarget_lib.cli import main

    assert main(["evaluate", "--table", "tdcn", "--rows", "TDCN", "--out", str(tmp_path)]) == 2
    assert "--rows recomputes rows of the stored contact tables" in capsys.readouterr().err


def test_ordering_checks_compare_directions_with_the_paper():
    cols = [f"{w} {length} avg" for w in ("ours", "paper") for length in ("short", "long")]
    table = pd.DataFrame(
        [
            [2.0, 4.0, 2.45, 2.48],  # ours
            [4.0, 2.0, 4.94, 6.20],
        ],  # A2: worse short, better long here
        index=["ours", "A2"],
        columns=cols,
    )
    checks = ordering_checks(table)
    assert list(checks.index) == ["A2"]
    assert checks.loc["A2", "ours short avg ratio"] == pytest.approx(2.0)
    assert checks.loc["A2", "paper long avg ratio"] == pytest.approx(6.20 / 2.48)
    assert bool(checks.loc["A2", "short reproduces"]) and not bool(
        checks.loc["A2", "long reproduces"]
    )
    assert list(paper_comparison(table).columns) == [
        "ours short avg",
        "paper short avg",
        "ours long avg",
        "paper long avg",
    ]
