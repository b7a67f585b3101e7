"""The offline HTML book: the learning path lists every notebook, pages load nothing from other
hosts, and the widget fallbacks (the motion player's scrubber, the knobs' sliders) are in the
HTML."""

import base64
import re
from pathlib import Path

import nbformat
import pytest

from retarget_lib.notebook import book
from retarget_lib.notebook.book import (
    LearningPath,
    build_book,
    load_learning_path,
    offline_outputs,
    remote_references,
)
from retarget_lib.notebook.viewer import VIEWER_PAGE

pytestmark = pytest.mark.tooling  # nothing here depends on the thread count (make unit-threads)

ROOT = Path(__file__).resolve().parents[1]
NOTEBOOK_FILES = sorted(p.name for p in (ROOT / "notebooks").glob("*.ipynb"))


# ------------------------------------------------------------------------------------ learning path
def test_learning_path_lists_every_notebook_and_only_existing_ones():
    path = load_learning_path()
    listed = [les.file for les in path.lessons]
    unlisted = sorted(set(NOTEBOOK_FILES) - set(listed))
    assert not unlisted, f"add these notebooks to notebooks/learning_path.yaml: {unlisted}"
    missing = [f for f in listed if not (ROOT / "notebooks" / f).exists()]
    assert not missing, f"notebooks/learning_path.yaml lists files that do not exist: {missing}"
    for les in path.lessons:
        assert les.title and les.teaches and les.minutes > 0, les.file


def test_learning_path_is_in_file_order():
    """The path reads 00, 01, ... in order; lettered companions (08b) follow their notebook."""
    listed = [les.file for les in load_learning_path().lessons]
    assert listed == sorted(listed)


def test_learning_path_rejects_a_need_that_comes_later(tmp_path):
    bad = tmp_path / "learning_path.yaml"
    bad.write_text(
        "notebooks:\n"
        "  - {file: a.ipynb, title: A, teaches: x, needs: [b.ipynb], minutes: 5, workshop: yes}\n"
        "  - {file: b.ipynb, title: B, teaches: y, needs: [], minutes: 5, workshop: yes}\n"
    )
    with pytest.raises(ValueError, match="needs b.ipynb"):
        load_learning_path(bad)
    bad.write_text(
        "notebooks:\n"
        "  - {file: a.ipynb, title: A, teaches: x, needs: [], minutes: 5, workshop: no}\n"
    )
    with pytest.raises(ValueError, match="workshop_note"):
        load_learning_path(bad)


def test_workshop_runs_the_marked_notebooks_and_names_the_others():
    from retarget_lib.notebook.runner import workshop_notebooks

    path = load_learning_path()
    run, left_out = workshop_notebooks()
    assert [p.name for p in run] == [les.file for les in path.lessons if les.workshop]
    assert all(p.exists() for p in run)
    assert {name for name, _ in left_out} == {les.file for les in path.lessons if not les.workshop}
    assert all(why for _, why in left_out)


# ------------------------------------------------------------------------------------ offline pages
def test_remote_reference_pattern_catches_cdn_loads_and_spares_links():
    assert remote_references('<script src="https://cdn.example/x.js"></script>')
    assert remote_references("<link rel='stylesheet' href='//cdn.example/x.css'>")
    assert remote_references('<img src="http://example.org/a.png">')
    assert remote_references('const m = (await import("https://cdn.example/m.mjs")).default;')
    assert remote_references("<style>@import url('https://fonts.example/f.css');</style>")
    assert not remote_references('<a href="https://doi.org/10.1111/cgf.13947">the paper</a>')
    assert not remote_references('<script src="_static/mathjax/tex-svg-full.js"></script>')
    assert not remote_references('<img src="data:image/png;base64,AAAA">')


def test_saved_notebooks_keep_only_widget_views_with_nothing_else_to_show():
    """What the runner saves: a widget view that comes with HTML or a picture (a knob, the player)
    is dropped; the widget state goes with the last widget view."""
    html_out = {book.WIDGET_VIEW: {"model_id": "k"}, "text/html": "<div>", "text/plain": "k"}
    bare_out = {book.WIDGET_VIEW: {"model_id": "w"}, "text/plain": "w"}
    state = {"application/vnd.jupyter.widget-state+json": {"state": {}}}

    def notebook(*datas):
        nb = nbformat.v4.new_notebook()
        nb.metadata["widgets"] = state
        outputs = [nbformat.v4.new_output("display_data", data=dict(d)) for d in datas]
        nb.cells = [nbformat.v4.new_code_cell("k", outputs=outputs)]
        return nb

    nb = book.drop_widget_views(notebook(html_out))
    assert nb.cells[0].outputs[0]["data"] == {"text/html": "<div>", "text/plain": "k"}
    assert "widgets" not in nb.metadata
    nb = book.drop_widget_views(notebook(html_out, bare_out))
    assert book.WIDGET_VIEW not in nb.cells[0].outputs[0]["data"]
    assert nb.cells[0].outputs[1]["data"] == bare_out  # nothing else to show: kept, with its state
    assert nb.metadata["widgets"] == state


