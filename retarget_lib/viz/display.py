"""Showing pictures in a notebook, small: PNGs re-encoded to stay under a size budget."""

from __future__ import annotations

import io
from pathlib import Path

import imageio.v3 as iio
import numpy as np
from IPython import display as ipython_display
from PIL import Image

#: committed notebook outputs stay below this (project rule: images <= 150 KB)
MAX_KB = 150


def png_bytes(image: np.ndarray, max_kb: float = MAX_KB) -> bytes:
    """Encode ``image (H, W, 3)`` uint8 as PNG no larger than ``max_kb``.

    Tries lossless, then a 256-colour palette, then halves the resolution until it fits.
    """
    im = Image.fromarray(np.asarray(image, dtype=np.uint8))
    while True:
        for candidate in (
            im,
            im.quantize(colors=256, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE),
        ):
            buf = io.BytesIO()
            candidate.save(buf, format="PNG", optimize=True)
            if buf.tell() <= max_kb * 1024:
                return buf.getvalue()
        im = im.resize((max(1, im.width // 2), max(1, im.height // 2)), Image.Resampling.LANCZOS)


def show(image: np.ndarray, max_kb: float = MAX_KB):
    """Display an image inline (returns an ``IPython.display.Image``; the last expression of a cell
    shows it).

    Args:
        image: ``(H, W, 3)`` uint8.
        max_kb: size budget of the embedded PNG.
    """
    return ipython_display.Image(data=png_bytes(image, max_kb), format="png")


def show_gif(path: str | Path, max_kb: float = MAX_KB):
    """Display a GIF inline; if the file is over ``max_kb`` its first frame is shown instead (and
    the path is printed) so the notebook stays small."""
    path = Path(path)
    if path.stat().st_size <= max_kb * 1024:
        return ipython_display.Image(data=path.read_bytes(), format="gif")
    print(f"{path} is {path.stat().st_size // 1024} KB; showing its first frame")
    return show(iio.imread(path, index=0)[..., :3], max_kb)
