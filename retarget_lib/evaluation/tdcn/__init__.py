"""Evaluation: TDCN's Table 4 protocol (Kim et al. 2020, Sec. 6.1) on the synthetic four-scenario
split, with the paper's numbers beside ours.

Metric (NKN/TDCN): squared error of the **global** joint positions summed over x, y, z, divided by
the target character's height ``H``, averaged over joints and frames. Lengths are in
**centimetres** for this number, as in the Mixamo data both papers use, so magnitudes are
comparable with the paper's (a ratio of cm² to cm). The squared-height variant divides by ``H²``
and is unit-free.

Protocol: "short" cuts every test clip into 120-frame chunks (4 s at 30 fps) and retargets each
chunk on its own; "long" retargets whole clips. Scenario ``k`` is the mean over its pairs; "avg"
is the mean over the four scenarios.

The package: :mod:`.cases` (cases, scores, evaluating a method) and :mod:`.tables` (the table,
stored results, the command).
"""

from __future__ import annotations

from .cases import (
    METRES_TO_CM,
    SHORT_FRAMES,
    WINDOWED_ROW,
    EvalCase,
    Method,
    Scores,
    aligned_positions,
    cmu_cases,
    error_breakdown,
    evaluate_case,
    evaluate_method,
    evaluate_methods,
    mixamo_convention_cases,
    normalized_mse,
    short_chunks,
    table4_scores,
    tdcn_cases,
    truth_frames,
)
from .tables import (
    CASE_KEYS,
    MIXAMO_CONVENTION_TABLE,
    RERUN_FLOOR,
    RERUN_RTOL,
    markdown_table,
    mixamo_convention_checkpoints,
    mixamo_convention_methods,
    ordering_checks,
    paper_comparison,
    rerun_cases,
    rerun_subset,
    rerun_tolerance,
    run_tdcn_evaluation,
    stored_table4,
    table4_row,
    table_from_cases,
    tdcn_methods,
    tdcn_table,
    write_table,
)

__all__ = [
    "METRES_TO_CM",
    "SHORT_FRAMES",
    "WINDOWED_ROW",
    "EvalCase",
    "Method",
    "Scores",
    "aligned_positions",
    "cmu_cases",
    "error_breakdown",
    "evaluate_case",
    "evaluate_method",
    "evaluate_methods",
    "mixamo_convention_cases",
    "normalized_mse",
    "short_chunks",
    "table4_scores",
    "tdcn_cases",
    "truth_frames",
    "CASE_KEYS",
    "MIXAMO_CONVENTION_TABLE",
    "RERUN_FLOOR",
    "RERUN_RTOL",
    "markdown_table",
    "mixamo_convention_checkpoints",
    "mixamo_convention_methods",
    "ordering_checks",
    "paper_comparison",
    "rerun_cases",
    "rerun_subset",
    "rerun_tolerance",
    "run_tdcn_evaluation",
    "stored_table4",
    "table4_row",
    "table_from_cases",
    "tdcn_methods",
    "tdcn_table",
    "write_table",
]
