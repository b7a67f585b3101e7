"""Offscreen 3-D pictures with PyVista: skeletons, skinned meshes, side-by-side lineups, animations.

Everything renders offscreen (EGL + Mesa on a machine without X or GPU) into ``(H, W, 3)`` uint8
images. World conventions are the library's: +Y up, characters face +Z, a character's left is +X.

How a picture is built: each character is a :class:`Scene` (a pose ``(J, 3)`` and/or a mesh).
Joint spheres and bone tubes are generated in NumPy with a fixed topology, so animating only
overwrites point coordinates and normals of existing VTK arrays; one plotter is reused for all
frames (:func:`~retarget_lib.viz.animate.animate`, :class:`~retarget_lib.viz.player.Player`). A flat
"shadow" (the geometry projected onto the floor) on a checkerboard floor makes foot contact and
sliding readable.

Framing: the camera is fitted to what is drawn (the convex hull of the spheres, tubes and mesh
vertices, over the whole clip for animations) so the subject fills the canvas up to a small
margin, with a band kept free at the top for the titles; the floor sits at the lowest drawn point
(side-by-side lineups first stand every character on it), so feet touch the floor.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Sequence

import numpy as np
from matplotlib import colormaps
from matplotlib.colors import to_rgb
from PIL import Image

from ..geometry.normals import vertex_normals
from ..core.skeleton import CANONICAL22

#: camera presets: name -> (azimuth from +Z towards +X, elevation), degrees
VIEWS: dict[str, tuple[float, float]] = {
    "front": (0.0, 8.0), "front_side": (30.0, 14.0), "side": (-90.0, 6.0), "top": (0.0, 90.0),
    "back": (180.0, 10.0),
}
LEFT_COLOR, RIGHT_COLOR, CENTER_COLOR = "#2f6fbf", "#d1495b", "#4d4d4d"
#: one tint per character when several are drawn (source / retargeted / ground truth, ...)
PALETTE = ("#3b6fb6", "#d1495b", "#2a9d8f", "#e9a23b", "#7b5ea7", "#8c6d46", "#e377c2", "#5f6b73")
MESH_COLOR = "#d9c6b0"
_GROUND = ("#f3f3f3", "#e4e4e4")
_SHADOW = "#c9c9c9"
_state: dict[str, Any] = {"configured": False}
#: joint sphere radius as a share of the character size
_JOINT_RADIUS = 0.018


def configure_offscreen(window_size: tuple[int, int] = (640, 400), anti_aliasing: str | None = "msaa"):
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
    # pyvista (VTK) is imported where a picture is made, not at the top: it costs ~1.3 s, which
    # the plots and the rest of the library do without
    import pyvista as pv

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


def _rgb(color) -> np.ndarray:
    """Any matplotlib colour -> ``(3,)`` float RGB in [0, 1]."""
    return np.asarray(to_rgb(color), dtype=np.float64)


def _mix(color, other, t: float) -> np.ndarray:
    return (1 - t) * _rgb(color) + t * _rgb(other)


# ---------------------------------------------------------------------------------- scenes
@dataclass
class Scene:
    """One character to draw: a skeleton pose and/or a triangle mesh.

    Attributes:
        positions: ``(J, 3)`` joint positions (metres) or ``None``.
        parents: ``J`` parent indices (root ``-1``); needed with ``positions``.
        joint_names: ``J`` names; joints named ``Left*``/``Right*`` get side colours (the canonical
            22 are assumed when ``J == 22`` and no names are given).
        vertices: ``(V, 3)`` mesh vertices or ``None``.
        faces: ``(F, 3)`` int triangle indices.
        scalars: ``(V,)`` per-vertex values coloured with ``cmap`` (e.g. a contact energy).
        vertex_colors: ``(V, 3)`` RGB per vertex (floats in [0, 1]), e.g. one colour per body
            part; used instead of ``scalars`` and ``mesh_color``.
        highlight_faces: ``(K,)`` face indices or ``(F,)`` bool mask drawn in ``highlight_color``.
        point_pairs: ``(P, 2)`` int vertex index pairs or ``(P, 2, 3)`` positions (contact pairs),
            drawn as two spheres joined by a tube, one colour per pair.
        pair_radius: sphere radius of the pairs in metres (default ``0.012 * size``).
        smooth_shading: interpolate the mesh's normals across its triangles (a ~3000-vertex body
            then reads as a smooth surface); ``False`` shows every facet.
        color: skeleton tint; ``None`` = blue left / red right / grey centre.
        mesh_color, mesh_opacity, cmap, clim, highlight_color: mesh appearance (``mesh_opacity``
            ``None`` = 0.45 when a skeleton is drawn too, else opaque).
        title: label drawn above the character by the side-by-side renderers.
    """

    positions: np.ndarray | None = None
    parents: Sequence[int] | None = None
    joint_names: Sequence[str] | None = None
    vertices: np.ndarray | None = None
    faces: np.ndarray | None = None
    scalars: np.ndarray | None = None
    vertex_colors: np.ndarray | None = None
    pair_radius: float | None = None
    smooth_shading: bool = True
    highlight_faces: np.ndarray | None = None
    point_pairs: np.ndarray | None = None
    color: Any = None
    mesh_color: Any = MESH_COLOR
    mesh_opacity: float | None = None
    cmap: str = "viridis"
    clim: tuple[float, float] | None = None
    highlight_color: Any = "#e63946"
    title: str = ""
    meta: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.positions is not None:
            self.positions = np.asarray(self.positions, dtype=np.float64).reshape(-1, 3)
            if self.parents is None or len(self.parents) != len(self.positions):
                raise ValueError(f"Scene: {len(self.positions)} joints need as many parents, "
                                 f"got {None if self.parents is None else len(self.parents)}")
        if self.vertices is not None:
            self.vertices = np.asarray(self.vertices, dtype=np.float64).reshape(-1, 3)
            if self.faces is None:
                raise ValueError("Scene: vertices need faces (F, 3)")
            self.faces = np.asarray(self.faces, dtype=np.int64).reshape(-1, 3)

    def points(self) -> np.ndarray:
        """``(N, 3)`` all positions used for framing (joints, vertices, pair ends)."""
        parts = [p for p in (self.positions, self.vertices) if p is not None]
        return np.concatenate(parts) if parts else np.zeros((1, 3))

    def size(self) -> float:
        """Characteristic size in metres (the largest extent of the points, at least 0.1)."""
        return max(float(np.ptp(self.points(), axis=0).max()), 0.1)

    def translated(self, offset) -> "Scene":
        off = np.asarray(offset, dtype=np.float64)
        pp = self.point_pairs
        if pp is not None and np.asarray(pp).ndim == 3:
            pp = np.asarray(pp, dtype=np.float64) + off
        return replace(self, positions=None if self.positions is None else self.positions + off,
                       vertices=None if self.vertices is None else self.vertices + off, point_pairs=pp)


def as_scene(obj, parents: Sequence[int] | None = None, **kw) -> Scene:
    """Coerce ``Scene`` / ``(J, 3)`` array / ``(positions, parents)`` tuple / ``Motion`` (frame 0)."""
    if isinstance(obj, Scene):
        return replace(obj, **kw) if kw else obj
    if isinstance(obj, tuple) and len(obj) == 2 and not np.isscalar(obj[1]):
        return Scene(positions=obj[0], parents=obj[1], **kw)
    if hasattr(obj, "global_positions") and hasattr(obj, "skeleton"):
        return Scene(positions=obj.global_positions()[0], parents=obj.skeleton.parents,
                     joint_names=obj.skeleton.joint_names, **kw)
    return Scene(positions=obj, parents=parents, **kw)


def _joint_colors(scene: Scene) -> np.ndarray:
    """``(J, 3)`` float RGB per joint: side colours, or tints of ``scene.color``."""
    n = len(scene.positions)
    names = scene.joint_names
    if names is None and n == 22:
        names = CANONICAL22
    side = np.zeros(n, dtype=int)  # 0 centre, 1 left, 2 right
    if names is not None:
        for j, nm in enumerate(names):
            low = str(nm).lower().split(":")[-1]
            side[j] = 1 if low.startswith(("left", "l_")) or "left" in low else (
                2 if low.startswith(("right", "r_")) or "right" in low else 0)
    if scene.color is None:
        table = np.stack([_rgb(CENTER_COLOR), _rgb(LEFT_COLOR), _rgb(RIGHT_COLOR)])
    else:
        c = scene.color
        table = np.stack([_rgb(c), _mix(c, "white", 0.38), _mix(c, "black", 0.32)])
    return table[side]


# ------------------------------------------------------------------------------- geometry
def _sphere_template(theta: int = 14, phi: int = 10) -> tuple[np.ndarray, np.ndarray]:
    th = np.linspace(0, 2 * np.pi, theta, endpoint=False)
    ph = np.linspace(0, np.pi, phi + 1)[1:-1]
    ring = np.stack([np.outer(np.sin(ph), np.cos(th)), np.repeat(np.cos(ph)[:, None], theta, 1),
                     np.outer(np.sin(ph), np.sin(th))], -1).reshape(-1, 3)
    pts = np.concatenate([[[0, 1, 0]], ring, [[0, -1, 0]]])
    faces = []
    k = np.arange(theta)
    k2 = (k + 1) % theta
    faces += [np.stack([np.zeros(theta, int), 1 + k2, 1 + k], 1)]
    for r in range(len(ph) - 1):
        a, b = 1 + r * theta, 1 + (r + 1) * theta
        faces += [np.stack([a + k, a + k2, b + k2], 1), np.stack([a + k, b + k2, b + k], 1)]
    last, bottom = 1 + (len(ph) - 1) * theta, len(pts) - 1
    faces += [np.stack([np.full(theta, bottom), last + k, last + k2], 1)]
    return pts, np.concatenate(faces)


_SPHERE = _sphere_template()


class _Geometry:
    """Fixed-topology triangle soup for one scene; :meth:`compute` maps a scene to points/normals."""

    def __init__(self, scene: Scene, radius: float, tube_sides: int = 12):
        sp, sf = _SPHERE
        self.ns, self.sides = len(sp), tube_sides
        faces, colors, self.nverts = [], [], 0
        self.bones = np.zeros((0, 2), int)
        self.radius = radius
        if scene.positions is not None:
            n = len(scene.positions)
            jc = _joint_colors(scene)
            self.bones = np.array([(p, j) for j, p in enumerate(scene.parents) if p >= 0], int).reshape(-1, 2)
            self.jrad = np.full(n, radius)
            names = list(scene.joint_names) if scene.joint_names is not None else (
                ["Head" if j == 5 else "" for j in range(n)] if n == 22 else [])
            self.head = names.index("Head") if "Head" in names else None
            if self.head is not None:
                self.jrad[self.head] = 3.4 * radius
            for j in range(n):
                faces.append(sf + j * self.ns)
            colors.append(np.repeat(jc, self.ns, 0))
            base = n * self.ns
            k = np.arange(tube_sides)
            k2 = (k + 1) % tube_sides
            tube = np.concatenate([np.stack([k, k2, tube_sides + k2], 1),
                                   np.stack([k, tube_sides + k2, tube_sides + k], 1)])
            for b in range(len(self.bones)):
                faces.append(tube + base + b * 2 * tube_sides)
            colors.append(np.repeat(jc[self.bones[:, 1]], 2 * tube_sides, 0))
            self.nverts = base + len(self.bones) * 2 * tube_sides
        self.skel_verts = self.nverts
        self.mesh_faces = None
        if scene.vertices is not None:
            self.mesh_faces = scene.faces
            self.nverts_mesh = len(scene.vertices)
        self.faces = np.concatenate(faces) if faces else np.zeros((0, 3), int)
        self.colors = (np.concatenate(colors) * 255).astype(np.uint8) if colors else None

    def skeleton(self, pos: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(N, 3)`` points and normals of joint spheres + bone tubes for pose ``pos (J, 3)``."""
        sp = _SPHERE[0]
        pos = pos.copy()
        centres = pos.copy()
        if self.head is not None:  # skull above the head joint, along the neck direction
            p = [b[0] for b in self.bones if b[1] == self.head]
            up = pos[self.head] - pos[p[0]] if p else np.array([0, 1.0, 0])
            centres[self.head] += 0.55 * self.jrad[self.head] * up / max(np.linalg.norm(up), 1e-9)
        sph = centres[:, None] + self.jrad[:, None, None] * sp[None]
        sph_n = np.broadcast_to(sp[None], sph.shape)
        a, b = pos[self.bones[:, 0]], pos[self.bones[:, 1]]
        d = b - a
        ln = np.linalg.norm(d, axis=1, keepdims=True)
        d = np.where(ln > 1e-9, d / np.maximum(ln, 1e-12), [0.0, 1.0, 0.0])
        helper = np.eye(3)[np.argmin(np.abs(d), axis=1)]
        u = np.cross(d, helper)
        u /= np.linalg.norm(u, axis=1, keepdims=True)
        v = np.cross(d, u)
        th = np.linspace(0, 2 * np.pi, self.sides, endpoint=False)
        ring = np.cos(th)[None, :, None] * u[:, None] + np.sin(th)[None, :, None] * v[:, None]
        r = 0.55 * self.radius
        tube = np.concatenate([a[:, None] + r * ring, b[:, None] + r * ring], 1)
        tube_n = np.concatenate([ring, ring], 1)
        pts = np.concatenate([sph.reshape(-1, 3), tube.reshape(-1, 3)])
        nrm = np.concatenate([sph_n.reshape(-1, 3), tube_n.reshape(-1, 3)])
        return pts, nrm


