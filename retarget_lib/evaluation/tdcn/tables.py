"""Table 4 from the per-case scores: the rows and their checkpoints, the paper's numbers and the
ablation orderings, Markdown, stored results and their re-run tolerances, and ``retarget evaluate
--table tdcn``."""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence
from functools import partial
from pathlib import Path

import numpy as np
import pandas as pd

from ...data.manifest import CheckpointEntry, table_checkpoints
from ...files import atomic_write
from ...methods.registry import get_method
from ...methods.tdcn import load_generator, retarget_motion_with
from ..paper import PAPER_TABLE4, TABLE4_COLUMNS
from ..results import StoredResult, compare_with_stored, load_result, write_result
from .cases import (
    WINDOWED_ROW,
    EvalCase,
    Method,
    cmu_cases,
    evaluate_methods,
    mixamo_convention_cases,
    tdcn_cases,
)


def table4_row(per_case: pd.DataFrame, squared_height: bool = False) -> pd.Series:
    """Scenario means and their average, short then long, in :data:`TABLE4_COLUMNS` order.

    A scenario without cases is NaN; "avg" is the mean over the scenarios present.
    """
    suffix = "_h2" if squared_height else ""
    values = []
    for length in ("short", "long"):
        by = per_case.groupby("scenario")[length + suffix].mean().reindex([1, 2, 3, 4])
        values += list(by.values) + [float(by.mean())]
    return pd.Series(values, index=list(TABLE4_COLUMNS))


def table_from_cases(per_case: pd.DataFrame, squared_height: bool = False) -> pd.DataFrame:
    """Table 4 from per-case results (:func:`evaluate_methods`): a row per method (in order of
    appearance) with ``ours <column>`` and, for rows the paper reports, ``paper <column>``."""
    rows = {}
    for name, res in per_case.groupby("method", sort=False):
        row = {f"ours {c}": v for c, v in table4_row(res, squared_height).items()}
        paper = PAPER_TABLE4.get(name) if not squared_height else None
        if paper is not None:
            row.update({f"paper {c}": v for c, v in zip(TABLE4_COLUMNS, paper, strict=False)})
        rows[name] = row
    return pd.DataFrame(rows).T


def tdcn_table(
    methods: Mapping[str, Method], cases: list[EvalCase] | None = None, squared_height: bool = False
) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Table 4: our measurement of each method, and the paper's numbers beside it.

    Args:
        methods: row name -> method (row names as in :data:`PAPER_TABLE4` get the paper's numbers).
        cases: test cases (default :func:`tdcn_cases`).
        squared_height: report the ``H²`` variant.

    Returns:
        ``(table, per_case)``: ``table`` has a row per method with our columns and, for rows the
        paper reports, ``paper <column>`` columns; ``per_case`` has every case's numbers.
    """
    per_case = evaluate_methods(methods, cases if cases is not None else tdcn_cases())
    return table_from_cases(per_case, squared_height), per_case


def paper_comparison(table: pd.DataFrame) -> pd.DataFrame:
    """The short and long averages of :func:`tdcn_table`'s result, ours beside the paper's.

    Returns:
        One row per method, columns ``ours short avg``, ``paper short avg``, ``ours long avg``,
        ``paper long avg`` (NaN where the paper has no such row).
    """
    cols = [f"{who} {length} avg" for length in ("short", "long") for who in ("ours", "paper")]
    return table.reindex(columns=cols).astype(float)


def ordering_checks(table: pd.DataFrame, reference: str = "ours") -> pd.DataFrame:
    """Does ``reference`` beat each other Table 4 row here as it does in the paper?

    For every measured row that the paper also reports, compares ``reference`` with it on the
    short and the long average; the paper's direction comes from :data:`PAPER_TABLE4`, not from
    a hand-written list.

    Returns:
        One row per compared method: the paper's and our ratio ``row / reference`` (> 1 means
        ``reference`` is better) and whether the direction reproduces.
    """
    rows = {}
    for name in table.index:
        if name == reference or name not in PAPER_TABLE4 or reference not in table.index:
            continue
        row = {}
        for length in ("short", "long"):
            col = f"{length} avg"
            paper = table.loc[name, f"paper {col}"] / table.loc[reference, f"paper {col}"]
            ours = table.loc[name, f"ours {col}"] / table.loc[reference, f"ours {col}"]
            row.update(
                {
                    f"paper {col} ratio": paper,
                    f"ours {col} ratio": ours,
                    f"{length} reproduces": bool((paper > 1) == (ours > 1)),
                }
            )
        rows[name] = row
    return pd.DataFrame(rows).T


def markdown_table(table: pd.DataFrame, digits: int = 2) -> str:
    """A pipe table of ``table`` (index as the first column), numbers with ``digits`` decimals."""

    def cell(v):
        return (
            f"{v:.{digits}f}"
            if isinstance(v, (float, np.floating)) and np.isfinite(v)
            else ("" if v is None or (isinstance(v, float) and np.isnan(v)) else str(v))
        )

    head = [str(table.index.name or "")] + [str(c) for c in table.columns]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for idx, row in table.iterrows():
        lines.append("| " + " | ".join([str(idx)] + [cell(v) for v in row.values]) + " |")
    return "\n".join(lines)


def write_table(
    table: pd.DataFrame, out_dir: str | Path, name: str, note: str = ""
) -> tuple[Path, Path]:
    """Write ``<name>.csv`` and ``<name>.md`` (atomically) into ``out_dir``."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    csv_path, md_path = out_dir / f"{name}.csv", out_dir / f"{name}.md"
    with atomic_write(csv_path, "w") as f:
        table.to_csv(f, float_format="%.4f")
    text = (f"{note}\n\n" if note else "") + markdown_table(table) + "\n"
    with atomic_write(md_path, "w") as f:
        f.write(text)
    return csv_path, md_path


