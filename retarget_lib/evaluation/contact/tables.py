"""Tables 1, 3, 5 and 6 from the per-case metrics, the Table 3 ablation steps, stored results and
their re-run tolerances, and ``retarget evaluate --table contact``."""

from __future__ import annotations

import json
import time
from collections.abc import Mapping
from pathlib import Path

import numpy as np
import pandas as pd

from ...data.manifest import (
    CheckpointEntry,
    checkpoint_entries,
    default_checkpoint,
    table_checkpoints,
)
from ..paper import CONTACT_PAPER_METRICS, PAPER_TABLE1, PAPER_TABLE3, PAPER_TABLE5, PAPER_TABLE6
from ..results import StoredResult, compare_with_stored, load_result, write_result
from ..tdcn import write_table
from .cases import (
    CONTACT_PROFILES,
    CONTACT_SOURCE,
    CONTACT_TARGETS,
    EFULL_ROWS,
    ESO_ROWS,
    METRICS,
    REGISTRY_ROWS,
    TABLE1_ROWS,
    TABLE3_ROWS,
    contact_cases,
)
from .methods import contact_methods, evaluate_contact_methods

__all__ = [
    "stored_contact_results",
    "contact_row_checkpoints",
    "rerun_cases",
    "rerun_tolerance",
    "write_contact_tables",
    "contact_tables",
    "summary_table",
    "TABLE3_STEPS",
    "ablation_steps",
    "run_contact_evaluation",
]


def summary_table(
    per_case: pd.DataFrame, rows: tuple[str, ...], paper: Mapping[str, tuple], mask=None
) -> pd.DataFrame:
    """One row per table row: the mean of each of :data:`METRICS` over the cases (``mask``
    selects some), ``"ours <metric>"``, beside the paper's values ``paper`` (row -> the four
    :data:`~retarget_lib.evaluation.paper.CONTACT_PAPER_METRICS`), ``"paper <metric>"``."""
    data = per_case if mask is None else per_case[mask]
    ours = data.groupby("method")[list(METRICS)].mean()
    out = []
    for row in dict.fromkeys(list(rows) + list(paper)):
        r = {f"ours {m}": (ours.loc[row, m] if row in ours.index else np.nan) for m in METRICS}
        r.update(
            {
                f"paper {m}": v
                for m, v in zip(CONTACT_PAPER_METRICS, paper.get(row, (np.nan,) * 4), strict=False)
            }
        )
        out.append(pd.Series(r, name=row))
    cols = [
        c
        for m in METRICS
        for c in (f"ours {m}", f"paper {m}")
        if not (c.startswith("paper") and m not in CONTACT_PAPER_METRICS)
    ]
    return pd.DataFrame(out)[cols]


def contact_tables(per_case: pd.DataFrame) -> dict[str, pd.DataFrame]:
    """Tables 1, 3, 5 (skinny targets), 6 (bulky targets) from per-case metrics."""
    return {
        "table1": summary_table(per_case, TABLE1_ROWS, PAPER_TABLE1),
        "table3": summary_table(per_case, TABLE3_ROWS, PAPER_TABLE3),
        "table5": summary_table(per_case, TABLE1_ROWS, PAPER_TABLE5, per_case["body"] == "skinny"),
        "table6": summary_table(per_case, TABLE1_ROWS, PAPER_TABLE6, per_case["body"] == "bulky"),
    }


#: Table 3's ablation steps: each adds one ingredient to the row before it
TABLE3_STEPS = (
    ("Eskel", "Eskel+Efoot"),
    ("Eskel+Efoot", "Eskel+Efoot+Eint"),
    ("Eskel+Efoot+Eint w/o w", "Eskel+Efoot+Eint"),
    ("Eskel+Efoot+Eint", "Efull"),
    ("Efull", "Efull + ESO"),
)


