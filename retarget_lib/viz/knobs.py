"""Knobs: a slider over precomputed pictures, live in a Jupyter kernel and working offline too.

:func:`knob` draws a picture for each value of one constant (the twist loss's alpha, the cone
field's sigma, the ESO iterations, the contact threshold, ...) once, up front, so moving the slider
only swaps pictures: instant, whatever the drawing costs. One display bundle carries three views:

- in a running kernel (JupyterLab, Notebook, VS Code) an ipywidgets control: a
  ``SelectionSlider`` over the values, a label ``name = value`` and an ``Image`` widget that takes
  the chosen value's PNG bytes on every change (the ``widget-view`` entry of the bundle; the
  widget is built only where ipywidgets is installed and an IPython kernel runs, see
  :func:`live_kernel`);
- a slider made of plain HTML and a few lines of inline JavaScript (``text/html``): no widget
  manager, no CDN, so it works in the offline HTML book and in a trusted notebook opened without a
  kernel;
- a PNG of the default value (``image/png``), which front ends that run no script (GitHub's viewer,
  an untrusted notebook, a PDF export) show.

Outside a kernel (plain Python, the tests) the bundle is the HTML slider, the PNG and a text line,
and no widget is created. The runner (:mod:`retarget_lib.notebook.runner`) drops the widget view
from the notebooks it saves, since its model id is random and its model lives only as long as the
kernel, and the book (:mod:`retarget_lib.notebook.book`) drops it from its pages: both keep the
HTML slider and the PNG. The HTML slider's element id is a hash of the pictures and labels, so a
re-run that draws the same pictures writes the same output.
"""

from __future__ import annotations

import base64
import hashlib
import html
from collections.abc import Callable, Sequence

import matplotlib.pyplot as plt
import numpy as np

from .display import png_bytes

try:  # the live control; ipywidgets is a dependency, but the fallbacks must not need it
    import ipywidgets as widgets
    from IPython import get_ipython
except ImportError:  # pragma: no cover - exercised by monkeypatching ``widgets`` in the tests
    widgets = None
    get_ipython = None

__all__ = ["Knob", "knob", "figure_image", "live_kernel"]

WIDGET_VIEW = "application/vnd.jupyter.widget-view+json"


def figure_image(fig) -> np.ndarray:
    """A matplotlib figure as an ``(H, W, 3)`` uint8 image (the figure is closed)."""
    fig.canvas.draw()
    image = np.asarray(fig.canvas.buffer_rgba())[..., :3].copy()
    plt.close(fig)
    return image


def live_kernel() -> bool:
    """Whether a knob shown now can be a live widget: ipywidgets is installed and this code runs
    in an IPython kernel (whose comms reach a Jupyter front end). False in plain Python, in a
    terminal IPython and under pytest."""
    if widgets is None or get_ipython is None:
        return False
    shell = get_ipython()
    return shell is not None and getattr(shell, "kernel", None) is not None


class Knob:
    """Pictures for several values of one constant, shown behind a slider.

    Attributes:
        name: the constant's name (slider label).
        values: the values, in slider order.
        pngs: one PNG (bytes) per value.
        default: index of the value shown first and in the PNG fallback.
        index: index of the value the live control shows (``default`` until it is moved).
        widget: the live control (an ipywidgets ``VBox``: slider and label above the image), built
            by :meth:`make_widget` the first time the knob is shown in a kernel; ``None`` before.
    """

    def __init__(
        self, name: str, values: Sequence, images: Sequence[np.ndarray], default: int, max_kb: float
    ):
        self.name, self.values, self.default = name, list(values), int(default)
        self.pngs = [png_bytes(im, max_kb) for im in images]
        if len(self.pngs) != len(self.values):
            raise ValueError(f"{len(self.values)} values but {len(self.pngs)} pictures")
        self.index = self.default
        self.widget = None
        self.slider = self.label = self.image = None

    @property
    def value(self):
        """The value the live control shows."""
        return self.values[self.index]

    def caption(self, index: int) -> str:
        """``name = value`` for the value at ``index``."""
        return f"{self.name} = {self.values[index]}"

    def html(self) -> str:
        """The slider as self-contained HTML (images inline as base64, no external scripts)."""
        labels = [html.escape(self.caption(i)) for i in range(len(self.values))]
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

    def make_widget(self):
        """The live control, built once: a ``SelectionSlider`` over the values (its options are
        ``(str(value), index)``), a ``Label`` ``name = value`` and an ``Image`` that gets the
        chosen value's PNG bytes on every change (the pictures are precomputed: no redraw)."""
        if self.widget is not None:
            return self.widget
        if widgets is None:
            raise RuntimeError("a live knob needs ipywidgets (pip install ipywidgets)")
        self.slider = widgets.SelectionSlider(
            options=[(str(v), i) for i, v in enumerate(self.values)],
            value=self.index,
            readout=False,
            continuous_update=True,
            layout=widgets.Layout(width="60%"),
        )
        self.label = widgets.Label(self.caption(self.index))
        self.image = widgets.Image(value=self.pngs[self.index], format="png")
        self.slider.observe(self._on_change, names="value")
        self.widget = widgets.VBox([widgets.HBox([self.slider, self.label]), self.image])
        return self.widget

    def _on_change(self, change) -> None:
        self.index = int(change["new"])
        self.image.value = self.pngs[self.index]
        self.label.value = self.caption(self.index)

    def close(self) -> None:
        """Close the live control's widgets (their comms), if it was built."""
        if self.widget is not None:
            for w in (self.slider, self.label, self.image, *self.widget.children, self.widget):
                w.close()
            self.widget = None
            self.slider = self.label = self.image = None

    def _repr_mimebundle_(self, include=None, exclude=None):
        bundle = {}
        if live_kernel():
            view = self.make_widget()._repr_mimebundle_(include=include, exclude=exclude) or {}
            if WIDGET_VIEW in view:
                bundle[WIDGET_VIEW] = view[WIDGET_VIEW]
        bundle["text/html"] = self.html()
        bundle["image/png"] = self.pngs[self.default]
        bundle["text/plain"] = f"<knob {self.name}: {len(self.values)} values>"
        return bundle


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
        a :class:`Knob` (the last expression of a cell shows it: a live ipywidgets slider in a
        kernel, the HTML slider and the default's PNG elsewhere; see the module docstring).
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
