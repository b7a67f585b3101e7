"""The drawing kit of the diagrams: a canvas measured in inches, rounded boxes with a title and a
detail line, arrows, the colours of each role, and :func:`layout_problems`, what makes a diagram
hard to read (text under 9 pt, outside its box or the canvas, overlapping text).
"""

from __future__ import annotations

import io
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.patches import FancyArrowPatch, FancyBboxPatch
from matplotlib.text import Text

__all__ = ["COLORS", "FONT", "MIN_FONT", "Box", "Canvas", "DiagramFigure", "layout_problems"]

#: smallest font size in any diagram (points)
MIN_FONT = 9.0
FONT = 9.5
_MONO = "DejaVu Sans Mono"
#: fill colours by role
COLORS = {
    "io": "#eeeeee",
    "data": "#e3ecf7",
    "conv": "#fbe7a1",
    "rnn": "#d9ead3",
    "head": "#cfe8f3",
    "fk": "#f4d6e4",
    "opt": "#fdd9b5",
    "out": "#e6dcf2",
    "energy": "#f8cecc",
}
_EDGE = "#555555"


class DiagramFigure(Figure):
    """A figure that shows itself as a PNG in a notebook even before pyplot is imported."""

    def _repr_png_(self) -> bytes:
        buf = io.BytesIO()
        self.savefig(buf, format="png", dpi=100, bbox_inches="tight")
        return buf.getvalue()


class Box(NamedTuple):
    """A drawn box (inches from the figure's lower left corner)."""

    x: float
    y: float
    w: float
    h: float

    @property
    def left(self) -> tuple[float, float]:
        return self.x, self.y + self.h / 2

    @property
    def right(self) -> tuple[float, float]:
        return self.x + self.w, self.y + self.h / 2

    @property
    def top(self) -> tuple[float, float]:
        return self.x + self.w / 2, self.y + self.h

    @property
    def bottom(self) -> tuple[float, float]:
        return self.x + self.w / 2, self.y

    def at(self, fx: float, fy: float) -> tuple[float, float]:
        """The point at fractions ``(fx, fy)`` of the box's width and height."""
        return self.x + fx * self.w, self.y + fy * self.h


