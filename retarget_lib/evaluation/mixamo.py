"""TDCN's Table 4 on a reviewer's ``mixamo-local`` folder, with the paper's protocol (Kim et al.
2020, Sec. 5 and 6.1).

**Ground truth** is the target character's own Mixamo clip of the same motion (not the synthetic
convention of :mod:`retarget_lib.evaluation.tdcn`). **Cases** are every ordered pair of different
characters that perform the same motion (same file name) with the same frame count, once both
are expressed at the ground truth's frame rate (:func:`same_length`); the rest of the folder is
reported as coverage, never as an error.

**Scenarios** (Tables 2-3, :mod:`retarget_lib.data.mixamo_splits`): by default a target is *seen*
if it is one of the manifest's TDCN training characters, and a motion is *unseen* if it is performed
by a source of scenario 3 or 4 (Sporty Granny, Claire, Mutant) and by no source of scenario 1 or 2 —
our rule (the paper names its test motions by Mixamo page, which file names do not carry), which
gives exactly the paper's eight pairs their scenarios (pages 45, 51, 52 unseen; 18, 23, 28, 33
seen). A folder's ``splits.yaml`` replaces either list
(:func:`~retarget_lib.data.mixamo_splits.folder_split`); training follows the same split, and
``table4.md`` states the split in force.
Table 4 is reported twice: over the paper's eight (source, target) pairs, on every motion they
share, and over every pair of the folder by the same rule.

**Protocol** (Sec. 6.1): the source is resampled to :data:`METHOD_FPS` (the methods' rate, and
Mixamo's download default) and retargeted onto the target's skeleton (the ground-truth file's rest
offsets); "long" retargets the whole clip, "short" every 120-frame chunk on its own
(:func:`~retarget_lib.evaluation.tdcn.short_chunks`). The output is compared with the ground truth
at the ground truth's frame times (:func:`~retarget_lib.evaluation.tdcn.aligned_positions`; the
output is interpolated when the ground truth was exported at another rate). The metric is
:func:`~retarget_lib.evaluation.tdcn.normalized_mse` (cm² / H in cm, H of the target skeleton),
also on root-relative positions (root subtracted from both, i.e. pose only).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from functools import partial
from pathlib import Path

import numpy as np
import pandas as pd

from ..core.motion import Motion
from ..data.manifest import mixamo_local_dir
from ..data.mixamo_splits import folder_split, paper_pairs
from ..data.sources.mixamo_local import MixamoFolder, load_mixamo_folder
from ..files import atomic_write
from ..methods.tdcn import load_generator, retarget_motion_with
from .tdcn import (
    EvalCase,
    Method,
    evaluate_methods,
    markdown_table,
    normalized_mse,
    short_chunks,
    table_from_cases,
    tdcn_methods,
    truth_frames,
)

__all__ = [
    "METHOD_FPS",
    "CASE_COLUMNS",
    "same_length",
    "mixamo_scores",
    "mixamo_tdcn_cases",
    "is_paper_case",
    "checkpoint_method",
    "mixamo_tdcn_per_case",
    "run_mixamo_tdcn_evaluation",
]

#: frame rate the methods run at (the source is resampled to it)
METHOD_FPS = 30.0
#: the per-case CSV's columns: the required ones first, then the context
CASE_COLUMNS = (
    "source",
    "target",
    "motion",
    "method",
    "frames",
    "nmse",
    "nmse_root_relative",
    "scenario",
    "paper_pair",
    "nmse_short",
    "nmse_short_root_relative",
    "short_chunks",
    "source_fps",
    "truth_fps",
)


def same_length(source: Motion, truth: Motion) -> bool:
    """Do two clips have the same frame count once the source is expressed at the ground truth's
    rate (``(T_s - 1) · fps_t / fps_s + 1`` rounds to ``T_t``)?"""
    return int(round((source.num_frames - 1) * truth.fps / source.fps)) + 1 == truth.num_frames


def mixamo_scores(pred: np.ndarray, truth: np.ndarray, height: float) -> dict[str, float]:
    """The folder protocol's scores of one comparison (cm²/cm): ``""`` on global positions and
    ``"_root_relative"`` with each frame's root subtracted from prediction and ground truth."""
    return {
        "": normalized_mse(pred, truth, height),
        "_root_relative": normalized_mse(pred - pred[:, :1], truth - truth[:, :1], height),
    }


