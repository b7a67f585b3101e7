"""The notebook runner writes what a notebook computes and nothing that changes from run to run."""

import nbformat

from retarget_lib.notebook.runner import run_notebook


def test_a_rerun_that_computes_the_same_values_writes_the_same_file(tmp_path):
    nb = nbformat.v4.new_notebook()
    nb.cells = [nbformat.v4.new_code_cell("x = sum(range(10))\nprint(x)")]
    nb.cells[0].metadata["execution"] = {"iopub.execute_input": "2026-01-01T00:00:00Z"}  # old run
    source = tmp_path / "tiny.ipynb"
    nbformat.write(nb, source)
    written = []
    for run in ("first", "second"):
        out = tmp_path / run
        out.mkdir()
        assert run_notebook(source, out, force=True) is not None
        written.append((out / "tiny.ipynb").read_bytes())
    assert written[0] == written[1]
    cell = nbformat.reads(written[0].decode(), as_version=4).cells[0]
    assert cell.outputs[0]["text"] == "45\n"
    assert "execution" not in cell.metadata
