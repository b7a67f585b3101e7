"""The book's 3-D viewer page: retargeted characters as animated GLBs, side by side and in sync,
that a reader turns and zooms in the browser, with no network.

:func:`viewer_models` retargets one real clip (CMU subject 1's forward jumps, :data:`CLIP`) with
each method of :data:`VIEWER_METHODS` (``copy``, ``tdcn``, ``contact``: the registry's baseline
and the two papers' methods) onto each character of :data:`VIEWER_CHARACTERS` (a real character
of the repository's set and a synthetic one) through
:func:`~retarget_lib.methods.retarget.retarget_file`, the same command a user runs, and keeps the
GLBs. :func:`write_viewer` writes ``viewer.html`` beside the book's pages: one row per character,
one panel per method.

The page plays the GLBs with Google's ``<model-viewer>`` component
(:mod:`retarget_lib.data.sources.model_viewer`, copied to ``_static/model-viewer/``). A page opened
from disk may load classic scripts but not fetch files, so each GLB also goes into a small script
(``_static/models/NAME.glb.js``) that hands its bytes to the page as a blob; the ``.glb`` files
themselves sit beside it for download, unchanged. Nothing on the page comes from another host
(:func:`~retarget_lib.notebook.book.remote_references` is empty).

How the page shows the motion:

* **One clock.** A single play/pause button and time slider drive every panel: a script sets each
  ``<model-viewer>``'s ``currentTime`` from the page's clock on every frame (the elements' own
  playback stays paused), so all panels show the same instant. ``viewer.html#t=1.5`` opens paused
  at 1.5 s (the tests' screenshots use it).
* **The character stays centred.** The camera's target follows the character's hips over the
  floor (the root track of each GLB, :func:`root_track`, written into the page), so a jump forward
  does not carry the character out of its panel; the floor path is drawn as dots where the hips
  were every :data:`PATH_STEP` seconds (``<model-viewer>`` hotspots at floor level), so the
  travel stays visible. The GLBs keep their root motion: what a reader downloads is the result as
  the command wrote it.

In a notebook, :func:`show_viewer` shows the same viewer as the cell's output: the page's viewer
element (``build/book/viewer.html``, written if missing), its script loading ``<model-viewer>``
and the models from the book's folder, so the output stays a few kilobytes. :data:`VIEWER_LINK` is
the relative link a notebook in ``notebooks/`` gives to the page; the book rewrites every
``../build/book/`` link of a notebook's page to its own folder (:func:`book_links`).
"""

from __future__ import annotations

import base64
import html
import os
import re
import shutil
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from ..core.measures import mesh_standing_height
from ..core.skeleton import J
from ..data.sources.cmu import cmu_clip_path
from ..data.sources.model_viewer import model_viewer_path
from ..data.sources.real_characters import (
    joint_map_path,
    real_character_entry,
    real_character_names,
    real_character_path,
)
from ..files import REPO_ROOT, atomic_write
from ..io.bvh import load_bvh, save_bvh
from ..io.gltf import load_gltf_motion
from ..methods.retarget import retarget_file

__all__ = [
    "VIEWER_PAGE",
    "VIEWER_LINK",
    "VIEWER_METHODS",
    "VIEWER_CHARACTERS",
    "CLIP",
    "PATH_STEP",
    "viewer_models",
    "root_track",
    "write_viewer",
    "show_viewer",
    "ViewerCell",
    "book_links",
]

