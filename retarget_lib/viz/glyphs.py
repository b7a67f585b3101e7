"""Skeleton glyphs: joint spheres and bone tubes generated in NumPy with a fixed topology, so that
animating a pose only overwrites the point coordinates and normals of existing VTK arrays
(:class:`~retarget_lib.viz.plotter.SceneRenderer`). Joints named ``Left*``/``Right*`` get side
colours (left +X blue, right red, centre grey), or tints of one colour.
"""

from __future__ import annotations

import numpy as np

from ..core.skeleton import CANONICAL22
from .scene import CENTER_COLOR, LEFT_COLOR, RIGHT_COLOR, Scene, as_rgb

__all__ = ["JOINT_RADIUS", "Glyphs"]

#: joint sphere radius as a share of the character size
JOINT_RADIUS = 0.018


def _mix(color, other, t: float) -> np.ndarray:
    return (1 - t) * as_rgb(color) + t * as_rgb(other)


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
            side[j] = (
                1
                if low.startswith(("left", "l_")) or "left" in low
                else (2 if low.startswith(("right", "r_")) or "right" in low else 0)
            )
    if scene.color is None:
        table = np.stack([as_rgb(CENTER_COLOR), as_rgb(LEFT_COLOR), as_rgb(RIGHT_COLOR)])
    else:
        c = scene.color
        table = np.stack([as_rgb(c), _mix(c, "white", 0.38), _mix(c, "black", 0.32)])
    return table[side]


# ------------------------------------------------------------------------------- geometry
def _sphere_template(theta: int = 14, phi: int = 10) -> tuple[np.ndarray, np.ndarray]:
    th = np.linspace(0, 2 * np.pi, theta, endpoint=False)
    ph = np.linspace(0, np.pi, phi + 1)[1:-1]
    ring = np.stack(
        [
            np.outer(np.sin(ph), np.cos(th)),
            np.repeat(np.cos(ph)[:, None], theta, 1),
            np.outer(np.sin(ph), np.sin(th)),
        ],
        -1,
    ).reshape(-1, 3)
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


class Glyphs:
    """Fixed-topology triangle soup for one scene; :meth:`compute` maps a scene to
    points/normals."""

    def __init__(self, scene: Scene, radius: float, tube_sides: int = 12):
        sp, sf = _SPHERE
        self.ns, self.sides = len(sp), tube_sides
        faces, colors, self.nverts = [], [], 0
        self.bones = np.zeros((0, 2), int)
        self.radius = radius
        if scene.positions is not None:
            n = len(scene.positions)
            jc = _joint_colors(scene)
            self.bones = np.array(
                [(p, j) for j, p in enumerate(scene.parents) if p >= 0], int
            ).reshape(-1, 2)
            self.jrad = np.full(n, radius)
            names = (
                list(scene.joint_names)
                if scene.joint_names is not None
                else (["Head" if j == 5 else "" for j in range(n)] if n == 22 else [])
            )
            self.head = names.index("Head") if "Head" in names else None
            if self.head is not None:
                self.jrad[self.head] = 3.4 * radius
            for j in range(n):
                faces.append(sf + j * self.ns)
            colors.append(np.repeat(jc, self.ns, 0))
            base = n * self.ns
            k = np.arange(tube_sides)
            k2 = (k + 1) % tube_sides
            tube = np.concatenate(
                [
                    np.stack([k, k2, tube_sides + k2], 1),
                    np.stack([k, tube_sides + k2, tube_sides + k], 1),
                ]
            )
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
