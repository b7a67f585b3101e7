"""The ``evaluate`` subcommand: every table, one table, the stored results' status and a comparison
with a folder of re-computed ones."""

from __future__ import annotations

import argparse

from ..errors import RetargetInputError


def _evaluate_contact(args: argparse.Namespace, runs) -> int:
    if args.data == "mixamo-local":
        from ..evaluation.mixamo_contact import run_mixamo_contact_evaluation

        tables, coverage, missing = run_mixamo_contact_evaluation(
            args.out, args.mixamo, args.profile or "fast", args.methods
        )
        print(
            "coverage (target, motion) of the appendix's lists:\n"
            + coverage.groupby(["body", "status"]).size().rename("cases").to_string()
        )
    else:
        from ..evaluation.contact import run_contact_evaluation

        rows = tuple(args.rows) if args.rows else None
        profile = args.profile or "fast"
        command = f"retarget evaluate --table contact --profile {profile} --out {args.out}" + (
            " --rows " + " ".join(repr(r) for r in rows) if rows else ""
        )
        tables, missing = run_contact_evaluation(
            args.out, profile, rows=rows, device=args.device, runs=runs, command=command
        )
        if rows is None and runs is None:
            _evaluate_contact_mixamo_convention(args, profile, command)
    for name, table in tables.items():
        print(f"{name}:\n{table.filter(like='ours').round(3).to_string()}\n")
    if missing:
        print(f"no trained checkpoint yet for: {', '.join(missing)}")
    print(
        f"wrote {args.out}/contact_table1.csv/.md, contact_table3.*, contact_table5.*, "
        "contact_table6.*, "
        "contact_cases.csv" + (", contact_coverage.csv" if args.data == "mixamo-local" else "")
    )
    return 0


def _evaluate_contact_mixamo_convention(
    args: argparse.Namespace, profile: str, command: str
) -> None:
    """Table 1's metrics on the Mixamo-convention characters (the shipped checkpoints)."""
    from ..evaluation.contact_mixamo_convention import run_mixamo_convention_contact_evaluation

    table = run_mixamo_convention_contact_evaluation(
        args.out, profile, args.device, command=command
    )
    print(f"Mixamo-convention characters:\n{table.filter(like='ours').round(3).to_string()}\n")
    print(
        f"wrote {args.out}/contact_mixamo_convention.csv/.md, contact_mixamo_convention_cases.csv"
    )


def _evaluate_all(args: argparse.Namespace) -> int:
    """Every stored table (Table 4, its real-clip and windowed companions, the contact tables) into
    ``--out`` with provenance; ``results/`` is the repository's copy."""
    from ..evaluation.claims import write_claims
    from ..evaluation.contact import run_contact_evaluation
    from ..evaluation.tdcn import run_tdcn_evaluation

    command = f"retarget evaluate --all --out {args.out}"
    table, missing = run_tdcn_evaluation(args.out, args.device, command=command)
    _report_table4(
        table,
        missing,
        f"{args.out}/table4.*, table4_h2.*, table4_cases.csv, table4_cmu_cases.csv, "
        "table4_windowed_cases.csv, table4_mixamo_convention.*, "
        "table4_mixamo_convention_cases.csv (each with .provenance.json)",
    )
    _evaluate_real(args, command)
    tables, missing = run_contact_evaluation(
        args.out, args.profile or "fast", device=args.device, command=command
    )
    print(f"table1:\n{tables['table1'].filter(like='ours').round(3).to_string()}")
    _evaluate_contact_mixamo_convention(args, args.profile or "fast", command)
    print(
        f"wrote {args.out}/contact_table1.*, contact_table3.*, contact_table5.*, contact_table6.*, "
        "contact_cases.csv (with .provenance.json)"
    )
    csv_path, md_path = write_claims(args.out)
    print(f"wrote {md_path}, {csv_path.name}: every claim of both papers, judged on these tables")
    return 0


def _stored_results() -> dict:
    """Every stored result in ``results/``, one entry each: name -> (load it, the columns naming a
    case, the compared metrics, the live re-run tolerance)."""
    from ..evaluation import contact, contact_mixamo_convention, real, tdcn

    table4 = (tdcn.CASE_KEYS, ("short", "long", "short_h2", "long_h2"), tdcn.rerun_tolerance)
    return {
        **{
            name: (lambda name=name: tdcn.stored_table4(name), *table4)
            for name in (
                "table4_cases",
                "table4_cmu_cases",
                "table4_windowed_cases",
                "table4_mixamo_convention_cases",
            )
        },
        "real_cases": (
            real.stored_real_results,
            ("character", "method", "clip"),
            real.MEASURES,
            real.rerun_tolerance,
        ),
        "contact_cases": (
            contact.stored_contact_results,
            ("method", "clip", "target"),
            contact.METRICS,
            contact.rerun_tolerance,
        ),
        "contact_mixamo_convention_cases": (
            contact_mixamo_convention.stored_mixamo_convention_contact_results,
            ("method", "clip", "source", "target"),
            contact.METRICS,
            contact.rerun_tolerance,
        ),
    }


def _results_status() -> int:
    """Each stored result in ``results/``: where it comes from and whether it is stale."""
    stale = 0
    for load, *_ in _stored_results().values():
        result = load()
        stale += bool(result.stale)
        print(result.report())
    print(
        f"{stale} stale stored result(s)" if stale else "every stored result matches this checkout"
    )
    return 1 if stale else 0


