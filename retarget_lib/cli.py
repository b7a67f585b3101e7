"""Command line: ``retarget …`` (also ``python -m retarget_lib …``).

::

    retarget data build|list|verify      build the embedded dataset; list/verify data_manifest.yaml
    retarget retarget --source IN.bvh --target TARGET.bvh|CHARACTER [--target-mesh SHAPE.npz]
                      [--source-mesh SHAPE.npz] --method NAME (from retarget_lib.methods.registry)
                      [--checkpoint ID|PATH] [--fps N] [--force] [--device auto] --out OUT.bvh
    retarget train    --config configs/NAME.yaml [key=value ...] [--profile fast|paper] [--out DIR]
                      [--resume] [--export MODEL.pt] [--device auto|cpu|cuda|mps] [--amp]
                                         also under ``torchrun --nproc-per-node N -m retarget_lib
                                         train …`` train a TDCN/NKN Table 4 row
                                         (retarget_lib.training.tdcn) or, for
                                         configs/contact_*.yaml, a contact-aware Table 3 row
                                         (retarget_lib.training.contact)
    retarget sweep    --table tdcn|contact --out DIR [key=value ...] [--profile fast|paper] [--rows
    ROW ...]
                      [--cluster auto|slurm|local] [--gpus-per-row N] [--timeout-min M] [--partition
                      P] [--wait] [--status]     one submitit job per table row
                      (retarget_lib.training.sweep)
    retarget evaluate --all --out DIR    every table with provenance (``make tables``: into
    results/) retarget evaluate --status           each stored result in results/: provenance, stale
    or not retarget evaluate --compare DIR      results/ against DIR's per-case files, within the
    re-run tolerances retarget evaluate --table tdcn|contact|real [--profile fast|paper] [--runs
    SWEEP_DIR] [--device auto] --out DIR
                      [--data synthetic|mixamo-local [--mixamo DIR] [--methods ROW ...]
                      [--checkpoint PATH]]
                                         mixamo-local: the papers' protocols on a reviewer's Mixamo
                                         folder (retarget_lib.evaluation.mixamo, .mixamo_contact)
    retarget bench [--quick]             speed table (ratios against references in the same run)

Each command imports what it runs inside its ``_cmd_*`` function: the library below this module
loads torch (about 3 s here), which ``retarget --help`` (0.2 s) does without.

Bad input (a :class:`~retarget_lib.errors.RetargetInputError`, a
:class:`~retarget_lib.files.DataError`, or an ``OSError`` on a user's path) exits with status 2
and one line on stderr naming the file and the problem, never a traceback. SIGTERM and SIGINT
exit with 128 + the signal number after removing the temporary file of any write in progress.
"""

from __future__ import annotations

import argparse
import sys
import warnings

from .errors import RetargetInputError, RetargetWarning
from .files import DataError, atomic_write, exit_on_signals, sha256_file


def _cmd_data(args: argparse.Namespace) -> int:
    from .data import status

    if args.action == "list":
        print(status.cache_summary())
        print(status.source_table())
        return 0
    if args.action == "verify":
        statuses = status.verify()
        for s in statuses:
            print(f"{s.id}: {s.state} — {s.detail}")
        print("all required sources verified")
        return 0
    from .data.build import build_all

    build_all(force=args.force)
    return 0


def _cmd_retarget(args: argparse.Namespace) -> int:
    from .methods.retarget import retarget_file

    out = retarget_file(
        args.source,
        args.target,
        args.method,
        args.out,
        args.checkpoint,
        args.target_mesh,
        args.source_mesh,
        fps=args.fps,
        force=args.force,
        joint_map=args.joint_map,
        source_joint_map=args.source_joint_map,
        device=args.device,
    )
    print(f"wrote {out}")
    return 0


