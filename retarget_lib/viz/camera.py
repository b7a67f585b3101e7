"""Camera placement: the camera is fitted to what is drawn (the convex hull of the spheres, tubes
and mesh vertices, over the whole clip for animations), so the subject fills the canvas up to a
small margin, with a band kept free at the top for the titles.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import ConvexHull, QhullError

__all__ = ["VIEWS", "fit_camera", "hull_points"]

#: camera presets: name -> (azimuth from +Z towards +X, elevation), degrees
VIEWS: dict[str, tuple[float, float]] = {
    "front": (0.0, 8.0),
    "front_side": (30.0, 14.0),
    "side": (-90.0, 6.0),
    "top": (0.0, 90.0),
    "back": (180.0, 10.0),
}


def _view_axes(view) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Unit ``(back, up, right)`` of a camera preset or ``(azimuth, elevation)`` in degrees."""
    az, el = VIEWS[view] if isinstance(view, str) else view
    az, el = np.radians(az), np.radians(el)
    back = np.array([np.sin(az) * np.cos(el), np.sin(el), np.cos(az) * np.cos(el)])
    up = (
        np.array([0.0, 1.0, 0.0])
        if abs(np.degrees(el)) < 80
        else np.array([-np.sin(az), 0, -np.cos(az)])
    )
    right = np.cross(-back, up)
    right /= np.linalg.norm(right)
    return back, np.cross(right, -back), right


def hull_points(points: np.ndarray) -> np.ndarray:
    """``(K, 3)`` the vertices of the convex hull of ``points (N, 3)`` (all points if degenerate).

    A (perspective or parallel) projection maps a convex set onto a convex set, so the hull's
    vertices are all a camera fit needs.
    """
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    if len(points) < 5:
        return points
    try:
        return points[ConvexHull(points).vertices]
    except (QhullError, ValueError):
        return points


def fit_camera(
    points: np.ndarray,
    view,
    window_size: tuple[int, int],
    parallel: bool = False,
    view_angle: float = 30.0,
    margin: float = 0.04,
    top_px: float = 0.0,
) -> dict:
    """Camera that shows all ``points`` as large as the canvas allows.

    The points' projection fills the window up to ``margin`` (a fraction of the window's smaller
    side, on every edge) and leaves a free band of ``top_px`` pixels at the top (for titles).
    Perspective: the distance and the focal point are found by a fixed-point iteration on the
    projected extents (a few steps; exact for parallel projection).

    Args:
        points: ``(N, 3)`` world points that must be visible (e.g. :func:`hull_points`).
        view: a key of :data:`VIEWS` or ``(azimuth, elevation)`` degrees.
        window_size: ``(width, height)`` pixels.
        parallel: orthographic projection.
        view_angle: vertical field of view in degrees (perspective).
        margin: free border, fraction of ``min(width, height)``.
        top_px: free band at the top in pixels.

    Returns:
        dict with ``position``, ``focal_point``, ``up`` (``(3,)`` each), ``scale`` (parallel
        half-height in metres) and ``dist`` (camera to focal point, metres).
    """
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    back, up, right = _view_axes(view)
    w, h = window_size
    aspect = w / h
    mx, my = 2 * margin * min(w, h) / w, 2 * margin * min(w, h) / h
    x_lo, x_hi = -1 + mx, 1 - mx
    y_lo, y_hi = -1 + my, 1 - my - 2 * top_px / h
    if y_hi - y_lo < 0.2:  # a title band taller than the window: keep a fifth for the subject
        y_hi = y_lo + 0.2
    tx, ty, wt, ht = 0.5 * (x_lo + x_hi), 0.5 * (y_lo + y_hi), x_hi - x_lo, y_hi - y_lo
    lo, hi = pts.min(0), pts.max(0)
    size = max(float(np.linalg.norm(hi - lo)), 1e-3)
    f = 0.5 * (lo + hi)
    tv = np.tan(np.radians(view_angle) / 2)
    if parallel:
        rel = pts - f
        a, b = rel @ right, rel @ up
        scale = max(np.ptp(a) / (aspect * wt), np.ptp(b) / ht, 1e-3)
        f = (
            f
            + right * (0.5 * (a.max() + a.min()) - tx * scale * aspect)
            + up * (0.5 * (b.max() + b.min()) - ty * scale)
        )
        dist = float(((pts - f) @ back).max()) + size
        return dict(position=f + back * dist, focal_point=f, up=up, scale=scale, dist=dist)
    dist = 1.2 * size / tv
    for _ in range(60):
        rel = pts - f
        depth_off = rel @ back
        dist = max(dist, float(depth_off.max()) + 0.05 * size)
        z = dist - depth_off
        x, y = rel @ right / (z * tv * aspect), rel @ up / (z * tv)
        s = max(np.ptp(x) / wt, np.ptp(y) / ht, 1e-6)
        cx, cy = 0.5 * (x.max() + x.min()), 0.5 * (y.max() + y.min())
        if abs(s - 1) < 1e-4 and abs(cx - tx) < 1e-4 and abs(cy - ty) < 1e-4:
            break
        f = f + right * (cx - tx) * dist * tv * aspect + up * (cy - ty) * dist * tv
        mid = float(np.median(depth_off))
        dist = mid + (dist - mid) * s
    scale = dist * tv
    return dict(position=f + back * dist, focal_point=f, up=up, scale=scale, dist=dist)