VIEWER_PAGE = "viewer.html"
#: the book's folder as ``make book`` writes it
BOOK_DIR = REPO_ROOT / "build" / "book"
#: the link to the viewer from a notebook in ``notebooks/`` (markdown ``[...](VIEWER_LINK)``); the
#: book's pages sit beside the viewer, and :func:`book_links` rewrites it there
VIEWER_LINK = "../build/book/viewer.html"
#: the methods shown side by side (one panel each), with what each is
VIEWER_METHODS = {
    "copy": "copied rotations, root scaled by leg length (the baseline)",
    "tdcn": "the default TDCN checkpoint (Kim et al. 2020; notebook 04)",
    "contact": "the default contact-aware checkpoint with encoder-space optimisation, on the "
    "target's mesh (Villegas et al. 2021; notebook 07b)",
}
#: the characters (one row each), real first: a GLB of ``data/real_characters`` or a synthetic name
VIEWER_CHARACTERS = {
    "quaternius_male_casual": "a real character (Quaternius' 2019 characters; its own 33-joint "
    "Blender rig, read through data/real_characters/quaternius.joints.yaml)",
    "gus": "a synthetic character of the training set",
}
#: the clip: CMU 01_01 from START seconds, SECONDS long (two forward jumps), retargeted at FPS
CLIP, START, SECONDS, FPS = "01_01.bvh", 1.5, 2.5, 30.0
#: seconds between two dots of the drawn floor path
PATH_STEP = 0.1
#: the view: seen from this azimuth and polar angle, at this many standing heights
ORBIT_THETA, ORBIT_PHI, ORBIT_HEIGHTS = 60.0, 78.0, 2.6


def _target(character: str) -> tuple[str, Path | None]:
    """``(retarget_file target, joint map or None)`` of a real character's name or a synthetic
    one."""
    if character in real_character_names():
        return str(real_character_path(character)), joint_map_path(character)
    return character, None


def viewer_models(folder: Path) -> dict[str, dict[str, Path]]:
    """Retarget :data:`CLIP` onto every :data:`VIEWER_CHARACTERS` entry with every
    :data:`VIEWER_METHODS` entry (``contact`` takes about 0.3 s a frame on a CPU core: about a
    minute in all).

    Args:
        folder: where the GLBs go (``CHARACTER_METHOD.glb``).

    Returns:
        ``{character: {method: GLB path in folder}}``.
    """
    folder.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        source = Path(tmp) / "jumps.bvh"
        clip = load_bvh(cmu_clip_path(CLIP))
        first = round(START * clip.fps)
        save_bvh(
            clip.slice(first, first + round(SECONDS * clip.fps) + 1).normalize_root(), source
        )  # starts at the origin, facing +Z
        models: dict[str, dict[str, Path]] = {}
        for character in VIEWER_CHARACTERS:
            target, joint_map = _target(character)
            models[character] = {
                m: retarget_file(
                    source,
                    target,
                    m,
                    folder / f"{character}_{m}.glb",
                    fps=FPS,
                    joint_map=joint_map,
                )
                for m in VIEWER_METHODS
            }
        return models


def root_track(glb: Path, joint_map: Path | None = None) -> tuple[np.ndarray, float, float]:
    """Where a result GLB's hips go over the floor, read back from the file.

    Args:
        glb: a skinned, animated GLB (a :func:`~retarget_lib.methods.retarget.retarget_file`
            result).
        joint_map: the joint map its joint names need (a real character's), or None.

    Returns:
        ``(track, fps, height)``: ``track`` ``(T, 2)`` the hips' ``x, z`` in metres, one row per
        animation frame at ``fps``; ``height`` the rest mesh's standing height (metres).
    """
    motion, rig = load_gltf_motion(glb, mapping=joint_map)
    hips = rig.motion_to_canonical(motion).global_positions()[:, J["Hips"]]
    height = float(mesh_standing_height(rig.rest_vertices))
    return hips[:, [0, 2]], float(motion.fps), height


def _caption(character: str) -> str:
    if character in real_character_names():
        entry = real_character_entry(character)
        licence = str(entry["license"]).split(" (")[0]  # the manifest's, without its note
        return f"{VIEWER_CHARACTERS.get(character, 'a real character')}; licence {licence}"
    return VIEWER_CHARACTERS.get(character, "a character")


