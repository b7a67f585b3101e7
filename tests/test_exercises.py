"""Exercises that check the student: every student cell ends with ``answer = None``, only student
cells assign ``answer``, every solution cell judges ``answer`` (and shows its own ``solution`` when
there is none), and a wrong answer in any student cell makes its check fail, naming the exercise."""

import ast
import json
import re
from pathlib import Path

import nbformat
import pytest

NOTEBOOK_DIR = Path(__file__).resolve().parents[1] / "notebooks"
NOTEBOOKS = sorted(NOTEBOOK_DIR.glob("[0-9][0-9]*_*.ipynb"))
LABEL = re.compile(r"check_answer\(\s*[\"']([^\"']+)[\"']")


def exercises(nb) -> list[tuple[int, int, str]]:
    """``(student cell index, solution cell index, label)`` of every exercise."""
    found = []
    for i, cell in enumerate(nb.cells):
        if cell.cell_type == "code" and "solution" in cell.metadata.get("tags", []):
            found.append((i - 1, i, LABEL.search(cell.source).group(1)))
    return found


def _check_call(source: str) -> ast.Call:
    calls = [
        n
        for n in ast.walk(ast.parse(source))
        if isinstance(n, ast.Call) and getattr(n.func, "id", None) == "check_answer"
    ]
    assert len(calls) == 1, source
    return calls[0]


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_only_student_cells_assign_answer_and_every_check_judges_it(path):
    nb = nbformat.read(path, as_version=4)
    found = exercises(nb)
    assert len(found) >= 3, f"{path.name}: {len(found)} exercises"
    students = {s for s, _, _ in found}
    for s, sol, label in found:
        student = nb.cells[s].source
        assert nb.cells[s].cell_type == "code" and student.startswith("# your code here"), (
            label,
            student,
        )
        assert student.rstrip().endswith("answer = None"), (label, student)
        call = _check_call(nb.cells[sol].source)
        assert isinstance(call.args[1], ast.Name) and call.args[1].id == "answer", (
            label,
            "judges something else",
        )
        assert "solution" in {k.arg for k in call.keywords}, (label, "shows no reference solution")
    for i, cell in enumerate(nb.cells):
        if cell.cell_type == "code" and i not in students:
            assigned = {
                t.id
                for n in ast.walk(ast.parse(cell.source))
                if isinstance(n, (ast.Assign, ast.AugAssign))
                for t in (n.targets if isinstance(n, ast.Assign) else [n.target])
                if isinstance(t, ast.Name)
            }
            assert "answer" not in assigned, f"{path.name} cell {i} assigns answer"


#: what the injected student cells use to spoil the reference solution's value
PERTURB = '''
import numpy as _np

def _wrong(x):
    """A wrong answer of the same kind: another bool, string, count or value."""
    if isinstance(x, (bool, _np.bool_)):
        return not x
    if isinstance(x, str):
        return x + " (wrong)"
    if isinstance(x, tuple):
        return tuple(_wrong(v) for v in x)
    if isinstance(x, (int, _np.integer)):
        return int(x) + 1
    return _np.asarray(x, dtype=float) * 1.1 + 0.1
'''


def _inject_wrong_answers(nb) -> None:
    """Each student cell computes the reference solution as ``answer`` and spoils it
    (``_wrong``)."""
    for s, sol, _ in exercises(nb):
        source = nb.cells[sol].source
        call = _check_call(source)
        lines = source.splitlines()
        before = "\n".join(
            lines[: call.lineno - 1]
        )  # the solution's computation, without the check
        solution = ast.unparse(next(k.value for k in call.keywords if k.arg == "solution"))
        nb.cells[s].source = f"{PERTURB}\n{before}\nanswer = _wrong({solution})"


def _wrong_answers_fail(path: Path) -> None:
    from nbclient import NotebookClient

    nb = nbformat.read(path, as_version=4)
    _inject_wrong_answers(nb)
    NotebookClient(
        nb,
        timeout=900,
        kernel_name="python3",
        allow_errors=True,
        resources={"metadata": {"path": str(NOTEBOOK_DIR)}},
    ).execute()
    for s, sol, label in exercises(nb):
        student_errors = [o for o in nb.cells[s].outputs if o.output_type == "error"]
        assert not student_errors, (
            f"{label}: the injected answer itself failed: {student_errors[0].evalue}"
        )
        errors = [o for o in nb.cells[sol].outputs if o.output_type == "error"]
        assert errors, (
            f"{label}: a wrong answer passed its check: {json.dumps(nb.cells[sol].outputs)[:300]}"
        )
        assert (
            errors[0].ename == "AssertionError"
            and f"exercise {label}: your answer" in errors[0].evalue
        ), (label, errors[0].ename, errors[0].evalue)


# Two classes, so that `make test-slow` (pytest-xdist --dist loadscope) runs the two halves of the
# notebooks on its two workers: each notebook is executed once more in full here
@pytest.mark.slow
class TestWrongAnswersFailFirstHalf:
    @pytest.mark.parametrize("path", NOTEBOOKS[::2], ids=lambda p: p.name)
    def test_a_wrong_answer_in_every_student_cell_fails_its_check(self, path):
        _wrong_answers_fail(path)


@pytest.mark.slow
class TestWrongAnswersFailSecondHalf:
    @pytest.mark.parametrize("path", NOTEBOOKS[1::2], ids=lambda p: p.name)
    def test_a_wrong_answer_in_every_student_cell_fails_its_check(self, path):
        _wrong_answers_fail(path)
