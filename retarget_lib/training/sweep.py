"""Ablation sweeps on a scheduler: one ``submitit`` job per paper-table row (``retarget sweep``).

The rows of a table are the manifest's checkpoints with that ``table:`` (``table_checkpoints``;
each names its ``row:`` and ``config:``): 11 for ``tdcn`` (Kim et al. 2020, Table 4, with our
``ours-residual``), 6 for ``contact`` (Villegas et al. 2021, Table 3). :func:`submit` sends them as
one job array through :class:`submitit.AutoExecutor` — a Slurm job array on a cluster, the local
executor (subprocesses) elsewhere — each job running :func:`~retarget_lib.training.run.train_config`
into ``<out>/<row>/``. Nothing here schedules, retries or polls on its own: submitit does.

* **Resumable.** A job is a :class:`submitit.helpers.Checkpointable`: on a Slurm time limit or
  preemption submitit requeues it, and it continues from ``<out>/<row>/last.pt`` (``resume``);
  submitting the same sweep again skips the finished rows and resumes the others.
* **Several GPUs per row.** ``gpus_per_row > 1`` starts that many tasks per job; each exports the
  ``torchrun`` variables (:class:`submitit.helpers.TorchDistributedEnvironment`) and trains as one
  rank of :mod:`.distributed`.
* **State.** ``<out>/sweep.json`` records the table, rows, overrides and job ids (written
  atomically); :func:`sweep_status` reads it with the run folders (``final.pt``: done;
  ``losses.csv``: the step reached; submitit's result file: the error of a failed job).
* **Collecting.** :func:`finished_rows` gives the ``final.pt`` of every finished row, which
  ``retarget evaluate --runs <out>`` puts in the table instead of the shipped checkpoint.
"""

from __future__ import annotations

import json
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import submitit

from ..data.manifest import table_checkpoints
from ..errors import RetargetInputError
from ..files import REPO_ROOT, atomic_write
from .run import train_config

__all__ = [
    "TABLES",
    "SweepError",
    "RowStatus",
    "table_rows",
    "TrainJob",
    "submit",
    "wait",
    "sweep_status",
    "finished_rows",
]

#: ``--table`` names
TABLES: tuple[str, ...] = ("tdcn", "contact")
STATE_FILE = "sweep.json"


class SweepError(RetargetInputError):
    """A sweep request or folder that cannot be used (unknown table or row, no ``sweep.json``)."""


def table_rows(table: str, rows: Sequence[str] | None = None) -> dict[str, Path]:
    """Row name -> config file of ``table`` (manifest order), optionally only ``rows``.

    Raises:
        SweepError: an unknown table or row (the known ones are named).
    """
    if table not in TABLES:
        raise SweepError(f"--table {table!r}: choose from {', '.join(TABLES)}")
    every = {row: REPO_ROOT / entry.config for row, entry in table_checkpoints(table).items()}
    unknown = [r for r in rows or () if r not in every]
    if unknown:
        raise SweepError(
            f"--rows {', '.join(unknown)}: not rows of table {table}; rows: {', '.join(every)}"
        )
    return {r: every[r] for r in (rows or every)}


class TrainJob(submitit.helpers.Checkpointable):
    """What one array task runs: a resumable :func:`~retarget_lib.training.run.train_config`.

    Pickled by submitit into the job folder; on a time limit or preemption submitit calls the
    inherited ``checkpoint()``, which resubmits the same call — it resumes from ``last.pt``.
    """

    def __call__(
        self,
        config: str,
        out: str,
        overrides: Sequence[str],
        profile: str | None,
        device: str,
        amp: bool,
    ) -> str:
        if (
            submitit.JobEnvironment().num_tasks > 1
        ):  # one rank per task, as torchrun would start them
            submitit.helpers.TorchDistributedEnvironment().export(overwrite=True)
        return str(
            train_config(config, overrides, profile, out, resume=True, device=device, amp=amp).final
        )


def _executor(
    out: Path,
    cluster: str,
    gpus_per_row: int,
    timeout_min: int,
    partition: str | None,
    parallel: int | None,
    table: str,
) -> submitit.AutoExecutor:
    executor = submitit.AutoExecutor(
        folder=out / "jobs", cluster=None if cluster == "auto" else cluster
    )
    params = dict(
        name=f"retarget-{table}",
        timeout_min=int(timeout_min),
        tasks_per_node=max(gpus_per_row, 1),
        nodes=1,
    )
    if executor.cluster == "slurm":
        params.update(
            gpus_per_node=gpus_per_row, cpus_per_task=4, slurm_array_parallelism=parallel or 64
        )
        if partition:
            params["slurm_partition"] = partition
    executor.update_parameters(**params)
    return executor


