"""Placing scenes in world space before a picture: characters stood on the floor (``y = 0``), a
lineup spread along x by each character's own width plus a gap (so relative sizes stay true), the
box that holds them and where each title goes.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from .glyphs import JOINT_RADIUS
from .scene import Scene

__all__ = ["layout_row", "scene_bounds", "stand_on_floor", "title_anchor"]


def scene_bounds(
    scenes: Sequence[Scene], size: float | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """``(lo (3,), hi (3,))`` box of the scenes' points; with ``size``, padded for the joint
    spheres and (on skeletons with a ``Head`` joint) the skull drawn above the head joint."""
    pts = np.concatenate([s.points() for s in scenes])
    lo, hi = pts.min(0), pts.max(0)
    if size is not None:
        lo, hi = lo - 0.03 * size, hi + 0.03 * size
        if any(_has_head(s) for s in scenes):
            hi[1] += 0.09 * size
    return lo, hi


def _has_head(s: Scene) -> bool:
    if s.positions is None:
        return False
    return "Head" in list(s.joint_names) if s.joint_names is not None else len(s.positions) == 22


def title_anchor(s: Scene, size: float) -> list[float]:
    """World point just above the scene's padded box (where its label is centred)."""
    lo, hi = scene_bounds([s], size)
    return [0.5 * (lo[0] + hi[0]), hi[1] + 0.02 * size, hi[2]]


def layout_row(scenes: Sequence[Scene], gap: float | None = None, extents=None) -> list[Scene]:
    """Translate scenes along x so they stand next to each other (x-extents + ``gap`` apart).

    ``extents`` (one ``(lo, hi)`` per scene) may come from a whole clip so the offsets stay fixed.
    """
    extents = extents or [(s.points().min(0), s.points().max(0)) for s in scenes]
    gap = gap if gap is not None else 0.35 * float(np.median([s.size() for s in scenes]))
    out, cursor = [], 0.0
    for s, (lo, hi) in zip(scenes, extents, strict=False):
        width = max(hi[0] - lo[0], 0.2 * s.size())
        dx = cursor + 0.5 * width - 0.5 * (lo[0] + hi[0])
        out.append(s.translated([dx, 0, 0]))
        cursor += width + gap
    shift = -0.5 * (cursor - gap)
    return [s.translated([shift, 0, 0]) for s in out]


def stand_on_floor(scene: Scene, size: float | None = None) -> Scene:
    """The scene moved up or down so its lowest drawn point is at ``y = 0``.

    Args:
        scene: the scene.
        size: the renderer's character size; a skeleton's lowest joint sphere (radius
            ``0.018 * size``, see :class:`SceneRenderer`) then rests on the floor too.
    """
    lowest = float(scene.points()[:, 1].min())
    if scene.vertices is None and scene.positions is not None and size is not None:
        lowest -= JOINT_RADIUS * size
    return scene.translated([0.0, -lowest, 0.0])
