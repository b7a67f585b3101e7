"""Reference answers kept out of the notebooks, and putting them (or other answers) back in.

Each notebook's exercises have their answers in ``notebooks/solutions/<notebook stem>.py``, never
in the notebook or the book. The file is a list of blocks, each starting with the exact line
``# exercise NN.K``; a block is what the student cell of exercise ``NN.K`` (the code cell whose
first line is ``# exercise NN.K: your code here``) holds once answered. Text before the first block
(the file's docstring) is ignored. The file is not a module: its blocks run in the notebook's
namespace, after the cells above them.

:func:`inject` puts answers in the student cells of a copy of a notebook (the solutions for the
teacher's book and the checks' own tests, or wrong answers to prove that every check can fail);
:func:`~retarget_lib.notebook.exercises.solution_value` runs one block in a copy of the notebook's
namespace: the reference of a value exercise, which the notebook cannot show.

Usage::

    python -m retarget_lib.notebook.solutions notebooks/01_rotations_and_fk.ipynb --out 01.ipynb
"""

from __future__ import annotations

import argparse
import copy
import re
import sys
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from ..files import atomic_write

__all__ = [
    "SOLUTIONS_FOLDER",
    "STUDENT_HEADER",
    "parse_solutions",
    "read_solutions",
    "solutions_file",
    "student_cells",
    "inject",
    "with_solutions",
    "write_injected",
]

#: the folder beside the notebooks that holds their solutions
SOLUTIONS_FOLDER = "solutions"
#: the first line of a student cell, as committed
STUDENT_HEADER = "# exercise {label}: your code here"
#: the first line of a student cell holding an injected answer
INJECTED_HEADER = "# exercise {label}: {note}"
_BLOCK = re.compile(r"^# exercise (\d{2}[a-z]?\.\d+)\s*$", re.MULTILINE)
_STUDENT = re.compile(r"^# exercise (\d{2}[a-z]?\.\d+): ")


def parse_solutions(text: str) -> dict[str, str]:
    """``{label: code}`` of a solutions file's blocks (the ``# exercise NN.K`` line left out).

    Raises:
        ValueError: a label given twice, or a block without code.
    """
    marks = list(_BLOCK.finditer(text))
    out: dict[str, str] = {}
    for k, m in enumerate(marks):
        end = marks[k + 1].start() if k + 1 < len(marks) else len(text)
        code = text[m.end() : end].strip("\n").rstrip()
        label = m.group(1)
        if label in out:
            raise ValueError(f"exercise {label} has two solution blocks")
        if not code.strip():
            raise ValueError(f"exercise {label}: its solution block is empty")
        out[label] = code + "\n"
    return out


def read_solutions(path: str | Path) -> dict[str, str]:
    """:func:`parse_solutions` of a file."""
    return parse_solutions(Path(path).read_text(encoding="utf-8"))


def solutions_file(notebook: str | Path) -> Path:
    """Where a notebook's solutions live: ``solutions/<stem>.py`` beside it (it may not exist: a
    notebook of the reader's own, without exercises)."""
    notebook = Path(notebook)
    return notebook.parent / SOLUTIONS_FOLDER / f"{notebook.stem}.py"


def student_cells(nb: Any) -> dict[str, int]:
    """``{label: cell index}`` of a notebook's student cells (first line ``# exercise NN.K: ...``).

    Raises:
        ValueError: two student cells with one label.
    """
    found: dict[str, int] = {}
    for i, cell in enumerate(nb.cells):
        m = _STUDENT.match(cell.source) if cell.cell_type == "code" else None
        if m:
            if m.group(1) in found:
                raise ValueError(f"exercise {m.group(1)} has two student cells")
            found[m.group(1)] = i
    return found


def inject(nb: Any, answers: Mapping[str, str], note: str = "reference answer") -> Any:
    """A copy of ``nb`` whose student cells hold ``answers`` (the other cells unchanged; the
    injected cells' outputs cleared).

    Args:
        nb: a notebook (``nbformat.NotebookNode``).
        answers: ``{label: code}``; a label missing here keeps its student cell as it is.
        note: what the injected cells' first line says after the label.

    Raises:
        ValueError: an answer for an exercise the notebook has no student cell for.
    """
    cells = student_cells(nb)
    unknown = sorted(set(answers) - set(cells))
    if unknown:
        raise ValueError(f"no student cell for exercise(s) {', '.join(unknown)}")
    out = copy.deepcopy(nb)
    for label, code in answers.items():
        cell = out.cells[cells[label]]
        cell.source = INJECTED_HEADER.format(label=label, note=note) + "\n" + code.rstrip() + "\n"
        cell.outputs = []
        cell.execution_count = None
    return out


def with_solutions(nb: Any, solutions: str | Path) -> Any:
    """A copy of ``nb`` with every student cell holding its reference answer.

    Raises:
        ValueError: a student cell without a solution block, or a block without a student cell.
    """
    answers = read_solutions(solutions)
    missing = sorted(set(student_cells(nb)) - set(answers))
    if missing:
        raise ValueError(f"{solutions}: no solution block for exercise(s) {', '.join(missing)}")
    return inject(nb, answers)


def write_injected(
    notebook: str | Path,
    out: str | Path,
    answers: Mapping[str, str] | None = None,
    note: str = "reference answer",
) -> Path:
    """Write a copy of ``notebook`` with its solutions (``answers=None``) or the given answers in
    its student cells.

    Returns:
        ``out``.
    """
    import nbformat  # the dev extra (docs/architecture.md): only here, never in a kernel

    nb = nbformat.read(notebook, as_version=4)
    nb = (
        with_solutions(nb, solutions_file(notebook))
        if answers is None
        else inject(nb, answers, note)
    )
    with atomic_write(Path(out), "w") as f:
        nbformat.write(nb, f)
    return Path(out)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description="Write a copy of a notebook with its solutions in the student cells."
    )
    parser.add_argument("notebook", type=Path)
    parser.add_argument("--out", type=Path, required=True)
    args = parser.parse_args(argv)
    try:
        print(write_injected(args.notebook, args.out))
    except (OSError, ValueError) as e:
        print(f"solutions: {e}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
