"""The book's 3-D viewer page: every script and model is a file inside the book folder (no other
host), one row per character (a real one and a synthetic one) and one panel per method, and a real
headless browser (Chromium) renders it: every panel draws its character, in the middle of the
panel, one clock moves every panel, and the browser asks no other host for anything."""

import base64
import io
import json
import os
import re
import shutil
import socketserver
import subprocess
import threading
import time
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from retarget_lib.core.rig import Rig
from retarget_lib.data.sources.real_characters import load_real_character
from retarget_lib.data.synthetic.characters import make_character
from retarget_lib.data.synthetic.motions import make_motion
from retarget_lib.io import save_glb
from retarget_lib.notebook.book import remote_references
from retarget_lib.notebook.viewer import (
    PATH_STEP,
    VIEWER_CHARACTERS,
    VIEWER_LINK,
    VIEWER_METHODS,
    VIEWER_PAGE,
    book_links,
    root_track,
    show_viewer,
    write_viewer,
)

#: the model-viewer element's background (the page's CSS); an unrendered element shows only it
BACKGROUND = np.array([0xEE, 0xF1, 0xF4])
#: the rows and panels of the fixture: the page's characters, each motion travelling (seconds)
CHARACTERS = list(VIEWER_CHARACTERS)
FAMILIES = {"copy": "walk", "tdcn": "jump", "contact": "run"}
SECONDS = 2.0
GLIDE = {"copy": (0.0, 2.0), "tdcn": (1.5, 0.0), "contact": (-1.2, 1.2)}
#: the two moments the browser shows (seconds) and the window it shows them in
T1, T2 = 0.3, 1.6
WINDOW = (1280, 1100)


@pytest.fixture(scope="module")
def book(tmp_path_factory):
    """A viewer of the page's characters and methods in ``REPO/build/book``, each panel a
    synthetic motion written as a GLB (the retargeting itself is the book build's, slow:
    ``test_book.py``)."""
    folder = tmp_path_factory.mktemp("repo") / "build" / "book"
    folder.mkdir(parents=True)
    models = {}
    for name in CHARACTERS:
        rig = (
            Rig.from_character(make_character(name)) if name == "gus" else load_real_character(name)
        )
        skeleton = rig.character().skeleton
        models[name] = {}
        for method, family in FAMILIES.items():
            glb = folder / f"{name}_{method}.glb"
            motion = make_motion(family, skeleton, 0, SECONDS)
            # the root glides GLIDE metres over the clip: a panel's camera must follow it
            motion.root_positions[:, [0, 2]] += np.linspace(0, 1, motion.num_frames)[
                :, None
            ] * np.array(GLIDE[method])
            save_glb(rig, glb, rig.motion_from_canonical(motion))
            models[name][method] = glb
    write_viewer(folder, models)
    return folder


def _glb_names() -> list[str]:
    return [f"{c}_{m}.glb" for c in CHARACTERS for m in FAMILIES]


def test_the_viewer_shows_the_registry_methods_on_a_real_and_a_synthetic_character():
    from retarget_lib.data.sources.real_characters import real_character_names
    from retarget_lib.data.synthetic.characters import CHARACTER_NAMES
    from retarget_lib.methods.registry import REGISTRY

    assert {"copy", "tdcn", "contact"} <= set(VIEWER_METHODS) <= set(REGISTRY)
    assert any(c in real_character_names() for c in VIEWER_CHARACTERS)
    assert any(c in CHARACTER_NAMES for c in VIEWER_CHARACTERS)