def ablation_steps(
    table3: pd.DataFrame, steps: tuple[tuple[str, str], ...] = TABLE3_STEPS
) -> pd.DataFrame:
    """What each Table 3 step does to each metric, here and in the paper.

    Args:
        table3: :func:`contact_tables`'s ``"table3"`` (``ours <metric>`` and ``paper <metric>``
            columns).
        steps: ``(before, after)`` row pairs.

    Returns:
        One row per step and metric: ``before``, ``after``, ``ours change`` and ``paper change``
        (``after − before``) and ``same direction`` (both changes have the same sign; ``False`` if
        either is zero or missing).
    """
    out = []
    for before, after in steps:
        for metric in CONTACT_PAPER_METRICS:
            ours = table3.loc[after, f"ours {metric}"] - table3.loc[before, f"ours {metric}"]
            paper = table3.loc[after, f"paper {metric}"] - table3.loc[before, f"paper {metric}"]
            out.append(
                {
                    "step": f"{before} → {after}",
                    "metric": metric,
                    "ours change": ours,
                    "paper change": paper,
                    "same direction": bool(np.sign(ours) * np.sign(paper) > 0),
                }
            )
    return pd.DataFrame(out).set_index(["step", "metric"])


def contact_row_checkpoints(
    rows: tuple[str, ...] = TABLE1_ROWS + TABLE3_ROWS, runs: Mapping[str, Path] | None = None
) -> dict[str, CheckpointEntry | Path]:
    """Row -> the checkpoint that row runs (:func:`contact_methods`): a network row's own (or its
    ``runs`` replacement), the registry rows' defaults (TDCN, NKN); copy rows need none."""
    shipped, entries, runs = table_checkpoints("contact"), checkpoint_entries(), runs or {}
    out: dict[str, CheckpointEntry | Path] = {}
    for row in rows:
        base = EFULL_ROWS.get(row, row)
        if base in runs:
            out[row] = Path(runs[base])
        elif base in shipped:
            out[row] = shipped[base]
        elif row in REGISTRY_ROWS and default_checkpoint(REGISTRY_ROWS[row]) is not None:
            out[row] = entries[default_checkpoint(REGISTRY_ROWS[row])]
    return out


def stored_contact_results() -> StoredResult:
    """The stored per-case metrics of the contact tables on the shipped checkpoints (``results/
    contact_cases.csv``, written by ``retarget evaluate --table contact --profile fast``; one row
    per method and case), with its provenance and staleness
    (:func:`~retarget_lib.evaluation.results.load_result`).

    ESO makes the full run take ~20 min on 2 cores, so the notebooks read these and re-run a few
    cases live (:func:`rerun_cases`) to show that they reproduce.
    """
    return load_result("contact_cases", rows=contact_row_checkpoints())


#: relative tolerance of a live re-run against the stored table: feed-forward rows (networks, copy,
#: IK) reproduce to float rounding; ESO rows run 30 Adam steps per frame against colliding triangle
#: pairs found anew at every step, so a last-bit change in a matrix product (MKL picks its kernels
#: by CPU) can change which pairs collide and the optimisation takes another path. Measured on
#: hands_on_hips_008 -> otto, Ours (residual): foot height error 0.776-0.796 cm over MKL's code
#: paths (``MKL_CBWR``) on one AMD EPYC, 0.856 cm stored from another CPU; position MSE
#: 0.0900-0.0912. Every other value of that re-run agreed to 0.05 %.
RERUN_RTOL = {"feed-forward": 1e-3, "ESO": 2e-2}


#: the magnitude below which a tolerance is absolute (``rtol * floor``): 1 in every metric's unit,
#: 5 cm (a typical planted-foot distance) for the foot height error
RERUN_FLOOR = {"foot height error": 5.0}


def rerun_tolerance(method: str, metric: str, stored: float) -> float:
    """Largest ``|now - stored|`` accepted when a stored contact result is re-run (see
    :data:`RERUN_RTOL`): ``rtol * max(|stored|, floor)``."""
    rtol = RERUN_RTOL["ESO" if method in ESO_ROWS else "feed-forward"]
    return rtol * max(abs(stored), RERUN_FLOOR.get(metric, 1.0))