def test_widget_view_is_dropped_where_a_picture_or_html_is_there():
    png = base64.b64encode(b"\x89PNG fake").decode()
    nb = nbformat.v4.new_notebook()
    nb.metadata["widgets"] = {"application/vnd.jupyter.widget-state+json": {"state": {}}}
    nb.cells = [
        nbformat.v4.new_code_cell(
            "p",
            outputs=[
                nbformat.v4.new_output(
                    "display_data",
                    data={
                        book.WIDGET_VIEW: {"model_id": "x"},
                        "image/png": png,
                        "text/plain": "player",
                    },
                ),
                nbformat.v4.new_output(
                    "display_data", data={book.WIDGET_VIEW: {"model_id": "y"}, "text/plain": "w"}
                ),
                nbformat.v4.new_output(
                    "display_data", data={"image/gif": png, "text/plain": "gif"}
                ),
            ],
        )
    ]
    assert book.widget_only_outputs(nb) == [0]
    offline_outputs(nb)
    with_png, widget_only, gif = (o["data"] for o in nb.cells[0].outputs)
    assert book.WIDGET_VIEW not in with_png and with_png["image/png"] == png
    assert book.WIDGET_VIEW in widget_only  # nothing else to show: left as it is
    assert f"data:image/gif;base64,{png}" in gif["text/html"]
    assert "widgets" not in nb.metadata


FIXTURE_CELLS = [
    """import numpy as np
import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt
from retarget_lib import viz
from retarget_lib.core.motion import Motion
from retarget_lib.core.skeleton import canonical22_skeleton

viz.configure_offscreen()
sk = canonical22_skeleton(np.zeros((22, 3)) + 0.1)
rot = np.zeros((12, 22, 4))
rot[..., 0] = 1
root = np.zeros((12, 3))
root[:, 0] = np.linspace(0, 0.5, 12)
motions = {"slide": Motion(sk, rot, root, 30.0)}""",
    "viz.player(motions, window_size=(160, 120), offline_frames=3)",
    """def draw(alpha):
    fig, ax = plt.subplots(figsize=(2, 1.5))
    ax.plot([0, 1], [0, alpha])
    return fig

viz.knob(draw, "alpha", [1, 2, 3], default=2)""",
    "Some math: $E_{int} = \\sum w$.",
]


@pytest.mark.slow
def test_book_from_a_fixture_shows_the_player_and_knob_offline(tmp_path, monkeypatch):
    """Executed headless (as `make` does) and exported: the widget's CDN script is gone, the
    player's scrubber frames and the knob's pictures are inline, nothing is fetched."""
    from retarget_lib.notebook.runner import run_notebook

    def no_viewer(out: Path) -> Path:  # the 3-D viewer's retargeting takes a minute or two and
        page = out / "viewer.html"  # this book does not show it (test_book_viewer.py does)
        page.write_text("<!DOCTYPE html>")
        return page

    monkeypatch.setattr(book, "write_viewer", no_viewer)

    nb = nbformat.v4.new_notebook()
    nb.cells = [nbformat.v4.new_code_cell(c) for c in FIXTURE_CELLS[:3]] + [
        nbformat.v4.new_markdown_cell(FIXTURE_CELLS[3])
    ]
    src = tmp_path / "src" / "fixture.ipynb"
    src.parent.mkdir()
    nbformat.write(nb, src)
    executed = tmp_path / "executed"
    executed.mkdir()
    assert run_notebook(src, executed, timeout=300) is not None
    run = nbformat.read(executed / "fixture.ipynb", as_version=4)
    # the runner keeps the offline views and drops the widget view (a random model id)
    player_out, knob_out = (run.cells[i].outputs[0]["data"] for i in (1, 2))
    assert {"image/png", "text/html"} <= set(player_out) and book.WIDGET_VIEW not in player_out
    assert {"image/png", "text/html"} <= set(knob_out) and book.WIDGET_VIEW not in knob_out
    assert "widgets" not in run.metadata

    out = tmp_path / "book"
    pages = build_book(
        out,
        executed=None,
        committed=src.parent,
        path=LearningPath("fixture"),
        extra=[executed / "fixture.ipynb"],
        verbose=False,
    )
    page = (out / "fixture.html").read_text()
    assert (
        pages[0].name == "index.html" and (out / "_static" / "mathjax" / "tex-svg-full.js").exists()
    )
    assert remote_references(page) == []
    assert "application/vnd.jupyter.widget" not in page
    pictures = set(re.findall(r"data:image/png;base64,([A-Za-z0-9+/=]+)", page))
    # the scrubber: 3 frames + the current one (all distinct: the root slides); the knob: 3 values
    assert len(pictures) >= 3 + 3
    assert page.count('type="range"') == 2
    assert "tex-svg-full.js" in page and "$E_{int}" in page