def _polydata(points: np.ndarray, faces: np.ndarray):
    import pyvista as pv

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
    """A floor at height ``y`` over ``[x0, x1] x [z0, z1]``: one quad per ``step`` square, two greys."""
    xs = np.arange(x0, x1 + 0.5 * step, step)
    zs = np.arange(z0, z1 + 0.5 * step, step)
    gx, gz = np.meshgrid(xs, zs, indexing="ij")
    pts = np.stack([gx.ravel(), np.full(gx.size, float(y)), gz.ravel()], -1)
    nx, nz = len(xs), len(zs)
    i, k = np.meshgrid(np.arange(nx - 1), np.arange(nz - 1), indexing="ij")
    a = (i * nz + k).ravel()
    quads = np.stack([np.full_like(a, 4), a, a + 1, a + nz + 1, a + nz], -1)
    import pyvista as pv

    plane = pv.PolyData(pts, quads.ravel())
    par = (np.floor(xs[i.ravel()] / step + 0.5) + np.floor(zs[k.ravel()] / step + 0.5)).astype(int) % 2
    cols = np.stack([_rgb(_GROUND[0]), _rgb(_GROUND[1])])[par]
    plane.cell_data["rgb"] = (cols * 255).astype(np.uint8)
    return plane


def _nice_step(x: float) -> float:
    steps = np.array([0.05, 0.1, 0.2, 0.25, 0.5, 1.0, 2.0, 5.0, 10.0])
    return float(steps[np.argmin(np.abs(np.log(steps / x)))])