def _compare_results(other_dir: str) -> int:
    """Every stored per-case file in ``results/`` against the same file in ``other_dir`` (e.g. a
    fresh ``retarget evaluate --all --out DIR``), value by value, within the live re-runs'
    tolerances; exit 1 when a case is missing or a value is outside its tolerance."""
    from pathlib import Path

    import pandas as pd

    from ..evaluation.results import compare_with_stored

    bad = 0
    for name, (load, keys, metrics, tolerance) in _stored_results().items():
        stored = load().frame
        path = Path(other_dir) / f"{name}.csv"
        if not path.exists():
            raise RetargetInputError(
                f"{path}: not found (run `retarget evaluate --all --out {other_dir}` first)"
            )
        other = pd.read_csv(path)
        cmp = compare_with_stored(other, stored, keys, metrics, tolerance)
        outside = int((~cmp["reproduces"]).sum()) + abs(len(other) - len(stored))
        worst = (cmp["abs diff"] / cmp["tolerance"]).max()
        print(
            f"{name}: {len(other)} cases against {len(stored)} stored, {len(cmp)} values; "
            f"{outside} outside tolerance; largest |difference| / tolerance {worst:.3f}"
        )
        bad += outside
    print(
        "every value reproduces the stored results"
        if bad == 0
        else f"{bad} value(s) or case(s) do not reproduce"
    )
    return 1 if bad else 0


def _cmd_evaluate(args: argparse.Namespace) -> int:
    if args.status:
        return _results_status()
    if args.compare:
        return _compare_results(args.compare)
    if args.out is None:
        raise RetargetInputError("retarget evaluate: give --out DIR")
    if args.all:
        if args.table or args.data != "synthetic" or args.runs:
            raise RetargetInputError(
                "--all evaluates every table on the shipped checkpoints: leave out "
                "--table, --data and --runs"
            )
        return _evaluate_all(args)
    if args.table is None:
        raise RetargetInputError(
            "retarget evaluate: give --table tdcn|contact|real, --all or --status"
        )
    if args.data != "mixamo-local" and (args.mixamo or args.methods or args.checkpoint):
        raise RetargetInputError("--mixamo, --methods and --checkpoint need --data mixamo-local")
    if args.rows and (args.table != "contact" or args.data != "synthetic"):
        raise RetargetInputError(
            "--rows recomputes rows of the stored contact tables: use it with --table contact"
        )
    if args.table == "contact" and args.checkpoint:
        raise RetargetInputError("--checkpoint adds a TDCN/NKN row: use it with --table tdcn")
    if args.data == "mixamo-local" and args.runs:
        raise RetargetInputError(
            "--runs replaces the shipped checkpoints of the synthetic protocol; "
            "with --data mixamo-local give --checkpoint PATH"
        )
    runs = None
    if args.runs:
        from ..training.sweep import finished_rows

        runs = finished_rows(args.runs)
        print(f"trained rows from {args.runs}: {', '.join(runs) or 'none finished yet'}")
    if args.table == "contact":
        return _evaluate_contact(args, runs)
    if args.table == "real":
        return _evaluate_real(args)
    if args.data == "mixamo-local":
        return _evaluate_tdcn_mixamo(args)
    from ..evaluation.tdcn import run_tdcn_evaluation

    table, missing = run_tdcn_evaluation(args.out, args.device, runs)
    return _report_table4(
        table, missing, f"{args.out}/table4.csv, table4.md, table4_h2.*, table4_cases.csv"
    )


def _evaluate_real(args: argparse.Namespace, command: str | None = None) -> int:
    """``--table real``: every method on the real-character set (retarget_lib.evaluation.real)."""
    import numpy as np

    from .. import viz
    from ..evaluation.real import run_real_evaluation

    if args.runs or args.data != "synthetic":
        raise RetargetInputError(
            "--table real scores the shipped checkpoints on data/real_characters: leave out "
            "--runs and --data"
        )
    table, worst = run_real_evaluation(
        args.out, args.device, command=command or f"retarget evaluate --table real --out {args.out}"
    )
    print(table.round(3).to_string())
    scenes = [
        viz.Scene(
            vertices=w.vertices,
            faces=w.faces,
            vertex_colors=np.where(w.inside[:, None], (0.85, 0.15, 0.1), (0.72, 0.72, 0.72)),
            title=f"{w.method}: {w.character}\n{w.clip}, frame {w.frame}",
        )
        for w in worst
    ]
    viz.save_png(
        viz.render_side_by_side(scenes, ncols=3, window_size=(1260, 440)),
        f"{args.out}/real_worst.png",
    )
    print(
        f"wrote {args.out}/real.csv, real.md, real_cases.csv (with .provenance.json), "
        "real_worst.png (each "
        "method's case with the most arm vertices inside the body, those vertices red)"
    )
    return 0


def _report_table4(table, missing, written: str) -> int:
    """Print a Table 4's average columns, the rows without a checkpoint and the files written."""
    if len(table):
        cols = [c for c in table.columns if c.endswith("avg")]
        print(table[cols].round(3).to_string())
    if missing:
        print(f"no trained checkpoint yet for: {', '.join(missing)}")
    print(f"wrote {written}")
    return 0


def _evaluate_tdcn_mixamo(args: argparse.Namespace) -> int:
    from ..evaluation.mixamo import run_mixamo_tdcn_evaluation

    table, coverage, missing = run_mixamo_tdcn_evaluation(
        args.out, args.mixamo, args.methods, args.checkpoint or ()
    )
    print("paper's pairs (Table 3):\n" + coverage.to_string(index=False))
    return _report_table4(table, missing, f"{args.out}/table4.md, table4.csv, table4_cases.csv")
