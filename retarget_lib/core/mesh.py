"""Triangle-mesh quantities shared by the readers, writers and renderers (NumPy; the differentiable
versions the energies need live in :mod:`retarget_lib.geometry.penetration`)."""

from __future__ import annotations

import numpy as np

__all__ = ["vertex_normals"]


def vertex_normals(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """``(V, 3)`` unit area-weighted vertex normals (+Y for a vertex on no triangle).

    Args:
        vertices: ``(V, 3)``.
        faces: ``(F, 3)`` int triangles, counter-clockwise seen from outside.
    """
    vertices = np.asarray(vertices, dtype=np.float64)
    faces = np.asarray(faces)
    v = vertices[faces]
    face_n = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])  # twice the area, along the normal
    normals = np.zeros_like(vertices)
    for k in range(3):
        np.add.at(normals, faces[:, k], face_n)
    length = np.linalg.norm(normals, axis=1, keepdims=True)
    return np.where(length > 1e-20, normals / np.maximum(length, 1e-20), [0.0, 1.0, 0.0])