def _view_axes(view) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Unit ``(back, up, right)`` of a camera preset or ``(azimuth, elevation)`` in degrees."""
    az, el = VIEWS[view] if isinstance(view, str) else view
    az, el = np.radians(az), np.radians(el)
    back = np.array([np.sin(az) * np.cos(el), np.sin(el), np.cos(az) * np.cos(el)])
    up = np.array([0.0, 1.0, 0.0]) if abs(np.degrees(el)) < 80 else np.array([-np.sin(az), 0, -np.cos(az)])
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
    from scipy.spatial import ConvexHull, QhullError

    try:
        return points[ConvexHull(points).vertices]
    except (QhullError, ValueError):
        return points


def fit_camera(points: np.ndarray, view, window_size: tuple[int, int], parallel: bool = False,
               view_angle: float = 30.0, margin: float = 0.04, top_px: float = 0.0) -> dict:
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
        f = f + right * (0.5 * (a.max() + a.min()) - tx * scale * aspect) + up * (0.5 * (b.max() + b.min()) - ty * scale)
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

    def __init__(self, window_size=(640, 400), view="front_side", parallel=False, ground=True,
                 shadow=True, font_size=12):
        pv = configure_offscreen()
        self.pl = pv.Plotter(off_screen=True, window_size=list(window_size))
        self.window_size, self.view, self.parallel = tuple(window_size), view, parallel
        self.ground, self.shadow, self.font_size = ground, shadow, font_size
        self._items: list[dict] = []
        self._key = None
        self._floor = None
        self.floor_y = 0.0
        self._texts: list = []

    def close(self) -> None:
        self.pl.close()

    # -------------------------------------------------------------------------- building
    @staticmethod
    def _structure(scenes: Sequence[Scene]):
        return tuple((None if s.positions is None else tuple(s.parents),
                      None if s.vertices is None else (len(s.vertices), len(s.faces)),
                      s.scalars is not None, s.vertex_colors is not None, s.highlight_faces is not None,
                      None if s.point_pairs is None else np.shape(s.point_pairs)) for s in scenes)

    def _build(self, scenes: Sequence[Scene], size: float) -> None:
        self.pl.clear_actors()
        self._items, self._floor = [], None
        radius = _JOINT_RADIUS * size
        for i, s in enumerate(scenes):
            g = _Geometry(s, radius)
            it: dict[str, Any] = {"geom": g}
            if s.positions is not None:
                pts, nrm = g.skeleton(s.positions)
                m = _polydata(pts, g.faces)
                m.point_data["Normals"] = nrm
                m.point_data.active_normals_name = "Normals"
                m.point_data["rgb"] = g.colors
                self.pl.add_mesh(m, render=False, scalars="rgb", rgb=True, specular=0.3, specular_power=20,
                                 smooth_shading=False, show_scalar_bar=False)
                it["skel"] = m
            if s.vertices is not None:
                m = _polydata(s.vertices, s.faces)
                m.point_data["Normals"] = vertex_normals(s.vertices, s.faces)
                m.point_data.active_normals_name = "Normals"
                op = s.mesh_opacity if s.mesh_opacity is not None else (0.45 if s.positions is not None else 1.0)
                kw = dict(opacity=op, specular=0.15, smooth_shading=s.smooth_shading, show_scalar_bar=False)
                if s.vertex_colors is not None:
                    rgb = np.asarray(s.vertex_colors, dtype=np.float64).reshape(-1, 3)
                    m.point_data["rgb"] = (np.clip(rgb, 0, 1) * 255).astype(np.uint8)
                    self.pl.add_mesh(m, render=False, scalars="rgb", rgb=True, **kw)
                elif s.scalars is not None:
                    m.point_data["values"] = np.asarray(s.scalars, dtype=np.float64).reshape(-1)
                    clim = s.clim or (float(np.nanmin(s.scalars)), float(np.nanmax(s.scalars)) + 1e-12)
                    self.pl.add_mesh(m, render=False, scalars="values", cmap=s.cmap, clim=clim, **kw)
                else:
                    self.pl.add_mesh(m, render=False, color=s.mesh_color, **kw)
                it["mesh"] = m
                if s.highlight_faces is not None:
                    hf = np.asarray(s.highlight_faces)
                    hf = np.flatnonzero(hf) if hf.dtype == bool else hf.astype(int)
                    it["hl_faces"] = s.faces[hf]
                    hm = _polydata(self._lifted(s.vertices, m, size), s.faces[hf])
                    self.pl.add_mesh(hm, render=False, color=s.highlight_color, lighting=True, show_scalar_bar=False)
                    it["hl"] = hm
            if s.point_pairs is not None:
                it["pairs_n"] = len(s.point_pairs)
                pm = self._pairs_mesh(s, size)
                if pm is not None:
                    self.pl.add_mesh(pm[0], render=False, scalars="rgb", rgb=True, show_scalar_bar=False)
                    it["pairs"], it["pair_geom"] = pm
            if self.shadow and (s.positions is not None or s.vertices is not None):
                parts = [it[k].points for k in ("skel", "mesh") if k in it]
                fl = [g.faces] if "skel" in it else []
                if "mesh" in it:
                    fl.append(s.faces + (len(parts[0]) if "skel" in it else 0))
                sh = _polydata(self._flat(np.concatenate(parts)), np.concatenate(fl))
                self.pl.add_mesh(sh, render=False, color=_SHADOW, lighting=False, show_scalar_bar=False)
                it["shadow"] = sh
            self._items.append(it)

    def _lifted(self, verts, mesh, size):
        return verts + mesh.point_data["Normals"] * 0.002 * size

    def _flat(self, points: np.ndarray) -> np.ndarray:
        p = points.copy()
        p[:, 1] = self.floor_y + 0.002
        return p

    def drawn_points(self) -> np.ndarray:
        """``(N, 3)`` every point currently drawn (joint spheres, bone tubes, meshes, contact pairs),
        without floor and shadows."""
        parts = [np.asarray(it[k].points) for it in self._items for k in ("skel", "mesh", "pairs") if k in it]
        return np.concatenate(parts) if parts else np.zeros((1, 3))

    def _pairs_mesh(self, s: Scene, size: float):
        """Contact pairs as a 'skeleton' of ``P`` two-joint chains: sphere, tube, sphere."""
        pp = np.asarray(s.point_pairs)
        if len(pp) == 0:
            return None
        ends = (s.vertices[pp.astype(int)] if pp.ndim == 2 else pp.astype(np.float64)).reshape(-1, 3)
        n = len(ends) // 2
        parents = [(-1 if j % 2 == 0 else j - 1) for j in range(2 * n)]
        radius = s.pair_radius if s.pair_radius is not None else 0.012 * size
        g = _Geometry(Scene(positions=ends, parents=parents, joint_names=[""] * (2 * n)), radius)
        cols = colormaps["tab10"](np.arange(n) % 10)[:, :3]
        rgb = np.concatenate([np.repeat(np.repeat(cols, 2, 0), g.ns, 0), np.repeat(cols, 2 * g.sides, 0)])
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
        self.pl.add_mesh(plane, render=False, scalars="rgb", rgb=True, lighting=False, name="floor", show_scalar_bar=False)
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
        for s, it in zip(scenes, self._items):
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

    def frame(self, lo, hi, size: float, points: np.ndarray | None = None, floor: float | None = None,
              top_px: float = 0.0, margin: float = 0.04) -> None:
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
        cam = fit_camera(pts, self.view, self.window_size, self.parallel, margin=margin, top_px=top_px)
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

    def set_titles(self, titles: Sequence[str], anchors: Sequence[np.ndarray]) -> int:
        """Centred text labels just above the projected world ``anchors`` (one ``(3,)`` each).

        Labels are kept inside the image. When neighbours would overlap, the font shrinks (down to
        65 %), then a label that still collides moves up a line (at most three lines).

        Returns:
            the number of text lines used (0 without titles).
        """
        for t in self._texts:
            self.pl.remove_actor(t, render=False)
        self._texts = []
        w, h = self.window_size
        items = sorted((self.to_display(a)[0], self.to_display(a)[1], str(t))
                       for t, a in zip(titles, anchors) if t)
        if not items:
            return 0
        actors = []
        for x, y, text in items:
            actor = self.pl.add_text(text, position=(x, y), font_size=self.font_size, color="black",
                                     render=False)
            actor.GetTextProperty().SetJustificationToCentered()
            actors.append(actor)

        def width(actor) -> float:
            bb = [0.0] * 4
            actor.GetBoundingBox(self.pl.renderer, bb)
            return bb[1] - bb[0]

        widths = [width(ac) for ac in actors]
        scale = min([1.0] + [max(xb - xa, 1.0) / (0.5 * (wa + wb) + 8) for (xa, _, _), (xb, _, _), wa, wb
                             in zip(items, items[1:], widths, widths[1:])])
        base = actors[0].GetTextProperty().GetFontSize()  # pyvista's units: 2x font_size
        fs = max(8, int(round(base * max(scale, 0.65))))
        # a label wider than the window shrinks until it fits (never cut off at the edges)
        fs = max(6, min(fs, int(base * (w - 12) / (1.12 * max(widths) + 1e-9))))
        line = 0.95 * fs  # one line of text in pixels (measured: 22 px at size 24)
        right: list[float] = []  # right edge of the last label on each line (base line first)
        placed = []
        for (x, y, _), actor in zip(items, actors):
            actor.GetTextProperty().SetFontSize(fs)
            tw = width(actor)
            half = 0.55 * tw + 4  # the measured box is a little narrower than the drawn glyphs
            x = float(np.clip(x, half, w - half))
            free = [k for k, edge in enumerate(right) if x - 0.5 * tw > edge + max(8.0, 0.5 * line)]
            row = free[0] if free else (len(right) if len(right) < 3 else int(np.argmin(right)))
            right[row:row + 1] = [x + 0.5 * tw]
            placed.append((x, y, row))
        top = h - (1.2 + max(row for _, _, row in placed)) * line  # highest base line
        for (x, y, row), actor in zip(placed, actors):
            actor.SetPosition(x, min(y + 4, top) + row * line)
            self._texts.append(actor)
        return 1 + max(row for _, _, row in placed)

    def screenshot(self) -> np.ndarray:
        """``(H, W, 3)`` uint8 image of the current scene."""
        self.pl.render()
        return np.ascontiguousarray(self.pl.screenshot(return_img=True)[..., :3])


def scene_bounds(scenes: Sequence[Scene], size: float | None = None) -> tuple[np.ndarray, np.ndarray]:
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


def _title_anchor(s: Scene, size: float) -> list[float]:
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
    for s, (lo, hi) in zip(scenes, extents):
        width = max(hi[0] - lo[0], 0.2 * s.size())
        dx = cursor + 0.5 * width - 0.5 * (lo[0] + hi[0])
        out.append(s.translated([dx, 0, 0]))
        cursor += width + gap
    shift = -0.5 * (cursor - gap)
    return [s.translated([shift, 0, 0]) for s in out]


def _frame_and_title(r: "SceneRenderer", lo, hi, size: float, titles: Sequence[str], anchors,
                     points: np.ndarray | None = None, floor: float | None = None) -> None:
    """Fit the camera to the drawn subject, leaving a top band for the titles (re-fitted once if
    the labels need more than one line)."""
    rows = 1 if any(titles) else 0
    r.frame(lo, hi, size, points=points, floor=floor, top_px=r.title_band(rows) if rows else 0.0)
    if rows:
        used = r.set_titles(titles, anchors)
        if used > rows:
            r.frame(lo, hi, size, points=points, floor=floor, top_px=r.title_band(used))
            r.set_titles(titles, anchors)


def render_scenes(scenes: Sequence[Scene], titles: Sequence[str] | None = None, view="front_side",
                  window_size=(640, 400), parallel: bool = False, ground: bool = True,
                  shadow: bool = True, font_size: int = 12, floor: float | None = None) -> np.ndarray:
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
        _frame_and_title(r, lo, hi, size, titles, [_title_anchor(s, size) for s in scenes], floor=floor)
        return r.screenshot()
    finally:
        r.close()


def render_skeleton(positions, parents: Sequence[int], joint_names: Sequence[str] | None = None,
                    colors: Sequence | None = None, view="front_side", window_size=(640, 400),
                    title: str | None = None, parallel: bool = False, ground: bool = True,
                    shadow: bool = True) -> np.ndarray:
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
    arr = [np.asarray(positions, float)] if np.ndim(positions) == 2 else [np.asarray(p, float) for p in positions]
    if colors is None:
        colors = [None] if len(arr) == 1 else [PALETTE[i % len(PALETTE)] for i in range(len(arr))]
    scenes = [Scene(positions=p, parents=parents, joint_names=joint_names, color=c)
              for p, c in zip(arr, colors)]
    titles = [title or ""] + [""] * (len(scenes) - 1)
    return render_scenes(scenes, titles, view, window_size, parallel, ground, shadow)


def render_mesh(vertices, faces, scalars=None, highlight_faces=None, point_pairs=None,
                skeleton: tuple | None = None, cmap: str = "viridis", clim=None, color=MESH_COLOR,
                opacity: float | None = None, view="front_side", window_size=(640, 400),
                title: str | None = None, ground: bool = True, shadow: bool = True,
                vertex_colors=None, pair_radius: float | None = None) -> np.ndarray:
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
    sk = dict(zip(("positions", "parents", "joint_names"), skeleton)) if skeleton is not None else {}
    s = Scene(vertices=vertices, faces=faces, scalars=scalars, highlight_faces=highlight_faces,
              point_pairs=point_pairs, cmap=cmap, clim=clim, mesh_color=color, mesh_opacity=opacity,
              vertex_colors=vertex_colors, pair_radius=pair_radius, **sk)
    return render_scenes([s], [title or ""], view, window_size, ground=ground, shadow=shadow)


def stand_on_floor(scene: Scene, size: float | None = None) -> Scene:
    """The scene moved up or down so its lowest drawn point is at ``y = 0``.

    Args:
        scene: the scene.
        size: the renderer's character size; a skeleton's lowest joint sphere (radius
            ``0.018 * size``, see :class:`SceneRenderer`) then rests on the floor too.
    """
    lowest = float(scene.points()[:, 1].min())
    if scene.vertices is None and scene.positions is not None and size is not None:
        lowest -= _JOINT_RADIUS * size
    return scene.translated([0.0, -lowest, 0.0])


def render_side_by_side(scenes: Sequence, titles: Sequence[str] | None = None, parents=None,
                        view="front", window_size=None, ncols: int | None = None,
                        parallel: bool = False, gap: float | None = None, font_size: int = 12,
                        stand: bool = True) -> np.ndarray:
    """Several characters next to each other (a lineup or a source / retargeted / truth comparison).

    Each scene is stood on the floor (its lowest point at ``y = 0``, unless ``stand=False``) and
    translated along x by its own width plus a gap (35 % of the median character size), so
    relative sizes stay true. The camera is fitted to the drawn characters. With ``ncols`` the
    lineup wraps into rows rendered with one camera (same scale) and stacked vertically.

    Args:
        scenes: :class:`Scene` objects, ``(J, 3)`` arrays (with ``parents``), ``(positions, parents)``
            tuples or Motions (frame 0).
        titles: one label per scene (default: each scene's ``title``).
        parents: parents for bare arrays.
        view: camera preset or ``(az, el)``; ``"front"`` by default.
        window_size: ``(width, height)`` of one row (default: 640x400 up to 3 characters, wider after).
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
        for r, p in zip(renderers, placed):
            r.update(p, size)
        # one camera for all rows (fitted to their overlaid geometry), so sizes stay comparable
        points = np.concatenate([hull_points(r.drawn_points()) for r in renderers])
        floor = 0.0 if stand else None
        lo, hi = scene_bounds([s for p in placed for s in p], size)
        band = 0
        for r, row, p in zip(renderers, rows, placed):
            if any(titles[i] for i in row):
                r.frame(lo, hi, size, points=points, floor=floor, top_px=r.title_band(1))
                band = max(band, r.set_titles([titles[i] for i in row], [_title_anchor(s, size) for s in p]))
        images = []
        for r, row, p in zip(renderers, rows, placed):
            r.frame(lo, hi, size, points=points, floor=floor, top_px=r.title_band(band) if band else 0.0)
            if band:
                r.set_titles([titles[i] for i in row], [_title_anchor(s, size) for s in p])
            images.append(r.screenshot())
    finally:
        for r in renderers:
            r.close()
    return np.concatenate(images, axis=0)


def render_filmstrip(positions: np.ndarray, parents: Sequence[int], frames: Sequence[int],
                     fps: float | None = None, titles: Sequence[str] | None = None, **kw) -> np.ndarray:
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
    return render_side_by_side([Scene(positions=p, parents=parents) for p in poses], titles=titles, **kw)


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
        im.quantize(colors=256, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE).save(path, optimize=True)
    return path


# ------------------------------------------------------------------- colour keys for renders
def _strip(fig) -> np.ndarray:
    from .knobs import figure_image

    return figure_image(fig)


def _beside(image: np.ndarray, strip: np.ndarray) -> np.ndarray:
    """``image`` with ``strip`` pasted on its right (white-padded to the same height)."""
    h = max(image.shape[0], strip.shape[0])
    pad = lambda im: np.concatenate([im, np.full((h - im.shape[0], im.shape[1], 3), 255, np.uint8)], 0)
    return np.concatenate([pad(np.asarray(image, np.uint8)), pad(strip)], axis=1)


def add_colorbar(image: np.ndarray, cmap, clim: tuple[float, float], label: str, width_px: int = 110,
                 extend: str = "neither") -> np.ndarray:
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
    import matplotlib.pyplot as plt
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import Normalize

    h = image.shape[0]
    dpi = 100
    fig = plt.figure(figsize=(width_px / dpi, h / dpi), dpi=dpi)
    ax = fig.add_axes([0.12, 0.08, 0.16, 0.84])
    bar = fig.colorbar(ScalarMappable(Normalize(*clim), cmap), cax=ax, extend=extend)
    bar.set_label(label, fontsize=10)
    bar.ax.tick_params(labelsize=9)
    return _beside(image, _strip(fig))


def add_legend(image: np.ndarray, labels: Sequence[str], colors: Sequence, title: str | None = None,
               ncol: int = 1, width_px: int = 150) -> np.ndarray:
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
    import matplotlib.pyplot as plt
    from matplotlib.patches import Patch

    h = image.shape[0]
    dpi = 100
    fig = plt.figure(figsize=(width_px / dpi, h / dpi), dpi=dpi)
    fig.legend([Patch(color=c) for c in colors], labels, loc="center left", bbox_to_anchor=(0.0, 0.5),
               ncol=ncol, fontsize=9, title=title, title_fontsize=9, frameon=False, handlelength=1.0,
               columnspacing=0.8, labelspacing=0.25)
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
