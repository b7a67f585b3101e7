"""What the renderer draws: a :class:`Scene` is one character (a pose ``(J, 3)`` and/or a triangle
mesh) with its colours and title, and the colours every picture shares.

World conventions are the library's: +Y up, characters face +Z, a character's left is +X.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from matplotlib.colors import to_rgb

__all__ = [
    "CENTER_COLOR",
    "LEFT_COLOR",
    "MESH_COLOR",
    "PALETTE",
    "RIGHT_COLOR",
    "Scene",
    "as_rgb",
    "as_scene",
]

LEFT_COLOR, RIGHT_COLOR, CENTER_COLOR = "#2f6fbf", "#d1495b", "#4d4d4d"
#: one tint per character when several are drawn (source / retargeted / ground truth, ...)
PALETTE = ("#3b6fb6", "#d1495b", "#2a9d8f", "#e9a23b", "#7b5ea7", "#8c6d46", "#e377c2", "#5f6b73")
MESH_COLOR = "#d9c6b0"


def as_rgb(color) -> np.ndarray:
    """Any matplotlib colour -> ``(3,)`` float RGB in [0, 1]."""
    return np.asarray(to_rgb(color), dtype=np.float64)


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
                raise ValueError(
                    f"Scene: {len(self.positions)} joints need as many parents, "
                    f"got {None if self.parents is None else len(self.parents)}"
                )
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

    def translated(self, offset) -> Scene:
        off = np.asarray(offset, dtype=np.float64)
        pp = self.point_pairs
        if pp is not None and np.asarray(pp).ndim == 3:
            pp = np.asarray(pp, dtype=np.float64) + off
        return replace(
            self,
            positions=None if self.positions is None else self.positions + off,
            vertices=None if self.vertices is None else self.vertices + off,
            point_pairs=pp,
        )


def as_scene(obj, parents: Sequence[int] | None = None, **kw) -> Scene:
    """Coerce ``Scene`` / ``(J, 3)`` array / ``(positions, parents)`` tuple / ``Motion`` (frame
    0)."""
    if isinstance(obj, Scene):
        return replace(obj, **kw) if kw else obj
    if isinstance(obj, tuple) and len(obj) == 2 and not np.isscalar(obj[1]):
        return Scene(positions=obj[0], parents=obj[1], **kw)
    if hasattr(obj, "global_positions") and hasattr(obj, "skeleton"):
        return Scene(
            positions=obj.global_positions()[0],
            parents=obj.skeleton.parents,
            joint_names=obj.skeleton.joint_names,
            **kw,
        )
    return Scene(positions=obj, parents=parents, **kw)
