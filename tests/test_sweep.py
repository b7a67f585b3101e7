"""`retarget sweep` (retarget_lib.training.sweep): two Table 4 rows as a job array on submitit's
local executor (tiny width, 2 steps), their status, a second submission that skips them, and
`evaluate`'s use of the finished rows. Each job is a fresh Python process (torch import, the
TDCN training clips): about a minute on the busy 2-core machine."""

import pytest

from retarget_lib.cli import main
from retarget_lib.evaluation.tdcn import tdcn_methods
from retarget_lib.training import sweep

pytestmark = [pytest.mark.data, pytest.mark.slow]

ROWS = ["ours", "A3"]
TINY = [
    "train.steps=2",
    "train.checkpoint_every=1",
    "model.channels=16",
    "model.disc_channels=16",
    "train.batch=4",
]


@pytest.fixture(scope="module")
def swept(tmp_path_factory):
    out = tmp_path_factory.mktemp("sweep")
    assert (
        main(
            [
                "sweep",
                "--table",
                "tdcn",
                "--out",
                str(out),
                "--rows",
                *ROWS,
                "--cluster",
                "local",
                "--device",
                "cpu",
                "--wait",
                *TINY,
            ]
        )
        == 0
    )
    return out


def test_local_sweep_trains_each_row_in_its_own_job(swept, capsys):
    statuses = {s.row: s for s in sweep.sweep_status(swept)}
    assert set(statuses) == set(ROWS)
    assert all(s.state == "done" and s.step == 2 and s.job_id for s in statuses.values())
    assert (swept / "A3" / "final.pt").exists() and (swept / "jobs").is_dir()
    assert main(["sweep", "--table", "tdcn", "--out", str(swept), "--status"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert any(line.startswith("ours") and "done" in line for line in lines)


def test_resubmitting_skips_finished_rows(swept, capsys):
    assert sweep.submit("tdcn", swept, TINY, rows=ROWS, cluster="local", device="cpu") == {}


def test_evaluate_takes_the_finished_rows(swept):
    finished = sweep.finished_rows(swept)
    assert finished == {r: swept / r / "final.pt" for r in ROWS}
    methods, _ = tdcn_methods(runs=finished)
    assert {"ours", "A3", "copy"} <= set(methods)
    assert (
        methods["ours"].args[0].config["channels"] == 16
    )  # the swept, tiny generator, not the shipped one


def test_bad_sweep_requests_exit_2_with_one_line(tmp_path, capsys):
    assert main(["sweep", "--table", "tdcn", "--out", str(tmp_path), "--status"]) == 2
    assert main(["sweep", "--table", "tdcn", "--out", str(tmp_path), "--rows", "A9"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 2 and "no sweep.json" in err[0] and "A9" in err[1]
