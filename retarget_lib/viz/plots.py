"""Matplotlib figures: root trajectories from above (TDCN Fig. 5b), contact timelines, and a
lightweight stick figure for when 3-D rendering is not wanted."""

from __future__ import annotations

from typing import Mapping, Sequence

import matplotlib.pyplot as plt
import numpy as np

from ..core.skeleton import CANONICAL22
from .render import CENTER_COLOR, LEFT_COLOR, RIGHT_COLOR


def plot_root_trajectories(trajectories: Mapping[str, np.ndarray], ax=None, mark_start: bool = True):
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
        ax.pcolormesh(t, [row - 0.4, row + 0.4], v[None, :], cmap="Blues", vmin=0, vmax=1, shading="flat")
    ax.set_yticks(range(len(names)), names)
    ax.set_ylim(-0.6, len(names) - 0.4)
    ax.set_xlabel("time (s)")
    ax.grid(False)
    return ax


def plot_skeleton_mpl(positions: np.ndarray, parents: Sequence[int], ax=None, view: str = "front",
                      joint_names: Sequence[str] | None = None):
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
        c = LEFT_COLOR if "Left" in names[j] else RIGHT_COLOR if "Right" in names[j] else CENTER_COLOR
        ax.plot(p[[par, j], 0], p[[par, j], 1], "-o", color=c, ms=3, lw=2)
    ax.set_aspect("equal")
    ax.set_xlabel("xyz"[axes[0]])
    ax.set_ylabel("xyz"[axes[1]])
    return ax