def _panel(
    character: str, method: str, glb: Path, track: np.ndarray, fps: float, height: float
) -> str:
    """One ``<figure>``: the model's viewer (its root track, the floor path's dots) and caption."""
    x, z = track[0]
    step = max(1, round(PATH_STEP * fps))
    dots = "".join(
        f'<div slot="hotspot-{k}" class="rv-step" data-position="{px:.3f}m 0.005m {pz:.3f}m" '
        'data-normal="0m 1m 0m"></div>'
        for k, (px, pz) in enumerate(track[::step])
    )
    flat = ",".join(f"{v:.3f}" for v in track.ravel())
    what = VIEWER_METHODS.get(method, method)
    return (
        f'<figure><model-viewer data-glb="{html.escape(glb.stem)}" data-fps="{fps:g}" '
        f'data-track="{flat}" data-y="{0.5 * height:.3f}" camera-controls disable-pan '
        'interaction-prompt="none" animation-crossfade-duration="0" shadow-intensity="1" '
        f'exposure="1" camera-orbit="{ORBIT_THETA:g}deg {ORBIT_PHI:g}deg '
        f'{ORBIT_HEIGHTS * height:.2f}m" camera-target="{x:.3f}m {0.5 * height:.3f}m {z:.3f}m" '
        'min-camera-orbit="auto auto 0.5m" max-camera-orbit="auto auto 30m" '
        f'alt="{html.escape(method)} on {html.escape(character)}">{dots}</model-viewer>'
        f"<figcaption><b>{html.escape(method)}</b>: {html.escape(what)} "
        f'(<a href="_static/models/{html.escape(glb.name)}">{html.escape(glb.name)}</a>)'
        "</figcaption></figure>"
    )


#: the viewer's script, run once per viewer (``root``: its ``.rv-viewer`` element): loads what is
#: missing (in a notebook), then one clock for every panel and each camera on its hips
_SCRIPT = """
(function (root) {
const viewers = [...root.querySelectorAll("model-viewer[data-glb]")];
const button = root.querySelector(".rv-play"), slider = root.querySelector(".rv-time");
const label = root.querySelector(".rv-clock"), speed = root.querySelector(".rv-speed");
const duration = Number(slider.max);
const clock = {t: 0, playing: true, last: null};
const glbs = () => window.RETARGET_GLB || {};
function script(src) {
  return new Promise((ok, fail) => {
    const s = document.createElement("script");
    s.src = src;
    s.onload = ok;
    s.onerror = () => fail(new Error(`cannot load ${src}`));
    document.head.appendChild(s);
  });
}
function settled(a) {  // JupyterLab rewrites an output's relative links to the server's file
  const first = a.getAttribute("href");  // URLs just after running its scripts: wait for it
  return new Promise(ok => {
    let n = 0;
    const poll = () =>
      a.getAttribute("href") !== first || ++n > 10 ? ok(a.href) : setTimeout(poll, 50);
    poll();
  });
}
async function load() {  // the page has them all; a notebook's output loads them from the book
  const missing = [...root.querySelectorAll("a.rv-asset")].filter(
    a => a.dataset.glb ? !glbs()[a.dataset.glb] : !customElements.get("model-viewer"));
  await Promise.all(missing.map(a => settled(a).then(script)));
}
function follow(viewer, t) {  // the camera's target on the hips' floor point at time t
  if (!viewer.jumpCameraToGoal) return;  // <model-viewer> did not load
  const track = viewer.track, f = Math.min(track.length - 1, Math.max(0, t * viewer.dataset.fps));
  const i = Math.floor(f), j = Math.min(i + 1, track.length - 1), a = f - i;
  const x = track[i][0] * (1 - a) + track[j][0] * a, z = track[i][1] * (1 - a) + track[j][1] * a;
  viewer.cameraTarget = `${x.toFixed(3)}m ${viewer.dataset.y}m ${z.toFixed(3)}m`;
  viewer.jumpCameraToGoal();
}
function show(t) {
  for (const viewer of viewers) {
    if (viewer.ready) viewer.currentTime = Math.min(t, duration - 1e-4);  // not wrapped to 0
    follow(viewer, t);
  }
  slider.value = t;
  label.textContent = `${t.toFixed(2)} / ${duration.toFixed(2)} s`;
  // what the panels show, for a reader of the DOM (the tests): each one's time and box
  root.dataset.times = viewers.map(v => v.ready ? v.currentTime.toFixed(3) : "-").join(" ");
  root.dataset.panels = JSON.stringify(viewers.map(v => {
    const r = v.getBoundingClientRect();
    return [r.left, r.top, r.width, r.height].map(Math.round);
  }));
}
function tick(now) {
  if (clock.playing && clock.last !== null)
    clock.t = (clock.t + (now - clock.last) / 1000 * Number(speed.value)) % duration;
  clock.last = now;
  show(clock.t);
  requestAnimationFrame(tick);
}
function setPlaying(playing) {
  clock.playing = playing;
  button.textContent = playing ? "pause" : "play";
}
function start() {
  for (const viewer of viewers) {
    const v = viewer.dataset.track.split(",").map(Number);
    viewer.track = Array.from({length: v.length / 2}, (_, i) => [v[2 * i], v[2 * i + 1]]);
    const b64 = glbs()[viewer.dataset.glb];
    if (!b64) continue;
    const bytes = Uint8Array.from(atob(b64), c => c.charCodeAt(0));
    viewer.addEventListener("load", () => {
      viewer.play();  // makes the clip's action current ...
      viewer.pause();  // ... which the page's clock moves
      for (const m of viewer.model.materials)  // a tint: the GLBs carry no material colour
        m.pbrMetallicRoughness.setBaseColorFactor([0.55, 0.68, 0.85, 1]);
      viewer.ready = true;
    });
    viewer.src = URL.createObjectURL(new Blob([bytes], {type: "model/gltf-binary"}));
  }
  button.addEventListener("click", () => setPlaying(!clock.playing));
  slider.addEventListener("input", () => { setPlaying(false); clock.t = Number(slider.value); });
  const hash = new URLSearchParams(location.hash.slice(1));
  if (hash.has("t")) {  // viewer.html#t=1.5: paused at 1.5 s, through the slider
    slider.value = hash.get("t");
    slider.dispatchEvent(new Event("input"));
  }
  requestAnimationFrame(tick);
}
load().catch(e => console.warn("3-D viewer:", e)).finally(start);
})(document.currentScript.closest(".rv-viewer"));
"""