def test_every_script_and_model_is_a_file_of_the_book(book):
    page = (book / VIEWER_PAGE).read_text()
    assert remote_references(page) == []
    local = [
        r for r in re.findall(r'(?:src|href)="([^"#]+)"', page) if r != "index.html"
    ]  # the book's front page
    expected = {"_static/model-viewer/model-viewer-umd.min.js"}
    expected |= {f"_static/models/{n}" for n in _glb_names()}
    expected |= {f"_static/models/{n}.js" for n in _glb_names()}
    assert expected <= set(local)
    for ref in local:
        assert not ref.startswith(("http:", "https:", "//", "/")) and (book / ref).is_file(), ref
    for name in _glb_names():
        script = (book / f"_static/models/{name}.js").read_text()
        data = re.search(r'= "([A-Za-z0-9+/=]+)";', script).group(1)
        glb = (book / f"_static/models/{name}").read_bytes()
        assert base64.b64decode(data) == glb  # the same bytes
        assert len(glb) < 400_000, name  # a few hundred KB at most


class _Panels(HTMLParser):
    """The page's ``<model-viewer>`` elements' attributes, in order."""

    def __init__(self):
        super().__init__()
        self.panels: list[dict] = []

    def handle_starttag(self, tag, attrs):
        if tag == "model-viewer":
            self.panels.append(dict(attrs))


def test_one_row_per_character_one_panel_per_method_each_with_its_root_track(book):
    parser = _Panels()
    parser.feed((book / VIEWER_PAGE).read_text())
    assert [p["data-glb"] for p in parser.panels] == [Path(n).stem for n in _glb_names()]
    for panel in parser.panels:
        track = np.array(panel["data-track"].split(","), float).reshape(-1, 2)
        glb = book / "_static/models" / f"{panel['data-glb']}.glb"
        mapping = None
        if not panel["data-glb"].startswith("gus"):
            from retarget_lib.data.sources.real_characters import joint_map_path

            mapping = joint_map_path(CHARACTERS[0])
        expected, fps, height = root_track(glb, mapping)
        assert float(panel["data-fps"]) == fps == 30.0
        np.testing.assert_allclose(track, expected, atol=1e-3)
        assert 1.0 < height < 2.5 and abs(float(panel["data-y"]) - height / 2) < 1e-3
    # the floor path: a dot where the hips are every PATH_STEP (every 3rd frame at 30 fps)
    inside = re.findall(
        r"<model-viewer\b[^>]*>(.*?)</model-viewer>", (book / VIEWER_PAGE).read_text()
    )
    for panel, dots in zip(parser.panels, inside, strict=True):
        track = np.array(panel["data-track"].split(","), float).reshape(-1, 2)
        at = re.findall(r'class="rv-step" data-position="([-\d.]+)m 0.005m ([-\d.]+)m"', dots)
        np.testing.assert_allclose(np.array(at, float), track[:: round(PATH_STEP * 30)])
    walk = np.array(parser.panels[0]["data-track"].split(","), float).reshape(-1, 2)
    assert np.linalg.norm(walk[-1] - walk[0]) > 1.0  # the fixture's walk travels


def _notebook_cell(book: Path) -> tuple[Path, object]:
    """``(REPO/notebooks, show_viewer's output there)``."""
    notebooks = book.parent.parent / "notebooks"
    notebooks.mkdir(exist_ok=True)
    cwd = os.getcwd()
    os.chdir(notebooks)
    try:
        return notebooks, show_viewer(book, build=False)
    finally:
        os.chdir(cwd)


@pytest.fixture(scope="module")
def notebook_page(book):
    """The book's page of a notebook in ``notebooks/`` that links to the viewer and shows it."""
    import nbformat

    from retarget_lib.notebook.book import copy_mathjax, export_page

    _, cell = _notebook_cell(book)
    nb = nbformat.v4.new_notebook()
    shown = nbformat.v4.new_output(
        "execute_result", {"text/html": cell._repr_html_(), "text/plain": repr(cell)}
    )
    shown.execution_count = 1
    nb.cells = [
        nbformat.v4.new_markdown_cell(f"See [the 3-D viewer]({VIEWER_LINK})."),
        nbformat.v4.new_code_cell("show_viewer()", execution_count=1, outputs=[shown]),
    ]
    copy_mathjax(book)  # as the book's build does: the page loads it
    page = book / "notebook.html"
    page.write_text(export_page(nb, None, None, "test"))
    return page


