"""Grade one notebook's exercises outside Jupyter (``retarget exercises NN``).

The notebook (the student's copy, or the committed one with its solutions injected) is executed
headless with every cell run even after an error; each exercise's result is read back from what its
check printed (``Exercise NN.K: correct`` / ``not answered yet``) or raised
(:class:`~retarget_lib.notebook.exercises.ExerciseError`, one line). A student cell that raised, or
a check that raised anything else, makes the exercise wrong with that exception's type.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from .book import NOTEBOOKS_DIR
from .solutions import inject, solutions_file, student_cells, with_solutions

__all__ = [
    "Result",
    "CORRECT",
    "NOT_ANSWERED",
    "WRONG",
    "find_notebook",
    "prepare",
    "grade",
    "grade_notebook",
    "grade_variants",
]

CORRECT, NOT_ANSWERED, WRONG = "correct", "not answered yet", "wrong"
_NUMBER = re.compile(r"^\d{1,2}[a-z]?$")


@dataclass(frozen=True)
class Result:
    """One exercise's outcome.

    Attributes:
        label: ``"NN.K"``.
        status: ``"correct"``, ``"not answered yet"`` or ``"wrong"``.
        line: the line to print (for a wrong answer, the check's own line: why, and the hint).
    """

    label: str
    status: str
    line: str


def find_notebook(number: str, notebooks_dir: Path = NOTEBOOKS_DIR) -> Path:
    """The notebook numbered ``number`` (``"01"``, ``"1"``, ``"08b"``).

    Raises:
        ValueError: no such notebook, or one whose exercises are still the old kind (no student
            cells ``# exercise NN.K: your code here``).
    """
    text = str(number).strip()
    if not _NUMBER.match(text):
        raise ValueError(f"{number!r} is not a notebook number (e.g. 01 or 08b)")
    digits = re.match(r"\d+", text)
    assert digits is not None
    text = digits.group().zfill(2) + text[digits.end() :]
    found = sorted(notebooks_dir.glob(f"{text}_*.ipynb"))
    if not found:
        raise ValueError(f"no notebook numbered {text} in {notebooks_dir.name}/")
    return found[0]


def _outputs_text(cell: Any) -> list[str]:
    lines: list[str] = []
    for out in cell.get("outputs", []):
        if out.get("output_type") == "stream":
            text = out.get("text", "")
            lines += ("".join(text) if isinstance(text, list) else text).splitlines()
    return lines


def _errors(cell: Any) -> list[Any]:
    return [o for o in cell.get("outputs", []) if o.get("output_type") == "error"]


def _read_results(nb: Any, labels: list[str]) -> tuple[list[Result], list[str]]:
    """Each exercise's result, and one line per other cell that raised."""
    students = student_cells(nb)
    owner: dict[int, str] = {}
    results = []
    for label in labels:
        line = re.compile(rf"^Exercise {re.escape(label)}: (correct|not answered yet)$")
        result = None
        student_error = _errors(nb.cells[students[label]])
        if student_error:
            e = student_error[0]
            result = Result(label, WRONG, f"Exercise {label}: wrong: your cell raised {e.ename}")
        for i, cell in enumerate(nb.cells):
            if cell.cell_type != "code" or result is not None:
                continue
            errors = _errors(cell)
            for e in errors:
                if e.ename == "ExerciseError" and e.evalue.startswith(f"Exercise {label}: "):
                    result, owner[i] = Result(label, WRONG, e.evalue), label
            for text in _outputs_text(cell):
                m = line.match(text)
                if m and result is None:
                    result, owner[i] = Result(label, m.group(1), text), label
            if (
                result is None
                and errors
                and re.search(rf"check_\w+\(\s*['\"]{re.escape(label)}['\"]", cell.source)
            ):
                owner[i] = label
                result = Result(
                    label, WRONG, f"Exercise {label}: wrong: its check raised {errors[0].ename}"
                )
        if result is None:
            result = Result(label, WRONG, f"Exercise {label}: wrong: its check did not run")
        results.append(result)
    other = [
        f"cell {i}: {_errors(cell)[0].ename}"
        for i, cell in enumerate(nb.cells)
        if cell.cell_type == "code"
        and _errors(cell)
        and i not in owner
        and i not in set(students.values())
    ]
    return results, other


def grade(nb: Any, cwd: Path, timeout: int = 900) -> tuple[list[Result], list[str]]:
    """Execute a notebook (in place, every cell even after an error) and read its exercises.

    Args:
        nb: the notebook (``nbformat.NotebookNode``), with the answers to grade in its cells.
        cwd: the folder the kernel runs in (the notebooks' folder, for relative paths).
        timeout: seconds per cell.

    Returns:
        ``(one Result per exercise in notebook order, "cell N: ExceptionType" for each other
        cell that raised)``.
    """
    labels = list(student_cells(nb))
    _client(nb, cwd, timeout).execute()
    return _read_results(nb, labels)


def _client(nb: Any, cwd: Path, timeout: int) -> Any:
    """A kernel client that runs ``nb``'s cells in ``cwd`` and keeps going after an error."""
    from nbclient import NotebookClient  # the dev extra, as in runner.py

    return NotebookClient(
        nb,
        timeout=timeout,
        kernel_name="python3",
        allow_errors=True,
        record_timing=False,
        resources={"metadata": {"path": str(cwd)}},
    )


def prepare(
    number: str,
    notebook: str | Path | None = None,
    solutions: bool = False,
    answers: Mapping[str, str] | None = None,
    notebooks_dir: Path = NOTEBOOKS_DIR,
) -> tuple[Any, Path]:
    """The notebook to grade, and the folder its kernel runs in: notebook ``number``'s student copy
    (``notebook``, default the one in ``notebooks/``), optionally with the reference answers
    (``solutions``) or the given ``answers`` put in its student cells.

    Raises:
        ValueError: an unknown notebook, one without exercises of this kind, or answers for
            exercises it does not have.
        OSError: ``notebook`` cannot be read.
    """
    import nbformat

    committed = find_notebook(number, notebooks_dir)
    path = Path(notebook) if notebook is not None else committed
    nb = nbformat.read(path, as_version=4)
    if not student_cells(nb):
        raise ValueError(
            f"{path.name} has no exercise cells '# exercise NN.K: your code here' (its exercises "
            "are still the old kind: open the notebook and run its solution cells)"
        )
    if solutions:
        nb = with_solutions(nb, solutions_file(committed))
    if answers:
        nb = inject(nb, answers, note="answer under test")
    return nb, committed.parent


def grade_notebook(
    number: str,
    notebook: str | Path | None = None,
    solutions: bool = False,
    answers: Mapping[str, str] | None = None,
    notebooks_dir: Path = NOTEBOOKS_DIR,
    timeout: int = 900,
) -> tuple[list[Result], list[str]]:
    """:func:`grade` what :func:`prepare` (same arguments) gives."""
    return grade(*prepare(number, notebook, solutions, answers, notebooks_dir), timeout=timeout)


def grade_variants(
    number: str,
    variants: Mapping[str, Mapping[str, str] | None],
    notebooks_dir: Path = NOTEBOOKS_DIR,
    timeout: int = 900,
) -> dict[str, tuple[list[Result], list[str]]]:
    """Grade several sets of answers with one execution of the notebook's lesson.

    The cells above the first student cell (the lesson, and the exercises' setup) run once; then,
    for each variant in turn, the cells from the first student cell to the end run again with
    that variant's answers in the student cells, in the same kernel. A variant's exercise cells
    therefore see what earlier variants defined: list the unanswered variant (``{}``) first, and
    the reference answers (``None``) last. The checks' own tests grade four variants of every
    notebook this way, at the cost of one run of the lesson.

    Args:
        number: the notebook (``"01"``).
        variants: ``{name: answers}``; ``answers`` is ``{label: code}`` as for :func:`prepare`
            (``{}`` leaves the placeholders), or ``None`` for the solutions file's answers.
        notebooks_dir: where the notebooks are.
        timeout: seconds per cell.

    Returns:
        ``{name: (results, other cells that raised)}`` as :func:`grade` returns them.
    """
    base, cwd = prepare(number, notebooks_dir=notebooks_dir)
    committed = find_notebook(number, notebooks_dir)
    labels = list(student_cells(base))
    first = min(student_cells(base).values())
    client = _client(base, cwd, timeout)
    out: dict[str, tuple[list[Result], list[str]]] = {}
    with client.setup_kernel():
        for i in range(first):
            client.execute_cell(base.cells[i], i)
        for name, answers in variants.items():
            nb = (
                with_solutions(base, solutions_file(committed))
                if answers is None
                else inject(base, answers, note="answer under test")
            )
            for i in range(first, len(nb.cells)):
                if nb.cells[i].cell_type == "code":
                    nb.cells[i].outputs = []
                    client.execute_cell(nb.cells[i], i)
            out[name] = _read_results(nb, labels)
    return out
