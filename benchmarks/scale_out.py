"""Measure the figures of ``benchmarks/scale-out.md`` (issue 13: paper-scale training).

    python benchmarks/scale_out.py [--quick] [--out benchmarks/scale-out.md]

1. Step time of every Table 4 and Table 3 row on this CPU, one thread, at fast and paper width
   (the fast profile's batch for both widths, so the two columns differ only by width).
2. FLOPs of one training step at paper width (``torch.utils.flop_counter``, forward + backward of
   every network in the step), scaled linearly to the paper batch, times the paper schedule, and
   the GPU-hours that makes at an assumed sustained GPU throughput (stated in the output).
3. 2-process gloo scaling: ``retarget train`` alone vs under ``torchrun --nproc-per-node 2`` at the
   same global batch, fast width, same run, one thread per process.

The machine's load average is recorded beside every section: the cores are shared, so compare the
ratios within a run, not the absolute seconds across runs.
"""

from __future__ import annotations

import argparse
import csv
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import torch
from torch.utils.flop_counter import FlopCounterMode

from retarget_lib.config import load_config
from retarget_lib.evaluation.timing import time_it
from retarget_lib.files import REPO_ROOT, atomic_write
from retarget_lib.training.sweep import table_rows

#: assumed sustained throughput of one data-centre GPU on these small convolution/GRU steps
#: (an A100: 19.5 TFLOP/s FP32, 156 TF32 peak; small kernels reach a fraction of it)
GPU_TFLOPS = 20.0
#: the fast profile's batch of each table, used for both widths
BATCH = {"tdcn": 16, "contact": 8}


def load() -> str:
    one, five, fifteen = os.getloadavg()
    return f"load average {one:.1f} / {five:.1f} / {fifteen:.1f}"


def training(table: str, config_path: Path, profile: str, batch: int):
    cfg = load_config(config_path, [f"train.batch={batch}"], profile)
    if table == "contact":
        from retarget_lib.training.contact import ContactTraining

        return ContactTraining(cfg), cfg
    from retarget_lib.training.tdcn import RetargetTraining

    return RetargetTraining(cfg), cfg


def step_seconds(run, repeat: int) -> float:
    counter = iter(range(10**6))
    return time_it(lambda: run.step(next(counter)), repeat=repeat, warmup=1)


def step_flops(run) -> int:
    with FlopCounterMode(display=False) as counter:
        run.step(0)
    return counter.get_total_flops()


def rows_section(quick: bool) -> tuple[list[str], list[str]]:
    speed = [
        f"Measured {time.strftime('%Y-%m-%d %H:%M')} UTC, {load()} at the start.",
        "",
        "| table | row | s/step fast width | s/step paper width | paper / fast |",
        "|---|---|---|---|---|",
    ]
    cost = [
        "| table | row | GFLOP/step at batch 16/8 (paper width) | paper batch x steps | PFLOP "
        "total | "
        f"projected GPU-h at {GPU_TFLOPS:.0f} TFLOP/s |",
        "|---|---|---|---|---|---|",
    ]
    repeat = 2 if quick else 3
    for table in ("tdcn", "contact"):
        for row, config in table_rows(table).items():
            fast_run, _ = training(table, config, "fast", BATCH[table])
            fast = step_seconds(fast_run, repeat)
            del fast_run
            paper_run, paper_cfg = training(table, config, "paper", BATCH[table])
            paper = step_seconds(paper_run, repeat)
            flops = step_flops(paper_run)
            del paper_run
            full = load_config(config, [], "paper")["train"]
            total = flops * full["batch"] / BATCH[table] * full["steps"]
            speed.append(f"| {table} | {row} | {fast:.2f} | {paper:.2f} | {paper / fast:.1f}x |")
            cost.append(
                f"| {table} | {row} | {flops / 1e9:.1f} | {full['batch']} x {full['steps']} | "
                f"{total / 1e15:.0f} | {total / (GPU_TFLOPS * 1e12) / 3600:.1f} |"
            )
            print(speed[-1], cost[-1], load(), flush=True)
    speed.append(f"\n{load()} at the end.")
    return speed, cost


def _median_step(run_dir: Path) -> float:
    with open(run_dir / "losses.csv") as f:
        seconds = [float(r["seconds"]) for r in csv.DictReader(f)]
    return statistics.median(
        b - a for a, b in zip(seconds[1:], seconds[2:], strict=False)
    )  # step 0 (warm-up) left out


def scaling_section(quick: bool) -> list[str]:
    steps = 6 if quick else 10
    args = [
        "--config",
        str(REPO_ROOT / "configs/tdcn_paper.yaml"),
        f"train.steps={steps}",
        "train.batch=16",
        "--profile",
        "fast",
        "--device",
        "cpu",
    ]
    env = dict(os.environ, OMP_NUM_THREADS="1", MKL_NUM_THREADS="1")
    lines = [
        "| processes | global batch | per-process batch | median s/step | speed-up |",
        "|---|---|---|---|---|",
    ]
    with tempfile.TemporaryDirectory() as tmp:
        before = load()
        subprocess.run(
            [sys.executable, "-m", "retarget_lib", "train", *args, "--out", f"{tmp}/one"],
            env=env,
            check=True,
            capture_output=True,
        )
        subprocess.run(
            [
                sys.executable,
                "-m",
                "torch.distributed.run",
                "--standalone",
                "--nproc-per-node",
                "2",
                "-m",
                "retarget_lib",
                "train",
                *args,
                "--out",
                f"{tmp}/two",
            ],
            env=env,
            check=True,
            capture_output=True,
        )
        one, two = _median_step(Path(tmp) / "one"), _median_step(Path(tmp) / "two")
    lines += [
        f"| 1 | 16 | 16 | {one:.3f} | 1.0x |",
        f"| 2 (gloo, torchrun) | 16 | 8 | {two:.3f} | {one / two:.2f}x |",
        "",
        f"TDCN 'ours', fast width, {steps} steps each (median of steps 1…), one thread per "
        "process; "
        f"{before} before, {load()} after.",
    ]
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--out", default=str(REPO_ROOT / "benchmarks" / "scale-out.md"))
    args = parser.parse_args()
    torch.set_num_threads(1)
    scaling = scaling_section(args.quick)
    speed, cost = rows_section(args.quick)
    text = "\n".join(
        [
            "# Scale-out measurements (generated by benchmarks/scale_out.py)",
            "",
            "## Step time per row on this CPU (1 thread)",
            "",
            *speed,
            "",
            "## Projected paper-schedule cost per row on one GPU",
            "",
            *cost,
            "",
            "## 2-process gloo scaling on this machine",
            "",
            *scaling,
            "",
        ]
    )
    with atomic_write(args.out, "w") as f:
        f.write(text)
    print(text)


if __name__ == "__main__":
    main()