#: the registry's copy baselines in every Table 4: ours (root scaled by the leg ratio), the papers'
#: row (root displacements unscaled, :func:`~retarget_lib.methods.copy.copy_unscaled`) and the
#: rest-compensated copy
COPY_ROWS = ("copy", "copy-unscaled", "copy-rest")


def tdcn_methods(
    only: Sequence[str] | None = None,
    device: str | None = None,
    runs: Mapping[str, Path] | None = None,
) -> tuple[dict[str, Method], list[str]]:
    """The methods to put in Table 4: the registry's copy baselines (:data:`COPY_ROWS`), every
    Table 4 row whose
    checkpoint is shipped (``table: tdcn`` in the manifest; loaded once, by the registry method its
    entry names), then our shipped variants that are not rows of the paper (e.g. ``ours-residual``,
    no paper numbers); and the paper's rows still without one (reported, never faked).

    Args:
        only: keep only these row names (default: all; a name that is not a row is ignored).
        device: where the generators run (a ``--device`` name; default the CPU).
        runs: row -> checkpoint trained for that row (e.g. the finished rows of a ``retarget
            sweep``, :func:`~retarget_lib.training.sweep.finished_rows`), used instead of the
            shipped one.
    """
    keep = (lambda row: True) if only is None else (lambda row: row in only)
    methods: dict[str, Method] = {
        name: get_method(name).retargeter() for name in COPY_ROWS if keep(name)
    }
    shipped = table_checkpoints("tdcn")
    runs = runs or {}
    missing = []
    for row in PAPER_TABLE4:
        entry = shipped.get(row)
        if entry is None:
            missing.append(row)
        elif keep(row):
            methods[row] = get_method(entry.method).retargeter(runs.get(row, entry.id), device)
    for row, entry in shipped.items():  # our variants (not rows of the paper), e.g. "ours-residual"
        if row not in PAPER_TABLE4 and keep(row):
            methods[row] = get_method(entry.method).retargeter(runs.get(row, entry.id), device)
    return methods, missing


#: the manifest's ``table:`` of the checkpoints trained on the Mixamo-convention profile
MIXAMO_CONVENTION_TABLE = "tdcn-mixamo-convention"


def mixamo_convention_checkpoints() -> dict[str, CheckpointEntry]:
    """Row -> checkpoint of the Mixamo-convention Table 4: every checkpoint trained on that
    profile (``table: tdcn-mixamo-convention`` in the manifest), then the registry methods' default
    checkpoints of Table 4 (``--method tdcn``'s residual default, ``--method nkn``'s Baseline;
    trained on whatever their entries say) under their own row names, where no row of the profile
    has that name."""
    rows = dict(table_checkpoints(MIXAMO_CONVENTION_TABLE))
    for row, entry in table_checkpoints("tdcn").items():
        if entry.default and row not in rows:
            rows[row] = entry
    return rows