def _cmd_train(args: argparse.Namespace) -> int:
    from .losses import NonFiniteLossError
    from .training.distributed import from_environment
    from .training.run import train_config

    try:
        result = train_config(
            args.config,
            args.overrides,
            args.profile,
            args.out,
            args.resume,
            args.export,
            args.device,
            args.amp,
            progress=sys.stderr.isatty(),
        )
    except NonFiniteLossError as e:
        print(f"retarget train: stopped: {e}", file=sys.stderr)
        return 1
    if not from_environment().is_main:  # torchrun: rank 0 reports
        return 0
    print(f"checkpoint: {result.final}  (losses: {result.final.parent / 'losses.csv'})")
    if result.exported:
        print(f"exported model: {result.exported}  sha256 {sha256_file(result.exported)}")
    return 0


def _evaluate_contact(args: argparse.Namespace, runs) -> int:
    if args.data == "mixamo-local":
        from .evaluation.mixamo_contact import run_mixamo_contact_evaluation

        tables, coverage, missing = run_mixamo_contact_evaluation(
            args.out, args.mixamo, args.profile or "fast", args.methods
        )
        print(
            "coverage (target, motion) of the appendix's lists:\n"
            + coverage.groupby(["body", "status"]).size().rename("cases").to_string()
        )
    else:
        from .evaluation.contact import run_contact_evaluation

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
    from .evaluation.contact_mixamo_convention import run_mixamo_convention_contact_evaluation

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
    from .evaluation.contact import run_contact_evaluation
    from .evaluation.tdcn import run_tdcn_evaluation

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
    return 0


def _stored_results() -> dict:
    """Every stored result in ``results/``, one entry each: name -> (load it, the columns naming a
    case, the compared metrics, the live re-run tolerance)."""
    from .evaluation import contact, contact_mixamo_convention, real, tdcn

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

    from .evaluation.results import compare_with_stored

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
        from .training.sweep import finished_rows

        runs = finished_rows(args.runs)
        print(f"trained rows from {args.runs}: {', '.join(runs) or 'none finished yet'}")
    if args.table == "contact":
        return _evaluate_contact(args, runs)
    if args.table == "real":
        return _evaluate_real(args)
    if args.data == "mixamo-local":
        return _evaluate_tdcn_mixamo(args)
    from .evaluation.tdcn import run_tdcn_evaluation

    table, missing = run_tdcn_evaluation(args.out, args.device, runs)
    return _report_table4(
        table, missing, f"{args.out}/table4.csv, table4.md, table4_h2.*, table4_cases.csv"
    )


def _evaluate_real(args: argparse.Namespace, command: str | None = None) -> int:
    """``--table real``: every method on the real-character set (retarget_lib.evaluation.real)."""
    import numpy as np

    from . import viz
    from .evaluation.real import run_real_evaluation

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
    from .evaluation.mixamo import run_mixamo_tdcn_evaluation

    table, coverage, missing = run_mixamo_tdcn_evaluation(
        args.out, args.mixamo, args.methods, args.checkpoint or ()
    )
    print("paper's pairs (Table 3):\n" + coverage.to_string(index=False))
    return _report_table4(table, missing, f"{args.out}/table4.md, table4.csv, table4_cases.csv")


def _cmd_sweep(args: argparse.Namespace) -> int:
    from .training import sweep

    if not args.status:
        jobs = sweep.submit(
            args.table,
            args.out,
            args.overrides,
            args.profile,
            args.rows,
            args.cluster,
            args.device,
            args.amp,
            args.gpus_per_row,
            args.timeout_min,
            args.partition,
            args.parallel,
        )
        print(
            f"submitted {len(jobs)} job(s) to {args.out}/jobs: "
            + (
                ", ".join(f"{r} ({j.job_id})" for r, j in jobs.items())
                or "every row is finished already"
            )
        )
        if args.wait:
            sweep.wait(jobs)
    statuses = sweep.sweep_status(args.out)
    width = max(len(s.row) for s in statuses)
    for s in statuses:
        print(
            (
                f"{s.row:<{width}}  {s.state:<8} step {s.step:>6}  "
                f"job {s.job_id or '-'}  {s.detail}"
            ).rstrip()
        )
    return 1 if any(s.state == "failed" for s in statuses) else 0