def test_a_notebook_shows_the_same_viewer_loading_its_files_from_the_book(book):
    notebooks, cell = _notebook_cell(book)
    assert cell.page == VIEWER_LINK  # ../build/book/viewer.html
    out = cell._repr_html_()
    assert remote_references(out) == [] and "<iframe" not in out
    page = (book / VIEWER_PAGE).read_text()
    assert out.count("<model-viewer data-glb") == page.count("<model-viewer data-glb") == 6
    assert len(out) < 60_000  # the models and scripts are not in it: it loads them
    assets = re.findall(r'<a class="rv-asset"[^>]*href="([^"]+)"', out)
    assert len(assets) == 1 + len(_glb_names())
    for href in assets + re.findall(r'href="([^"]+\.glb)"', out):
        assert href.startswith("../build/book/_static/") and (notebooks / href).is_file(), href
    missing = show_viewer(book.parent / "nowhere", build=False)  # not built: a link and a note
    assert not missing.built and "make book" in missing._repr_html_()
    assert (
        missing.page.endswith("nowhere/viewer.html")
        and "<model-viewer" not in missing._repr_html_()
    )


def test_show_viewer_writes_a_missing_or_older_viewer(book, tmp_path, monkeypatch):
    import retarget_lib.notebook.viewer as viewer

    written = []

    def write(out: Path) -> Path:  # the fixture's page in place of a minute of retargeting
        written.append(out)
        return Path(shutil.copy(book / VIEWER_PAGE, out / VIEWER_PAGE))

    monkeypatch.setattr(viewer, "write_viewer", write)
    monkeypatch.chdir(tmp_path)
    target = tmp_path / "build" / "book"
    assert show_viewer(target).page == "build/book/viewer.html"  # missing: written
    (target / VIEWER_PAGE).write_text("<!DOCTYPE html><p>an older viewer</p>")
    show_viewer(target)  # older: written again
    show_viewer(target)  # current: kept
    assert written == [target, target]


def test_the_book_page_of_that_notebook_finds_the_viewer_and_its_files(book, notebook_page):
    page = notebook_page.read_text()
    assert remote_references(page) == [] and "build/book" not in page
    assert '<a href="viewer.html">the 3-D viewer</a>' in page
    local = set(re.findall(r'(?:src|href)="([^"#:]+)"', page)) - {"index.html"}
    assert {"viewer.html", "_static/model-viewer/model-viewer-umd.min.js"} <= local
    for ref in local:
        assert (book / ref).is_file(), ref


def test_the_book_puts_its_viewer_in_place_of_a_not_built_note(book):
    """``make`` runs the notebooks with ``show_viewer(build=False)`` (a link and a note when the
    viewer is not written yet); the book, which writes the viewer, shows it in those cells."""
    import nbformat

    from retarget_lib.notebook.book import with_viewer
    from retarget_lib.notebook.viewer import viewer_cell

    note = show_viewer(book.parent / "nowhere", build=False)
    shown = nbformat.v4.new_output("display_data", {"text/html": note._repr_html_()})
    nb = nbformat.v4.new_notebook()
    nb.cells = [
        nbformat.v4.new_code_cell("x = 1", outputs=[shown]),
        nbformat.v4.new_code_cell("show_viewer(build=False)", outputs=[shown]),
    ]
    with_viewer(nb, viewer_cell(book, book))
    assert nb.cells[0].outputs[0]["data"]["text/html"] == note._repr_html_()  # not a viewer cell
    page = nb.cells[1].outputs[0]["data"]["text/html"]
    assert "<model-viewer" in page and 'href="viewer.html"' in page and "not built" not in page


