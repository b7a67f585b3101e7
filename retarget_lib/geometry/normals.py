"""Vertex normals: the library's one definition, area-weighted unit normals of a triangle mesh.

A vertex's normal is the sum of the cross products ``(v1 - v0) x (v2 - v0)`` of the triangles
around it (each twice the triangle's area, along its normal, counter-clockwise seen from outside),
scaled to unit length. :func:`vertex_normals` is the one function: NumPy arrays in, NumPy out for
the renderer and the FBX writer; tensors in, tensors out (differentiable) for the interpenetration
energy (Eq. 4, :mod:`retarget_lib.geometry.penetration`).

The energy needs the normals of a few hundred colliding vertices per frame, not all of them, in
a step that ``torch.compile`` fuses: :func:`normals_at` computes the same normals at chosen
vertices from the faces around them (:func:`vertex_face_csr`, :func:`faces_around`), and
:func:`area_weighted_normals` is its tensor kernel (gathers and sums only, no scatter).
"""

from __future__ import annotations

import numpy as np
import torch

from .collision import as_face_array

Tensor = torch.Tensor

__all__ = [
    "area_weighted_normals",
    "faces_around",
    "normals_at",
    "vertex_face_csr",
    "vertex_normals",
]


def vertex_normals(vertices, faces):
    """Area-weighted unit vertex normals.

    Args:
        vertices: ``(V, 3)`` NumPy array, or a ``(..., V, 3)`` tensor (metres).
        faces: ``(F, 3)`` int triangles, counter-clockwise seen from outside.

    Returns:
        The normals, of the kind of ``vertices``: from an array, ``(V, 3)`` float64 (``+Y`` for a
        vertex on no triangle, as a renderer needs a direction); from a tensor, ``(..., V, 3)``
        in its dtype, differentiable (zero for a vertex on no triangle).
    """
    if isinstance(vertices, torch.Tensor):
        faces = as_face_array(faces, vertices.shape[-2])
        nv = vertices.shape[-2]
        return normals_at(vertices, faces, vertex_face_csr(faces, nv), np.arange(nv))
    vertices = np.asarray(vertices, dtype=np.float64)
    faces = np.asarray(faces)
    v = vertices[faces]
    face_n = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])  # twice the area, along the normal
    normals = np.zeros_like(vertices)
    for k in range(3):
        np.add.at(normals, faces[:, k], face_n)
    length = np.linalg.norm(normals, axis=1, keepdims=True)
    return np.where(length > 1e-20, normals / np.maximum(length, 1e-20), [0.0, 1.0, 0.0])


def vertex_face_csr(faces: np.ndarray, num_vertices: int) -> tuple[np.ndarray, np.ndarray]:
    """The faces around each vertex: ``ptr (V + 1,)`` and face ids, vertex ``v``'s being
    ``ids[ptr[v]:ptr[v + 1]]``."""
    corners = faces.ravel()
    ptr = np.concatenate([[0], np.cumsum(np.bincount(corners, minlength=num_vertices))])
    return ptr, np.argsort(corners, kind="stable") // 3


def faces_around(
    faces: np.ndarray, csr: tuple[np.ndarray, np.ndarray], corners: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The faces around each of the ``corners (U,)`` vertices, padded to the largest count ``M``:
    ``(U, M, 3)`` their vertex ids and ``(U, M)`` bool, which slots hold a face (a padding slot
    repeats the corner's first face)."""
    ptr, ids = csr
    counts = ptr[corners + 1] - ptr[corners]
    slots = np.arange(counts.max(initial=0))
    present = slots[None] < counts[:, None]
    first = np.minimum(ptr[corners], len(ids) - 1)[:, None]
    face = (
        ids[np.where(present, ptr[corners][:, None] + slots[None], first)]
        if len(ids)
        else np.zeros(present.shape, np.int64)
    )
    return faces[face], present


def area_weighted_normals(vertices: Tensor, around: Tensor, present: Tensor) -> Tensor:
    """``(..., U, 3)`` unit normals summed from the faces around each corner (``around (U, M, 3)``,
    ``present (U, M)``, :func:`faces_around`), each face weighted by its area. Gathers and sums
    only (no scatter), so a compiled step has no atomic writes."""
    tri = vertices[..., around, :]  # (..., U, M, 3, 3)
    face_normal = torch.cross(
        tri[..., 1, :] - tri[..., 0, :], tri[..., 2, :] - tri[..., 0, :], dim=-1
    )
    summed = (face_normal * present.to(vertices.dtype)[..., None]).sum(-2)
    return summed / summed.norm(dim=-1, keepdim=True).clamp(min=1e-12)


def normals_at(
    vertices: Tensor, faces: np.ndarray, csr: tuple[np.ndarray, np.ndarray], needed: np.ndarray
) -> Tensor:
    """``(..., U, 3)`` area-weighted unit normals of the ``needed (U,)`` vertices, from their own
    faces only (a colliding frame needs a few hundred vertices' normals, not all of them)."""
    around, present = faces_around(faces, csr, needed)
    device = vertices.device
    return area_weighted_normals(
        vertices, torch.as_tensor(around, device=device), torch.as_tensor(present, device=device)
    )
