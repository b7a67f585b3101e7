"""Committed notebooks stay small and clean: every embedded image <= 150 KB, no error outputs, each
notebook opens with one setup_notebook() call and ends with a "What to try" cell or, once it has
been given them (issue 11), with the sections "## Summary", "## Exercises" and "## References" in
this order."""

import base64
import re
from pathlib import Path

import nbformat
import pytest

pytestmark = pytest.mark.tooling  # nothing here depends on the thread count (make unit-threads)

#: 00_ ... 09_, and lettered companions such as 08b_
NOTEBOOKS = sorted((Path(__file__).resolve().parents[1] / "notebooks").glob("[0-9][0-9]*_*.ipynb"))


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_images_small_no_errors_setup_and_what_to_try(path):
    nb = nbformat.read(path, as_version=4)
    code = [c for c in nb.cells if c.cell_type == "code"]
    assert "setup_notebook(" in code[0].source
    assert sum("setup_notebook(" in c.source for c in code) == 1
    headings = [
        c.source.lstrip().split("\n")[0].strip() for c in nb.cells if c.cell_type == "markdown"
    ]
    if "## Summary" in headings:
        assert headings[-1] == "## References", f"{path.name} must end with ## References"
        tail = [h for h in headings if h in ("## Summary", "## Exercises", "## References")]
        assert tail == ["## Summary", "## Exercises", "## References"]
        assert (
            headings.index("## Summary")
            < headings.index("## Exercises")
            < headings.index("## References")
        )
    else:
        assert "What to try" in nb.cells[-1].source
    for i, cell in enumerate(code):
        assert "!pip" not in cell.source and "!wget" not in cell.source
        for out in cell.get("outputs", []):
            assert out.get("output_type") != "error", f"{path.name} cell {i} has an error output"
            for mime in ("image/png", "image/gif", "image/jpeg"):
                if mime in out.get("data", {}):
                    kb = len(base64.b64decode(out["data"][mime])) / 1024
                    assert kb <= 150, f"{path.name} cell {i}: {mime} of {kb:.0f} KB"


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_outputs_name_no_path_of_the_machine_that_ran_them(path):
    # a committed page must not show where it was executed (the repository, a home or temp folder)
    repo = str(Path(__file__).resolve().parents[1])
    for i, cell in enumerate(
        c for c in nbformat.read(path, as_version=4).cells if c.cell_type == "code"
    ):
        for out in cell.get("outputs", []):
            texts = [out.get("text", "")] + [
                v for k, v in out.get("data", {}).items() if k.startswith("text/")
            ]
            for text in texts:
                text = "".join(text) if isinstance(text, list) else text
                for bad in (repo, "/home/", "/root/", "/tmp/"):
                    assert bad not in text, (
                        f"{path.name} code cell {i} prints a machine path ({bad!r})"
                    )


#: what changes on every run of the same cell: an object's memory address (``<... at 0x7f...>``,
#: a cell ending on a call that returns an object), a pandas Styler's random table id, and the
#: execution times nbclient records in a cell's metadata (checked apart)
_RUN_NOISE = re.compile(r" at 0x[0-9a-f]{6,}>|\bT_[0-9a-f]{5}_")


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_outputs_are_the_same_on_every_run(path):
    # a re-run that changes no value must not rewrite the committed outputs
    for i, cell in enumerate(
        c for c in nbformat.read(path, as_version=4).cells if c.cell_type == "code"
    ):
        assert "execution" not in cell.metadata, f"{path.name} code cell {i} keeps run times"
        for out in cell.get("outputs", []):
            for text in [out.get("text", "")] + list(out.get("data", {}).values()):
                text = "".join(text) if isinstance(text, list) else str(text)
                noise = _RUN_NOISE.search(text)
                assert noise is None, f"{path.name} code cell {i} shows {noise.group()!r}"


def test_notebooks_exist_in_order():
    numbers = sorted({p.name[:2] for p in NOTEBOOKS})
    assert numbers == [f"{i:02d}" for i in range(len(numbers))]