def test_the_book_rewrites_a_notebooks_links_into_the_book():
    assert VIEWER_LINK == "../build/book/viewer.html"  # from a notebook in notebooks/
    cell = f'<a href="{VIEWER_LINK}">x</a> [y]({VIEWER_LINK}) <a href="../build/book/_static/a.js">'
    assert (
        book_links(cell) == '<a href="viewer.html">x</a> [y](viewer.html) <a href="_static/a.js">'
    )
    assert book_links("see ../build/book/viewer.html") == "see ../build/book/viewer.html"


# ------------------------------------------------------------------------------------ the browser
def _chromium() -> str | None:
    return (
        shutil.which("chromium")
        or shutil.which("chromium-browser")
        or shutil.which("google-chrome")
    )


class _RefusingProxy(socketserver.ThreadingTCPServer):
    """An HTTP proxy on the loopback that refuses every request (and keeps its first line): the
    browser is told to reach every host through it, so nothing it asks for leaves the machine,
    whatever the network. Chromium's own services (updates, sign-in) ask it too, so what the page
    asks for is read from the browser's network events instead (:meth:`_Browser.requested`)."""

    daemon_threads = True
    allow_reuse_address = True

    def __init__(self):
        self.requests: list[str] = []
        requests = self.requests

        class Handler(socketserver.StreamRequestHandler):
            timeout = 5

            def handle(self):
                try:
                    line = self.rfile.readline(2048).decode("latin-1").strip()
                except OSError:
                    return
                if line:
                    requests.append(line)
                self.wfile.write(b"HTTP/1.1 403 Forbidden\r\nContent-Length: 0\r\n\r\n")

        super().__init__(("127.0.0.1", 0), Handler)


@pytest.fixture(scope="module")
def proxy():
    server = _RefusingProxy()
    thread = threading.Thread(target=server.serve_forever, kwargs={"poll_interval": 0.2})
    thread.start()
    yield server
    server.shutdown()
    server.server_close()
    thread.join(timeout=5)


