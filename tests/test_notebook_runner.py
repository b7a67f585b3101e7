"""The notebook runner writes what a notebook computes and nothing that changes from run to run."""

import os
from pathlib import Path

import nbformat

from retarget_lib.notebook.runner import run_notebook

ROOT = Path(__file__).resolve().parents[1]


def _run_twice(source: Path, tmp_path: Path) -> list[bytes]:
    """The bytes the runner writes for ``source`` in two separate runs."""
    written = []
    for run in ("first", "second"):
        out = tmp_path / run
        out.mkdir()
        assert run_notebook(source, out, force=True) is not None
        written.append((out / source.name).read_bytes())
    return written


def test_a_rerun_that_computes_the_same_values_writes_the_same_file(tmp_path):
    nb = nbformat.v4.new_notebook()
    nb.cells = [nbformat.v4.new_code_cell("x = sum(range(10))\nprint(x)")]
    nb.cells[0].metadata["execution"] = {"iopub.execute_input": "2026-01-01T00:00:00Z"}  # old run
    source = tmp_path / "tiny.ipynb"
    nbformat.write(nb, source)
    written = _run_twice(source, tmp_path)
    assert written[0] == written[1]
    cell = nbformat.reads(written[0].decode(), as_version=4).cells[0]
    assert cell.outputs[0]["text"] == "45\n"
    assert "execution" not in cell.metadata


def test_solutions_are_put_in_before_executing(tmp_path):
    """``--solutions`` (the teacher's book): the student cells hold the reference answers."""
    nb = nbformat.v4.new_notebook()
    nb.cells = [nbformat.v4.new_code_cell("# exercise 07.1: your code here\nx = None\nprint(x)")]
    source = tmp_path / "07_tiny.ipynb"
    nbformat.write(nb, source)
    (tmp_path / "solutions").mkdir()
    (tmp_path / "solutions" / "07_tiny.py").write_text("# exercise 07.1\nx = 6 * 7\nprint(x)\n")
    out = tmp_path / "teacher"
    out.mkdir()
    assert run_notebook(source, out, force=True, solutions=True) is not None
    cell = nbformat.read(out / "07_tiny.ipynb", as_version=4).cells[0]
    assert cell.source.startswith("# exercise 07.1: reference answer\nx = 6 * 7")
    assert cell.outputs[0]["text"] == "42\n"


def test_a_knob_is_live_in_the_kernel_and_saved_as_the_same_offline_output(tmp_path, monkeypatch):
    """In the kernel the knob builds its ipywidgets control; the saved notebook keeps the HTML
    slider and the still, not the widget view (a random model id) nor the widget state, so two
    runs write the same file."""
    # the kernel runs in tmp_path: make it import this checkout's library
    paths = [str(ROOT), *filter(None, os.environ.get("PYTHONPATH", "").split(os.pathsep))]
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join(paths))
    nb = nbformat.v4.new_notebook()
    nb.cells = [
        nbformat.v4.new_code_cell(
            "import numpy as np\n"
            "from retarget_lib.viz.knobs import knob\n"
            "k = knob(lambda v: np.full((8, 8, 3), v, np.uint8), 'level', [0, 100, 200], "
            "default=100)\n"
            "k"
        ),
        nbformat.v4.new_code_cell("print(k.widget is not None, k.image.value == k.pngs[1])"),
    ]
    source = tmp_path / "knob.ipynb"
    nbformat.write(nb, source)
    written = _run_twice(source, tmp_path)
    assert written[0] == written[1]
    saved = nbformat.reads(written[0].decode(), as_version=4)
    assert set(saved.cells[0].outputs[0]["data"]) == {"text/html", "image/png", "text/plain"}
    assert saved.cells[1].outputs[0]["text"] == "True True\n"  # the live control was built
    assert "widgets" not in saved.metadata