def mixamo_tdcn_cases(folder: MixamoFolder) -> tuple[list[EvalCase], pd.DataFrame, pd.DataFrame]:
    """The folder's cases and its coverage.

    Returns:
        ``(cases, coverage, skipped)``: the :class:`~retarget_lib.evaluation.tdcn.EvalCase` list
        (source at :data:`METHOD_FPS`, target = the ground-truth clip's skeleton, truth at its own
        rate); ``coverage``, one row per paper pair (``scenario, source, target, motions,
        status``); ``skipped``, the ordered pairs sharing a motion whose frame counts differ.
    """
    performers = folder.performers()
    split = folder_split(folder)
    cases, skipped = [], []
    for motion, who in performers.items():
        for src in sorted(who):
            for tgt in sorted(who - {src}):
                a, b = folder.clips[src, motion], folder.clips[tgt, motion]
                if not same_length(a, b):
                    skipped.append(
                        {
                            "source": src,
                            "target": tgt,
                            "motion": motion,
                            "why": f"{a.num_frames} frames at {a.fps:g} fps vs {b.num_frames} at "
                            f"{b.fps:g} fps",
                        }
                    )
                    continue
                cases.append(
                    EvalCase(
                        split.scenario(tgt, motion),
                        src,
                        tgt,
                        motion,
                        a.resample(METHOD_FPS),
                        b.skeleton,
                        b,
                    )
                )
    present = {c.name for c in folder.characters}
    rows = []
    for (src, tgt), scenario in paper_pairs().items():
        motions = sorted(
            c.clip
            for c in cases
            if (c.source_name, c.target_name) == (src, tgt) and is_paper_case(c)
        )
        absent = [n for n in (src, tgt) if n not in present]
        status = (
            "present"
            if motions
            else f"missing: no {', '.join(absent)} folder"
            if absent
            else "missing: no shared motion with the same frame count"
        )
        rows.append(
            {
                "scenario": scenario,
                "source": src,
                "target": tgt,
                "motions": "; ".join(motions),
                "status": status,
            }
        )
    return (
        cases,
        pd.DataFrame(rows),
        pd.DataFrame(skipped, columns=["source", "target", "motion", "why"]),
    )


def is_paper_case(case: EvalCase) -> bool:
    """Is ``case`` one of the paper's eight pairs (Table 3) on a motion of that pair's scenario?"""
    return paper_pairs().get((case.source_name, case.target_name)) == case.scenario


def checkpoint_method(path: str | Path) -> tuple[str, Method]:
    """A given TDCN or NKN checkpoint as a Table 4 row: ``("<row> (<file stem>)", method)``."""
    generator, config = load_generator(path)
    return f"{config['model']['row']} ({Path(path).stem})", partial(retarget_motion_with, generator)


def mixamo_tdcn_per_case(methods: Mapping[str, Method], cases: list[EvalCase]) -> pd.DataFrame:
    """Every method on every case: one row per (source, target, motion, method),
    :data:`CASE_COLUMNS`."""
    per_case = evaluate_methods(methods, cases, scores=mixamo_scores)
    by_case = {(c.source_name, c.target_name, c.clip): c for c in cases}
    extra = []
    for src, tgt, motion in zip(
        per_case["source"], per_case["target"], per_case["clip"], strict=False
    ):
        c = by_case[src, tgt, motion]
        extra.append(
            {
                "frames": len(
                    truth_frames(
                        c.source.num_frames, c.source.fps, 0, c.truth.num_frames, c.truth.fps
                    )
                ),
                "paper_pair": is_paper_case(c),
                "short_chunks": len(short_chunks(c.source.num_frames)),
                "source_fps": c.source.fps,
                "truth_fps": c.truth.fps,
            }
        )
    per_case = pd.concat([per_case, pd.DataFrame(extra)], axis=1).rename(
        columns={
            "clip": "motion",
            "long": "nmse",
            "long_root_relative": "nmse_root_relative",
            "short": "nmse_short",
            "short_root_relative": "nmse_short_root_relative",
        }
    )
    return per_case[list(CASE_COLUMNS)]


def _table4(per_case: pd.DataFrame) -> pd.DataFrame:
    """:func:`~retarget_lib.evaluation.tdcn.table_from_cases` of per-case rows in
    :data:`CASE_COLUMNS`."""
    if per_case.empty:
        return pd.DataFrame()
    return table_from_cases(per_case.rename(columns={"nmse": "long", "nmse_short": "short"}))