def rerun_cases(
    per_case: pd.DataFrame,
    clips: tuple[str, ...],
    targets: tuple[str, ...],
    rows: tuple[str, ...] = TABLE1_ROWS,
    profile: str = "fast",
) -> pd.DataFrame:
    """Re-evaluate some (clip, target) cases live and put the new metrics beside the stored ones.

    Returns:
        One row per (method, clip, target, metric) with ``stored``, ``now``, ``abs diff``,
        ``tolerance`` (:func:`rerun_tolerance`) and ``reproduces`` (within it, or both NaN).
    """
    methods, _ = contact_methods(rows)
    cases = [c for c in contact_cases(profile) if c.clip in clips and c.target.name in targets]
    now = evaluate_contact_methods(methods, cases, CONTACT_PROFILES[profile]["eval_every"])
    return compare_with_stored(
        now, per_case, ("method", "clip", "target"), METRICS, rerun_tolerance
    )


def run_contact_evaluation(
    out_dir: str | Path,
    profile: str = "fast",
    rows: tuple[str, ...] | None = None,
    device: str | None = None,
    runs: Mapping[str, Path] | None = None,
    command: str = "retarget evaluate --table contact --profile fast --out DIR",
) -> tuple[dict[str, pd.DataFrame], list[str]]:
    """Evaluate every Table 1/3 row with a shipped checkpoint on :func:`contact_cases`; write
    ``contact_table{1,3,5,6}.csv/.md`` and ``contact_cases.csv`` into ``out_dir``.

    Args:
        out_dir: output folder.
        profile: :data:`CONTACT_PROFILES` key.
        rows: evaluate only these rows and merge them into an existing ``contact_cases.csv`` of
            ``out_dir`` (replacing their old results); default every row, from scratch.
        device, runs: as :func:`contact_methods`.
        command: the command recorded in the provenance of ``contact_cases``.

    Returns:
        ``(tables, missing_rows)``.
    """
    out = Path(out_dir)
    t0 = time.perf_counter()
    methods, missing = contact_methods(rows or TABLE1_ROWS + TABLE3_ROWS, device, runs)
    cases = contact_cases(profile)
    per_case = evaluate_contact_methods(
        methods,
        cases,
        CONTACT_PROFILES[profile]["eval_every"],
        same={"Efull + ESO": "Ours", "Efull-residual + ESO": "Ours (residual)"},
    )
    if rows and (out / "contact_cases.csv").exists():
        old = pd.read_csv(out / "contact_cases.csv")
        per_case = pd.concat(
            [old[~old["method"].isin(per_case["method"].unique())], per_case], ignore_index=True
        )
        previous = out / "contact_cases.provenance.json"
        if previous.exists():  # say which rows are new and where the others come from
            before = json.loads(previous.read_text())
            command += (
                f" [rows {', '.join(sorted(set(methods)))} recomputed; the others kept from commit "
                f"{before['commit'][:12]}, {before['date']}]"
            )
    note = (
        f"Contact-aware retargeting, profile {profile}: source {CONTACT_SOURCE} (unseen), "
        f"{len(cases)} cases "
        f"(targets {CONTACT_TARGETS}); interpenetration x1000, vertex contact MSE and global "
        "position MSE "
        "in cm^2/cm; 'paper' columns: Villegas et al. 2021 (Mixamo). "
        + (f"Rows without a shipped checkpoint: {', '.join(missing)}." if missing else "")
    )
    tables = write_contact_tables(per_case, out, note)
    write_result(
        per_case,
        out,
        "contact_cases",
        command=command,
        profile=profile,
        checkpoints=contact_row_checkpoints(tuple(per_case["method"].unique()), runs),
        seconds=time.perf_counter() - t0,
    )
    return tables, missing


def write_contact_tables(
    per_case: pd.DataFrame, out_dir: str | Path, note: str
) -> dict[str, pd.DataFrame]:
    """:func:`contact_tables` of ``per_case`` written as ``contact_table{1,3,5,6}.csv/.md`` (each
    with ``note``) into ``out_dir`` (atomically); the per-case file with its provenance is written
    by :func:`run_contact_evaluation`.

    Returns:
        the tables.
    """
    out = Path(out_dir)
    tables = contact_tables(per_case)
    titles = {
        "table1": "Table 1",
        "table3": "Table 3 (ablation)",
        "table5": "Table 5 (skinny targets)",
        "table6": "Table 6 (bulky targets)",
    }
    for name, table in tables.items():
        write_table(table, out, f"contact_{name}", f"{titles[name]}. {note}")
    return tables
