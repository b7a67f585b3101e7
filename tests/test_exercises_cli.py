"""``retarget exercises NN``: one line per exercise and the exit code (0: every answered exercise
is correct, 1: one is wrong, 2: bad input with one line on stderr). The student's copy here is a
small notebook with two exercises (numbered like notebook 01's, whose folder the kernel runs in), so
that each run costs one kernel start, not the whole of notebook 01 (tests/test_exercises.py runs
that)."""

import nbformat
import pytest

from retarget_lib.cli import main

pytestmark = pytest.mark.tooling  # nothing here depends on the thread count (make unit-threads)

SETUP = """import numpy as np

from retarget_lib.notebook.exercises import NotAnswered, check_function, check_prediction"""
CHECK_DOUBLE = (
    'check_function("01.1", double, lambda x: 2 * x, '
    "[(np.arange(3.0),), (np.full(2, 5.0),), (np.array([-1.5]),), (np.eye(2),)])"
)
UNANSWERED = {
    "01.1": "def double(x):\n    raise NotImplementedError",
    "01.2": "direction = NotAnswered",
}


def student_copy(tmp_path, answers):
    md, code = nbformat.v4.new_markdown_cell, nbformat.v4.new_code_cell
    nb = nbformat.v4.new_notebook()
    nb.cells = [
        code(SETUP),
        md("**Exercise 01.1** Double it."),
        code(f"# exercise 01.1: your code here\n{answers['01.1']}"),
        code(CHECK_DOUBLE),
        md("**Exercise 01.2** Predict: does it go up, down or stay the same?"),
        code(f"# exercise 01.2: your code here\n{answers['01.2']}"),
        code('check_prediction("01.2", direction, -0.25)'),
    ]
    path = tmp_path / "mine.ipynb"
    nbformat.write(nb, path)
    return str(path)


def run(capsys, *argv):
    code = main(["exercises", *argv])
    out, err = capsys.readouterr()
    return code, out.splitlines(), err


def test_unanswered_is_not_wrong(tmp_path, capsys):
    code, lines, _ = run(capsys, "01", "--notebook", student_copy(tmp_path, UNANSWERED))
    assert code == 0
    assert lines == ["Exercise 01.1: not answered yet", "Exercise 01.2: not answered yet"]


def test_right_answers_exit_zero(tmp_path, capsys):
    answers = {"01.1": "def double(x):\n    return x + x", "01.2": 'direction = "down"'}
    code, lines, _ = run(capsys, "1", "--notebook", student_copy(tmp_path, answers))
    assert code == 0
    assert lines == ["Exercise 01.1: correct", "Exercise 01.2: correct"]


def test_a_wrong_answer_or_a_broken_cell_exits_one_with_why(tmp_path, capsys):
    answers = {"01.1": "def double(x):\n    return x * 3", "01.2": "direction = undefined_name"}
    code, lines, _ = run(capsys, "01", "--notebook", student_copy(tmp_path, answers))
    assert code == 1
    assert lines[0].startswith("Exercise 01.1: wrong on ") and "reference" in lines[0]
    assert lines[1] == "Exercise 01.2: wrong: your cell raised NameError"


@pytest.mark.parametrize(
    "argv, says",
    [
        (["99"], "no notebook numbered 99"),
        (["x1"], "not a notebook number"),
        (["01", "--notebook", "/nonexistent/mine.ipynb"], "mine.ipynb"),
    ],
)
def test_bad_input_exits_two_with_one_line(argv, says, capsys):
    code, lines, err = run(capsys, *argv)
    assert code == 2 and lines == []
    err_lines = [e for e in err.splitlines() if "executing" not in e]
    assert len(err_lines) == 1 and "Traceback" not in err, err
    assert err_lines[0].startswith("retarget exercises: error: ") and says in err_lines[0], err


def test_a_copy_with_old_exercises_exits_two_with_one_line(tmp_path, capsys):
    """A notebook whose exercises are still the old kind (no student cell): its own file, since
    every notebook of the suite is being converted."""
    nb = nbformat.v4.new_notebook()
    nb.cells = [
        nbformat.v4.new_markdown_cell("**Exercise 01.1** Double it."),
        nbformat.v4.new_code_cell("# your code here\nanswer = None"),
    ]
    path = tmp_path / "old.ipynb"
    nbformat.write(nb, path)
    test_bad_input_exits_two_with_one_line(["01", "--notebook", str(path)], "old kind", capsys)
