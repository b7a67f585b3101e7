"""One offscreen PyVista plotter, :class:`SceneRenderer`, that draws scenes and updates them in
place; a flat "shadow" (the geometry projected onto the floor) on a checkerboard floor makes foot
contact and sliding readable.

Everything renders offscreen (EGL + Mesa on a machine without X or GPU) into ``(H, W, 3)`` uint8
images. One plotter is reused for all frames of an animation
(:func:`~retarget_lib.viz.animate.animate`, :class:`~retarget_lib.viz.player.Player`): a scene with
the same structure only rewrites point arrays. The floor sits at the lowest drawn point, so feet
touch it.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from typing import Any

import numpy as np
import pyvista as pv
from matplotlib import colormaps

from ..geometry.normals import vertex_normals
from .camera import fit_camera, hull_points
from .glyphs import JOINT_RADIUS, Glyphs
from .scene import Scene, as_rgb

__all__ = ["SceneRenderer", "configure_offscreen", "frame_and_title"]

_GROUND = ("#f3f3f3", "#e4e4e4")
_SHADOW = "#c9c9c9"
_state: dict[str, Any] = {"configured": False}


def configure_offscreen(
    window_size: tuple[int, int] = (640, 400), anti_aliasing: str | None = "msaa"
):
    """Set up PyVista for headless rendering; safe to call many times.

    Sets ``VTK_DEFAULT_OPENGL_WINDOW=vtkEGLRenderWindow`` (unless already set) before any plotter
    exists, ``pyvista.OFF_SCREEN = True`` and a theme: white background, black text, the default
    window size and anti-aliasing.

    Args:
        window_size: default ``(width, height)`` in pixels; 640x400 PNGs stay well under 150 KB.
        anti_aliasing: ``"msaa"`` (fast on Mesa llvmpipe), ``"ssaa"`` or ``None``.

    Returns:
        the ``pyvista`` module.
    """
    os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
    pv.OFF_SCREEN = True
    if not _state["configured"] or tuple(pv.global_theme.window_size) != tuple(window_size):
        th = pv.global_theme
        th.background = "white"
        th.font.color = "black"
        th.window_size = list(window_size)
        th.anti_aliasing = anti_aliasing
        th.show_scalar_bar = False
        th.jupyter_backend = "static"
        _state["configured"] = True
    return pv


def _polydata(points: np.ndarray, faces: np.ndarray):
    return pv.PolyData(points.copy(), np.hstack([np.full((len(faces), 1), 3), faces]).ravel())


def _set_points(mesh, points: np.ndarray, normals: np.ndarray | None = None) -> None:
    """Overwrite a PolyData's points (and active normals) in place."""
    mesh.points[:] = points
    mesh.GetPoints().Modified()
    if normals is not None:
        mesh.point_data["Normals"][:] = normals
        mesh.GetPointData().GetNormals().Modified()
    mesh.Modified()


def _checkerboard(x0: float, x1: float, z0: float, z1: float, step: float, y: float = 0.0):
    """A floor at height ``y`` over ``[x0, x1] x [z0, z1]``: one quad per ``step`` square, two
    greys."""
    xs = np.arange(x0, x1 + 0.5 * step, step)
    zs = np.arange(z0, z1 + 0.5 * step, step)
    gx, gz = np.meshgrid(xs, zs, indexing="ij")
    pts = np.stack([gx.ravel(), np.full(gx.size, float(y)), gz.ravel()], -1)
    nx, nz = len(xs), len(zs)
    i, k = np.meshgrid(np.arange(nx - 1), np.arange(nz - 1), indexing="ij")
    a = (i * nz + k).ravel()
    quads = np.stack([np.full_like(a, 4), a, a + 1, a + nz + 1, a + nz], -1)
    plane = pv.PolyData(pts, quads.ravel())
    par = (np.floor(xs[i.ravel()] / step + 0.5) + np.floor(zs[k.ravel()] / step + 0.5)).astype(
        int
    ) % 2
    cols = np.stack([as_rgb(_GROUND[0]), as_rgb(_GROUND[1])])[par]
    plane.cell_data["rgb"] = (cols * 255).astype(np.uint8)
    return plane


