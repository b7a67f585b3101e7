"""Matplotlib figures: root trajectories from above (TDCN Fig. 5b), contact timelines, and a
lightweight stick figure for when 3-D rendering is not wanted."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter

from ..core.skeleton import CANONICAL22
from .scene import CENTER_COLOR, LEFT_COLOR, RIGHT_COLOR


def plot_root_trajectories(
    trajectories: Mapping[str, np.ndarray], ax=None, mark_start: bool = True
):
    """Top view (x-z plane) of root trajectories, equal aspect, like TDCN's Fig. 5b.

    Args:
        trajectories: name -> ``(T, 3)`` root positions (metres; y is ignored).
        ax: matplotlib Axes (new figure if ``None``).
        mark_start: draw a dot at each start.

    Returns:
        the Axes (one line per trajectory).
    """
    if ax is None:
        _, ax = plt.subplots(figsize=(5, 4))
    for name, traj in trajectories.items():
        traj = np.asarray(traj)
        (line,) = ax.plot(traj[:, 0], traj[:, 2], label=name, lw=1.6)
        if mark_start:
            ax.plot(traj[:1, 0], traj[:1, 2], "o", color=line.get_color(), ms=4)
    ax.set_xlabel("x (m)  — character's left")
    ax.set_ylabel("z (m)  — forward")
    ax.set_aspect("equal", adjustable="datalim")
    ax.legend(fontsize=8, loc="best")
    ax.set_title("root trajectories, top view")
    return ax


def plot_timeline(tracks: Mapping[str, np.ndarray], fps: float = 30.0, ax=None):
    """Boolean or [0, 1] tracks over time as horizontal bands (e.g. foot contacts).

    Args:
        tracks: name -> ``(T,)`` bool/float values.
        fps: frames per second (x axis in seconds).
        ax: matplotlib Axes (new figure if ``None``).

    Returns:
        the Axes.
    """
    if ax is None:
        _, ax = plt.subplots(figsize=(8, 0.5 + 0.45 * len(tracks)))
    names = list(tracks)
    for row, name in enumerate(names):
        v = np.asarray(tracks[name], dtype=float)
        t = np.arange(len(v) + 1) / fps
        ax.pcolormesh(
            t, [row - 0.4, row + 0.4], v[None, :], cmap="Blues", vmin=0, vmax=1, shading="flat"
        )
    ax.set_yticks(range(len(names)), names)
    ax.set_ylim(-0.6, len(names) - 0.4)
    ax.set_xlabel("time (s)")
    ax.grid(False)
    return ax


def plot_skeleton_mpl(
    positions: np.ndarray,
    parents: Sequence[int],
    ax=None,
    view: str = "front",
    joint_names: Sequence[str] | None = None,
):
    """A 2-D stick figure (front: x-y, side: z-y, top: x-z) with left/right colours.

    Args:
        positions: ``(J, 3)`` joint positions.
        parents: ``J`` parents.
        ax: matplotlib Axes (new figure if ``None``).
        view: ``"front"``, ``"side"`` or ``"top"``.
        joint_names: names for side colours (canonical 22 assumed when ``J == 22``).

    Returns:
        the Axes.
    """

    if ax is None:
        _, ax = plt.subplots(figsize=(3, 4))
    names = joint_names or (CANONICAL22 if len(parents) == 22 else [""] * len(parents))
    axes = {"front": (0, 1), "side": (2, 1), "top": (0, 2)}[view]
    p = np.asarray(positions)[:, axes]
    for j, par in enumerate(parents):
        if par < 0:
            continue
        c = (
            LEFT_COLOR
            if "Left" in names[j]
            else RIGHT_COLOR
            if "Right" in names[j]
            else CENTER_COLOR
        )
        ax.plot(p[[par, j], 0], p[[par, j], 1], "-o", color=c, ms=3, lw=2)
    ax.set_aspect("equal")
    ax.set_xlabel("xyz"[axes[0]])
    ax.set_ylabel("xyz"[axes[1]])
    return ax


def plain_log_ticks(axis, subs: Sequence[float] | None = None) -> None:
    """Label a log axis with plain numbers (``0.01, 0.1, 1, 10``) instead of ``10^k`` and
    ``4×10^0``.

    Call it after the data are drawn (the automatic choice reads the axis' current limits).

    Args:
        axis: ``ax.xaxis`` or ``ax.yaxis`` of a log-scaled Axes.
        subs: labelled multiples of each power of ten; default ``(1, 2, 5)`` when the axis spans
            less than about two and a half decades (so it has several labels), else ``(1,)``.
    """
    if subs is None:
        lo, hi = sorted(axis.get_view_interval())
        subs = (1.0, 2.0, 5.0) if lo > 0 and hi / lo < 300 else (1.0,)
    axis.set_major_locator(LogLocator(base=10.0, subs=tuple(subs), numticks=12))
    axis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
    axis.set_minor_formatter(NullFormatter())


def plot_grouped_barh(
    values,
    ax=None,
    log: bool = False,
    xlabel: str = "",
    title: str = "",
    colors: Sequence | None = None,
    reference: float | None = None,
    reference_label: str | None = None,
    legend: bool = True,
    fontsize: float = 10,
    base: float | None = None,
):
    """Horizontal grouped bars: one group per row of ``values`` (top to bottom, labels read
    horizontally), one colour per column, named in a legend.

    Horizontal bars keep long row names (``Eskel+Efoot+Eint w/o w``) readable without rotating them.
    On a log axis a value ``<= 0`` cannot be drawn: it is marked with a ``0`` at the axis' left end
    instead of vanishing; a missing value (NaN, e.g. a paper column the paper does not report)
    draws no bar.

    Args:
        values: ``pandas.DataFrame`` (rows = categories, columns = series) or a mapping
            series name -> ``pandas.Series`` indexed by category.
        ax: matplotlib Axes (new figure if ``None``).
        log: logarithmic value axis (use it when the values span decades), ticks as plain numbers.
        xlabel: value-axis label (say "log scale" yourself if you want it in the label).
        title: Axes title.
        colors: one colour per column (default the ``tab10`` cycle).
        reference: draw a vertical line at this value (e.g. ``1`` for ratios).
        reference_label: legend entry of the reference line.
        legend: draw the legend.
        fontsize: tick-label size in points (>= 9 for a readable figure).
        base: where the bars start (default: 0 on a linear axis, below the smallest value on a log
            axis); e.g. ``1`` for ratios, so a bar points right when the ratio is above 1 and left
            when below.

    Returns:
        the Axes.
    """
    frame = pd.DataFrame(values).astype(float)
    if ax is None:
        _, ax = plt.subplots(figsize=(5.0, 0.6 + 0.35 * len(frame) * max(1, frame.shape[1]) ** 0.5))
    n_rows, n_cols = frame.shape
    colors = list(colors) if colors is not None else list(plt.cm.tab10.colors)
    height = 0.8 / max(n_cols, 1)
    y = np.arange(n_rows)
    positive = frame.to_numpy()[np.isfinite(frame.to_numpy()) & (frame.to_numpy() > 0)]
    lowest = positive.min() if positive.size else 1.0
    if base is not None:
        lowest = min(lowest, base)
    floor = lowest / 3 if log else 0.0
    start = base if base is not None else floor
    handles = []
    for k, column in enumerate(frame.columns):
        offset = (k - (n_cols - 1) / 2) * height
        v = frame[column].to_numpy()
        drawn = np.isfinite(v) & ((v > 0) if log else True)
        handles.append(
            ax.barh(
                y[drawn] + offset,
                v[drawn] - start,
                height,
                left=start,
                color=colors[k % len(colors)],
                label=str(column),
            )
        )
        for row in np.flatnonzero(np.isfinite(v) & ~drawn):  # zero or negative on a log axis
            ax.text(
                floor,
                y[row] + offset,
                " 0",
                va="center",
                ha="left",
                fontsize=fontsize - 1,
                color=colors[k % len(colors)],
            )
    if reference is not None:
        line = ax.axvline(reference, color="k", lw=1, ls=":", label=reference_label)
        if reference_label:
            handles.append(line)
    ax.set_yticks(y, [str(i) for i in frame.index], fontsize=fontsize)
    ax.tick_params(axis="x", labelsize=fontsize)
    ax.set_ylim(n_rows - 0.5, -0.5)  # first row on top
    if log:
        ax.set_xscale("log")
        top = max(positive.max(), base or 0.0) * 2 if positive.size else 10.0
        ax.set_xlim(floor, top)
        plain_log_ticks(ax.xaxis)
    ax.grid(True, axis="x", which="major", alpha=0.3)
    ax.grid(False, axis="y")
    if xlabel:
        ax.set_xlabel(xlabel, fontsize=fontsize)
    if title:
        ax.set_title(title, fontsize=fontsize + 1)
    if legend:
        ax.legend(handles=handles, fontsize=fontsize - 1, loc="best")
    return ax