def mixamo_convention_methods(device: str | None = None) -> dict[str, Method]:
    """The methods of the Mixamo-convention Table 4: :data:`COPY_ROWS` and
    :func:`mixamo_convention_checkpoints`, each through the registry method its entry names."""
    methods: dict[str, Method] = {name: get_method(name).retargeter() for name in COPY_ROWS}
    for row, entry in mixamo_convention_checkpoints().items():
        methods[row] = get_method(entry.method).retargeter(entry.id, device)
    return methods


#: relative tolerance of a live re-run of stored Table 4 numbers: every method is feed-forward
#: (float32 networks, float64 metric), so a re-run differs only by kernel rounding (measured below
#: 1e-5 relative between CPUs); the stored CSV keeps 7 significant digits
RERUN_RTOL = 1e-3


#: the magnitude below which the tolerance is absolute (``copy-rest`` scores 0 by construction)
RERUN_FLOOR = 1e-3


#: the columns that identify one Table 4 case; the first is the row (method)
CASE_KEYS = ("method", "scenario", "source", "target", "clip")


def rerun_tolerance(method: str, metric: str, stored: float) -> float:
    """Largest ``|now - stored|`` accepted when a stored Table 4 case is re-run: ``RERUN_RTOL *
    max(|stored|, RERUN_FLOOR)`` for every method and metric."""
    return RERUN_RTOL * max(abs(stored), RERUN_FLOOR)


def rerun_subset(cases: Sequence[EvalCase], per_group: int = 1) -> list[EvalCase]:
    """The live re-run's cases: the first ``per_group`` cases of each scenario (CMU cases: of each
    clip), in order, so every scenario and clip is checked."""
    seen: dict[tuple, int] = {}
    out = []
    for c in cases:
        group = (c.scenario, c.clip if c.scenario == 0 else "")
        if seen.get(group, 0) < per_group:
            seen[group] = seen.get(group, 0) + 1
            out.append(c)
    return out


def rerun_cases(
    stored: pd.DataFrame,
    methods: Mapping[str, Method],
    cases: Sequence[EvalCase],
    per_group: int = 1,
    metrics: Sequence[str] = ("short", "long"),
) -> pd.DataFrame:
    """Re-evaluate a few stored Table 4 cases live (:func:`rerun_subset`) and put the new numbers
    beside the stored ones (:func:`~retarget_lib.evaluation.results.compare_with_stored`,
    :func:`rerun_tolerance`).

    Args:
        stored: the stored per-case frame (``load_result("table4_cases").frame``).
        methods: row name -> method; each is re-run on the subset.
        cases: the cases the stored frame was computed on.
        per_group: cases per scenario (per clip for CMU cases).
        metrics: the compared columns.
    """
    now = evaluate_methods(methods, rerun_subset(cases, per_group))
    return compare_with_stored(now, stored, CASE_KEYS, metrics, rerun_tolerance)


def stored_table4(name: str = "table4_cases") -> StoredResult:
    """A stored Table 4 result from ``results/`` (``table4_cases``, ``table4_cmu_cases`` or
    ``table4_windowed_cases``; written by :func:`run_tdcn_evaluation`), with its provenance and
    staleness against the shipped checkpoints
    (:func:`~retarget_lib.evaluation.results.load_result`)."""
    if name == "table4_mixamo_convention_cases":
        return load_result(name, rows=mixamo_convention_checkpoints())
    rows = table_checkpoints("tdcn")
    if name == "table4_windowed_cases":
        rows = {WINDOWED_ROW: rows["ours"]} if "ours" in rows else {}
    return load_result(name, rows=rows)


def _row_checkpoints(rows: Sequence[str], runs: Mapping[str, Path] | None) -> dict:
    """row -> the checkpoint it was evaluated with (a sweep run's file, else the shipped entry)."""
    shipped, runs = table_checkpoints("tdcn"), runs or {}
    return {row: runs.get(row, shipped[row]) for row in rows if row in shipped}


