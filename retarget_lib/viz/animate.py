"""Animations: one :class:`~retarget_lib.viz.plotter.SceneRenderer` reused for every frame (only
point coordinates change), a camera fixed on the box that holds the whole clip, written as GIF or
MP4 with imageio."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import imageio.v3 as iio
import numpy as np
from PIL import Image

from .camera import hull_points
from .glyphs import JOINT_RADIUS
from .layout import layout_row
from .plotter import SceneRenderer, frame_and_title
from .scene import Scene


def render_frames(
    frames: Sequence[Sequence[Scene]],
    view="front_side",
    window_size=(480, 300),
    titles: Sequence[str] | None = None,
    side_by_side: bool = False,
    stand: bool = True,
) -> list[np.ndarray]:
    """Render a sequence of frames, each a list of scenes with the same structure.

    The camera is fitted once to everything drawn over the whole clip (the characters fill the
    canvas, titles get a band at the top) and the floor lies at the clip's lowest drawn point.

    Args:
        frames: ``T`` lists of :class:`Scene` (same joint counts / mesh topologies in every frame).
        view: camera preset or ``(azimuth, elevation)``.
        window_size: ``(width, height)``.
        titles: one label per scene, drawn above it (at a fixed place) in every frame.
        side_by_side: spread the scenes along x (by their extents over the whole clip) instead of
            drawing them where they are.
        stand: with ``side_by_side``, move each character up or down (once for the whole clip)
            so its lowest point over the clip rests on the floor.

    Returns:
        ``T`` images ``(H, W, 3)`` uint8.
    """
    frames = [list(f) for f in frames]
    size = float(np.median([s.size() for s in frames[0]]))
    if side_by_side:
        n = len(frames[0])
        # one shift per scene for the whole clip, from the scenes' extents over all frames
        ext = [np.concatenate([f[i].points() for f in frames]) for i in range(n)]
        boxes = [
            Scene(positions=np.stack([e.min(0), e.max(0)]), parents=(-1, 0), joint_names=["", ""])
            for e in ext
        ]
        # gap from the characters' own size (not the clip box, which grows with walking distance),
        # widened for long labels so neighbouring titles do not run into each other
        longest = max((len(str(t)) for t in titles or ()), default=0)
        gap = size * (0.35 + 0.03 * longest)  # labels that still collide shrink or stagger
        placed = layout_row(boxes, gap)
        shifts = [p.positions[0] - b.positions[0] for p, b in zip(placed, boxes, strict=False)]
        if stand:
            for k, (e, s0) in enumerate(zip(ext, frames[0], strict=False)):
                lift = (
                    JOINT_RADIUS * size if s0.vertices is None and s0.positions is not None else 0.0
                )
                shifts[k] = shifts[k] + [0.0, lift - e[:, 1].min(), 0.0]
        frames = [[s.translated(d) for s, d in zip(f, shifts, strict=False)] for f in frames]
    allpts = np.concatenate([s.points() for f in frames for s in f])
    lo, hi = allpts.min(0), allpts.max(0)
    r = SceneRenderer(window_size, view)
    try:
        # the drawn geometry of every frame (its hull), so the whole clip stays in view
        hulls = []
        for f in frames:
            r.update(f, size)
            hulls.append(hull_points(r.drawn_points()))
        points = hull_points(np.concatenate(hulls))
        anchors = None
        if titles is not None and any(titles):
            top = float(points[:, 1].max())
            anchors = []
            for i in range(len(frames[0])):
                e = np.concatenate([f[i].points() for f in frames])
                anchors.append([0.5 * (e[:, 0].min() + e[:, 0].max()), top, e[:, 2].max()])
        images = []
        for k, f in enumerate(frames):
            r.update(f, size)
            if k == 0:
                if anchors is None:
                    r.frame(lo, hi, size, points=points)
                else:
                    frame_and_title(r, lo, hi, size, titles, anchors, points=points)
            images.append(r.screenshot())
        return images
    finally:
        r.close()


def _write_gif(images: Sequence[np.ndarray], path: Path, fps: float, colors: int) -> None:
    strip = Image.fromarray(np.concatenate(list(images[:: max(1, len(images) // 8)]), axis=0))
    palette = strip.quantize(
        colors=colors, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE
    )
    frames = [
        Image.fromarray(im).quantize(palette=palette, dither=Image.Dither.NONE) for im in images
    ]
    frames[0].save(
        path,
        save_all=True,
        append_images=frames[1:],
        duration=int(round(1000 / fps)),
        loop=0,
        optimize=True,
        disposal=1,
    )


def write_animation(
    images: Sequence[np.ndarray], path: str | Path, fps: float = 10.0, max_kb: float | None = None
) -> Path:
    """Write frames as ``.gif`` (looping, one palette shared by all frames) or ``.mp4``.

    Args:
        images: ``(H, W, 3)`` uint8 frames.
        path: output path; the suffix picks the format.
        fps: playback rate.
        max_kb: size budget of a GIF: the palette shrinks (128 down to 32 colours), then every
            other frame is dropped (the playback keeps its duration), until the file fits.

    Returns:
        the path.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    if path.suffix.lower() == ".gif":
        images = list(images)
        while True:
            for colors in (128, 96, 64, 48, 32):
                _write_gif(images, path, fps, colors)
                if max_kb is None or path.stat().st_size <= max_kb * 1024:
                    return path
            if len(images) < 4:
                return path
            images, fps = images[::2], fps / 2
    # yuv420p needs even sizes only; 8/16 would resize (and warn about) e.g. 480x300
    iio.imwrite(path, np.stack(images), fps=fps, codec="libx264", macro_block_size=2)
    return path


