"""Colour keys beside a render: a colorbar for meshes coloured by a value, a legend of patches for
categorical colours, and a fixed table of up to 24 distinct categorical colours.
"""

from __future__ import annotations

from collections.abc import Sequence

import matplotlib.pyplot as plt
import numpy as np
from matplotlib import colormaps
from matplotlib.cm import ScalarMappable
from matplotlib.colors import Normalize
from matplotlib.patches import Patch

from .knobs import figure_image

__all__ = ["add_colorbar", "add_legend", "categorical_colors"]


def _strip(fig) -> np.ndarray:
    return figure_image(fig)


def _beside(image: np.ndarray, strip: np.ndarray) -> np.ndarray:
    """``image`` with ``strip`` pasted on its right (white-padded to the same height)."""
    h = max(image.shape[0], strip.shape[0])

    def pad(im):
        return np.concatenate([im, np.full((h - im.shape[0], im.shape[1], 3), 255, np.uint8)], 0)

    return np.concatenate([pad(np.asarray(image, np.uint8)), pad(strip)], axis=1)


def add_colorbar(
    image: np.ndarray,
    cmap,
    clim: tuple[float, float],
    label: str,
    width_px: int = 110,
    extend: str = "neither",
) -> np.ndarray:
    """A render with a vertical colorbar on its right (for meshes coloured by ``scalars``).

    Args:
        image: ``(H, W, 3)`` uint8 render.
        cmap: the colormap name (or object) the render used.
        clim: ``(low, high)`` the render's colour range.
        label: what the colour means, with its unit.
        width_px: width of the added strip.
        extend: ``"max"`` etc. when values beyond ``clim`` were clipped (drawn as an arrow).

    Returns:
        ``(H, W + width_px, 3)`` uint8.
    """
    h = image.shape[0]
    dpi = 100
    fig = plt.figure(figsize=(width_px / dpi, h / dpi), dpi=dpi)
    ax = fig.add_axes([0.12, 0.08, 0.16, 0.84])
    bar = fig.colorbar(ScalarMappable(Normalize(*clim), cmap), cax=ax, extend=extend)
    bar.set_label(label, fontsize=10)
    bar.ax.tick_params(labelsize=9)
    return _beside(image, _strip(fig))


def add_legend(
    image: np.ndarray,
    labels: Sequence[str],
    colors: Sequence,
    title: str | None = None,
    ncol: int = 1,
    width_px: int = 150,
) -> np.ndarray:
    """A render with a legend of coloured patches on its right (for categorical colours).

    Args:
        image: ``(H, W, 3)`` uint8 render.
        labels: one name per colour.
        colors: matplotlib colours, same order.
        title: legend title.
        ncol: legend columns.
        width_px: width of the added strip.

    Returns:
        ``(H, W + width_px, 3)`` uint8.
    """
    h = image.shape[0]
    dpi = 100
    fig = plt.figure(figsize=(width_px / dpi, h / dpi), dpi=dpi)
    fig.legend(
        [Patch(color=c) for c in colors],
        labels,
        loc="center left",
        bbox_to_anchor=(0.0, 0.5),
        ncol=ncol,
        fontsize=9,
        title=title,
        title_fontsize=9,
        frameon=False,
        handlelength=1.0,
        columnspacing=0.8,
        labelspacing=0.25,
    )
    return _beside(image, _strip(fig))


def categorical_colors(n: int) -> np.ndarray:
    """``(n, 3)`` RGB colours that stay distinct for up to 24 categories (tab10, then the dark
    and the light shades of tab20b, then two of tab20c that differ from all of those), in a
    fixed order."""
    base = [colormaps["tab10"](i)[:3] for i in range(10)]
    extra = [colormaps["tab20b"](i)[:3] for i in (0, 4, 8, 12, 16, 2, 6, 10, 14, 18)]
    extra += [colormaps["tab20c"](i)[:3] for i in (12, 2, 9, 17)]
    table = np.array(base + extra)
    if n > len(table):
        raise ValueError(f"categorical_colors: at most {len(table)} categories, got {n}")
    return table[:n]