def run_tdcn_evaluation(
    out_dir: str | Path,
    device: str | None = None,
    runs: Mapping[str, Path] | None = None,
    command: str = "retarget evaluate --table tdcn --out DIR",
) -> tuple[pd.DataFrame, list[str]]:
    """Evaluate :func:`tdcn_methods` on the four scenarios; write ``table4.csv/.md`` (normalised
    MSE, paper beside ours), ``table4_h2.csv/.md`` (squared-height variant), and three per-case
    files with their provenance (:func:`~retarget_lib.evaluation.results.write_result`):
    ``table4_cases`` (every row, every pair), ``table4_cmu_cases`` (every row on the real CMU clips,
    :func:`cmu_cases`) and ``table4_windowed_cases`` ("ours" with a re-centred window per frame);
    and ``table4_mixamo_convention.csv/.md`` with its per-case file
    (:func:`mixamo_convention_cases`, :func:`mixamo_convention_methods`).

    Args:
        out_dir: output folder.
        device, runs: as :func:`tdcn_methods`.
        command: the command recorded in the provenance.

    Returns:
        ``(table, missing_rows)``.
    """
    methods, missing = tdcn_methods(device=device, runs=runs)
    checkpoints = _row_checkpoints(list(methods), runs)
    t0 = time.perf_counter()
    cases = tdcn_cases()
    table, per_case = tdcn_table(methods, cases)
    table_h2 = table_from_cases(per_case, squared_height=True)
    note = (
        "Normalised MSE of global joint positions (cm² / H in cm; NKN/TDCN definition) on the "
        "synthetic four-scenario split; 'paper' columns are Kim et al. 2020, Table 4 (Mixamo). "
        "copy-rest is the synthetic ground truth's own definition, so it scores 0 by construction. "
        "copy-unscaled is the papers' copy row (NKN's 'copy input quaternions and velocities': "
        "the root's displacements not scaled); copy scales them by the leg ratio. "
        "Short: 120-frame windows as the authors' code cuts them (the last one overlapping). "
        + (f"Rows without a trained checkpoint yet: {', '.join(missing)}." if missing else "")
    )
    write_table(table, out_dir, "table4", note)
    write_table(table_h2, out_dir, "table4_h2", "Same, divided by H² (unit-free).")
    write_result(
        per_case,
        out_dir,
        "table4_cases",
        command=command,
        checkpoints=checkpoints,
        profile="fast",
        seconds=time.perf_counter() - t0,
    )
    t0 = time.perf_counter()
    _, real = tdcn_table(methods, cmu_cases())
    write_result(
        real,
        out_dir,
        "table4_cmu_cases",
        command=command,
        checkpoints=checkpoints,
        profile="fast",
        seconds=time.perf_counter() - t0,
    )
    if "ours" in checkpoints:
        t0 = time.perf_counter()
        ours = checkpoints["ours"]
        generator, _ = load_generator(
            ours.id if isinstance(ours, CheckpointEntry) else ours, device
        )
        windowed = evaluate_methods(
            {WINDOWED_ROW: partial(retarget_motion_with, generator, windowed=True)}, cases
        )
        write_result(
            windowed,
            out_dir,
            "table4_windowed_cases",
            command=command,
            checkpoints={WINDOWED_ROW: ours},
            profile="fast",
            seconds=time.perf_counter() - t0,
        )
    t0 = time.perf_counter()
    mc_table, mc_per_case = tdcn_table(mixamo_convention_methods(device), mixamo_convention_cases())
    write_table(
        mc_table,
        out_dir,
        "table4_mixamo_convention",
        "Normalised MSE (as table4.md) on the Mixamo-convention synthetic profile: every character "
        "in "
        "one T-pose rest, each clip authored on every character (its own version is the ground "
        "truth), "
        "as on Mixamo. Rows trained on this profile, and the default TDCN.",
    )
    write_result(
        mc_per_case,
        out_dir,
        "table4_mixamo_convention_cases",
        command=command,
        checkpoints=mixamo_convention_checkpoints(),
        profile="fast",
        seconds=time.perf_counter() - t0,
    )
    return table, missing