def animate(
    frames: Sequence[Sequence[Scene]],
    path: str | Path,
    fps: float = 10.0,
    max_kb: float | None = None,
    **kw,
) -> Path:
    """Render scene frames (:func:`render_frames`, same keywords) and write them
    (:func:`write_animation`, with its GIF size budget ``max_kb``)."""
    return write_animation(render_frames(frames, **kw), path, fps, max_kb)


def animate_motion(
    positions: np.ndarray | Sequence[np.ndarray],
    parents: Sequence[int],
    path: str | Path,
    fps: float = 10.0,
    every: int = 3,
    titles: Sequence[str] | None = None,
    **kw,
) -> Path:
    """Animate one or several skeletons side by side.

    Args:
        positions: ``(T, J, 3)`` joint positions, or a list of them (same ``T``).
        parents: ``J`` parents.
        path: ``.gif`` or ``.mp4``.
        fps: playback rate of the written file (after taking every ``every``-th frame).
        every: frame step.
        titles: one label per skeleton.
    """
    seq = (
        [np.asarray(positions)]
        if isinstance(positions, np.ndarray)
        else [np.asarray(p) for p in positions]
    )
    frames = [
        [Scene(positions=p[t], parents=parents) for p in seq] for t in range(0, len(seq[0]), every)
    ]
    return animate(frames, path, fps, titles=titles, side_by_side=len(seq) > 1, **kw)


def animate_mesh(
    vertices: np.ndarray | Sequence[np.ndarray],
    faces,
    path: str | Path,
    fps: float = 10.0,
    every: int = 3,
    titles: Sequence[str] | None = None,
    **kw,
) -> Path:
    """Animate one or several skinned meshes side by side.

    Args:
        vertices: ``(T, V, 3)`` per-frame vertices, or a list of them (same ``T``).
        faces: ``(F, 3)`` triangles, or a list (one per mesh).
        path: ``.gif`` or ``.mp4``.
        fps: playback rate; every: frame step; titles: one label per mesh.
    """
    seq = (
        [np.asarray(vertices)]
        if isinstance(vertices, np.ndarray)
        else [np.asarray(v) for v in vertices]
    )
    fl = [faces] * len(seq) if isinstance(faces, np.ndarray) else list(faces)
    frames = [
        [Scene(vertices=v[t], faces=f) for v, f in zip(seq, fl, strict=False)]
        for t in range(0, len(seq[0]), every)
    ]
    return animate(frames, path, fps, titles=titles, side_by_side=len(seq) > 1, **kw)
