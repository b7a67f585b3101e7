"""Interactive knobs that also work offline: a slider over precomputed pictures.

:func:`knob` draws a picture for each value of one constant (the twist loss's alpha, the cone
field's sigma, the ESO iterations, the contact threshold, ...) and shows them behind a slider made
of plain HTML and a few lines of inline JavaScript: no widget kernel, no CDN. The same display
bundle carries a PNG of the default value, so front ends that do not run scripts (GitHub's viewer,
an untrusted notebook, a PDF export) show the still picture, and the HTML book keeps both. The
slider's element id is a hash of the pictures and labels, so a re-run writes the same output.
"""

from __future__ import annotations

import base64
import hashlib
import html
from collections.abc import Callable, Sequence

import matplotlib.pyplot as plt
import numpy as np

from .display import png_bytes

__all__ = ["Knob", "knob", "figure_image"]


def figure_image(fig) -> np.ndarray:
    """A matplotlib figure as an ``(H, W, 3)`` uint8 image (the figure is closed)."""
    fig.canvas.draw()
    image = np.asarray(fig.canvas.buffer_rgba())[..., :3].copy()
    plt.close(fig)
    return image


class Knob:
    """Pictures for several values of one constant, shown behind a slider.

    Attributes:
        name: the constant's name (slider label).
        values: the values, in slider order.
        images: one ``(H, W, 3)`` uint8 image per value.
        default: index of the value shown first and in the PNG fallback.
    """

    def __init__(
        self, name: str, values: Sequence, images: Sequence[np.ndarray], default: int, max_kb: float
    ):
        self.name, self.values, self.default = name, list(values), int(default)
        self.pngs = [png_bytes(im, max_kb) for im in images]

    def html(self) -> str:
        """The slider as self-contained HTML (images inline as base64, no external scripts)."""
        labels = [html.escape(f"{self.name} = {v}") for v in self.values]
        # the same pictures and labels give the same id: a re-run writes the same output
        digest = hashlib.sha1("\n".join(labels).encode())
        for p in self.pngs:
            digest.update(p)
        uid = "knob" + digest.hexdigest()[:8]
        srcs = ["data:image/png;base64," + base64.b64encode(p).decode() for p in self.pngs]
        js_srcs = "[" + ",".join(f'"{s}"' for s in srcs) + "]"
        js_labels = "[" + ",".join(f'"{s}"' for s in labels) + "]"
        return (
            f'<div id="{uid}"><label><input type="range" min="0" max="{len(srcs) - 1}" step="1" '
            f'value="{self.default}" style="width:60%" '
            'oninput="var '
            f"k=window['{uid}'];this.parentNode.parentNode.querySelector('img').src=k.s[this.value];"
            f"this.parentNode.querySelector('span').textContent=k.l[this.value];\"> "
            f"<span>{labels[self.default]}</span></label><br>"
            f'<img src="{srcs[self.default]}" alt="{labels[self.default]}">'
            f'<script>window["{uid}"]={{s:{js_srcs},l:{js_labels}}};</script></div>'
        )

    def _repr_mimebundle_(self, include=None, exclude=None):
        return {
            "text/html": self.html(),
            "image/png": self.pngs[self.default],
            "text/plain": f"<knob {self.name}: {len(self.values)} values>",
        }


def knob(
    draw: Callable[[object], object], name: str, values: Sequence, default=None, max_kb: float = 40
) -> Knob:
    """Draw ``draw(v)`` for every ``v`` in ``values`` and show them behind a slider.

    Args:
        draw: value -> ``(H, W, 3)`` uint8 image or a matplotlib figure.
        name: the constant's name, e.g. ``"alpha (deg)"``.
        values: the values to offer (keep it to a handful: every picture is stored in the notebook).
        default: the value shown first and in the PNG fallback (default: the middle one).
        max_kb: size budget of each picture.

    Returns:
        a :class:`Knob` (the last expression of a cell shows it).
    """
    values = list(values)
    if not values:
        raise ValueError("knob needs at least one value")
    index = len(values) // 2 if default is None else values.index(default)
    images = []
    for v in values:
        out = draw(v)
        images.append(out if isinstance(out, np.ndarray) else figure_image(out))
    return Knob(name, values, images, index, max_kb)
