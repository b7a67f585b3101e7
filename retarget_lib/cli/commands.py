"""The ``data``, ``retarget``, ``train``, ``sweep``, ``capacity``, ``bench`` and ``exercises``
subcommands: each imports what it runs inside its function (see :mod:`retarget_lib.cli`)."""

from __future__ import annotations

import argparse
import sys

from ..files import atomic_write, sha256_file


def _cmd_data(args: argparse.Namespace) -> int:
    from ..data import status

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
    from ..data.build import build_all

    build_all(force=args.force)
    return 0


def _cmd_retarget(args: argparse.Namespace) -> int:
    from ..methods.retarget import retarget_file

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
        eso=not args.no_eso,
    )
    print(f"wrote {out}")
    return 0


def _cmd_train(args: argparse.Namespace) -> int:
    from ..losses import NonFiniteLossError
    from ..training.distributed import from_environment
    from ..training.run import train_config

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


def _cmd_sweep(args: argparse.Namespace) -> int:
    from ..training import sweep

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


def _cmd_capacity(args: argparse.Namespace) -> int:
    from pathlib import Path

    import yaml

    from ..errors import RetargetInputError
    from ..evaluation.capacity import (
        capacity_cases,
        capacity_check,
        capacity_clips,
        contact_capacity_cases,
        contact_capacity_check,
        contact_energy_at_truth,
        contact_network_method,
    )
    from ..methods.contact import load_contact_model
    from ..methods.registry import get_method

    run = Path(args.run)
    config_path, checkpoint = run / "config.yaml", run / args.checkpoint
    for path in (config_path, checkpoint):
        if not path.is_file():
            raise RetargetInputError(f"{path}: not found (a `retarget train --out` folder?)")
    config = yaml.safe_load(config_path.read_text())
    data = config.get("data", {}) if isinstance(config, dict) else {}
    if "max_clips" not in data or (
        config.get("method") == "contact" and data.get("source", "synthetic") != "synthetic"
    ):
        raise RetargetInputError(
            f"{config_path}: not a capacity run (needs data.max_clips, and a synthetic source for "
            "a contact run; e.g. configs/capacity/nkn.yaml, configs/capacity/contact.yaml)"
        )
    if config.get("method") == "contact":
        method = "contact"
        model, _ = load_contact_model(checkpoint)
        result = contact_capacity_check(
            contact_network_method(model), contact_capacity_cases(config)
        )
    else:
        method = "nkn" if str(config["model"].get("row", "")).startswith("Baseline") else "tdcn"
        result = capacity_check(
            get_method(method).retargeter(checkpoint), capacity_cases(capacity_clips(config))
        )
    print(f"{run.name} ({method}, {checkpoint.name}): {result.summary()}")
    if method == "contact":
        print(contact_energy_at_truth(config, model).summary())
    if args.out:
        with atomic_write(args.out, "w") as f:
            result.per_case.to_csv(f, index=False)
    return 0 if result.passed else 1


def _cmd_bench(args: argparse.Namespace) -> int:
    from ..evaluation.bench import run

    table = run(quick=args.quick, only=args.only)
    print(table)
    if args.out:
        with atomic_write(args.out, "w") as f:
            f.write(table + "\n")
    return 0


def _cmd_exercises(args: argparse.Namespace) -> int:
    from ..notebook.grading import WRONG, grade, prepare

    nb, cwd = prepare(args.number, args.notebook, solutions=args.solutions)
    print(f"retarget exercises: executing notebook {args.number} ...", file=sys.stderr, flush=True)
    results, other = grade(nb, cwd)
    for r in results:
        print(r.line)
    for line in other:
        print(f"retarget exercises: {line} (not an exercise) raised an error", file=sys.stderr)
    return 1 if other or any(r.status == WRONG for r in results) else 0
