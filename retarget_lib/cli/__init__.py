"""Command line: ``retarget …`` (also ``python -m retarget_lib …``).

::

    retarget data build|list|verify      build the embedded dataset; list/verify data_manifest.yaml
    retarget retarget --source IN.bvh --target TARGET.bvh|CHARACTER [--target-mesh SHAPE.npz]
                      [--source-mesh SHAPE.npz] --method NAME (from retarget_lib.methods.registry)
                      [--checkpoint ID|PATH] [--no-eso] [--fps N] [--force] [--device auto]
                      --out OUT.bvh
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
    retarget exercises NN [--notebook MINE.ipynb] [--solutions]
                                         a notebook's exercises checked outside Jupyter, one line
                                         each (retarget_lib.notebook.grading); exit 1 if one is
                                         wrong

Each command imports what it runs inside its ``_cmd_*`` function: the library below this module
loads torch (about 3 s here), which ``retarget --help`` (0.2 s) does without.

Bad input (a :class:`~retarget_lib.errors.RetargetInputError`, a
:class:`~retarget_lib.files.DataError`, or an ``OSError`` on a user's path) exits with status 2
and one line on stderr naming the file and the problem, never a traceback. SIGTERM and SIGINT
exit with 128 + the signal number after removing the temporary file of any write in progress.

The package: :mod:`.parser` (the arguments), :mod:`.commands` and :mod:`.evaluate` (what each
subcommand does); :func:`main` here.
"""

from __future__ import annotations

import sys
import warnings

from ..errors import RetargetInputError, RetargetWarning
from ..files import DataError, exit_on_signals
from .parser import build_parser

__all__ = ["build_parser", "main"]


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
