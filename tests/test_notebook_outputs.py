"""Committed notebooks stay small and clean: every embedded image <= 150 KB, no error outputs, each
notebook opens with one setup_notebook() call and ends with a "What to try" cell."""

import base64
from pathlib import Path

import nbformat
import pytest

#: 00_ ... 09_, and lettered companions such as 08b_
NOTEBOOKS = sorted((Path(__file__).resolve().parents[1] / "notebooks").glob("[0-9][0-9]*_*.ipynb"))


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_images_small_no_errors_setup_and_what_to_try(path):
    nb = nbformat.read(path, as_version=4)
    code = [c for c in nb.cells if c.cell_type == "code"]
    assert "setup_notebook(" in code[0].source
    assert sum("setup_notebook(" in c.source for c in code) == 1
    assert "What to try" in nb.cells[-1].source
    for i, cell in enumerate(code):
        assert "!pip" not in cell.source and "!wget" not in cell.source
        for out in cell.get("outputs", []):
            assert out.get("output_type") != "error", f"{path.name} cell {i} has an error output"
            for mime in ("image/png", "image/gif", "image/jpeg"):
                if mime in out.get("data", {}):
                    kb = len(base64.b64decode(out["data"][mime])) / 1024
                    assert kb <= 150, f"{path.name} cell {i}: {mime} of {kb:.0f} KB"


def test_notebooks_exist_in_order():
    numbers = sorted({p.name[:2] for p in NOTEBOOKS})
    assert numbers == [f"{i:02d}" for i in range(len(numbers))]