class _Browser:
    """Headless Chromium driven over the DevTools protocol (websocket-client, which Jupyter's server
    brings): one tab whose network requests (and its workers') are recorded; every other host is
    reached only through ``proxy``."""

    def __init__(self, profile: Path, proxy: _RefusingProxy | None, timeout: float = 600.0):
        import websocket

        host, port = proxy.server_address if proxy is not None else (None, None)
        self.timeout, self.events, self._id, self._attached = timeout, [], 0, []
        self.process = subprocess.Popen(
            [
                _chromium(),
                "--headless=new",
                "--no-sandbox",
                "--use-angle=swiftshader",
                "--enable-unsafe-swiftshader",
                "--hide-scrollbars",
                "--remote-debugging-port=0",
                f"--user-data-dir={profile}",
                *(
                    [f"--proxy-server=http://{host}:{port}", "--proxy-bypass-list=<-loopback>"]
                    if proxy is not None  # the loopback goes through it too
                    else []
                ),
                # the browser's own services stay quiet (updates, sign-in, hints, time)
                "--disable-background-networking",
                "--disable-component-update",
                "--disable-sync",
                "--disable-default-apps",
                "--disable-extensions",
                "--disable-client-side-phishing-detection",
                "--disable-domain-reliability",
                "--no-pings",
                "--metrics-recording-only",
                "--no-first-run",
                "--no-default-browser-check",
                "--disable-features=OptimizationHints,OptimizationGuideModelDownloading,"
                "OptimizationHintsFetching,NetworkTimeServiceQuerying,MediaRouter,Translate,"
                "AutofillServerCommunication,CertificateTransparencyComponentUpdater",
                "about:blank",
            ],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        active = profile / "DevToolsActivePort"  # the port and the browser's path, when it listens
        deadline = time.monotonic() + 120
        while not (active.is_file() and len(active.read_text().split()) == 2):
            if time.monotonic() > deadline or self.process.poll() is not None:
                self.close()
                raise RuntimeError("Chromium did not open its DevTools port")
            time.sleep(0.2)
        debug_port, path = active.read_text().split()
        self.ws = websocket.create_connection(
            f"ws://127.0.0.1:{debug_port}{path}", timeout=timeout, suppress_origin=True
        )
        target = self.send("Target.createTarget", url="about:blank")["targetId"]
        self.session = self.send("Target.attachToTarget", targetId=target, flatten=True)[
            "sessionId"
        ]
        self.send("Network.enable", session=self.session)
        self.send(  # its workers too, each paused until its requests are recorded
            "Target.setAutoAttach",
            session=self.session,
            autoAttach=True,
            waitForDebuggerOnStart=True,
            flatten=True,
        )
        self.send(
            "Emulation.setDeviceMetricsOverride",
            session=self.session,
            width=WINDOW[0],
            height=WINDOW[1],
            deviceScaleFactor=1,
            mobile=False,
        )

    def send(self, method: str, session: str | None = None, **params) -> dict:
        """One protocol command; the events read while waiting for its answer are kept."""
        self._id += 1
        message = {"id": self._id, "method": method, "params": params}
        if session:
            message["sessionId"] = session
        self.ws.send(json.dumps(message))
        sent = self._id
        while True:
            reply = json.loads(self.ws.recv())
            if reply.get("id") == sent:
                break
            self.events.append(reply)
            if reply.get("method") == "Target.attachedToTarget":
                self._attached.append(reply["params"]["sessionId"])
        if "error" in reply:
            raise RuntimeError(f"{method}: {reply['error']}")
        while self._attached and method != "Network.enable":  # a worker started meanwhile
            worker = self._attached.pop()
            self.send("Network.enable", session=worker)
            self.send("Runtime.runIfWaitingForDebugger", session=worker)
        return reply["result"]

    def evaluate(self, expression: str):
        """The value of a JavaScript expression in the tab (a promise is awaited)."""
        result = self.send(
            "Runtime.evaluate",
            session=self.session,
            expression=expression,
            returnByValue=True,
            awaitPromise=True,
        )
        if "exceptionDetails" in result:
            raise RuntimeError(f"{expression}: {result['exceptionDetails']}")
        return result["result"].get("value")

    def wait_for(self, expression: str, timeout: float | None = None):
        """Poll ``expression`` until it is truthy; then two more frames are drawn."""
        deadline = time.monotonic() + (timeout or self.timeout)
        while not (value := self.evaluate(expression)):
            if time.monotonic() > deadline:
                raise TimeoutError(f"{expression} still false")
            time.sleep(0.5)
        self.evaluate(FRAMES)
        return value

    def open(self, url: str) -> None:
        self.send("Page.navigate", session=self.session, url=url)
        self.wait_for("document.readyState === 'complete'")

    def click(self, x: float, y: float) -> None:
        for kind in ("mousePressed", "mouseReleased"):
            self.send(
                "Input.dispatchMouseEvent",
                session=self.session,
                type=kind,
                x=x,
                y=y,
                button="left",
                clickCount=1,
            )
        self.evaluate(FRAMES)

    def screenshot(self) -> np.ndarray:
        png = self.send("Page.captureScreenshot", session=self.session, format="png")["data"]
        return np.asarray(Image.open(io.BytesIO(base64.b64decode(png))).convert("RGB"))

    def state(self) -> dict:
        """The page's own account of its panels: each one's time and box, the clock's label."""
        return self.evaluate(
            "(v => ({times: v.dataset.times.split(' '), panels: JSON.parse(v.dataset.panels), "
            "clock: v.querySelector('.rv-clock').textContent, "
            "button: v.querySelector('.rv-play').textContent}))"
            "(document.querySelector('.rv-viewer'))"
        )

    def requested(self) -> list[str]:
        """Every URL the tab asked for."""
        return [
            e["params"]["request"]["url"]
            for e in self.events
            if e.get("method") == "Network.requestWillBeSent"
        ]

    def close(self) -> None:
        try:
            if getattr(self, "ws", None) is not None:
                self.send("Browser.close")
        except Exception:  # noqa: BLE001 (closing anyway)
            pass
        try:
            self.process.wait(timeout=20)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait(timeout=20)


#: JavaScript: wait for two frames to be drawn
FRAMES = "new Promise(r => requestAnimationFrame(() => requestAnimationFrame(() => r(true))))"
#: JavaScript: every panel shows its model (``data-times`` has no "-")
LOADED = (
    "(document.querySelector('.rv-viewer').dataset.times || '-').split(' ').every(t => t !== '-')"
)


@pytest.fixture(scope="module")
def browsed(book, notebook_page, proxy, tmp_path_factory):
    """What a reader sees: the page paused at T1 (through ``#t=``), then at the moment a click on
    the slider near T2 gives, then playing for a second; a copy of the page without one model
    (``gus_contact``), at T1; the book's page of a notebook showing the viewer, at T1.
    ``{key: (screenshot, state)}``, and ``"requested"``: every URL."""
    if _chromium() is None:
        if os.environ.get("RETARGET_REQUIRE_BROWSER"):
            pytest.fail("no Chromium: .ci/browser-deps.sh installs it")
        pytest.skip("no Chromium (apt-get install chromium)")
    tmp = tmp_path_factory.mktemp("browser")
    blank = tmp / "blank"
    shutil.copytree(book, blank)
    (blank / "_static/models/gus_contact.glb.js").write_text("")
    browser = _Browser(tmp / "profile", proxy)
    try:
        shots = {}
        browser.open(f"{(book / VIEWER_PAGE).as_uri()}#t={T1}")
        browser.wait_for(LOADED)
        shots["t1"] = (browser.screenshot(), browser.state())
        # a reader clicks the slider near T2
        x, y, w = browser.evaluate(
            "(r => [r.left, r.top + r.height / 2, r.width])("
            "document.querySelector('.rv-time').getBoundingClientRect())"
        )
        duration = float(browser.evaluate("document.querySelector('.rv-time').max"))
        browser.click(x + w * T2 / duration, y)
        shots["t2"] = (browser.screenshot(), browser.state())
        # ... and plays it for a second, then pauses it
        button = browser.evaluate(
            "(r => [r.left + r.width / 2, r.top + r.height / 2])("
            "document.querySelector('.rv-play').getBoundingClientRect())"
        )
        browser.click(*button)
        time.sleep(1.0)
        shots["playing"] = (None, browser.state())
        browser.click(*button)
        shots["paused"] = (None, browser.state())
        browser.open(f"{(blank / VIEWER_PAGE).as_uri()}#t={T1}")
        browser.wait_for(
            "(document.querySelector('.rv-viewer').dataset.times || '').split(' ')"
            ".filter(t => t && t !== '-').length === 5"
        )
        time.sleep(2.0)  # the missing model would have loaded by now
        shots["blank"] = (browser.screenshot(), browser.state())
        # the book's page of a notebook showing the viewer: its script loads the files itself
        browser.open(f"{notebook_page.as_uri()}#t={T1}")
        browser.wait_for(LOADED)
        shots["notebook"] = (None, browser.state())
        shots["requested"] = browser.requested()
        browser.evaluate("fetch('http://example.invalid/probe.glb').then(() => 1, () => 0)")
        shots["probe"] = browser.requested()[len(shots["requested"]) :]
    finally:
        browser.close()
    return shots


def _panels(shot) -> list[np.ndarray]:
    """The screenshot's pixels inside each ``<model-viewer>`` (the page's own layout)."""
    pixels, state = shot
    assert len(state["panels"]) == len(_glb_names())
    out = []
    for x, y, w, h in state["panels"]:
        assert y + h <= pixels.shape[0], "a panel lies below the window"
        out.append(pixels[y + 2 : y + h - 2, x + 2 : x + w - 2])
    return out


def _drawn(pixels: np.ndarray) -> np.ndarray:
    """Where a panel's pixels are not its background."""
    return np.abs(pixels.astype(int) - BACKGROUND).max(axis=-1) > 24


@pytest.mark.slow
def test_every_panel_draws_its_character_in_the_middle(browsed):
    for key in ("t1", "t2"):
        for name, panel in zip(_glb_names(), _panels(browsed[key]), strict=True):
            drawn = _drawn(panel)
            assert drawn.mean() > 0.02, (key, name, drawn.mean())
            # the character's middle (the median drawn column: the floor path's dots are few)
            middle = np.median(np.nonzero(drawn)[1]) / panel.shape[1]
            assert abs(middle - 0.5) < 0.1, (key, name, middle)  # the camera follows the hips
    # the check can fail: a panel whose model did not load is its background alone
    drawn = [_drawn(p).mean() for p in _panels(browsed["blank"])]
    assert drawn[-1] < 0.002 and min(drawn[:-1]) > 0.02, drawn


@pytest.mark.slow
def test_one_clock_moves_every_panel(browsed):
    n = len(_glb_names())
    assert browsed["t1"][1]["times"] == [f"{T1:.3f}"] * n
    t2 = browsed["t2"][1]["times"]  # where the click put the slider: near T2, every panel there
    assert len(set(t2)) == 1 and abs(float(t2[0]) - T2) < 0.1, t2
    assert browsed["t2"][1]["clock"].startswith(f"{float(t2[0]):.2f} /")
    playing, paused = browsed["playing"][1], browsed["paused"][1]
    assert playing["button"] == "pause" and paused["button"] == "play"
    assert len(set(playing["times"])) == 1 and float(playing["times"][0]) != float(t2[0])
    assert len(set(paused["times"])) == 1
    assert browsed["blank"][1]["times"][-1] == "-"  # never loaded
    assert browsed["notebook"][1]["times"] == [f"{T1:.3f}"] * n  # a notebook's page: the same
    for name, a, b in zip(
        _glb_names(), _panels(browsed["t1"]), _panels(browsed["t2"]), strict=True
    ):
        moved = (np.abs(a.astype(int) - b.astype(int)).max(axis=-1) > 24).mean()
        assert moved > 0.005, (name, moved)


@pytest.mark.slow
def test_the_page_asks_no_other_host_for_anything(browsed):
    requested = browsed["requested"]
    assert any(u.endswith("model-viewer-umd.min.js") for u in requested)  # the record works
    assert any(u.endswith("_static/models/gus_copy.glb.js") for u in requested)
    assert [u for u in requested if not u.startswith(("file:", "blob:", "data:"))] == []
    # ... and it can fail: the page's fetch of another host, made at the end, is recorded
    assert browsed["probe"] == ["http://example.invalid/probe.glb"]


#: the notebooks that link to the viewer and show it inline (issue: "notebooks 04, 07b, 08 and 10")
VIEWER_NOTEBOOKS = ("04", "07b", "08", "10")


@pytest.mark.parametrize("number", VIEWER_NOTEBOOKS)
def test_the_notebooks_link_to_the_viewer_and_show_it(number):
    import nbformat

    (path,) = (Path(__file__).resolve().parents[1] / "notebooks").glob(f"{number}_*.ipynb")
    nb = nbformat.read(path, as_version=4)
    links = [c for c in nb.cells if c.cell_type == "markdown" and f"]({VIEWER_LINK})" in c.source]
    shows = [
        c
        for c in nb.cells
        if c.cell_type == "code" and re.search(r"^show_viewer\(", c.source, re.M)
    ]
    assert links and shows, f"{path.name}: a link to {VIEWER_LINK} and a show_viewer() cell"
