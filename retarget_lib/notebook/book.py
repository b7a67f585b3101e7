"""The offline HTML book: every notebook as a self-contained HTML page plus an index of the learning
path.

``notebooks/learning_path.yaml`` lists the notebooks in reading order with what each teaches, what
it needs and how long it takes; :func:`build_book` turns each listed notebook into
``<out>/<name>.html`` (executed copy from ``build/notebooks/`` when ``make`` made one, otherwise the
outputs committed in ``notebooks/``) and writes ``<out>/index.html``.

Every page opens from disk with no network: nbconvert's ``lab`` template is used with the parts
that load from CDNs removed (require.js, the ipywidgets HTML manager, mermaid) and MathJax 3 served
from a local copy (``<out>/_static/mathjax/tex-svg-full.js``, copied from the PyPI package
``django-static-mathjax``, which bundles MathJax 3.2.2 and needs no Django to be imported: one
file with every TeX extension and SVG output, so no web fonts and nothing loaded on demand). Before
export each notebook goes through :func:`offline_outputs`: a widget view is dropped where the output
also carries a picture or HTML (the motion player's still image or offline scrubber), and GIFs
become inline ``<img>`` tags (nbconvert would otherwise show their ``text/plain``). Images are
embedded as ``data:`` URIs. A notebook's links into ``../build/book/`` (the 3-D viewer page, and
the files :func:`.viewer.show_viewer`'s output loads) are made relative to the book's folder,
where the pages sit (:func:`.viewer.book_links`).

Why nbconvert and not Jupyter Book: Jupyter Book 2 (mystmd) downloads its site theme from
api.mystmd.org at build time and fails offline; Jupyter Book 1 builds offline but is the legacy
line, its pages also load MathJax, require.js and the widget manager from CDNs unless reconfigured,
and it would add about 90 packages (Sphinx 7, myst-nb, and markdown-it-py held below 4) for what
nbconvert, already a dependency, does with one template and an index page.

No page shows an exercise's answer: the solutions live in ``notebooks/solutions/`` (see
:mod:`.solutions`). The **teacher's book**
(``--teacher``, ``make book-teacher``) is the opposite: each notebook with a solutions file has
its reference answers put in its student cells (executed so by ``runner --solutions`` into
``build/notebooks-teacher/``).

Usage::

    python -m retarget_lib.notebook.book --out build/book            # after `make` executed them
    python -m retarget_lib.notebook.book --out build/book --executed /nonexistent   # committed
    outputs
"""

from __future__ import annotations

import argparse
import base64
import datetime as dt
import html
import json
import re
import shutil
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import yaml

from ..files import REPO_ROOT, atomic_write
from .solutions import solutions_file, with_solutions
from .viewer import (
    VIEWER_CHARACTERS,
    VIEWER_METHODS,
    VIEWER_PAGE,
    book_links,
    viewer_cell,
    write_viewer,
)

NOTEBOOKS_DIR = REPO_ROOT / "notebooks"
LEARNING_PATH = NOTEBOOKS_DIR / "learning_path.yaml"
TEMPLATE_DIR = Path(__file__).resolve().parent / "book_template"
#: the MathJax files copied into every book: one self-contained component (TeX input, SVG output,
#: every TeX extension built in; 2.2 MB) and its licence
MATHJAX_PARTS = ("es5/tex-svg-full.js", "LICENSE")
WIDGET_VIEW = "application/vnd.jupyter.widget-view+json"
TIMINGS_FILE = "timings.json"

#: every reference to another host in a page (``<script src=``, ``<link href=``, ``<img src=``,
#: module imports and CSS ``url()``); tests and :func:`remote_references` use it
REMOTE_REFERENCE = re.compile(
    r"""<(?:script|link|img|iframe|source|video|audio)\b[^>]*?\b(?:src|href)\s*=\s*["']?\s*(?:https?:)?//"""
    r"""|\bimport\s*\(\s*["'](?:https?:)?//|@import\s+(?:url\()?["']?(?:https?:)?//|url\(\s*["']?(?:https?:)?//""",
    re.IGNORECASE,
)


@dataclass(frozen=True)
class Lesson:
    """One entry of the learning path (``notebooks/learning_path.yaml``)."""

    file: str
    title: str
    teaches: str
    needs: tuple[str, ...]
    minutes: int
    workshop: bool
    workshop_note: str = ""

    @property
    def stem(self) -> str:
        return Path(self.file).stem

    @property
    def number(self) -> str:
        """The notebook's number as written in its file name (``"08b"``)."""
        return self.file.split("_", 1)[0]


