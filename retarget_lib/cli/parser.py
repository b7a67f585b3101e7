"""The command line's argument parser: every subcommand, its options and their help (``retarget
retarget --help`` lists the registered methods)."""

from __future__ import annotations

import argparse

from .commands import (
    _cmd_bench,
    _cmd_capacity,
    _cmd_data,
    _cmd_exercises,
    _cmd_retarget,
    _cmd_sweep,
    _cmd_train,
)
from .evaluate import _cmd_evaluate


def _registry():
    """The method registry, imported on first use: it loads torch and the models (about 3 s here),
    which ``retarget --help`` and ``retarget data ...`` do without."""
    from ..methods import registry

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
        "--no-eso",
        action="store_true",
        help="--method contact: keep the network's output, without encoder-space "
        "optimisation (faster, smoother on real meshes; no hand contacts pulled together)",
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

    p = sub.add_parser(
        "capacity",
        help="a paper-form model's capacity check: its error on the tiny set it was trained on "
        "against the protocol copy row, and its identity (exit 1 if it fails)",
    )
    p.add_argument("run", help="a `retarget train --out` folder trained from configs/capacity/*")
    p.add_argument(
        "--checkpoint",
        default="final.pt",
        help="file in the run folder (default final.pt; last.pt for a run stopped before its end)",
    )
    p.add_argument("--out", help="also write the per-case scores here (CSV)")
    p.set_defaults(func=_cmd_capacity)

    p = sub.add_parser("bench", help="speed benchmarks (ratios against same-run references)")
    p.add_argument("--quick", action="store_true", help="fewer repeats (CI smoke run)")
    p.add_argument("--only", nargs="*", help="names of benchmarks to run (default: all)")
    p.add_argument("--out", help="also write the Markdown table to this file")
    p.set_defaults(func=_cmd_bench)

    p = sub.add_parser(
        "exercises",
        help="check a notebook's exercises outside Jupyter: one line each (correct, not answered "
        "yet, or wrong and why); exit 1 if one is wrong",
    )
    p.add_argument("number", help="the notebook's number, e.g. 01 or 08b")
    p.add_argument(
        "--notebook",
        help="your copy of the notebook (default: notebooks/NN_*.ipynb, the one Jupyter edits)",
    )
    p.add_argument(
        "--solutions",
        action="store_true",
        help="put the reference answers (notebooks/solutions/) in the exercise cells first",
    )
    p.set_defaults(func=_cmd_exercises)
    return parser
