"""Wall-clock time of each step of `make` and `make test`, printed at the end so a regression is
seen.

Used by the Makefile (standard library only: it runs before the virtual environment exists):

    python3 .ci/step_times.py RUN start STEP     # before a step
    python3 .ci/step_times.py RUN end STEP       # after it
    python3 .ci/step_times.py RUN report TITLE   # the steps of this make invocation, with a total

RUN identifies one `make` invocation (the Makefile passes the time it started); the records go to
build/step-times.tsv (one line per finished step: run, step, seconds). A step that make skipped
because it was up to date has no record and is reported as such.
"""

import sys
import time
from pathlib import Path

LOG = Path("build/step-times.tsv")


def main(run: str, action: str, name: str) -> None:
    LOG.parent.mkdir(parents=True, exist_ok=True)
    started = LOG.parent / f".step-{run}-{name}"
    if action == "start":
        started.write_text(repr(time.time()))
    elif action == "end":
        seconds = time.time() - float(started.read_text())
        started.unlink()
        with LOG.open("a") as f:
            f.write(f"{run}\t{name}\t{seconds:.1f}\n")
    elif action == "report":
        rows = [line.split("\t") for line in LOG.read_text().splitlines()] if LOG.exists() else []
        steps = [(step, float(s)) for r, step, s in rows if r == run]
        total = time.time() - int(run) / 1e9
        print(f"\n{name}: time of each step (build/step-times.tsv)")
        for step, s in steps:
            print(f"  {step:<34} {s:7.0f} s  ({s / 60:.1f} min)")
        if not steps:
            print("  every step was up to date")
        print(f"  {'total, this make':<34} {total:7.0f} s  ({total / 60:.1f} min)")
    else:
        raise SystemExit(f"step_times.py: unknown action {action!r}")


if __name__ == "__main__":
    main(*sys.argv[1:4])