def run_mixamo_tdcn_evaluation(
    out_dir: str | Path,
    root: str | Path | None = None,
    only: Sequence[str] | None = None,
    checkpoints: Sequence[str | Path] = (),
    methods: Mapping[str, Method] | None = None,
) -> tuple[pd.DataFrame, pd.DataFrame, list[str]]:
    """Table 4 on a ``mixamo-local`` folder; writes ``table4.md``, ``table4.csv`` and
    ``table4_cases.csv`` into ``out_dir``.

    Args:
        out_dir: output folder.
        root: the folder (default ``$RETARGET_MIXAMO`` or the manifest's path).
        only: evaluate only these rows of :func:`~retarget_lib.evaluation.tdcn.tdcn_methods`.
        checkpoints: more TDCN/NKN checkpoints (paths), one row each (:func:`checkpoint_method`).
        methods: use exactly these methods instead (``only`` and ``checkpoints`` are then ignored).

    Returns:
        ``(table, coverage, missing_rows)``: ``table`` has index ``(pairs, method)`` with ``pairs``
        ``"paper"`` (the eight pairs of Table 3) or ``"all"`` (every pair of the folder).
    """
    folder = load_mixamo_folder(root if root is not None else mixamo_local_dir())
    cases, coverage, skipped = mixamo_tdcn_cases(folder)
    missing: list[str] = []
    if methods is None:
        methods, missing = tdcn_methods(only)
        methods.update(checkpoint_method(p) for p in checkpoints)
    per_case = (
        mixamo_tdcn_per_case(methods, cases) if cases else pd.DataFrame(columns=list(CASE_COLUMNS))
    )
    tables = {
        "paper": _table4(per_case[per_case["paper_pair"].astype(bool)]),
        "all": _table4(per_case),
    }
    table = (
        pd.concat(tables, names=["pairs", "method"])
        if any(len(t) for t in tables.values())
        else pd.DataFrame()
    )
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    with atomic_write(out / "table4.csv", "w") as f:
        table.to_csv(f, float_format="%.4f")
    with atomic_write(out / "table4_cases.csv", "w") as f:
        per_case.to_csv(f, index=False, float_format="%.6f")
    with atomic_write(out / "table4.md", "w") as f:
        f.write(_report(folder, cases, tables, coverage, skipped, missing))
    return table, coverage, missing


def _report(
    folder: MixamoFolder,
    cases: list[EvalCase],
    tables: dict[str, pd.DataFrame],
    coverage: pd.DataFrame,
    skipped: pd.DataFrame,
    missing: list[str],
) -> str:
    """``table4.md``: protocol, coverage, both tables."""
    per_scenario = (
        pd.Series([c.scenario for c in cases], dtype=int)
        .value_counts()
        .reindex([1, 2, 3, 4], fill_value=0)
    )
    lines = [
        f"# Table 4 on the mixamo-local folder {folder.root}",
        "",
        "Protocol: Kim et al. 2020, Sec. 6.1. Ground truth = the target character's own clip of "
        "the same "
        "motion; normalised MSE of global joint positions (cm² / H in cm, H of the target). Short "
        "= "
        f"120-frame chunks at {METHOD_FPS:g} fps retargeted on their own, long = whole clip; "
        "compared at the "
        "ground truth's frame times. 'avg' is the mean over the scenarios present. 'paper' "
        "columns: Kim et al. "
        "2020, Table 4 (their data, not this folder).",
        "",
        f"Folder: {len(folder.characters)} characters, {len(folder.clips)} clips; {len(cases)} "
        "ordered "
        "(source, target, motion) cases; cases per scenario 1-4: "
        f"{', '.join(map(str, per_scenario.values))}.",
        "",
        f"Split: {folder_split(folder).describe()}.",
        "",
        "## Coverage of the paper's pairs (Table 3)",
        "",
        markdown_table(coverage.set_index("scenario")),
        "",
    ]
    if len(skipped):
        lines += [
            "## Pairs not evaluated (frame counts differ)",
            "",
            markdown_table(skipped.set_index("source")),
            "",
        ]
    if missing:
        lines += [f"Rows without a trained checkpoint: {', '.join(missing)}.", ""]
    for key, title in (
        ("paper", "Table 4 over the paper's pairs"),
        ("all", "Table 4 over every pair of the folder"),
    ):
        body = markdown_table(tables[key]) if len(tables[key]) else "(no case)"
        lines += [f"## {title}", "", body, ""]
    return "\n".join(lines)
