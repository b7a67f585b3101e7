"""The solutions files (notebooks/solutions/NN_name.py) and putting answers in the student cells
(retarget_lib/notebook/solutions.py), and the reference of a value exercise read from them."""

import nbformat
import pytest

from retarget_lib.notebook.exercises import ExerciseAuthoringError, solution_value
from retarget_lib.notebook.solutions import (
    inject,
    parse_solutions,
    solutions_file,
    student_cells,
    with_solutions,
    write_injected,
)

pytestmark = pytest.mark.tooling  # nothing here depends on the thread count (make unit-threads)

SOLUTIONS = '''"""Reference answers of notebook 07 (not a module: blocks run in the notebook)."""

# exercise 07.1
total = sum(values)

# exercise 07.2
def double(x):
    # exercise 07.2 is named in a comment, which does not start a block
    return 2 * x


'''


def notebook():
    md, code = nbformat.v4.new_markdown_cell, nbformat.v4.new_code_cell
    nb = nbformat.v4.new_notebook()
    nb.cells = [
        code("values = [1, 2, 3]"),
        md("**Exercise 07.1** Sum them."),
        code("# exercise 07.1: your code here\ntotal = NotAnswered"),
        code('check_value("07.1", total, 6.5)'),
        md("**Exercise 07.2** Double."),
        code("# exercise 07.2: your code here\ndef double(x):\n    raise NotImplementedError"),
    ]
    nb.cells[2].outputs = [nbformat.v4.new_output("stream", text="old output\n")]
    return nb


def test_parse_blocks_by_their_exact_first_line():
    blocks = parse_solutions(SOLUTIONS)
    assert blocks == {
        "07.1": "total = sum(values)\n",
        "07.2": "def double(x):\n    # exercise 07.2 is named in a comment, which does not start"
        " a block\n    return 2 * x\n",
    }
    with pytest.raises(ValueError, match="two solution blocks"):
        parse_solutions("# exercise 07.1\na = 1\n# exercise 07.1\na = 2\n")
    with pytest.raises(ValueError, match="empty"):
        parse_solutions("# exercise 07.1\n\n# exercise 07.2\nb = 1\n")
    assert parse_solutions("no blocks here") == {}


def test_student_cells_are_found_by_their_first_line():
    assert student_cells(notebook()) == {"07.1": 2, "07.2": 5}
    nb = notebook()
    nb.cells.append(nbformat.v4.new_code_cell("# exercise 07.1: your code here\ntotal = 1"))
    with pytest.raises(ValueError, match="two student cells"):
        student_cells(nb)


def test_inject_puts_answers_in_a_copy_and_is_idempotent(tmp_path):
    nb = notebook()
    path = tmp_path / "07_sums.ipynb"
    nbformat.write(nb, path)
    (tmp_path / "solutions").mkdir()
    solutions_file(path).write_text(SOLUTIONS)
    assert solutions_file(path) == tmp_path / "solutions" / "07_sums.py"
    solved = with_solutions(nb, solutions_file(path))
    assert nb.cells[2].source.endswith("total = NotAnswered")  # the original is unchanged
    assert solved.cells[2].source == "# exercise 07.1: reference answer\ntotal = sum(values)\n"
    assert solved.cells[2].outputs == []
    assert solved.cells[5].source.startswith("# exercise 07.2: reference answer\ndef double(x):")
    assert [c.source for i, c in enumerate(solved.cells) if i not in (2, 5)] == [
        c.source for i, c in enumerate(nb.cells) if i not in (2, 5)
    ]
    again = with_solutions(solved, solutions_file(path))  # the teacher's book re-injects
    assert [c.source for c in again.cells] == [c.source for c in solved.cells]
    # the copy executes as a notebook would: the answers define what the checks read
    namespace = {}
    for cell in solved.cells:
        if cell.cell_type == "code" and not cell.source.startswith("check_"):
            exec(cell.source, namespace)
    assert namespace["total"] == 6 and namespace["double"](4) == 8

    wrong = write_injected(path, tmp_path / "wrong.ipynb", {"07.2": "double = 0"}, note="wrong")
    cells = nbformat.read(wrong, as_version=4).cells
    assert cells[5].source == "# exercise 07.2: wrong\ndouble = 0\n"
    assert cells[2].source.endswith("total = NotAnswered")
    assert nbformat.read(write_injected(path, tmp_path / "s.ipynb"), as_version=4).cells[2].source
    with pytest.raises(ValueError, match="07.9"):
        inject(nb, {"07.9": "x = 1"})


def test_a_solutions_file_must_answer_every_exercise(tmp_path):
    path = tmp_path / "07.py"
    path.write_text("# exercise 07.1\ntotal = sum(values)\n")
    with pytest.raises(ValueError, match="07.2"):
        with_solutions(notebook(), path)


def test_solution_value_runs_the_block_in_a_copy_of_the_namespace():
    import numpy as np
    import torch

    from retarget_lib.core import rotations as R
    from retarget_lib.core.kinematics import forward_kinematics

    namespace = {
        "np": np,
        "torch": torch,
        "R": R,
        "forward_kinematics": forward_kinematics,
        "parents": (-1, 0, 1),
        "offsets": torch.tensor([[0, 0, 0], [0.3, 0, 0], [0.25, 0, 0]], dtype=torch.float64),
        "bend": R.quat_from_axis_angle(torch.tensor([0, 0, np.pi / 2], dtype=torch.float64)),
        "wrist": "the student's own",
    }
    value = solution_value("01.1", "wrist", namespace)
    assert np.allclose(value, [0.3, 0.25, 0.0])
    assert namespace["wrist"] == "the student's own"
    with pytest.raises(ExerciseAuthoringError, match="does not set"):
        solution_value("01.1", "no_such_name", namespace)
    with pytest.raises(ExerciseAuthoringError, match="01.99"):
        solution_value("01.99", "wrist", namespace)
    with pytest.raises(ExerciseAuthoringError, match="solutions"):
        solution_value("99.1", "wrist", namespace)