def _cmd_bench(args: argparse.Namespace) -> int:
    from .evaluation.bench import run

    table = run(quick=args.quick, only=args.only)
    print(table)
    if args.out:
        with atomic_write(args.out, "w") as f:
            f.write(table + "\n")
    return 0


def _registry():
    """The method registry, imported on first use: it loads torch and the models (about 3 s here),
    which ``retarget --help`` and ``retarget data ...`` do without."""
    from .methods import registry

    return registry


class _RegisteredMethods:
    """The registry's method names as ``--method`` choices, read only when ``retarget retarget``
    parses or prints its options."""

    def __iter__(self):
        return iter(_registry().REGISTRY)

    def __contains__(self, name: object) -> bool:
        return name in _registry().REGISTRY


class _RetargetHelp(argparse.HelpFormatter):
    """``retarget retarget --help`` describes each registered method (summaries from the
    registry)."""

    def _get_help_string(self, action: argparse.Action) -> str | None:
        if action.dest != "method":
            return super()._get_help_string(action)
        return "; ".join(
            f"{m.name}: {m.summary}"
            + (" (needs the target's mesh)" if m.needs_mesh else "")
            + (" (--checkpoint, default in the manifest)" if m.needs_checkpoint else "")
            for m in _registry().REGISTRY.values()
        )


def _device_option(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--device",
        choices=["auto", "cpu", "cuda", "mps"],
        default="auto",
        help="where networks run (auto: CUDA, else MPS, else CPU; under torchrun, GPU LOCAL_RANK)",
    )


