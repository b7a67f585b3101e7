"""Execute notebooks headless into ``build/notebooks/`` (used by ``make`` and ``make workshop``).

Each notebook is executed into ``<out>/<name>.ipynb``; the HTML pages are written from those by the
book builder (:mod:`retarget_lib.notebook.book`, ``build/book/``). A notebook is re-run only when
it, the library, the configs or the data manifest changed since its last successful run, so
``make`` is cheap the second time. The wall-clock and CPU seconds of every run (the kernel's CPU
time included) go to ``<out>/timings.json``, which the book's index and the teacher's guide quote.
Widget views that come with a picture or HTML to show (the knobs, the motion player) are left out
of the saved notebooks, with the widget state (:func:`.book.drop_widget_views`): a re-run that
computes the same values writes the same file, and the saved notebook shows the offline slider
until its cells run again in a kernel.

Usage::

    python -m retarget_lib.notebook.runner --out build/notebooks notebooks/00_overview.ipynb ...
    python -m retarget_lib.notebook.runner --out build/notebooks --workshop --jobs 2
    python -m retarget_lib.notebook.runner --out build/notebooks-teacher --solutions notebooks/0*

``--solutions`` executes the notebooks with their reference answers (``notebooks/solutions/``) in
the student cells, for the teacher's book (``make book-teacher``); a notebook without a solutions
file (still on the old exercises) is left out, and says so.
"""

from __future__ import annotations

import argparse
import concurrent.futures
import datetime as dt
import json
import resource
import subprocess
import sys
import time
from pathlib import Path

from ..config import active_profile
from ..files import REPO_ROOT, atomic_write
from .book import drop_widget_views, load_learning_path
from .solutions import solutions_file, with_solutions

TIMINGS_FILE = "timings.json"
#: per-notebook seconds of the last measured fresh-clone run (benchmarks/two_commands.py writes it):
#: the order in which ``--jobs`` starts notebooks when ``<out>/timings.json`` does not know them yet
REFERENCE_TIMINGS = REPO_ROOT / "benchmarks" / "notebook-times.json"
_TIMING_PREFIX = "RUNNER-TIMING "


def _newest_input(notebook: Path) -> float:
    inputs = [notebook, solutions_file(notebook), REPO_ROOT / "data_manifest.yaml"]
    for folder in ("retarget_lib", "configs"):
        inputs += list((REPO_ROOT / folder).rglob("*.py")) + list(
            (REPO_ROOT / folder).rglob("*.yaml")
        )
    return max(p.stat().st_mtime for p in inputs if p.exists())


def _cpu_seconds() -> float:
    """CPU seconds (user + system) of this process and of its finished children (the kernels)."""
    own, kids = (
        resource.getrusage(resource.RUSAGE_SELF),
        resource.getrusage(resource.RUSAGE_CHILDREN),
    )
    return own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime


def is_up_to_date(notebook: Path, out_dir: Path) -> bool:
    out_nb = out_dir / notebook.name
    return out_nb.exists() and out_nb.stat().st_mtime >= _newest_input(notebook)


def run_notebook(
    notebook: Path, out_dir: Path, timeout: int = 900, force: bool = False, solutions: bool = False
) -> dict | None:
    """Execute one notebook; write ``out_dir/<name>.ipynb``.

    Args:
        notebook: path of the source notebook.
        out_dir: destination folder.
        timeout: per-cell timeout in seconds.
        force: run even if the output is up to date.
        solutions: put the reference answers (:func:`.solutions.solutions_file`) in the student
            cells first.

    Returns:
        ``{"seconds": wall, "cpu_seconds": cpu, "finished": iso time}`` if it was executed, ``None``
        if the output was already up to date.
    """
    if not force and is_up_to_date(notebook, out_dir):
        return None
    # here, not at the top: these take ~3 s to import, which the up-to-date check and --help should
    # not pay
    import nbformat
    from nbclient import NotebookClient

    t0, c0 = time.perf_counter(), _cpu_seconds()
    nb = nbformat.read(notebook, as_version=4)
    if solutions:
        nb = with_solutions(nb, solutions_file(notebook))
    for cell in nb.cells:  # no execution times: a re-run that changes no value changes no line
        cell.metadata.pop("execution", None)
    client = NotebookClient(
        nb,
        timeout=timeout,
        kernel_name="python3",
        record_timing=False,
        resources={"metadata": {"path": str(notebook.parent)}},
    )
    client.execute()
    drop_widget_views(nb)  # random model ids, state only a live kernel can drive
    with atomic_write(out_dir / notebook.name, "w") as f:
        nbformat.write(nb, f)
    return {
        "seconds": round(time.perf_counter() - t0, 1),
        "cpu_seconds": round(_cpu_seconds() - c0, 1),
        "finished": dt.datetime.now(dt.UTC).isoformat(timespec="seconds"),
        "profile": active_profile(),
    }