class Canvas:
    """A figure whose main axes span it in inches: ``(0, 0)`` lower left, ``(width, height)`` upper
    right."""

    def __init__(self, width: float = 9.0, height: float = 4.0, title: str | None = None):
        self.fig = DiagramFigure(figsize=(width, height), dpi=100)
        FigureCanvasAgg(self.fig)
        self.ax = self.fig.add_axes([0, 0, 1, 1])
        self.ax.set_xlim(0, width)
        self.ax.set_ylim(0, height)
        self.ax.axis("off")
        self.width, self.height = width, height
        self.fig._diagram_boxes = []  # (patch, [texts]) for layout_problems
        if title:
            self.text(width / 2, height - 0.2, title, size=11, weight="bold")

    def text(
        self,
        x: float,
        y: float,
        s: str,
        size: float = FONT,
        mono: bool = False,
        ha: str = "center",
        va: str = "center",
        **kw,
    ) -> Text:
        return self.ax.text(
            x, y, s, fontsize=size, family=_MONO if mono else None, ha=ha, va=va, **kw
        )

    def box(
        self,
        x: float,
        y: float,
        w: float,
        h: float,
        title: str,
        detail: str | None = None,
        role: str = "data",
        size: float = FONT,
        mono_detail: bool = False,
        bold: bool = False,
        edge: str = _EDGE,
        lw: float = 1.0,
    ) -> Box:
        """A rounded box with a title line and an optional detail line below it."""
        patch = FancyBboxPatch(
            (x, y),
            w,
            h,
            boxstyle="round,pad=0,rounding_size=0.06",
            fc=COLORS.get(role, role),
            ec=edge,
            lw=lw,
            zorder=2,
        )
        self.ax.add_patch(patch)
        texts = []
        if detail is None:
            texts.append(
                self.text(
                    x + w / 2,
                    y + h / 2,
                    title,
                    size=size,
                    zorder=3,
                    weight="bold" if bold else None,
                )
            )
        else:
            texts.append(
                self.text(
                    x + w / 2,
                    y + 0.68 * h,
                    title,
                    size=size,
                    zorder=3,
                    weight="bold" if bold else None,
                )
            )
            texts.append(
                self.text(
                    x + w / 2,
                    y + 0.3 * h,
                    detail,
                    size=MIN_FONT,
                    mono=mono_detail,
                    zorder=3,
                    color="#333333",
                )
            )
        self.fig._diagram_boxes.append((patch, texts))
        return Box(x, y, w, h)

    def arrow(
        self,
        start: Sequence[float],
        end: Sequence[float],
        color: str = "#333333",
        lw: float = 1.3,
        rad: float = 0.0,
        style: str = "-|>",
        ls: str = "-",
        connection: str | None = None,
    ) -> None:
        cs = connection or f"arc3,rad={rad}"
        self.ax.add_patch(
            FancyArrowPatch(
                tuple(start),
                tuple(end),
                arrowstyle=style,
                mutation_scale=12,
                color=color,
                lw=lw,
                ls=ls,
                connectionstyle=cs,
                zorder=1,
                shrinkA=1,
                shrinkB=1,
            )
        )

    def polyline_arrow(
        self,
        points: Sequence[Sequence[float]],
        color: str = "#333333",
        lw: float = 1.3,
        ls: str = "-",
    ) -> None:
        """Straight segments through ``points`` with an arrow head on the last one."""
        pts = np.asarray(points, dtype=float)
        self.ax.plot(
            pts[:-1, 0], pts[:-1, 1], color=color, lw=lw, ls=ls, zorder=1, solid_capstyle="butt"
        )
        self.arrow(pts[-2], pts[-1], color=color, lw=lw, ls=ls)


# ------------------------------------------------------------------------------------------ checks
def layout_problems(fig: Figure) -> list[str]:
    """What makes a diagram hard to read: text below :data:`MIN_FONT`, text outside the figure or
    outside its box, and overlapping texts.

    Args:
        fig: a figure from this module (any matplotlib figure works for the font, canvas and
            overlap checks).

    Returns:
        one sentence per problem (empty when the diagram is readable).
    """
    if not hasattr(fig.canvas, "get_renderer"):
        FigureCanvasAgg(fig)
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    canvas = fig.bbox
    texts = [
        t
        for t in fig.findobj(Text)
        if t.get_visible() and t.get_text().strip() and t.get_window_extent(renderer).width > 0
    ]
    problems = []
    extents = []
    for t in texts:
        box = t.get_window_extent(renderer)
        extents.append(box)
        if t.get_fontsize() < MIN_FONT - 1e-6:
            problems.append(f"{t.get_text()!r}: {t.get_fontsize():.1f} pt < {MIN_FONT} pt")
        if (
            box.x0 < canvas.x0 - 1
            or box.x1 > canvas.x1 + 1
            or box.y0 < canvas.y0 - 1
            or box.y1 > canvas.y1 + 1
        ):
            problems.append(f"{t.get_text()!r}: outside the figure")
    for patch, owned in getattr(fig, "_diagram_boxes", []):
        pb = patch.get_window_extent(renderer)
        for t in owned:
            tb = t.get_window_extent(renderer)
            if tb.x0 < pb.x0 - 1 or tb.x1 > pb.x1 + 1 or tb.y0 < pb.y0 - 1 or tb.y1 > pb.y1 + 1:
                problems.append(f"{t.get_text()!r}: does not fit its box")
    for i in range(len(texts)):
        for k in range(i + 1, len(texts)):
            a, b = extents[i], extents[k]
            if min(a.x1, b.x1) - max(a.x0, b.x0) > 1 and min(a.y1, b.y1) - max(a.y0, b.y0) > 1:
                problems.append(f"{texts[i].get_text()!r} overlaps {texts[k].get_text()!r}")
    return problems