def build_parser() -> argparse.ArgumentParser:
    """The ``retarget`` argument parser."""
    parser = argparse.ArgumentParser(prog="retarget", description="retarget-notebooks command line")
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser("data", help="build / list / verify the data sources in data_manifest.yaml")
    p.add_argument("action", choices=["build", "list", "verify"])
    p.add_argument("--force", action="store_true", help="rebuild even if the cache is up to date")
    p.set_defaults(func=_cmd_data)

    p = sub.add_parser(
        "retarget",
        help="retarget a clip (BVH, SMPL-X/AMASS .npz, GLB, FBX) to a target skeleton or character",
        formatter_class=_RetargetHelp,
    )
    p.add_argument(
        "--source",
        required=True,
        help="source motion: .bvh (joints named by a rig convention or --source-joint-map), "
        "SMPL-X/AMASS .npz, .glb/.gltf/.vrm (its first animation), .fbx (needs the fbx extra)",
    )
    p.add_argument(
        "--target",
        required=True,
        help="target .bvh (its skeleton, units and joint names are used), .glb/.gltf/.vrm/.fbx "
        "character "
        "(skeleton, mesh, skin, all joints), shape .npz, SMPL-X/AMASS .npz (its betas' "
        "skeleton), or a character name",
    )
    p.add_argument(
        "--joint-map",
        help="joint map (YAML/JSON lines 'CanonicalName: file_joint_name', or "
        "'CanonicalName: null' for a joint the rig lacks; docs/joint-maps.md) for a "
        "target file (.bvh/.glb/.gltf/.vrm/.fbx/.npz) whose joint names no rig "
        "convention covers",
    )
    p.add_argument("--source-joint-map", help="the same for the source file (any format)")
    p.add_argument(
        "--method",
        required=True,
        choices=_RegisteredMethods(),
        metavar="NAME",
        help="a method of the registry (retarget_lib/methods/registry.py)",
    )
    p.add_argument(
        "--target-mesh",
        help="target character shape .npz (rest_vertices, faces, weights, "
        "offsets, joint names) for --method contact when the target has no mesh "
        "(a .bvh); a .glb/.fbx/name target brings its own",
    )
    p.add_argument(
        "--source-mesh",
        help="source character shape .npz: its hand self-contacts are detected "
        "and preserved by --method contact (without it: feet and "
        "interpenetration only)",
    )
    p.add_argument(
        "--checkpoint",
        help="manifest id or path of a checkpoint for a learned method (default: "
        "the method's default in data_manifest.yaml)",
    )
    p.add_argument("--fps", type=float, help="output frame rate (default: the source's)")
    p.add_argument("--force", action="store_true", help="allow --out to overwrite an input file")
    p.add_argument(
        "--out",
        required=True,
        help="output .bvh, or .glb/.fbx: the target's skinned mesh performing "
        "the result (never an input unless --force)",
    )
    _device_option(p)
    p.set_defaults(func=_cmd_retarget)

    p = sub.add_parser(
        "train",
        help="train a TDCN/NKN (Table 4) or contact-aware (Table 3) model from a YAML config",
    )
    p.add_argument("--config", required=True, help="experiment YAML, e.g. configs/tdcn_paper.yaml")
    p.add_argument(
        "overrides",
        nargs="*",
        metavar="key=value",
        help="dotted config overrides, e.g. train.steps=200 model.channels=64",
    )
    p.add_argument(
        "--profile",
        choices=["fast", "paper"],
        help="config profile (default $RETARGET_PROFILE or fast)",
    )
    p.add_argument("--out", help="run folder (default runs/<config name>)")
    p.add_argument("--resume", action="store_true", help="continue from <out>/last.pt if it exists")
    p.add_argument(
        "--export",
        help="also write a slim inference-only model checkpoint here (TDCN weights as "
        "float16, NKN and contact-aware ones as float32)",
    )
    _device_option(p)
    p.add_argument(
        "--amp", action="store_true", help="mixed precision (bfloat16 autocast; CUDA only)"
    )
    p.set_defaults(func=_cmd_train)

    p = sub.add_parser(
        "evaluate", help="regenerate a paper table (CSV + Markdown, paper numbers beside ours)"
    )
    p.add_argument(
        "--all",
        action="store_true",
        help="every table (Table 4 with its real-clip and windowed companions, contact Tables 1, "
        "3, "
        "5, 6) with provenance; `make tables` writes them into results/",
    )
    p.add_argument(
        "--status",
        action="store_true",
        help="say where each stored result in results/ comes from and whether it is stale "
        "(exit 1 when one is)",
    )
    p.add_argument(
        "--compare",
        metavar="DIR",
        help="compare the stored results in results/ with the per-case files of DIR (e.g. written "
        "by "
        "--all), value by value within the live re-runs' tolerances (exit 1 when one is outside)",
    )
    p.add_argument(
        "--table",
        choices=["tdcn", "contact", "real"],
        help="tdcn: Kim et al. 2020, Table 4 (both synthetic profiles); contact: Villegas et al. "
        "2021, "
        "Tables 1, 3, 5, 6; real: every method on the real characters, measures without ground "
        "truth",
    )
    p.add_argument(
        "--profile",
        choices=["fast", "paper"],
        help="contact protocol size (fast: 6 clips x 6 targets, 60 frames; paper: 16 clips, whole)",
    )
    p.add_argument(
        "--data",
        choices=["synthetic", "mixamo-local"],
        default="synthetic",
        help="synthetic: the embedded split; mixamo-local: your Mixamo download with the papers' "
        "protocols (ground truth = each target's own clip; see data_manifest.yaml)",
    )
    p.add_argument(
        "--mixamo", help="the mixamo-local folder (default $RETARGET_MIXAMO or data/mixamo)"
    )
    p.add_argument(
        "--methods",
        nargs="+",
        metavar="ROW",
        help="with --data mixamo-local: evaluate only these table rows (e.g. copy copy-rest ours; "
        "contact: e.g. copy copy-rest 'Ours (residual)')",
    )
    p.add_argument(
        "--checkpoint",
        action="append",
        metavar="PATH",
        help="with --table tdcn --data mixamo-local: also evaluate this TDCN/NKN checkpoint "
        "(repeatable)",
    )
    p.add_argument(
        "--rows",
        nargs="+",
        metavar="ROW",
        help="with --table contact: recompute only these rows (e.g. TDCN after retraining the "
        "default "
        "TDCN) and merge them into --out's contact_cases.csv; the provenance says which rows are "
        "new",
    )
    p.add_argument("--out", help="output folder")
    p.add_argument(
        "--runs",
        help="a `retarget sweep` folder: its finished rows replace the shipped checkpoints",
    )
    _device_option(p)
    p.set_defaults(func=_cmd_evaluate)

    p = sub.add_parser(
        "sweep",
        help="train every row of a paper table, one submitit job per row (Slurm array or "
        "local processes); --status shows progress",
    )
    p.add_argument(
        "--table",
        required=True,
        choices=["tdcn", "contact"],
        help="tdcn: Kim et al. 2020, Table 4 rows; contact: Villegas et al. 2021, Table 3 rows",
    )
    p.add_argument(
        "--out", required=True, help="sweep folder (<out>/<row>/ per row, <out>/jobs/ for submitit)"
    )
    p.add_argument(
        "overrides", nargs="*", metavar="key=value", help="config overrides applied to every row"
    )
    p.add_argument(
        "--profile",
        choices=["fast", "paper"],
        help="config profile (default $RETARGET_PROFILE or fast)",
    )
    p.add_argument(
        "--rows", nargs="+", metavar="ROW", help="only these rows (default: every row of the table)"
    )
    p.add_argument(
        "--cluster",
        choices=["auto", "slurm", "local"],
        default="auto",
        help="auto: Slurm when srun is on PATH, else local subprocesses",
    )
    p.add_argument(
        "--gpus-per-row",
        type=int,
        default=0,
        help="GPUs (torch processes) per row on Slurm (default 0)",
    )
    p.add_argument(
        "--timeout-min",
        type=int,
        default=24 * 60,
        help="wall-time limit per job; a job reaching it is requeued and resumes (default 1440)",
    )
    p.add_argument("--partition", help="Slurm partition")
    p.add_argument(
        "--parallel", type=int, help="at most this many rows at once (Slurm array parallelism)"
    )
    p.add_argument(
        "--wait", action="store_true", help="wait for the submitted jobs, then print the status"
    )
    p.add_argument(
        "--status", action="store_true", help="only print each row's state (submits nothing)"
    )
    _device_option(p)
    p.add_argument(
        "--amp", action="store_true", help="mixed precision (bfloat16 autocast; CUDA only)"
    )
    p.set_defaults(func=_cmd_sweep)

    p = sub.add_parser("bench", help="speed benchmarks (ratios against same-run references)")
    p.add_argument("--quick", action="store_true", help="fewer repeats (CI smoke run)")
    p.add_argument("--only", nargs="*", help="names of benchmarks to run (default: all)")
    p.add_argument("--out", help="also write the Markdown table to this file")
    p.set_defaults(func=_cmd_bench)
    return parser


