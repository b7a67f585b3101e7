"""Time the README's two commands from a fresh clone, as a first-time student runs them.

For each repetition: ``git clone`` this checkout's HEAD into a new temporary folder, then
``make`` (venv, data, every notebook, the book), then ``make test`` (unit tests + every notebook
under nbval), then ``make workshop WORKSHOP_FLAGS=--force`` (the workshop notebooks again, two at a
time). Writes ``benchmarks/two-commands.md`` (every run, the per-step times that ``make`` printed,
the slowest notebooks) and ``benchmarks/notebook-times.json`` (each notebook's median seconds, which
``make``'s runner uses to start the longest notebooks first).

Usage (about 15 minutes per repetition on 2 cores, 20 with ``--ci-once``; nothing else should run
meanwhile)::

    python3 benchmarks/two_commands.py --repeat 3 [--ci-once] [--append]

Every run is kept in ``benchmarks/two-commands.json`` as soon as it ends; ``--append`` adds the new
runs to those (each row names its commit), without it the table starts afresh.
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import os
import platform
import shutil
import statistics
import subprocess
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
OUT_MD = REPO / "benchmarks" / "two-commands.md"
OUT_TIMES = REPO / "benchmarks" / "notebook-times.json"
#: every run of the table, kept so that ``--append`` adds runs (a later commit, another session)
OUT_RUNS = REPO / "benchmarks" / "two-commands.json"
#: the product requirements (README): minutes on a 2-core machine from a fresh clone
LIMITS = {"make": 10, "make test": 15, "make workshop": 4}


def _cpu() -> str:
    for line in Path("/proc/cpuinfo").read_text().splitlines():
        if line.startswith("model name"):
            return line.split(":", 1)[1].strip()
    return platform.processor()


def _timed(cmd: list[str], cwd: Path, log: Path) -> float:
    t0 = time.perf_counter()
    with log.open("w") as f:
        proc = subprocess.run(cmd, cwd=cwd, stdout=f, stderr=subprocess.STDOUT)
    seconds = time.perf_counter() - t0
    if proc.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed in {cwd} after {seconds:.0f} s; see {log}")
    return seconds


def _steps(log: Path) -> dict[str, float]:
    """The per-step table that .ci/step_times.py printed at the end of a make."""
    steps = {}
    for line in log.read_text().splitlines():
        parts = line.split()
        if (
            len(parts) >= 5 and parts[-1] == "min)" and parts[-3] == "s"
        ):  # "  STEP   123 s  (2.1 min)"
            steps[" ".join(parts[:-4])] = float(parts[-4])
    return steps


def one_run(keep: Path, ci: bool) -> dict:
    clone = Path(tempfile.mkdtemp(prefix="retarget-fresh-"))
    try:
        subprocess.run(["git", "clone", "-q", str(REPO), str(clone)], check=True)
        commit = subprocess.run(
            ["git", "rev-parse", "--short", "HEAD"],
            cwd=clone,
            capture_output=True,
            text=True,
            check=True,
        ).stdout.strip()
        run = {
            "date": dt.date.today().isoformat(),
            "commit": commit,
            "load before": round(os.getloadavg()[0], 2),
        }
        commands = [
            ("make", ["make"]),
            ("make test", ["make", "test"]),
            ("make workshop", ["make", "workshop", "WORKSHOP_FLAGS=--force"]),
        ]
        if ci:  # the rest of .ci/run: CI = make test (with set-up and data) + these two
            commands += [
                ("make test-slow", ["make", "test-slow"]),
                ("make unit-threads", ["make", "unit-threads"]),
            ]
        for name, cmd in commands:
            log = keep / f"{name.replace(' ', '-')}.log"
            run[name] = round(_timed(cmd, clone, log), 1)
            run["load after"] = max(run.get("load after", 0.0), round(os.getloadavg()[0], 2))
            run[f"{name} steps"] = _steps(log)
            if name in (
                "make",
                "make workshop",
            ):  # the runner's own per-notebook record of that command
                timings = json.loads((clone / "build/notebooks/timings.json").read_text())
                run["notebooks" if name == "make" else "workshop notebooks"] = {
                    nb: t["seconds"]
                    for nb, t in timings.items()
                    if name == "make" or t["finished"] >= run["workshop from"]
                }
            if name == "make test":
                run["workshop from"] = dt.datetime.now(dt.UTC).isoformat(timespec="seconds")
        return run
    finally:
        shutil.rmtree(clone, ignore_errors=True)


def _machine(run: dict) -> str:
    """How loaded the machine was during a run (see the table's header)."""
    if "load before" in run:
        return f"load {run['load before']:.1f} before, {run['load after']:.1f} at most after"
    return run.get("machine", "not recorded")


def write(runs: list[dict]) -> None:
    names = sorted({nb for r in runs for nb in r["notebooks"]})
    median = {
        nb: statistics.median(r["notebooks"][nb] for r in runs if nb in r["notebooks"])
        for nb in names
    }
    OUT_TIMES.write_text(
        json.dumps({nb: {"seconds": s} for nb, s in median.items()}, indent=1) + "\n"
    )
    lines = [
        "# The two commands, timed from a fresh clone",
        "",
        "Measured by `python3 benchmarks/two_commands.py` (runs on "
        f"{', '.join(sorted({r['date'] for r in runs}))}) on "
        f"{_cpu()}, {os.cpu_count()} cores. Each run clones the "
        "repository into a new folder and runs `make`, `make test`, then `make workshop "
        "WORKSHOP_FLAGS=--force` there (the README's commands, as a first-time student types "
        "them).",
        "",
        "The machine column is the 1-minute load average before the run and the largest one seen "
        "after "
        "a command (2 cores: a load near 2 means the run had the machine to itself; well above 2, "
        "other "
        "work shared it and the run is slower than a student's), or a note where the load was not "
        "recorded.",
        "",
        "| run | commit | machine | `make` | `make test` | `make workshop` |",
        "|---|---|---|---|---|---|",
    ]
    for i, r in enumerate(runs, 1):
        lines.append(
            f"| {i} | {r['commit']} | {_machine(r)} | "
            + " | ".join(f"{r[k] / 60:.1f} min" for k in LIMITS)
            + " |"
        )
    lines.append("| **limit** | | | " + " | ".join(f"{v} min" for v in LIMITS.values()) + " |")
    lines += [
        "",
        "`make test` runs after `make` in the same clone, as the README orders them; typed first "
        "on a fresh clone it also pays the `setup` and `data` steps of `make` (add them).",
    ]
    ci = [r for r in runs if "make test-slow" in r]
    for r in ci:
        setup = r["make steps"].get("setup", 0) + r["make steps"].get("data", 0)
        total = setup + r["make test"] + r["make test-slow"] + r["make unit-threads"]
        lines += [
            "",
            "CI (`.ci/run` on a fresh clone = set-up and data + `make test` + `make test-slow` + "
            "`make "
            f"unit-threads`), run {runs.index(r) + 1}: {setup / 60:.1f} + "
            f"{r['make test'] / 60:.1f} + "
            f"{r['make test-slow'] / 60:.1f} + {r['make unit-threads'] / 60:.1f} = "
            f"**{total / 60:.1f} min** "
            "(limit 25 min).",
        ]
    lines += [
        "",
        "Steps of each command (median over the runs, seconds):",
        "",
        "| command | step | seconds |",
        "|---|---|---|",
    ]
    for cmd in LIMITS:
        steps = sorted(
            {s for r in runs for s in r[f"{cmd} steps"]},
            key=lambda s: (
                list(runs[0][f"{cmd} steps"]).index(s) if s in runs[0][f"{cmd} steps"] else 99
            ),
        )
        for s in steps:
            seconds = statistics.median(
                r[f"{cmd} steps"][s] for r in runs if s in r[f"{cmd} steps"]
            )
            lines.append(f"| {cmd} | {s} | {seconds:.0f} |")
    workshop = {
        nb: statistics.median(
            r["workshop notebooks"][nb] for r in runs if nb in r["workshop notebooks"]
        )
        for nb in names
        if any(nb in r["workshop notebooks"] for r in runs)
    }
    lines += [
        "",
        "Each notebook's wall-clock seconds as the runner recorded them "
        "(`build/notebooks/timings.json`; two "
        "at a time, one thread each; median over the runs, longest first):",
        "",
        "| notebook | during `make` | during `make workshop` |",
        "|---|---|---|",
    ]
    lines += [
        f"| {nb} | {s:.0f} | {f'{workshop[nb]:.0f}' if nb in workshop else 'not run'} |"
        for nb, s in sorted(median.items(), key=lambda kv: -kv[1])
    ]
    OUT_MD.write_text("\n".join(lines) + "\n")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument(
        "--append", action="store_true", help="add to the runs in benchmarks/two-commands.json"
    )
    parser.add_argument(
        "--ci-once",
        action="store_true",
        help="in the first run also time `make test-slow` and `make unit-threads` (the rest of CI)",
    )
    args = parser.parse_args()
    keep = Path(tempfile.mkdtemp(prefix="retarget-two-commands-logs-"))
    runs = json.loads(OUT_RUNS.read_text()) if args.append and OUT_RUNS.exists() else []
    for i in range(args.repeat):
        runs.append(one_run(keep, ci=args.ci_once and i == 0))
        OUT_RUNS.write_text(json.dumps(runs, indent=1) + "\n")
        print(
            f"run {i + 1}: " + ", ".join(f"{k} {runs[-1][k] / 60:.1f} min" for k in LIMITS),
            flush=True,
        )
        write(runs)
    print(
        f"wrote {OUT_MD.relative_to(REPO)}, {OUT_RUNS.relative_to(REPO)} and "
        f"{OUT_TIMES.relative_to(REPO)}; logs in {keep}"
    )


if __name__ == "__main__":
    main()