@pytest.mark.slow
def test_book_from_the_committed_notebooks_is_offline_and_keeps_every_picture(tmp_path):
    """The book built from notebooks/ as committed (no execution): every page loads nothing from
    another host, and every picture output of a notebook is inline in its page."""
    pages = build_book(tmp_path, executed=None, verbose=False)
    assert [p.name for p in pages[1:-1]] == [
        les.stem + ".html" for les in load_learning_path().lessons
    ]
    assert pages[-1].name == VIEWER_PAGE
    for page_path in pages:
        page = page_path.read_text()
        assert remote_references(page) == [], page_path.name
        if page_path.name in ("index.html", VIEWER_PAGE):
            continue
        nb = nbformat.read(ROOT / "notebooks" / (page_path.stem + ".ipynb"), as_version=4)
        for cell in nb.cells:
            for out in cell.get("outputs", []):
                data = out.get("data", {})
                # the picture a page shows: the output's own PNG/GIF unless an HTML view replaces it
                for mime in ("image/png", "image/gif"):
                    if mime in data and "text/html" not in data:
                        head = "".join(data[mime].split())[:200]
                        assert head in page, f"{page_path.name}: a {mime} output is missing"


def test_player_bundle_carries_an_offline_scrubber():
    """The player's display bundle: widget view + offline scrubber (text/html, inline pictures, no
    remote reference) + PNG; ``offline_frames=0`` leaves the scrubber out."""
    import numpy as np

    from retarget_lib import viz
    from retarget_lib.core.motion import Motion
    from retarget_lib.core.skeleton import canonical22_skeleton

    sk = canonical22_skeleton(np.zeros((22, 3)) + 0.1)
    rot = np.zeros((10, 22, 4))
    rot[..., 0] = 1
    root = np.zeros((10, 3))
    root[:, 0] = np.linspace(0, 0.5, 10)
    motions = {"slide": Motion(sk, rot, root, 30.0)}
    live = viz.player(motions, window_size=(120, 90), offline_frames=4)
    bundle = live._repr_mimebundle_()
    assert {book.WIDGET_VIEW, "text/html", "image/png"} <= set(bundle)
    frames = set(re.findall(r"data:image/png;base64,([A-Za-z0-9+/=]+)", bundle["text/html"]))
    assert (
        len(frames) == 4 + 1
    )  # 0, 3, 6, 9 and the current frame 5: the root slides, so all differ
    assert remote_references(bundle["text/html"]) == []
    live.close()
    still = viz.player(motions, mode="static", window_size=(120, 90), offline_frames=0)
    assert set(still._repr_mimebundle_()) == {"image/png", "text/plain"}
    still.close()


def test_pages_show_no_answer_and_the_teachers_show_them(tmp_path):
    """A student's page has no answer (they live in ``solutions/``); the teacher's page has them
    in the student cells (``make book-teacher``)."""
    md, code = nbformat.v4.new_markdown_cell, nbformat.v4.new_code_cell
    nb = nbformat.v4.new_notebook()
    nb.cells = [
        md("**Exercise 07.1** Write it."),
        code("# exercise 07.1: your code here\ny = NotAnswered"),
        code('check_value("07.1", y, solution_value("07.1", "y", globals()))'),
        md("**Exercise 07.2** And this."),
        code("# exercise 07.2: your code here\nx = NotAnswered"),
        code('check_value("07.2", x, solution_value("07.2", "x", globals()))'),
    ]
    path = tmp_path / "07_fixture.ipynb"
    nbformat.write(nb, path)
    (tmp_path / "solutions").mkdir()
    (tmp_path / "solutions" / "07_fixture.py").write_text(
        "# exercise 07.1\ny = SECRET_OLD\n# exercise 07.2\nx = SECRET_NEW\n"
    )

    def page(teacher):
        readers = book.for_readers(nbformat.read(path, as_version=4), path, teacher)
        return book.export_page(readers, None, None, "fixture")

    student, teacher = page(False), page(True)
    for secret in ("SECRET_OLD", "SECRET_NEW"):
        assert secret not in student and secret in teacher, secret
    assert "Exercise 07.1" in student and "your code here" in student