@dataclass(frozen=True)
class LearningPath:
    title: str
    lessons: tuple[Lesson, ...] = field(default_factory=tuple)

    def lesson(self, file: str) -> Lesson:
        return next(les for les in self.lessons if les.file == file)


def load_learning_path(path: Path = LEARNING_PATH) -> LearningPath:
    """Read and check the learning path.

    Raises:
        ValueError: a missing field, a duplicate file, or a ``needs`` entry that is not listed
            earlier.
    """
    raw = yaml.safe_load(Path(path).read_text())
    lessons, seen = [], set()
    for i, entry in enumerate(raw.get("notebooks") or []):
        missing = {"file", "title", "teaches", "needs", "minutes", "workshop"} - set(entry)
        if missing:
            raise ValueError(
                f"{path}: entry {i} ({entry.get('file', '?')}) lacks {sorted(missing)}"
            )
        if entry["file"] in seen:
            raise ValueError(f"{path}: {entry['file']} is listed twice")
        for need in entry["needs"] or []:
            if need not in seen:
                raise ValueError(
                    f"{path}: {entry['file']} needs {need}, which is not listed before it"
                )
        if not isinstance(entry["workshop"], bool):
            raise ValueError(f"{path}: {entry['file']}: workshop must be yes or no")
        if not entry["workshop"] and not entry.get("workshop_note"):
            raise ValueError(
                f"{path}: {entry['file']} is left out of the workshop without a workshop_note"
            )
        seen.add(entry["file"])
        lessons.append(
            Lesson(
                entry["file"],
                entry["title"],
                entry["teaches"],
                tuple(entry["needs"] or ()),
                int(entry["minutes"]),
                entry["workshop"],
                entry.get("workshop_note", ""),
            )
        )
    return LearningPath(raw.get("title", "Notebooks"), tuple(lessons))


# ------------------------------------------------------------------------------------------- export
def _has_fallback(data) -> bool:
    """A widget view's output also carries something else to show (a picture, HTML, ...)."""
    return bool(set(data) - {WIDGET_VIEW, "text/plain"})


def drop_widget_views(nb):
    """Drop the widget views a saved notebook cannot keep alive (in place; returns ``nb``).

    An output that carries a widget view *and* something else to show (the knobs' and the motion
    player's HTML slider and still PNG) loses the view: its model id is a fresh random id on every
    run, and its model's state saved in the notebook would only draw controls that do nothing
    until the cell is run again, where the HTML slider works without a kernel. The saved widget
    state goes too once no widget view is left. The runner applies this to every notebook it
    saves, so a re-run that computes the same values writes the same file; in a running kernel
    the same cells show the live widgets.
    """
    left = False
    for cell in nb.cells:
        for out in cell.get("outputs", []):
            data = out.get("data")
            if data and WIDGET_VIEW in data:
                if _has_fallback(data):
                    del data[WIDGET_VIEW]
                else:
                    left = True
    if not left:
        nb.metadata.pop("widgets", None)
    return nb


def offline_outputs(nb):
    """Make a notebook's outputs exportable offline (in place; returns ``nb``).

    - an output that carries a widget view *and* something else to show (``image/png``,
      ``text/html``, ...) loses the widget view (:func:`drop_widget_views`): the HTML export would
      render the widget with a script from a CDN, and the still image or offline scrubber is what
      the page can show;
    - the notebook's saved widget state is dropped (it only feeds that script);
    - ``image/gif`` outputs get a ``text/html`` ``<img>`` with the GIF inline (nbconvert's HTML
      template has no GIF renderer and would fall back to ``text/plain``).
    """
    drop_widget_views(nb)
    for cell in nb.cells:
        for out in cell.get("outputs", []):
            data = out.get("data")
            if not data:
                continue
            if "image/gif" in data and "text/html" not in data:
                gif = data["image/gif"]
                gif = gif if isinstance(gif, str) else base64.b64encode(gif).decode()
                data["text/html"] = (
                    f'<img src="data:image/gif;base64,{"".join(gif.split())}" alt="animation">'
                )
    nb.metadata.pop("widgets", None)
    return nb