def _one_line(error: Exception) -> str:
    """The message of a user-input error on one line (an ``OSError`` with its file name)."""
    if isinstance(error, OSError) and error.filename is not None:
        text = f"{error.filename}: {error.strerror or error}"
    else:
        text = str(error) or type(error).__name__
    return " ".join(part.strip() for part in text.splitlines() if part.strip())


def _warning_lines(command: str):
    """A ``warnings.showwarning`` that prints a :class:`~retarget_lib.errors.RetargetWarning` as one
    ``retarget COMMAND: warning: ...`` line (others as Python prints them)."""
    default = warnings.showwarning

    def show(message, category, filename, lineno, file=None, line=None):
        if issubclass(category, RetargetWarning):
            print(f"retarget {command}: warning: {_one_line(message)}", file=sys.stderr)
        else:
            default(message, category, filename, lineno, file, line)

    return show


def main(argv: list[str] | None = None) -> int:
    """Entry point; returns the exit status (2 with a one-line message on data/input errors)."""
    args = build_parser().parse_args(argv)
    exit_on_signals()
    try:
        with warnings.catch_warnings():
            warnings.showwarning = _warning_lines(args.command)
            warnings.simplefilter("always", RetargetWarning)
            return args.func(args)
    except (RetargetInputError, DataError, ValueError, OSError) as e:
        print(f"retarget {args.command}: error: {_one_line(e)}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
