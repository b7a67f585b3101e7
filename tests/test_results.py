"""Stored results (results/): provenance, checksums, staleness and the live re-run comparison."""

import json

import numpy as np
import pandas as pd
import pytest

from retarget_lib.data.manifest import CheckpointEntry, table_checkpoints
from retarget_lib.evaluation import results
from retarget_lib.evaluation.results import compare_with_stored, load_result, write_result
from retarget_lib.evaluation.tdcn import rerun_tolerance
from retarget_lib.files import DataError

pytestmark = pytest.mark.tooling  # nothing here depends on the thread count (make unit-threads)


def _entry():
    return table_checkpoints("tdcn")["ours"]


def _write(tmp_path, checkpoints=None, frame=None):
    frame = (
        frame
        if frame is not None
        else pd.DataFrame({"method": ["ours", "copy"], "long": [0.123456789, 2.0]})
    )
    return write_result(
        frame,
        tmp_path,
        "t",
        command="cmd",
        checkpoints=checkpoints or {"ours": _entry()},
        profile="fast",
        seconds=1.5,
    )


def test_a_written_result_reads_back_with_its_provenance_and_is_current(tmp_path):
    _write(tmp_path)
    stored = load_result("t", rows={"ours": _entry()}, results_dir=tmp_path)
    assert stored.stale == []
    assert stored.frame["long"].tolist() == [0.1234568, 2.0]  # 7 significant digits kept
    p = stored.provenance
    assert (
        p["command"] == "cmd"
        and p["profile"] == "fast"
        and p["checkpoints"]["ours"]["id"] == "tdcn-ours-fast"
    )
    assert "retarget_lib/core/kinematics.py" in p["code_files"] and not any(
        f.startswith("retarget_lib/cli/") for f in p["code_files"]
    )
    assert "/" not in p["machine"] and "STALE" not in stored.report()


def test_an_edited_or_missing_result_is_an_error_naming_the_command(tmp_path):
    with pytest.raises(DataError, match="make tables"):
        load_result("t", results_dir=tmp_path)
    csv = _write(tmp_path)
    csv.write_text(csv.read_text().replace("2", "3"))
    with pytest.raises(DataError, match="does not match the sha256"):
        load_result("t", results_dir=tmp_path)


def test_a_retrained_checkpoint_an_uncovered_row_and_changed_code_make_it_stale(tmp_path):
    ours = _entry()
    retrained = CheckpointEntry(ours.id, ours.path, "0" * 64, ours.config, ours.command)
    _write(tmp_path, checkpoints={"ours": retrained})
    prov_path = tmp_path / "t.provenance.json"
    prov = json.loads(prov_path.read_text())
    prov["code"] = "f" * 64  # as if the code that computed it had changed
    prov_path.write_text(json.dumps(prov))
    stored = load_result(
        "t", rows={"ours": ours, "A3": table_checkpoints("tdcn")["A3"]}, results_dir=tmp_path
    )
    reasons = " | ".join(stored.stale)
    assert len(stored.stale) == 3, reasons
    assert "'ours': checkpoint tdcn-ours-fast was retrained" in reasons
    assert "'A3' (checkpoint tdcn-a3-fast) has no stored numbers" in reasons
    assert "library code that computed them changed" in reasons
    assert "STALE" in stored.report() and "make tables" in stored.report()


def test_the_code_fingerprint_ignores_docstrings_and_comments_but_not_code(tmp_path, monkeypatch):
    monkeypatch.setattr(results, "REPO_ROOT", tmp_path)
    module = tmp_path / "m.py"
    module.write_text('"""Doc."""\n\ndef f(x):\n    """Doc."""\n    return x + 1  # one\n')
    before = results.code_fingerprint(["m.py"])
    module.write_text(
        '"""Other words."""\n\ndef f(x):\n    """More."""\n    # a comment\n    return x + 1\n'
    )
    assert results.code_fingerprint(["m.py"]) == before
    module.write_text('"""Doc."""\n\ndef f(x):\n    return x + 2\n')
    assert results.code_fingerprint(["m.py"]) != before
    module.unlink()
    assert results.code_fingerprint(["m.py"]) != before


def test_compare_with_stored_applies_the_tolerance_case_by_case():
    keys = ["method", "clip"]
    stored = pd.DataFrame(
        {"method": ["a", "a", "b"], "clip": ["x", "y", "x"], "long": [1.0, 2.0, np.nan]}
    )
    now = pd.DataFrame(
        {"method": ["a", "a", "b"], "clip": ["x", "y", "x"], "long": [1.0005, 2.01, np.nan]}
    )
    out = compare_with_stored(
        now, stored, keys, ["long"], lambda m, metric, v: 1e-3 * max(abs(v), 1.0)
    )
    # 1.0005 within 1e-3 of 1.0; 2.01 is 0.01 from 2.0, over its 2e-3; NaN beside NaN reproduces
    assert out["reproduces"].tolist() == [True, False, True]
    assert out.loc[1, "tolerance"] == pytest.approx(2e-3) and out.loc[
        1, "abs diff"
    ] == pytest.approx(0.01)
    with pytest.raises(ValueError, match="without stored numbers"):
        compare_with_stored(now.assign(clip="z"), stored, keys, ["long"], lambda *a: 1.0)


def test_table4_rerun_tolerance_is_relative_with_a_floor():
    assert rerun_tolerance("ours", "long", 70.0) == pytest.approx(0.07)  # 1e-3 relative
    assert rerun_tolerance("copy-rest", "short", 0.0) == pytest.approx(
        1e-6
    )  # 1e-3 x the 1e-3 floor


@pytest.mark.data
def test_the_stored_results_cover_the_shipped_checkpoints():
    # a retrained checkpoint or a new row without stored numbers must be followed by `make tables`;
    # a code change is only flagged (the notebooks' live re-runs check that the numbers still hold)
    from retarget_lib.evaluation.contact import stored_contact_results
    from retarget_lib.evaluation.contact_mixamo_convention import (
        stored_mixamo_convention_contact_results,
    )
    from retarget_lib.evaluation.real import stored_real_results
    from retarget_lib.evaluation.tdcn import stored_table4

    for stored in (
        stored_table4("table4_cases"),
        stored_table4("table4_cmu_cases"),
        stored_table4("table4_windowed_cases"),
        stored_table4("table4_mixamo_convention_cases"),
        stored_contact_results(),
        stored_mixamo_convention_contact_results(),
        stored_real_results(),
    ):
        about_checkpoints = [why for why in stored.stale if "library code" not in why]
        assert about_checkpoints == [], (stored.name, about_checkpoints)