#: the viewer's own style (scoped to it: a notebook's output carries it too)
_STYLE = """
.rv-viewer h2 { font-size: 1rem; font-weight: normal; margin: .8rem 0 .3rem; }
.rv-viewer .rv-panels { display: flex; gap: .8rem; flex-wrap: wrap; }
.rv-viewer figure { flex: 1 1 15rem; margin: 0; }
.rv-viewer model-viewer { width: 100%; height: 18rem; background: #eef1f4; }
.rv-viewer figcaption { font-size: .85em; color: #444; }
.rv-viewer .rv-controls { position: sticky; top: 0; z-index: 10; background: #fff;
  padding: .4rem 0; display: flex; gap: .8rem; align-items: center;
  border-bottom: 1px solid #ddd; }
.rv-viewer .rv-time { flex: 1; }
.rv-viewer .rv-clock { font-variant-numeric: tabular-nums; min-width: 8em; }
.rv-viewer .rv-step { width: 6px; height: 6px; border-radius: 50%; background: #c0562b;
  border: none; padding: 0; opacity: .6; pointer-events: none; }
"""
#: the table of GLBs (base64) that each model's script adds to
_GLB_TABLE = "(window.RETARGET_GLB = window.RETARGET_GLB || {})"
#: where the viewer starts and ends in the page (:func:`show_viewer` takes what lies between)
_BEGIN, _END = "<!-- retarget-viewer -->", "<!-- /retarget-viewer -->"


def _fragment(
    rows: dict[str, str], captions: dict[str, str], assets: list[tuple[str, str]], seconds: float
) -> str:
    """The viewer as one element: its style, the clock's controls, one row per character, the
    links to the scripts it needs (``(GLB key or "", path)``, loaded when missing) and its
    script."""
    sections = "\n".join(
        f"<h2><code>{html.escape(c)}</code>: {html.escape(captions[c])}</h2>\n"
        f'<div class="rv-panels">{panels}</div>'
        for c, panels in rows.items()
    )
    links = " ".join(
        f'<a class="rv-asset"{f" data-glb={chr(34)}{html.escape(key)}{chr(34)}" if key else ""} '
        f'href="{html.escape(path)}">{html.escape(Path(path).name)}</a>'
        for key, path in assets
    )
    return f"""{_BEGIN}
<div class="rv-viewer">
<style>{_STYLE}</style>
<div class="rv-controls"><button class="rv-play" type="button">pause</button>
<input class="rv-time" type="range" min="0" max="{seconds:.3f}" step="0.001" value="0"
 aria-label="time">
<output class="rv-clock">0.00 s</output>
<label>speed <select class="rv-speed"><option value="0.25">¼×</option>
<option value="0.5">½×</option><option value="1" selected>1×</option></select></label></div>
{sections}
<p class="rv-assets" hidden>{links}</p>
<script>{_SCRIPT}</script>
</div>
{_END}"""


