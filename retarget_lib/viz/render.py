"""Offscreen 3-D pictures with PyVista, one call each: skeletons, skinned meshes, side-by-side
lineups and filmstrips, written as optimised PNGs.

How a picture is built: each character is a :class:`~retarget_lib.viz.scene.Scene`; the scenes
are placed (:mod:`retarget_lib.viz.layout`: side-by-side lineups first stand every character on
the floor), drawn by one :class:`~retarget_lib.viz.plotter.SceneRenderer`, and the camera is fitted
to what is drawn (:mod:`retarget_lib.viz.camera`). Animations are :mod:`retarget_lib.viz.animate`.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
from PIL import Image

from .camera import hull_points
from .layout import layout_row, scene_bounds, stand_on_floor, title_anchor
from .plotter import SceneRenderer, frame_and_title
from .scene import MESH_COLOR, PALETTE, Scene, as_scene

__all__ = [
    "render_filmstrip",
    "render_mesh",
    "render_scenes",
    "render_side_by_side",
    "render_skeleton",
    "save_png",
]


def render_scenes(
    scenes: Sequence[Scene],
    titles: Sequence[str] | None = None,
    view="front_side",
    window_size=(640, 400),
    parallel: bool = False,
    ground: bool = True,
    shadow: bool = True,
    font_size: int = 12,
    floor: float | None = None,
) -> np.ndarray:
    """Render scenes already placed in world space (no re-layout) into one image.

    The camera is fitted to the drawn geometry (the subject fills the canvas up to a small
    margin, titles get a band at the top) and the floor lies at the lowest drawn point.

    Args:
        scenes: :class:`Scene` objects.
        titles: one label per scene (``None``: each scene's ``title``), drawn above it.
        view: a key of :data:`VIEWS` or ``(azimuth, elevation)`` in degrees.
        window_size: ``(width, height)``.
        floor: floor height in metres (default: the lowest drawn point).

    Returns:
        ``(H, W, 3)`` uint8 image.
    """
    r = SceneRenderer(window_size, view, parallel, ground, shadow, font_size)
    try:
        size = float(np.median([s.size() for s in scenes]))
        r.update(scenes, size)
        lo, hi = scene_bounds(scenes, size)
        titles = [s.title for s in scenes] if titles is None else titles
        frame_and_title(
            r, lo, hi, size, titles, [title_anchor(s, size) for s in scenes], floor=floor
        )
        return r.screenshot()
    finally:
        r.close()


def render_skeleton(
    positions,
    parents: Sequence[int],
    joint_names: Sequence[str] | None = None,
    colors: Sequence | None = None,
    view="front_side",
    window_size=(640, 400),
    title: str | None = None,
    parallel: bool = False,
    ground: bool = True,
    shadow: bool = True,
) -> np.ndarray:
    """Render one or several overlaid skeleton poses (spheres at joints, tubes for bones).

    One pose gets side colours (left +X blue, right red, centre grey); several poses are overlaid
    in world space, each tinted with :data:`PALETTE` (left lighter, right darker).

    Args:
        positions: ``(J, 3)`` joint positions or a list of them (each with the same ``parents``).
        parents: ``J`` parent indices, root ``-1``.
        joint_names: ``J`` names for side colours (canonical 22 assumed when ``J == 22``).
        colors: one colour per pose (``None``: side colours for one pose, palette for several).
        view: ``"front"``, ``"front_side"``, ``"side"``, ``"top"``, ``"back"`` or ``(az, el)`` deg.
        window_size: ``(width, height)`` pixels.
        title: optional caption above the (first) character.

    Returns:
        ``(H, W, 3)`` uint8 image.
    """
    arr = (
        [np.asarray(positions, float)]
        if np.ndim(positions) == 2
        else [np.asarray(p, float) for p in positions]
    )
    if colors is None:
        colors = [None] if len(arr) == 1 else [PALETTE[i % len(PALETTE)] for i in range(len(arr))]
    scenes = [
        Scene(positions=p, parents=parents, joint_names=joint_names, color=c)
        for p, c in zip(arr, colors, strict=False)
    ]
    titles = [title or ""] + [""] * (len(scenes) - 1)
    return render_scenes(scenes, titles, view, window_size, parallel, ground, shadow)


def render_mesh(
    vertices,
    faces,
    scalars=None,
    highlight_faces=None,
    point_pairs=None,
    skeleton: tuple | None = None,
    cmap: str = "viridis",
    clim=None,
    color=MESH_COLOR,
    opacity: float | None = None,
    view="front_side",
    window_size=(640, 400),
    title: str | None = None,
    ground: bool = True,
    shadow: bool = True,
    vertex_colors=None,
    pair_radius: float | None = None,
) -> np.ndarray:
    """Render a triangle mesh, optionally coloured per vertex, with highlighted faces, contact
    pairs and a skeleton overlay.

    Args:
        vertices: ``(V, 3)`` positions (metres).
        faces: ``(F, 3)`` int triangles.
        scalars: ``(V,)`` per-vertex values shown with ``cmap`` over ``clim`` (default min..max).
        highlight_faces: ``(K,)`` face indices or ``(F,)`` bool mask (e.g. penetrating faces).
        point_pairs: ``(P, 2)`` int vertex pairs or ``(P, 2, 3)`` positions (e.g. contact pairs).
        skeleton: ``(positions (J, 3), parents)`` or ``(positions, parents, joint_names)`` overlay;
            the mesh then turns translucent unless ``opacity`` is given.
        color: mesh colour when ``scalars`` is None.
        view, window_size, title: as in :func:`render_skeleton`.
        vertex_colors: ``(V, 3)`` RGB per vertex (instead of ``scalars`` / ``color``).
        pair_radius: radius of the contact-pair spheres in metres (default: 1.2 % of the
            mesh's size; make it larger for close-ups, where the pairs are few millimetres long).

    Returns:
        ``(H, W, 3)`` uint8 image.
    """
    sk = (
        dict(zip(("positions", "parents", "joint_names"), skeleton, strict=False))
        if skeleton is not None
        else {}
    )
    s = Scene(
        vertices=vertices,
        faces=faces,
        scalars=scalars,
        highlight_faces=highlight_faces,
        point_pairs=point_pairs,
        cmap=cmap,
        clim=clim,
        mesh_color=color,
        mesh_opacity=opacity,
        vertex_colors=vertex_colors,
        pair_radius=pair_radius,
        **sk,
    )
    return render_scenes([s], [title or ""], view, window_size, ground=ground, shadow=shadow)


def render_side_by_side(
    scenes: Sequence,
    titles: Sequence[str] | None = None,
    parents=None,
    view="front",
    window_size=None,
    ncols: int | None = None,
    parallel: bool = False,
    gap: float | None = None,
    font_size: int = 12,
    stand: bool = True,
) -> np.ndarray:
    """Several characters next to each other (a lineup or a source / retargeted / truth comparison).

    Each scene is stood on the floor (its lowest point at ``y = 0``, unless ``stand=False``) and
    translated along x by its own width plus a gap (35 % of the median character size), so
    relative sizes stay true. The camera is fitted to the drawn characters. With ``ncols`` the
    lineup wraps into rows rendered with one camera (same scale) and stacked vertically.

    Args:
        scenes: :class:`Scene` objects, ``(J, 3)`` arrays (with ``parents``), ``(positions,
            parents)`` tuples or Motions (frame 0).
        titles: one label per scene (default: each scene's ``title``).
        parents: parents for bare arrays.
        view: camera preset or ``(az, el)``; ``"front"`` by default.
        window_size: ``(width, height)`` of one row (default: 640x400 up to 3 characters, wider
            after).
        ncols: characters per row (default all in one row).
        parallel: orthographic projection.
        stand: put every character's lowest point on the floor.

    Returns:
        ``(H, W, 3)`` uint8 image (``rows * height`` tall).
    """
    sc = [as_scene(s, parents) for s in scenes]
    size = float(np.median([s.size() for s in sc]))
    if stand:
        sc = [stand_on_floor(s, size) for s in sc]
    titles = list(titles) if titles is not None else [s.title for s in sc]
    n = len(sc)
    ncols = min(ncols or n, n)
    if window_size is None:
        window_size = (int(min(max(640, 210 * ncols), 1600)), 400 if ncols <= 6 else 360)
    rows = [list(range(i, min(i + ncols, n))) for i in range(0, n, ncols)]
    placed = [layout_row([sc[i] for i in row], gap) for row in rows]
    renderers = [SceneRenderer(window_size, view, parallel, True, True, font_size) for _ in rows]
    try:
        for r, p in zip(renderers, placed, strict=False):
            r.update(p, size)
        # one camera for all rows (fitted to their overlaid geometry), so sizes stay comparable
        points = np.concatenate([hull_points(r.drawn_points()) for r in renderers])
        floor = 0.0 if stand else None
        lo, hi = scene_bounds([s for p in placed for s in p], size)
        band = 0
        for r, row, p in zip(renderers, rows, placed, strict=False):
            if any(titles[i] for i in row):
                r.frame(lo, hi, size, points=points, floor=floor, top_px=r.title_band(1))
                band = max(
                    band, r.set_titles([titles[i] for i in row], [title_anchor(s, size) for s in p])
                )
        # every row's labels at the smallest size any row needed (a lone label does not shrink)
        cap = min((r.title_font for r in renderers if r.title_font is not None), default=None)
        images = []
        for r, row, p in zip(renderers, rows, placed, strict=False):
            r.frame(
                lo, hi, size, points=points, floor=floor, top_px=r.title_band(band) if band else 0.0
            )
            if band:
                r.set_titles(
                    [titles[i] for i in row], [title_anchor(s, size) for s in p], font_cap=cap
                )
            images.append(r.screenshot())
    finally:
        for r in renderers:
            r.close()
    return np.concatenate(images, axis=0)


def render_filmstrip(
    positions: np.ndarray,
    parents: Sequence[int],
    frames: Sequence[int],
    fps: float | None = None,
    titles: Sequence[str] | None = None,
    **kw,
) -> np.ndarray:
    """Poses of one clip side by side, each moved so its root stands at ``x = z = 0`` first.

    Args:
        positions: ``(T, J, 3)`` joint positions (root = joint 0).
        parents: ``J`` parents.
        frames: frame indices to show.
        fps: when given (and ``titles`` is None) each pose is labelled with its time.
        titles: one label per frame.
        **kw: passed to :func:`render_side_by_side`.

    Returns:
        ``(H, W, 3)`` uint8 image.
    """
    positions = np.asarray(positions, dtype=np.float64)
    poses = [positions[f] - positions[f, 0] * np.array([1.0, 0.0, 1.0]) for f in frames]
    if titles is None and fps is not None:
        titles = [f"{f / fps:.1f} s" for f in frames]
    return render_side_by_side(
        [Scene(positions=p, parents=parents) for p in poses], titles=titles, **kw
    )


def save_png(image: np.ndarray, path, max_kb: float | None = 150) -> Path:
    """Write ``image (H, W, 3)`` uint8 as an optimised PNG.

    If the file exceeds ``max_kb`` it is re-written with a 256-colour adaptive palette (visually
    identical for these flat-shaded renders, typically 2-3x smaller).

    Returns:
        the path.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    im = Image.fromarray(np.asarray(image, dtype=np.uint8))
    im.save(path, optimize=True)
    if max_kb is not None and path.stat().st_size > max_kb * 1024:
        im.quantize(colors=256, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE).save(
            path, optimize=True
        )
    return path