#: a code cell that shows the 3-D viewer (its output is replaced by the book's own viewer)
_SHOWS_VIEWER = re.compile(r"^show_viewer\(", re.M)


def with_viewer(nb, cell):
    """The notebook with every ``show_viewer(...)`` cell's output replaced by ``cell`` (the book's
    viewer, :func:`.viewer.viewer_cell`): executed by ``make``, such a cell shows only a link
    (``build=False``: the viewer is written by the book, not by every notebook run). In place;
    returns ``nb``."""
    import nbformat

    for c in nb.cells:
        if c.cell_type == "code" and _SHOWS_VIEWER.search(c.source):
            c.outputs = [
                nbformat.v4.new_output(
                    "display_data",
                    data={"text/html": cell._repr_html_(), "text/plain": repr(cell)},
                )
            ]
    return nb


def for_readers(nb, notebook: Path, teacher: bool):
    """The notebook as a book shows it: for students as it is (its student cells hold no answer;
    the answers live in ``solutions/``), for the teacher with the reference answers of
    ``solutions/<stem>.py`` in the student cells when the notebook has such a file."""
    if not teacher:
        return nb
    solutions = solutions_file(notebook)
    return with_solutions(nb, solutions) if solutions.exists() else nb


def widget_only_outputs(nb) -> list[int]:
    """Indices of code cells with an output that is a widget view and nothing else to show: such an
    output is blank in the book (give it a picture, like the player and the knobs)."""
    return [
        i
        for i, cell in enumerate(nb.cells)
        for out in cell.get("outputs", [])
        if WIDGET_VIEW in out.get("data", {}) and not _has_fallback(out["data"])
    ]


def _exporter():
    from nbconvert import HTMLExporter
    from traitlets.config import Config

    # through the config: the template is looked up while the exporter is constructed
    config = Config({"TemplateExporter": {"extra_template_basedirs": [str(TEMPLATE_DIR)]}})
    return HTMLExporter(config=config, template_name="book", embed_images=True)


def export_page(
    nb, lesson: Lesson | None, path: LearningPath | None, source_note: str, exporter=None
) -> str:
    """One notebook as an offline HTML page with the book's navigation bar.

    Args:
        nb: the (executed) notebook; modified by :func:`offline_outputs`.
        lesson: its learning-path entry (``None`` for a notebook outside the path, e.g. a test
            fixture).
        path: the learning path (previous / next links).
        source_note: where the outputs come from, shown under the navigation bar.
        exporter: a reused ``HTMLExporter`` (building one costs ~0.3 s).
    """
    exporter = exporter or _exporter()
    prev_link = next_link = ""
    if lesson is not None and path is not None:
        stems = [les.stem for les in path.lessons]
        i = stems.index(lesson.stem)
        if i > 0:
            prev_link = f"{stems[i - 1]}.html"
        if i + 1 < len(stems):
            next_link = f"{stems[i + 1]}.html"
    needs = [(Path(n).stem + ".html", n.split("_", 1)[0]) for n in (lesson.needs if lesson else ())]
    resources = {
        "book": {
            "prev": prev_link,
            "next": next_link,
            "note": source_note,
            "needs": needs,
            "minutes": lesson.minutes if lesson else None,
        }
    }
    body, _ = exporter.from_notebook_node(offline_outputs(nb), resources=resources)
    return book_links(body)  # a notebook's links into build/book/ (the 3-D viewer) from here


def remote_references(page: str) -> list[str]:
    """Every place in an HTML page that would load something from another host."""
    return [page[max(0, m.start() - 20) : m.end() + 60] for m in REMOTE_REFERENCE.finditer(page)]


def copy_mathjax(out: Path) -> Path:
    """Copy MathJax into ``out/_static/mathjax`` (``tex-svg-full.js`` and its licence)."""
    import mathjax  # the PyPI package django-static-mathjax: MathJax 3.2.2 as package data

    src = Path(mathjax.__file__).parent / "static" / "mathjax"
    dst = out / "_static" / "mathjax"
    dst.mkdir(parents=True, exist_ok=True)
    for part in MATHJAX_PARTS:
        target = dst / Path(part).name
        if not target.exists() or target.stat().st_size != (src / part).stat().st_size:
            shutil.copy2(src / part, target)
    return dst


# -------------------------------------------------------------------------------------------- index
def _fmt_seconds(s: float) -> str:
    return f"{s:.0f} s" if s < 90 else f"{s / 60:.1f} min"