def _page(fragment: str, scripts: list[str], seconds: float) -> str:
    tags = "\n".join(f'<script src="{html.escape(s)}"></script>' for s in scripts)
    methods = ", ".join(f"<code>{html.escape(m)}</code>" for m in VIEWER_METHODS)
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1.0">
<title>Retargeted characters in 3-D</title>
<style>
body {{ font-family: system-ui, -apple-system, "Segoe UI", sans-serif; max-width: 80rem;
       margin: 1.5rem auto; padding: 0 1rem; color: #222; line-height: 1.45; }}
</style>
{tags}
</head>
<body>
<h1>Retargeted characters in 3-D</h1>
<p>CMU subject 1's forward jumps (<code>{CLIP}</code>, {seconds:.1f} s from {START:g} s) retargeted
by {methods} onto a real and a synthetic character with
<code>retarget retarget --method M --fps {FPS:g} --out CHARACTER_M.glb</code>, one method per view.
One clock plays every view: pause it, or drag the slider to a moment. The camera follows each
character's hips, so it stays in the middle of its view; the dots on the floor are where the hips
were every {PATH_STEP:g} s. Drag a character to turn it, scroll to zoom; the files load from this
folder, no network. <a href="index.html">Back to the learning path.</a></p>
{fragment}
</body></html>
"""


def write_viewer(out: Path, models: dict[str, dict[str, Path]] | None = None) -> Path:
    """Write ``out/viewer.html`` with its scripts and models under ``out/_static``.

    Args:
        out: the book folder.
        models: ``{character: {method: GLB}}`` to show, one row per character (a real
            character's name, whose joint map reads the GLB back, or a canonical-22 one); default
            :func:`viewer_models`, made into the book.

    Returns:
        the page's path.
    """
    static = out / "_static"
    for sub in ("model-viewer", "models"):
        (static / sub).mkdir(parents=True, exist_ok=True)
    shutil.copy2(model_viewer_path(), static / "model-viewer" / "model-viewer-umd.min.js")
    models = viewer_models(static / "models") if models is None else models
    assets = [("", "_static/model-viewer/model-viewer-umd.min.js")]
    rows, captions, seconds = {}, {}, []
    for character, panels in models.items():
        joint_map = _target(character)[1]
        captions[character] = _caption(character)
        cards = []
        for method, path in panels.items():
            glb = static / "models" / path.name
            if path.resolve() != glb.resolve():
                shutil.copy2(path, glb)
            data = base64.b64encode(glb.read_bytes()).decode("ascii")
            with atomic_write(static / "models" / f"{glb.name}.js", "w") as f:
                f.write(f'{_GLB_TABLE}["{glb.stem}"] = "{data}";\n')
            assets.append((glb.stem, f"_static/models/{glb.name}.js"))
            track, fps, height = root_track(glb, joint_map)
            cards.append(_panel(character, method, glb, track, fps, height))
            seconds.append((len(track) - 1) / fps)
        rows[character] = "\n".join(cards)
    page = out / VIEWER_PAGE
    with atomic_write(page, "w") as f:
        fragment = _fragment(rows, captions, assets, min(seconds))
        f.write(_page(fragment, [p for _, p in assets], min(seconds)))
    return page


#: a link into the book from a notebook in ``notebooks/`` (or from the repository's root)
_BOOK_PREFIX = re.compile(r'(?<=["\'(])(?:\.\./)*build/book/')


def book_links(page: str) -> str:
    """A notebook's exported HTML with its links into the book (:data:`VIEWER_LINK`, the
    viewer's scripts: ``../build/book/...``) made relative to the book's own pages, which sit in
    that folder (``viewer.html``, ``_static/...``)."""
    return _BOOK_PREFIX.sub("", page)


def _current(page: Path) -> bool:
    """A viewer page of this module's version (with the element :func:`show_viewer` takes)."""
    text = page.read_text() if page.is_file() else ""
    return _BEGIN in text and _END in text


@contextmanager
def _building(book: Path) -> Iterator[None]:
    """Hold ``book/.viewer.lock`` while the viewer is written: notebooks executed two at a time
    (``make``, nbval's workers) write it once (no lock where ``fcntl`` is missing)."""
    book.mkdir(parents=True, exist_ok=True)
    try:
        import fcntl
    except ImportError:  # not POSIX
        yield
        return
    with open(book / ".viewer.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(lock, fcntl.LOCK_UN)


class ViewerCell:
    """What :func:`show_viewer` returns: the book's viewer as a notebook cell's output (its
    ``_repr_html_``), the models and scripts loaded from the book's folder.

    Attributes:
        html: the viewer's HTML, its links relative to the notebook's folder.
        page: the viewer's page, relative to the notebook's folder.
    """

    def __init__(self, html: str, page: str, built: bool = True):
        self.html, self.page, self.built = html, page, built

    def _repr_html_(self) -> str:
        link = f'<a href="{html.escape(self.page)}" target="_blank">'
        if not self.built:
            return (
                "<p>The 3-D viewer is not built yet: `make book` writes it (every method "
                f"retargets the clip, a minute or two), then re-run this cell, or {link}open it on "
                "its own page</a>.</p>"
            )
        return (
            f"{self.html}\n<p>{link}Open the 3-D viewer on its own page</a> (in the book folder; a "
            "browser opens it from disk).</p>"
        )

    def __repr__(self) -> str:
        return f"3-D viewer: {self.page}" + ("" if self.built else " (not built yet: make book)")


def show_viewer(book: Path | None = None, build: bool = True) -> ViewerCell:
    """Show the book's 3-D viewer in a notebook cell (``show_viewer()`` as the cell's last line).

    The cell's output is the viewer itself (controls, one row per character, one panel per
    method; not an ``<iframe>``: Jupyter's file server would not give a framed page its scripts),
    a few kilobytes: the ``<model-viewer>`` script and the models load from the book's folder
    when the output runs (JupyterLab and Notebook 7 serve them; a trusted output only: re-run the
    cell in a notebook opened fresh). In the book, the notebook's page shows it from the book's
    own files (:func:`book_links`).

    Args:
        book: the book folder (default ``build/book``, where ``make book`` writes it).
        build: write the viewer into ``book`` when it is not there, or is an older page
            (:func:`write_viewer`: every method retargets the clip, a minute or two on a CPU
            core; one notebook at a time writes it); ``False``: show a note with the link
            instead (the notebooks do: ``make`` stays short, ``make book`` writes the viewer).

    Returns:
        a :class:`ViewerCell`, its links relative to the working directory (the notebook's
        folder).
    """
    book = Path(book) if book is not None else BOOK_DIR
    page = book / VIEWER_PAGE
    if not _current(page) and build:
        with _building(book):
            if not _current(page):  # another notebook may have written it meanwhile
                print(f"writing {page} (every method retargets the clip: a minute or two)")
                write_viewer(book)
    return viewer_cell(book)


def viewer_cell(book: Path, relative_to: Path | None = None) -> ViewerCell:
    """The viewer of ``book`` as a cell output, its links relative to ``relative_to`` (default the
    working directory); a note with the link when ``book`` has no viewer of this version (the
    book's pages put it in place of a ``show_viewer()`` cell's output, :mod:`.book`)."""
    page = Path(book) / VIEWER_PAGE
    base = Path(
        os.path.relpath(os.path.abspath(book), os.path.abspath(relative_to or os.getcwd()))
    ).as_posix()  # no symlink followed
    prefix = "" if base == "." else f"{base}/"
    if not _current(page):
        return ViewerCell("", f"{prefix}{VIEWER_PAGE}", built=False)
    text = page.read_text()
    begin, end = text.find(_BEGIN), text.find(_END)
    fragment = re.sub(
        r'(?<=\bhref=")(?=_static/)', prefix, text[begin : end + len(_END)]
    )  # the models' and scripts' links, from the notebook's folder
    return ViewerCell(fragment, f"{prefix}{VIEWER_PAGE}")
