"""Every notebook's exercises check the student, and every check can fail.

Each numbered notebook has a solutions file ``notebooks/solutions/<stem>.py`` (docs/notebooks.md,
"Writing an exercise"): each exercise is a student cell ``# exercise NN.K: your code here`` left as
its placeholder, then a check; the answers are only in the solutions file, and the committed
outputs show no answer. With the solutions put in, every check passes; with a constant or with the
reference answer spoiled, every check fails naming its exercise.
"""

import ast
import re
from pathlib import Path

import nbformat
import pytest

from retarget_lib.notebook.runner import longest_first
from retarget_lib.notebook.solutions import read_solutions, solutions_file, student_cells

NOTEBOOK_DIR = Path(__file__).resolve().parents[1] / "notebooks"
NOTEBOOKS = sorted(NOTEBOOK_DIR.glob("[0-9][0-9]*_*.ipynb"))
CONVERTED = [p for p in NOTEBOOKS if solutions_file(p).exists()]
EXERCISE = re.compile(r"\*\*Exercise\s+(\d+[a-z]?\.\d+)\.?\*\*")
NEW_CHECK = re.compile(r"check_(?:function|value|prediction)\(\s*[\"']([^\"']+)[\"']")


def test_every_notebook_is_converted():
    assert CONVERTED == NOTEBOOKS, [p.name for p in NOTEBOOKS if p not in CONVERTED]


# ------------------------------------------------------------------------------ converted notebooks
def _defined_name(code: str) -> tuple[str, bool]:
    """The name a student cell or a solution block answers with, and whether it is a function
    (the last top-level definition or assignment)."""
    found = None
    for node in ast.parse(code).body:
        if isinstance(node, ast.FunctionDef):
            found = (node.name, True)
        elif isinstance(node, ast.Assign) and isinstance(node.targets[-1], ast.Name):
            found = (node.targets[-1].id, False)
    assert found is not None, code
    return found


def _is_placeholder(code: str) -> bool:
    """A student cell as committed: ``name = NotAnswered``, or a function whose body (after its
    docstring) is ``raise NotImplementedError``."""
    body = ast.parse(code).body
    if len(body) != 1:
        return False
    node = body[0]
    if isinstance(node, ast.Assign):
        return isinstance(node.value, ast.Name) and node.value.id == "NotAnswered"
    if isinstance(node, ast.FunctionDef):
        stmts = [
            s
            for s in node.body
            if not (isinstance(s, ast.Expr) and isinstance(s.value, ast.Constant))
        ]
        return (
            len(stmts) == 1
            and isinstance(stmts[0], ast.Raise)
            and "NotImplementedError" in ast.unparse(stmts[0])
        )
    return False


@pytest.mark.parametrize("path", CONVERTED, ids=lambda p: p.name)
def test_converted_exercises_follow_the_contract(path):
    nb = nbformat.read(path, as_version=4)
    number = path.name.split("_", 1)[0]
    labels = [
        m.group(1)
        for c in nb.cells
        if c.cell_type == "markdown"
        for m in EXERCISE.finditer(c.source)
    ]
    students = student_cells(nb)
    assert list(students) == labels, (labels, list(students))
    solutions = read_solutions(solutions_file(path))
    assert set(solutions) == set(labels), "one solution block per exercise, no other"
    checks = [
        (i, m.group(1))
        for i, c in enumerate(nb.cells)
        if c.cell_type == "code"
        for m in NEW_CHECK.finditer(c.source)
    ]
    for label, i in students.items():
        assert label.startswith(number + ".")
        source = nb.cells[i].source
        header, _, body = source.partition("\n")
        assert header == f"# exercise {label}: your code here", header
        assert _is_placeholder(body), f"{label}: the committed student cell is answered:\n{body}"
        assert _defined_name(body) == _defined_name(solutions[label]), label
        after = [j for j, lab in checks if lab == label]
        assert after and min(after) > i, f"{label}: no check after its student cell"
    for i, cell in enumerate(nb.cells):
        assert "solution" not in cell.metadata.get("tags", []), f"cell {i} is a solution cell"
        assert not cell.metadata.get("jupyter", {}).get("source_hidden"), f"cell {i} is hidden"
        assert "check_answer" not in cell.source, f"cell {i} uses the old check_answer"


@pytest.mark.parametrize("path", CONVERTED, ids=lambda p: p.name)
def test_committed_outputs_show_no_answer(path):
    """The committed notebook is unanswered: every check line says so, and carries no number."""
    nb = nbformat.read(path, as_version=4)
    solutions = read_solutions(solutions_file(path))
    for i, cell in enumerate(nb.cells):
        for out in cell.get("outputs", []):
            assert out.get("output_type") != "error", f"cell {i} raised"
            text = "".join(out.get("text", "")) if out.get("output_type") == "stream" else ""
            for line in text.splitlines():
                if line.startswith("Exercise "):
                    assert re.fullmatch(r"Exercise \d+[a-z]?\.\d+: not answered yet", line), line
    assert _leaked(nb, solutions) == []


def test_the_leak_check_sees_a_solution_put_in_the_notebook():
    from retarget_lib.notebook.solutions import with_solutions

    path = CONVERTED[0]
    nb = nbformat.read(path, as_version=4)
    solutions = read_solutions(solutions_file(path))
    assert _leaked(with_solutions(nb, solutions_file(path)), solutions) == sorted(solutions)