def index_html(path: LearningPath, sources: dict[str, str], timings: dict[str, dict]) -> str:
    """The book's front page: the learning path as a table (what, needs, time) and a dependency
    list."""
    rows = []
    for les in path.lessons:
        needs = (
            ", ".join(
                f'<a href="{Path(n).stem}.html">{html.escape(n.split("_", 1)[0])}</a>'
                for n in les.needs
            )
            or "—"
        )
        t = timings.get(les.file)
        run = (
            f'{_fmt_seconds(t["seconds"])}<br><span class="note">{_fmt_seconds(t["cpu_seconds"])} '
            "CPU</span>"
            if t
            else "not executed here"
        )
        workshop = (
            "yes"
            if les.workshop
            else f'no <span class="note">({html.escape(les.workshop_note)})</span>'
        )
        rows.append(
            f'<tr><td class="num">{html.escape(les.number)}</td>'
            f'<td><a href="{les.stem}.html"><b>{html.escape(les.title)}</b></a><br>'
            f'<span class="teaches">{html.escape(les.teaches)}</span></td>'
            f'<td>{needs}</td><td class="num">{les.minutes} min</td><td class="num">{run}</td>'
            f"<td>{workshop}</td><td "
            f'class="note">{html.escape(sources.get(les.file, ""))}</td></tr>'
        )
    total = sum(les.minutes for les in path.lessons)
    total_ws = sum(les.minutes for les in path.lessons if les.workshop)
    built = dt.datetime.now(dt.UTC).strftime("%Y-%m-%d %H:%M UTC")
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1.0">
<title>{html.escape(path.title)}</title>
<style>
body {{ font-family: system-ui, -apple-system, "Segoe UI", sans-serif; max-width: 72rem;
       margin: 2rem auto; padding: 0 1rem; color: #222; line-height: 1.45; }}
table {{ border-collapse: collapse; width: 100%; }}
th, td {{ border-bottom: 1px solid #ddd; padding: .45rem .5rem; vertical-align: top;
         text-align: left; }}
th {{ background: #f4f4f4; }}
td.num {{ white-space: nowrap; }}
.teaches {{ color: #444; }}
.note {{ color: #777; font-size: .85em; }}
a {{ color: #1a5fb4; }}
</style></head>
<body>
<h1>{html.escape(path.title)}</h1>
<p>Read the notebooks in this order. Each page is the notebook executed headless, with every
picture inline; it opens from disk without a network. To change a value and re-run a cell, open the
notebook itself: <code>.venv/bin/jupyter lab notebooks/</code>.</p>
<p><b><a href="{VIEWER_PAGE}">The 3-D viewer</a></b>: one real clip retargeted by
{", ".join(VIEWER_METHODS)} onto a real and a synthetic character
({", ".join(VIEWER_CHARACTERS)}), playing side by side on one clock; turn and zoom the characters
in the browser.</p>
<p><b>Study time</b> is an estimate for a student who reads, runs and does the exercises
(the whole path: {total} min; the workshop notebooks: {total_ws} min).
<b>Run time</b> is measured: how long the notebook took to execute headless on this machine
(wall clock, and the CPU time of the kernel) the last time <code>make</code> or
<code>make workshop</code> executed it (<code>build/notebooks/{TIMINGS_FILE}</code>).</p>
<table>
<tr><th>#</th><th>notebook: what it teaches</th><th>needs</th><th>study time</th><th>run time</th>
<th>workshop</th><th>outputs</th></tr>
{chr(10).join(rows)}
</table>
<p class="note">Built {built} from <code>notebooks/learning_path.yaml</code> by
<code>python -m retarget_lib.notebook.book</code>.</p>
</body></html>
"""


# -------------------------------------------------------------------------------------------- build
def _folders(executed: Path | Sequence[Path] | None) -> list[Path]:
    if executed is None:
        return []
    return [Path(executed)] if isinstance(executed, (str, Path)) else [Path(p) for p in executed]


def _source_for(
    lesson: Lesson, executed: Path | Sequence[Path] | None, committed: Path
) -> tuple[Path, str]:
    for folder in _folders(executed):
        run = folder / lesson.file
        if run.exists():
            stamp = dt.datetime.fromtimestamp(run.stat().st_mtime, dt.UTC).strftime(
                "%Y-%m-%d %H:%M UTC"
            )
            return run, f"executed headless {stamp}"
    return committed / lesson.file, "outputs as committed in notebooks/ (not re-executed)"


def read_timings(executed: Path | Sequence[Path] | None) -> dict[str, dict]:
    timings: dict[str, dict] = {}
    for folder in reversed(_folders(executed)):  # the first folder's timings win
        if (folder / TIMINGS_FILE).exists():
            timings.update(json.loads((folder / TIMINGS_FILE).read_text()))
    return timings


def build_book(
    out: Path,
    executed: Path | Sequence[Path] | None = REPO_ROOT / "build" / "notebooks",
    committed: Path = NOTEBOOKS_DIR,
    path: LearningPath | None = None,
    extra: Sequence[Path] = (),
    verbose: bool = True,
    teacher: bool = False,
) -> list[Path]:
    """Write the book: one page per learning-path notebook, the index, the local MathJax, and the
    3-D viewer page (:mod:`.viewer`).

    Args:
        out: destination folder (``build/book``).
        executed: folder(s) of executed notebooks (``build/notebooks``), looked in in order; a
            notebook missing there is taken from ``committed`` with the outputs it was committed
            with.
        committed: the notebooks folder.
        path: the learning path (default: ``committed/learning_path.yaml``).
        extra: notebooks outside the path to add as pages (no index row).
        verbose: print one line per page.
        teacher: the teacher's book, with the answers (:func:`for_readers`).

    Returns:
        the pages written, index first.
    """
    import nbformat

    path = path or load_learning_path(committed / "learning_path.yaml")
    out.mkdir(parents=True, exist_ok=True)
    copy_mathjax(out)
    exporter = _exporter()
    t0 = time.perf_counter()
    viewer = write_viewer(out)
    if verbose:
        print(
            f"book: {viewer.name} (3-D viewer: {', '.join(VIEWER_METHODS)} on "
            f"{', '.join(VIEWER_CHARACTERS)}) in "
            f"{time.perf_counter() - t0:.1f} s",
            flush=True,
        )
    shown = viewer_cell(out, out)
    sources, pages = {}, []
    todo = [(les, *_source_for(les, executed, committed)) for les in path.lessons]
    todo += [(None, Path(p), "outputs as given") for p in extra]
    for lesson, src, note in todo:
        t0 = time.perf_counter()
        notebook = committed / lesson.file if lesson is not None else src
        nb = with_viewer(for_readers(nbformat.read(src, as_version=4), notebook, teacher), shown)
        blank = widget_only_outputs(nb)
        if blank:
            print(
                f"book: WARNING {src.name}: cells {blank} show a widget with no picture; blank in "
                "the book",
                file=sys.stderr,
            )
        page = out / f"{src.stem}.html"
        with atomic_write(page, "w") as f:
            f.write(export_page(nb, lesson, path if lesson else None, note, exporter))
        if lesson is not None:
            sources[lesson.file] = note
        pages.append(page)
        if verbose:
            print(f"book: {page.name} ({note}) in {time.perf_counter() - t0:.1f} s", flush=True)
    index = out / "index.html"
    with atomic_write(index, "w") as f:
        f.write(index_html(path, sources, read_timings(executed)))
    return [index] + pages + [viewer]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=REPO_ROOT / "build" / "book")
    parser.add_argument(
        "--executed",
        type=Path,
        action="append",
        help="folder of executed notebooks (repeatable, looked in in order; default "
        "build/notebooks); missing ones come from notebooks/ as committed",
    )
    parser.add_argument("--notebooks", type=Path, default=NOTEBOOKS_DIR)
    parser.add_argument(
        "--teacher",
        action="store_true",
        help="the teacher's book: the reference answers in the exercise cells",
    )
    args = parser.parse_args(argv)
    t0 = time.perf_counter()
    executed = args.executed or [REPO_ROOT / "build" / "notebooks"]
    pages = build_book(args.out, executed, args.notebooks, teacher=args.teacher)
    bad = {p.name: remote_references(p.read_text()) for p in pages}
    bad = {k: v for k, v in bad.items() if v}
    if bad:
        print(f"book: pages that reference other hosts: {bad}", file=sys.stderr)
        return 1
    print(f"book: {len(pages)} pages in {time.perf_counter() - t0:.0f} s -> {pages[0]}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