def submit(
    table: str,
    out: str | os.PathLike,
    overrides: Sequence[str] = (),
    profile: str | None = None,
    rows: Sequence[str] | None = None,
    cluster: str = "auto",
    device: str = "auto",
    amp: bool = False,
    gpus_per_row: int = 0,
    timeout_min: int = 24 * 60,
    partition: str | None = None,
    parallel: int | None = None,
) -> dict:
    """Submit one training job per row of ``table`` that has no ``final.pt`` yet in ``out``.

    Args:
        table: ``tdcn`` or ``contact``.
        out: sweep folder: ``<out>/<row>/`` per row, ``<out>/jobs/`` submitit's files,
            ``<out>/sweep.json``.
        overrides: ``key=value`` config overrides applied to every row.
        profile: ``fast`` or ``paper``.
        rows: only these rows (default: all of the table).
        cluster: ``auto`` (Slurm when ``srun`` is on the PATH, else local), ``slurm`` or ``local``.
        device, amp: as ``retarget train``.
        gpus_per_row: GPUs (= processes) per row on Slurm; 0 = a CPU job.
        timeout_min: wall-time limit per job (a job that reaches it is requeued and resumes).
        partition: Slurm partition.
        parallel: at most this many rows at once (Slurm array parallelism).

    Returns:
        row -> ``submitit.Job`` of the rows submitted now (``.job_id``; :func:`wait` waits for
        them).

    Raises:
        SweepError: an unknown table or row.
    """
    out = Path(out).resolve()
    configs = table_rows(table, rows)
    pending = {r: c for r, c in configs.items() if not (out / _folder(r) / "final.pt").exists()}
    state = _read_state(out) if (out / STATE_FILE).exists() else {"table": table, "rows": {}}
    if state["table"] != table:
        raise SweepError(f"{out}: holds a sweep of table {state['table']!r}, not {table!r}")
    jobs = {}
    if pending:
        executor = _executor(out, cluster, gpus_per_row, timeout_min, partition, parallel, table)
        n = len(pending)
        submitted = executor.map_array(
            TrainJob(),
            [str(c) for c in pending.values()],
            [str(out / _folder(r)) for r in pending],
            [list(overrides)] * n,
            [profile] * n,
            [device] * n,
            [amp] * n,
        )
        jobs = dict(zip(pending, submitted, strict=False))
        state["cluster"] = executor.cluster
    state.update(profile=profile, overrides=list(overrides))
    for r in configs:
        entry = state["rows"].setdefault(r, {})
        entry.update(config=str(configs[r]), out=_folder(r))
        if r in jobs:
            entry["job_id"] = jobs[r].job_id
    out.mkdir(parents=True, exist_ok=True)
    with atomic_write(out / STATE_FILE, "w") as f:
        json.dump(state, f, indent=1)
    return jobs


def wait(jobs: dict) -> None:
    """Block until the jobs :func:`submit` returned have ended (finished, failed or cancelled)."""
    for job in jobs.values():
        job.wait()


def _folder(row: str) -> str:
    """A row's run folder name (row names hold spaces and ``+``, e.g. ``Efull + ESO``)."""
    return "".join(c if c.isalnum() or c in "-_" else "_" for c in row)


def _read_state(out: Path) -> dict:
    path = out / STATE_FILE
    if not path.is_file():
        raise SweepError(f"{out}: no {STATE_FILE} (not a `retarget sweep` folder)")
    with open(path) as f:
        return json.load(f)


@dataclass(frozen=True)
class RowStatus:
    """One row of :func:`sweep_status`.

    Attributes:
        row: the table row.
        state: ``done``, ``running`` (a ``losses.csv`` is being written), ``pending`` (nothing
            yet), or ``failed`` (submitit recorded an error).
        step: steps logged so far.
        job_id: the scheduler's id of the last submission.
        detail: the last line of a failed job's error.
    """

    row: str
    state: str
    step: int
    job_id: str
    detail: str = ""


def _failure(out: Path, job_id: str) -> str:
    """The last line of the error submitit recorded for ``job_id`` (``""``: none)."""
    for result in sorted((out / "jobs").glob(f"{job_id}_*_result.pkl")):
        outcome, value = submitit.core.utils.pickle_load(result)
        if outcome == "error":
            return str(value).strip().splitlines()[-1]
    return ""


def sweep_status(out: str | os.PathLike) -> list[RowStatus]:
    """The state of every row of the sweep in ``out`` (from its files; no scheduler query).

    Raises:
        SweepError: ``out`` is not a sweep folder.
    """
    out = Path(out).resolve()
    state = _read_state(out)
    statuses = []
    for row, entry in state["rows"].items():
        run, job_id = out / entry["out"], entry.get("job_id", "")
        log = run / "losses.csv"
        step = max(sum(1 for _ in open(log)) - 1, 0) if log.exists() else 0
        failure = _failure(out, job_id) if job_id else ""
        kind = (
            "done"
            if (run / "final.pt").exists()
            else "failed"
            if failure
            else "running"
            if log.exists()
            else "pending"
        )
        statuses.append(RowStatus(row, kind, step, job_id, failure))
    return statuses


def finished_rows(out: str | os.PathLike) -> dict[str, Path]:
    """Row -> ``final.pt`` of every finished row of the sweep in ``out``.

    Raises:
        SweepError: ``out`` is not a sweep folder.
    """
    out = Path(out).resolve()
    return {
        s.row: out / _read_state(out)["rows"][s.row]["out"] / "final.pt"
        for s in sweep_status(out)
        if s.state == "done"
    }