def _leaked(nb, solutions: dict[str, str]) -> list[str]:
    """The exercises whose solution code is in the notebook (half its lines or more: a line of it
    may recur elsewhere, such as a loop over the joints)."""
    sources = "\n".join(c.source for c in nb.cells)
    leaked = []
    for label, code in sorted(solutions.items()):
        lines = _code_lines(code)
        if len([line for line in lines if line in sources]) >= max(1, len(lines) / 2):
            leaked.append(label)
    return leaked


def _code_lines(code: str) -> list[str]:
    """A block's lines of code worth searching for: not its docstrings, comments, signatures
    (the student cell has them too) or short lines."""
    lines = code.splitlines()
    for node in ast.walk(ast.parse(code)):
        if isinstance(node, ast.FunctionDef) and ast.get_docstring(node) is not None:
            for k in range(node.body[0].lineno - 1, node.body[0].end_lineno):
                lines[k] = ""
    return [
        s.strip() for s in lines if len(s.strip()) > 25 and not s.strip().startswith(("#", "def "))
    ]


#: spoils a value of any kind the answers produce (bool, str, int, float, array, tensor)
PERTURB = '''
def _spoiled(x):
    """A wrong answer of the same kind: another bool, string, integer or value."""
    if isinstance(x, bool):
        return not x
    if isinstance(x, str):
        return x + " (wrong)"
    if isinstance(x, tuple):
        return tuple(_spoiled(v) for v in x)
    if isinstance(x, int):
        return x + 1
    return x * 1.1 + 0.1
'''


def constant_answers(solutions: dict[str, str]) -> dict[str, str]:
    """Each exercise answered with a constant: zero, or a function returning zero."""
    out = {}
    for label, code in solutions.items():
        name, is_function = _defined_name(code)
        out[label] = (
            f"def {name}(*args, **kwargs):\n    return 0.0\n" if is_function else f"{name} = 0\n"
        )
    return out


def spoiled_answers(solutions: dict[str, str]) -> dict[str, str]:
    """Each exercise answered with its reference answer, spoiled (:data:`PERTURB`)."""
    out = {}
    for label, code in solutions.items():
        name, is_function = _defined_name(code)
        if is_function:
            tail = (
                f"_reference_{name} = {name}\n\n\ndef {name}(*args, **kwargs):\n"
                f"    return _spoiled(_reference_{name}(*args, **kwargs))\n"
            )
        else:
            tail = f"{name} = _spoiled({name})\n"
        out[label] = f"{PERTURB}\n{code}\n{tail}"
    return out


def _every_check_says_not_answered_passes_the_solutions_and_fails_wrong_answers(path):
    """Each notebook's lesson executed once, then its exercises four times in the same kernel
    (:func:`~retarget_lib.notebook.grading.grade_variants`): unanswered, with constants, with the
    reference answers spoiled, with the solutions."""
    from retarget_lib.notebook.grading import grade_variants

    solutions = read_solutions(solutions_file(path))
    graded = grade_variants(
        path.name.split("_", 1)[0],
        {
            "unanswered": {},
            "constant": constant_answers(solutions),
            "spoiled": spoiled_answers(solutions),
            "solutions": None,
        },
    )
    for name, (results, other) in graded.items():
        assert not other, f"{name}: cells that are not exercises raised: {other}"
        assert {r.label for r in results} == set(solutions), name
    assert [r.line for r in graded["unanswered"][0]] == [
        f"Exercise {r.label}: not answered yet" for r in graded["unanswered"][0]
    ]
    assert [r.line for r in graded["solutions"][0]] == [
        f"Exercise {r.label}: correct" for r in graded["solutions"][0]
    ]
    for name in ("constant", "spoiled"):
        for r in graded[name][0]:
            assert r.status == "wrong", f"{name} {r.label}: a wrong answer passed: {r.line}"
            assert r.line.startswith(f"Exercise {r.label}: wrong"), r.line
            assert "your cell raised" not in r.line, (
                f"{name} {r.label}: the answer itself failed: {r.line}"
            )
            assert "check raised" not in r.line, f"{name} {r.label}: the check broke: {r.line}"
            # nothing of the reference: no digit but the label's
            assert not re.search(r"\d", r.line.replace(f"Exercise {r.label}", "")), r.line


# Two classes, so that `make test-slow` (pytest-xdist --dist loadscope: a module or a class goes to
# one worker) runs them on its two workers: each notebook's lesson is executed once more in full
# here, most of test-slow's time. The halves alternate down the notebooks' reference times.
_BY_TIME = longest_first(CONVERTED)


@pytest.mark.slow
@pytest.mark.data
class TestExercisesFirstHalf:
    @pytest.mark.parametrize("path", _BY_TIME[::2], ids=lambda p: p.name)
    def test_every_check_says_not_answered_passes_the_solutions_and_fails_wrong_answers(self, path):
        _every_check_says_not_answered_passes_the_solutions_and_fails_wrong_answers(path)


@pytest.mark.slow
@pytest.mark.data
class TestExercisesSecondHalf:
    @pytest.mark.parametrize("path", _BY_TIME[1::2], ids=lambda p: p.name)
    def test_every_check_says_not_answered_passes_the_solutions_and_fails_wrong_answers(self, path):
        _every_check_says_not_answered_passes_the_solutions_and_fails_wrong_answers(path)


def test_the_two_halves_hold_every_notebook_once():
    assert sorted(_BY_TIME[::2] + _BY_TIME[1::2]) == sorted(CONVERTED)