def _nice_step(x: float) -> float:
    steps = np.array([0.05, 0.1, 0.2, 0.25, 0.5, 1.0, 2.0, 5.0, 10.0])
    return float(steps[np.argmin(np.abs(np.log(steps / x)))])


class SceneRenderer:
    """One offscreen plotter that draws a fixed set of scenes and updates them in place.

    ``update(scenes)`` with the same structure (joint counts, mesh topologies) only rewrites point
    arrays; a different structure rebuilds the actors. Used by
    :func:`~retarget_lib.viz.animate.animate` and the player.

    Args:
        window_size: ``(width, height)`` pixels.
        view: a key of :data:`VIEWS` or ``(azimuth, elevation)`` degrees.
        parallel: orthographic projection (good for comparing heights in a lineup).
        ground: draw the checkerboard floor (at the lowest drawn point unless :meth:`frame` is
            given a height); shadow: draw flat shadows on it.
        font_size: title size in points.
    """

    def __init__(
        self,
        window_size=(640, 400),
        view="front_side",
        parallel=False,
        ground=True,
        shadow=True,
        font_size=12,
    ):
        pv = configure_offscreen()
        self.pl = pv.Plotter(off_screen=True, window_size=list(window_size))
        self.window_size, self.view, self.parallel = tuple(window_size), view, parallel
        self.ground, self.shadow, self.font_size = ground, shadow, font_size
        self._items: list[dict] = []
        self._key = None
        self._floor = None
        self.floor_y = 0.0
        self._texts: list = []
        self.title_font: int | None = None  # the last set_titles' size, VTK's units

    def close(self) -> None:
        self.pl.close()

    # -------------------------------------------------------------------------- building
    @staticmethod
    def _structure(scenes: Sequence[Scene]):
        return tuple(
            (
                None if s.positions is None else tuple(s.parents),
                None if s.vertices is None else (len(s.vertices), len(s.faces)),
                s.scalars is not None,
                s.vertex_colors is not None,
                s.highlight_faces is not None,
                None if s.point_pairs is None else np.shape(s.point_pairs),
            )
            for s in scenes
        )

    def _build(self, scenes: Sequence[Scene], size: float) -> None:
        self.pl.clear_actors()
        self._items, self._floor = [], None
        radius = JOINT_RADIUS * size
        for _i, s in enumerate(scenes):
            g = Glyphs(s, radius)
            it: dict[str, Any] = {"geom": g}
            if s.positions is not None:
                pts, nrm = g.skeleton(s.positions)
                m = _polydata(pts, g.faces)
                m.point_data["Normals"] = nrm
                m.point_data.active_normals_name = "Normals"
                m.point_data["rgb"] = g.colors
                self.pl.add_mesh(
                    m,
                    render=False,
                    scalars="rgb",
                    rgb=True,
                    specular=0.3,
                    specular_power=20,
                    smooth_shading=False,
                    show_scalar_bar=False,
                )
                it["skel"] = m
            if s.vertices is not None:
                m = _polydata(s.vertices, s.faces)
                m.point_data["Normals"] = vertex_normals(s.vertices, s.faces)
                m.point_data.active_normals_name = "Normals"
                op = (
                    s.mesh_opacity
                    if s.mesh_opacity is not None
                    else (0.45 if s.positions is not None else 1.0)
                )
                kw = dict(
                    opacity=op,
                    specular=0.15,
                    smooth_shading=s.smooth_shading,
                    show_scalar_bar=False,
                )
                if s.vertex_colors is not None:
                    rgb = np.asarray(s.vertex_colors, dtype=np.float64).reshape(-1, 3)
                    m.point_data["rgb"] = (np.clip(rgb, 0, 1) * 255).astype(np.uint8)
                    self.pl.add_mesh(m, render=False, scalars="rgb", rgb=True, **kw)
                elif s.scalars is not None:
                    m.point_data["values"] = np.asarray(s.scalars, dtype=np.float64).reshape(-1)
                    clim = s.clim or (
                        float(np.nanmin(s.scalars)),
                        float(np.nanmax(s.scalars)) + 1e-12,
                    )
                    self.pl.add_mesh(
                        m, render=False, scalars="values", cmap=s.cmap, clim=clim, **kw
                    )
                else:
                    self.pl.add_mesh(m, render=False, color=s.mesh_color, **kw)
                it["mesh"] = m
                if s.highlight_faces is not None:
                    hf = np.asarray(s.highlight_faces)
                    hf = np.flatnonzero(hf) if hf.dtype == bool else hf.astype(int)
                    it["hl_faces"] = s.faces[hf]
                    hm = _polydata(self._lifted(s.vertices, m, size), s.faces[hf])
                    self.pl.add_mesh(
                        hm,
                        render=False,
                        color=s.highlight_color,
                        lighting=True,
                        show_scalar_bar=False,
                    )
                    it["hl"] = hm
            if s.point_pairs is not None:
                it["pairs_n"] = len(s.point_pairs)
                pm = self._pairs_mesh(s, size)
                if pm is not None:
                    self.pl.add_mesh(
                        pm[0], render=False, scalars="rgb", rgb=True, show_scalar_bar=False
                    )
                    it["pairs"], it["pair_geom"] = pm
            if self.shadow and (s.positions is not None or s.vertices is not None):
                parts = [it[k].points for k in ("skel", "mesh") if k in it]
                fl = [g.faces] if "skel" in it else []
                if "mesh" in it:
                    fl.append(s.faces + (len(parts[0]) if "skel" in it else 0))
                sh = _polydata(self._flat(np.concatenate(parts)), np.concatenate(fl))
                self.pl.add_mesh(
                    sh, render=False, color=_SHADOW, lighting=False, show_scalar_bar=False
                )
                it["shadow"] = sh
            self._items.append(it)

    def _lifted(self, verts, mesh, size):
        return verts + mesh.point_data["Normals"] * 0.002 * size

    def _flat(self, points: np.ndarray) -> np.ndarray:
        p = points.copy()
        p[:, 1] = self.floor_y + 0.002
        return p

    def drawn_points(self) -> np.ndarray:
        """``(N, 3)`` every point currently drawn (joint spheres, bone tubes, meshes, contact
        pairs), without floor and shadows."""
        parts = [
            np.asarray(it[k].points)
            for it in self._items
            for k in ("skel", "mesh", "pairs")
            if k in it
        ]
        return np.concatenate(parts) if parts else np.zeros((1, 3))

    def _pairs_mesh(self, s: Scene, size: float):
        """Contact pairs as a 'skeleton' of ``P`` two-joint chains: sphere, tube, sphere."""
        pp = np.asarray(s.point_pairs)
        if len(pp) == 0:
            return None
        ends = (s.vertices[pp.astype(int)] if pp.ndim == 2 else pp.astype(np.float64)).reshape(
            -1, 3
        )
        n = len(ends) // 2
        parents = [(-1 if j % 2 == 0 else j - 1) for j in range(2 * n)]
        radius = s.pair_radius if s.pair_radius is not None else 0.012 * size
        g = Glyphs(Scene(positions=ends, parents=parents, joint_names=[""] * (2 * n)), radius)
        cols = colormaps["tab10"](np.arange(n) % 10)[:, :3]
        rgb = np.concatenate(
            [np.repeat(np.repeat(cols, 2, 0), g.ns, 0), np.repeat(cols, 2 * g.sides, 0)]
        )
        pts, nrm = g.skeleton(ends)
        m = _polydata(pts, g.faces)
        m.point_data["Normals"] = nrm
        m.point_data.active_normals_name = "Normals"
        m.point_data["rgb"] = (rgb * 255).astype(np.uint8)
        return m, g

    def _set_floor(self, lo: np.ndarray, hi: np.ndarray, size: float) -> None:
        if not self.ground:
            return
        step = _nice_step(size / 3.5)
        pad = max(0.9 * size, 2 * step)
        x0, x1 = np.floor((lo[0] - pad) / step) * step, np.ceil((hi[0] + pad) / step) * step
        z0, z1 = np.floor((lo[2] - pad) / step) * step, np.ceil((hi[2] + pad) / step) * step
        key = (x0, x1, z0, z1, step, self.floor_y)
        if self._floor == key:
            return
        if self._floor is not None:
            self.pl.remove_actor("floor", render=False)
        plane = _checkerboard(x0, x1, z0, z1, step, self.floor_y)
        self.pl.add_mesh(
            plane,
            render=False,
            scalars="rgb",
            rgb=True,
            lighting=False,
            name="floor",
            show_scalar_bar=False,
        )
        self._floor = key

    # ---------------------------------------------------------------------------- public
    def update(self, scenes: Sequence[Scene], size: float | None = None) -> None:
        """Draw ``scenes``: in place when their structure matches the previous call."""
        size = size or max(s.size() for s in scenes)
        key = (self._structure(scenes), round(size, 6))
        if key != self._key:
            self._build(scenes, size)
            self._key = key
            return
        for s, it in zip(scenes, self._items, strict=False):
            g = it["geom"]
            parts = []
            if "skel" in it:
                pts, nrm = g.skeleton(s.positions)
                _set_points(it["skel"], pts, nrm)
                parts.append(pts)
            if "mesh" in it:
                nrm = vertex_normals(s.vertices, s.faces)
                _set_points(it["mesh"], s.vertices, nrm)
                parts.append(s.vertices)
                if "hl" in it:
                    # the highlight mesh keeps all V vertices, only its faces are a subset
                    _set_points(it["hl"], s.vertices + nrm * 0.002 * size)
                if s.scalars is not None and s.vertex_colors is None:
                    it["mesh"].point_data["values"][:] = np.asarray(s.scalars).reshape(-1)
                    it["mesh"].GetPointData().GetArray("values").Modified()
            if "pairs" in it:
                pp = np.asarray(s.point_pairs)
                ends = (s.vertices[pp.astype(int)] if pp.ndim == 2 else pp).reshape(-1, 3)
                pts, nrm = it["pair_geom"].skeleton(ends)
                _set_points(it["pairs"], pts, nrm)
            if "shadow" in it:
                _set_points(it["shadow"], self._flat(np.concatenate(parts)))

    def frame(
        self,
        lo,
        hi,
        size: float,
        points: np.ndarray | None = None,
        floor: float | None = None,
        top_px: float = 0.0,
        margin: float = 0.04,
    ) -> None:
        """Place the floor and point the camera so the drawn subject fills the window.

        Args:
            lo, hi: ``(3,)`` world box of the subject (the floor is laid out under it).
            size: characteristic size (metres) of one character.
            points: ``(N, 3)`` points the camera must show (default: everything drawn now, see
                :meth:`drawn_points`; pass a whole clip's points to keep an animation in view).
            floor: floor height (default: the lowest of ``points``, so feet rest on the floor).
            top_px: pixels kept free at the top for titles.
            margin: free border, fraction of the window's smaller side.
        """
        lo, hi = np.asarray(lo, float), np.asarray(hi, float)
        pts = hull_points(self.drawn_points() if points is None else points)
        self.floor_y = float(pts[:, 1].min()) if floor is None else float(floor)
        for it in self._items:
            if "shadow" in it:
                sh = it["shadow"]
                sh.points[:, 1] = self.floor_y + 0.002
                sh.GetPoints().Modified()
                sh.Modified()
        self._set_floor(lo, hi, size)
        cam = fit_camera(
            pts, self.view, self.window_size, self.parallel, margin=margin, top_px=top_px
        )
        c = self.pl.camera
        c.position, c.focal_point, c.up = cam["position"], cam["focal_point"], cam["up"]
        c.view_angle = 30.0
        if self.parallel:
            self.pl.enable_parallel_projection()
            c.parallel_scale = cam["scale"]
        c.clipping_range = (max(cam["dist"] * 0.02, 1e-3), cam["dist"] * 20 + 100 * size)

    def title_band(self, rows: int = 1) -> float:
        """Pixels to keep free at the top for ``rows`` lines of titles."""
        return (rows + 0.35) * 0.95 * 2 * self.font_size + 2

    def to_display(self, point) -> tuple[float, float]:
        """Pixel coordinates ``(x, y)`` (origin bottom-left) of a world point ``(3,)``."""
        r = self.pl.renderer
        r.SetWorldPoint(*np.asarray(point, float), 1.0)
        r.WorldToDisplay()
        x, y, _ = r.GetDisplayPoint()
        return x, y

    def set_titles(
        self, titles: Sequence[str], anchors: Sequence[np.ndarray], font_cap: int | None = None
    ) -> int:
        """Centred text labels over the projected world ``anchors`` (one ``(3,)`` each), on one base
        line just above the highest anchor.

        Labels are kept inside the image. When neighbours would overlap, the font shrinks (down to
        65 %), then a label that still collides moves up by its own height (at most three rows).
        The size used is kept in ``title_font`` (VTK's units); ``font_cap`` caps it, so that rows
        of one figure can share the smallest of their sizes.

        Returns:
            the number of text lines used (0 without titles): label rows x lines per label.
        """
        for t in self._texts:
            self.pl.remove_actor(t, render=False)
        self._texts = []
        w, h = self.window_size
        items = sorted(
            (self.to_display(a)[0], self.to_display(a)[1], str(t))
            for t, a in zip(titles, anchors, strict=False)
            if t
        )
        if not items:
            return 0
        actors = []
        for x, y, text in items:
            actor = self.pl.add_text(
                text, position=(x, y), font_size=self.font_size, color="black", render=False
            )
            actor.GetTextProperty().SetJustificationToCentered()
            actors.append(actor)

        def width(actor) -> float:
            bb = [0.0] * 4
            actor.GetBoundingBox(self.pl.renderer, bb)
            return bb[1] - bb[0]

        widths = [width(ac) for ac in actors]
        scale = min(
            [1.0]
            + [
                max(xb - xa, 1.0) / (0.5 * (wa + wb) + 8)
                for (xa, _, _), (xb, _, _), wa, wb in zip(
                    items, items[1:], widths, widths[1:], strict=False
                )
            ]
        )
        base = actors[0].GetTextProperty().GetFontSize()  # pyvista's units: 2x font_size
        fs = max(8, int(round(base * max(scale, 0.65))))
        # a label wider than the window shrinks until it fits (never cut off at the edges)
        fs = max(6, min(fs, int(base * (w - 12) / (1.12 * max(widths) + 1e-9))))
        fs = fs if font_cap is None else min(fs, font_cap)
        self.title_font = fs
        # one label's height in pixels (measured: 22 px a text line at size 24): a label that
        # moves up clears a whole label of two lines, not one line of it
        lines = max(text.count("\n") + 1 for _, _, text in items)
        line = 0.95 * fs * lines
        right: list[float] = []  # right edge of the last label on each line (base line first)
        placed = []
        for (x, y, _), actor in zip(items, actors, strict=False):
            actor.GetTextProperty().SetFontSize(fs)
            tw = width(actor)
            half = 0.55 * tw + 4  # the measured box is a little narrower than the drawn glyphs
            x = float(np.clip(x, half, w - half))
            free = [k for k, edge in enumerate(right) if x - 0.5 * tw > edge + max(8.0, 0.5 * line)]
            row = free[0] if free else (len(right) if len(right) < 3 else int(np.argmin(right)))
            right[row : row + 1] = [x + 0.5 * tw]
            placed.append((x, y, row))
        top = h - (1.2 + max(row for _, _, row in placed)) * line  # highest base line
        # one base line for the whole row, above the highest anchor: labels over characters of
        # different heights cannot meet (a label moved up from a short one's head did)
        base = min(max(y for _, y, _ in placed) + 4, top)
        for (x, _, row), actor in zip(placed, actors, strict=False):
            actor.SetPosition(x, base + row * line)
            self._texts.append(actor)
        return (1 + max(row for _, _, row in placed)) * lines

    def screenshot(self) -> np.ndarray:
        """``(H, W, 3)`` uint8 image of the current scene."""
        self.pl.render()
        return np.ascontiguousarray(self.pl.screenshot(return_img=True)[..., :3])


def frame_and_title(
    r: SceneRenderer,
    lo,
    hi,
    size: float,
    titles: Sequence[str],
    anchors,
    points: np.ndarray | None = None,
    floor: float | None = None,
) -> None:
    """Fit the camera to the drawn subject, leaving a top band for the titles (re-fitted once if
    the labels need more than one line)."""
    rows = 1 if any(titles) else 0
    r.frame(lo, hi, size, points=points, floor=floor, top_px=r.title_band(rows) if rows else 0.0)
    if rows:
        used = r.set_titles(titles, anchors)
        if used > rows:
            r.frame(lo, hi, size, points=points, floor=floor, top_px=r.title_band(used))
            r.set_titles(titles, anchors)
