"""The book's 3-D viewer page: every script and model is a file inside the book folder (no other
host), and a real headless browser (Chromium) renders the characters, not a blank canvas."""

import base64
import os
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from retarget_lib.core.rig import Rig
from retarget_lib.data.synthetic.characters import make_character
from retarget_lib.data.synthetic.motions import make_motion
from retarget_lib.io import save_glb
from retarget_lib.notebook.book import remote_references
from retarget_lib.notebook.viewer import VIEWER_PAGE, write_viewer

#: the model-viewer element's background (the page's CSS); an unrendered element shows only it
BACKGROUND = np.array([0xEE, 0xF1, 0xF4])


@pytest.fixture(scope="module")
def book(tmp_path_factory):
    folder = tmp_path_factory.mktemp("book")
    gus = make_character("gus")
    glb = folder / "gus_wave.glb"
    save_glb(Rig.from_character(gus), glb, make_motion("wave", gus.skeleton, 0, 1.0))
    write_viewer(folder, {"copy": glb})
    return folder


def test_every_script_and_model_is_a_file_of_the_book(book):
    page = (book / VIEWER_PAGE).read_text()
    assert remote_references(page) == []
    local = [
        r for r in re.findall(r'(?:src|href)="([^"#]+)"', page) if r != "index.html"
    ]  # the book's front page
    assert {
        "_static/model-viewer/model-viewer-umd.min.js",
        "_static/models/gus_wave.glb.js",
        "_static/models/gus_wave.glb",
    } <= set(local)
    for ref in local:
        assert not ref.startswith(("http:", "https:", "//", "/")) and (book / ref).is_file(), ref
    script = (book / "_static/models/gus_wave.glb.js").read_text()
    data = re.search(r'= "([A-Za-z0-9+/=]+)";', script).group(1)
    assert (
        base64.b64decode(data) == (book / "_static/models/gus_wave.glb").read_bytes()
    )  # the same bytes


def _chromium() -> str | None:
    return (
        shutil.which("chromium")
        or shutil.which("chromium-browser")
        or shutil.which("google-chrome")
    )


def _screenshot(page: Path, png: Path) -> np.ndarray:
    subprocess.run(
        [
            _chromium(),
            "--headless=new",
            "--no-sandbox",
            "--use-angle=swiftshader",
            "--enable-unsafe-swiftshader",
            "--hide-scrollbars",
            "--window-size=900,700",
            "--virtual-time-budget=20000",
            f"--screenshot={png}",
            page.as_uri(),
        ],
        check=True,
        capture_output=True,
        timeout=180,
    )
    return np.asarray(Image.open(png).convert("RGB"))[
        200:590, 20:880
    ]  # inside the viewer, below the text


def _drawn(pixels: np.ndarray) -> float:
    """The share of the viewer's pixels that are not its background."""
    return float((np.abs(pixels.astype(int) - BACKGROUND).max(axis=-1) > 24).mean())


@pytest.mark.slow
def test_a_headless_browser_renders_the_characters(book, tmp_path):
    if _chromium() is None:
        if os.environ.get("RETARGET_REQUIRE_BROWSER"):
            pytest.fail("no Chromium: .ci/browser-deps.sh installs it")
        pytest.skip("no Chromium (apt-get install chromium)")
    shown = _drawn(_screenshot(book / VIEWER_PAGE, tmp_path / "shown.png"))
    # the same page without its model: the check sees a blank viewer (it can fail)
    blank = tmp_path / "blank"
    shutil.copytree(book, blank)
    (blank / "_static/models/gus_wave.glb.js").write_text("")
    empty = _drawn(_screenshot(blank / VIEWER_PAGE, tmp_path / "blank.png"))
    assert empty < 0.002 and shown > 0.02, (empty, shown)