def _run_in_subprocess(
    notebook: Path, out_dir: Path, force: bool, solutions: bool = False
) -> dict | None:
    """:func:`run_notebook` in a fresh process (for ``--jobs``); its CPU time is that process's."""
    cmd = (
        [
            sys.executable,
            "-m",
            "retarget_lib.notebook.runner",
            "--out",
            str(out_dir),
            "--jobs",
            "1",
            "--no-timings",
            str(notebook),
        ]
        + (["--force"] if force else [])
        + (["--solutions"] if solutions else [])
    )
    proc = subprocess.run(cmd, capture_output=True, text=True)
    if proc.returncode != 0:
        raise RuntimeError(f"{notebook.name} failed:\n{proc.stdout[-4000:]}\n{proc.stderr[-4000:]}")
    for line in proc.stdout.splitlines():
        if line.startswith(_TIMING_PREFIX):
            return json.loads(line[len(_TIMING_PREFIX) :])
    return None


def record_timings(out_dir: Path, timings: dict[str, dict]) -> None:
    """Merge ``{notebook file name: timing}`` into ``out_dir/timings.json``."""
    path = out_dir / TIMINGS_FILE
    merged = json.loads(path.read_text()) if path.exists() else {}
    merged.update(timings)
    with atomic_write(path, "w") as f:
        json.dump(dict(sorted(merged.items())), f, indent=1)


def longest_first(notebooks: list[Path], out_dir: Path | None = None) -> list[Path]:
    """``notebooks`` ordered by their last known execution time, longest first, so that ``--jobs``
    does not start the longest one last (times from ``out_dir/timings.json``, else
    :data:`REFERENCE_TIMINGS`; an unknown notebook counts as long)."""
    known: dict[str, float] = {}
    for path in (REFERENCE_TIMINGS, None if out_dir is None else out_dir / TIMINGS_FILE):
        if path is not None and path.exists():
            known.update({name: t["seconds"] for name, t in json.loads(path.read_text()).items()})
    return sorted(notebooks, key=lambda nb: -known.get(nb.name, float("inf")))


def workshop_notebooks(
    notebooks_dir: Path = REPO_ROOT / "notebooks",
) -> tuple[list[Path], list[tuple[str, str]]]:
    """The notebooks ``make workshop`` executes, and the ones it leaves out with the reason."""
    path = load_learning_path(notebooks_dir / "learning_path.yaml")
    run = [notebooks_dir / les.file for les in path.lessons if les.workshop]
    left_out = [(les.file, les.workshop_note) for les in path.lessons if not les.workshop]
    return run, left_out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("notebooks", nargs="*", type=Path)
    parser.add_argument("--out", type=Path, default=REPO_ROOT / "build" / "notebooks")
    parser.add_argument("--force", action="store_true")
    parser.add_argument(
        "--workshop",
        action="store_true",
        help="execute the notebooks marked `workshop: yes` in notebooks/learning_path.yaml",
    )
    parser.add_argument(
        "--solutions",
        action="store_true",
        help="execute with the reference answers in the student cells (notebooks/solutions/); "
        "notebooks without a solutions file are left out",
    )
    parser.add_argument("--jobs", type=int, default=1, help="notebooks executed at the same time")
    parser.add_argument("--no-timings", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    notebooks = list(args.notebooks)
    if args.workshop:
        run, left_out = workshop_notebooks()
        notebooks += [nb for nb in run if nb not in notebooks]
        for name, why in left_out:
            print(
                f"{name}: NOT executed in the workshop run ({why}); the book shows its committed "
                "outputs",
                flush=True,
            )
    if not notebooks:
        parser.error("no notebooks given (and no --workshop)")
    if args.solutions:
        for nb in [nb for nb in notebooks if not solutions_file(nb).exists()]:
            print(
                f"{nb.name}: no {solutions_file(nb).name} in solutions/ (old exercises); left out"
            )
            notebooks.remove(nb)

    t0, c0 = time.perf_counter(), _cpu_seconds()
    timings: dict[str, dict] = {}

    def report(nb: Path, timing: dict | None) -> None:
        if timing is None:
            print(f"{nb.name}: up to date -> {args.out / nb.name}", flush=True)
            return
        timings[nb.name] = timing
        print(
            f"{nb.name}: executed in {timing['seconds']:.0f} s ({timing['cpu_seconds']:.0f} CPU s)"
            f" -> {args.out / nb.name}",
            flush=True,
        )
        if args.no_timings:
            print(_TIMING_PREFIX + json.dumps(timing), flush=True)

    try:
        if args.jobs <= 1:
            for nb in notebooks:
                report(nb, run_notebook(nb, args.out, force=args.force, solutions=args.solutions))
        else:
            with concurrent.futures.ThreadPoolExecutor(args.jobs) as pool:
                futures = {
                    pool.submit(_run_in_subprocess, nb, args.out, args.force, args.solutions): nb
                    for nb in longest_first(notebooks, args.out)
                }
                for fut in concurrent.futures.as_completed(futures):
                    report(futures[fut], fut.result())
    finally:
        if timings and not args.no_timings:
            record_timings(args.out, timings)
    if len(notebooks) > 1:
        print(
            f"runner: {len(notebooks)} notebooks in {time.perf_counter() - t0:.0f} s wall, "
            f"{_cpu_seconds() - c0:.0f} CPU s (kernels included), {args.jobs} at a time",
            flush=True,
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
