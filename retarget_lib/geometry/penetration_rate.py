"""Per-limb penetration rate, a metric of later work (R2ET, MeshRet): the share of a limb's
vertices inside the rest of the body, by winding numbers from signed ray crossings.

Units: metres.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import scipy.sparse
import torch
import trimesh
from scipy.sparse.csgraph import connected_components

from ..core.skeleton import CANONICAL22
from .collision import as_face_array, as_vertex_array

__all__ = [
    "DEFAULT_LIMBS",
    "cap_holes",
    "limb_vertices_inside",
    "penetration_rate",
    "ray_winding_numbers",
]

#: limbs of :func:`penetration_rate`: name -> canonical joints whose dominant-weight vertices form
#: it
DEFAULT_LIMBS: dict[str, tuple[str, ...]] = {
    "left_arm": ("LeftArm", "LeftForeArm", "LeftHand"),
    "right_arm": ("RightArm", "RightForeArm", "RightHand"),
    "left_leg": ("LeftUpLeg", "LeftLeg", "LeftFoot", "LeftToeBase"),
    "right_leg": ("RightUpLeg", "RightLeg", "RightFoot", "RightToeBase"),
}

#: three ray directions (unit, not axis-aligned) for :func:`ray_winding_numbers`
_RAY_DIRECTIONS = np.array([[1.0, 0.31, 0.17], [-0.23, 1.0, 0.41], [0.37, -0.29, 1.0]])
_RAY_DIRECTIONS /= np.linalg.norm(_RAY_DIRECTIONS, axis=1, keepdims=True)


def cap_holes(vertices, faces) -> tuple[np.ndarray, np.ndarray]:
    """Close every hole of an oriented mesh with a fan of triangles to the hole's centroid.

    A hole is a connected component of boundary edges (half-edges whose twin is missing); its new
    vertex is the mean of the component's vertices, and the cap triangles follow the mesh's
    orientation (counter-clockwise seen from outside).

    Args:
        vertices: ``(V, 3)`` metres.
        faces: ``(F, 3)`` int triangles, consistently oriented.

    Returns:
        ``(vertices (V + H, 3), faces (F + B, 3))``: one new vertex per hole, one new triangle per
        boundary edge (the input unchanged when there is no hole).
    """
    vertices = as_vertex_array(vertices)
    faces = as_face_array(faces, len(vertices))
    nv = len(vertices)
    half = faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    boundary = half[~np.isin(half[:, 1] * nv + half[:, 0], half[:, 0] * nv + half[:, 1])]
    if not len(boundary):
        return vertices, faces
    graph = scipy.sparse.coo_matrix(
        (np.ones(len(boundary)), (boundary[:, 0], boundary[:, 1])), shape=(nv, nv)
    )
    _, label = connected_components(graph, directed=False)
    on_boundary = np.unique(boundary)
    holes, hole_of_vertex = np.unique(label[on_boundary], return_inverse=True)
    centroids = np.zeros((len(holes), 3))
    np.add.at(centroids, hole_of_vertex, vertices[on_boundary])
    centroids /= np.bincount(hole_of_vertex)[:, None]
    hole_of_edge = np.searchsorted(holes, label[boundary[:, 0]])
    caps = np.stack([boundary[:, 1], boundary[:, 0], nv + hole_of_edge], 1)
    return np.concatenate([vertices, centroids]), np.concatenate([faces, caps])


def ray_winding_numbers(points, vertices, faces) -> np.ndarray:
    """Winding number of a closed, outward-oriented mesh at points, by signed ray crossings.

    From each point a ray is cast (Embree, through :mod:`trimesh`) and every surface it crosses
    counts ``+1`` when the ray leaves through it (normal along the ray) and ``-1`` when it enters.
    For a closed mesh that sum is the winding number whatever the ray: 1 inside, 0 outside, 2
    inside two overlapping parts (where ray *parity* would say "outside"). Three rays in fixed
    oblique directions are cast and the median kept, which absorbs a crossing missed or doubled at
    an edge.

    Args:
        points: ``(N, 3)`` metres.
        vertices: ``(V, 3)`` metres.
        faces: ``(F, 3)`` int triangles, closed (:func:`cap_holes`) and counter-clockwise seen from
            outside.

    Returns:
        ``(N,)`` int winding numbers.
    """
    points = as_vertex_array(points)
    vertices = as_vertex_array(vertices)
    faces = as_face_array(faces, len(vertices))
    mesh = trimesh.Trimesh(vertices, faces, process=False)
    tri = vertices[faces]
    normals = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    counts = []
    for direction in _RAY_DIRECTIONS:
        dirs = np.broadcast_to(direction, points.shape)
        index_tri, index_ray = mesh.ray.intersects_id(points, dirs, multiple_hits=True)
        sign = np.sign(normals[index_tri] @ direction)
        counts.append(np.bincount(index_ray, weights=sign, minlength=len(points)))
    return np.rint(np.median(counts, axis=0)).astype(np.int64)


def penetration_rate(
    vertices,
    faces,
    weights,
    limbs: Mapping[str, Sequence[str]] | None = None,
    rest_vertices=None,
) -> dict[str, float]:
    """Per-limb penetration rate: the share of a limb's vertices inside the rest of the body.

    Definition: a vertex belongs to the limb whose joints hold its largest skinning weight
    (:data:`DEFAULT_LIMBS`: each arm = Arm, ForeArm, Hand; each leg = UpLeg, Leg, Foot, ToeBase).
    The limb's *body* is the mesh without the limb's faces (every face with a limb vertex; the
    other limbs stay part of it), with the hole this leaves closed by :func:`cap_holes`. A limb
    vertex is *inside* when the body's winding number at it (:func:`ray_winding_numbers`) is at
    least 1 — inside the torso, a leg, the other arm, or several of them at once. The rate is
    (inside vertices) / (limb vertices), averaged over frames.

    With ``rest_vertices``, the rate counts only what a pose adds to the mesh as modelled: limb
    vertices already inside the body in the rest pose (a sleeve modelled into the torso, an armpit
    whose triangles overlap at bind) are left out of the limb, so the rest pose itself scores 0.
    Real characters need it: four of the real-character table's eleven score 0.018-0.047 unposed.

    Args:
        vertices: ``(V, 3)`` or ``(T, V, 3)`` metres.
        faces: ``(F, 3)`` int triangles, closed mesh, counter-clockwise seen from outside.
        weights: ``(V, 22)`` skinning weights on the canonical 22 joints.
        limbs: ``{name: joint names}``; ``None`` = :data:`DEFAULT_LIMBS`.
        rest_vertices: ``(V, 3)`` metres, the mesh in its rest pose, or ``None`` to count every
            limb vertex.

    Returns:
        ``{limb: rate in [0, 1]}`` (``nan`` for a limb with no vertex).
    """
    rates = {}
    for name, _, inside in _limbs_inside(vertices, faces, weights, limbs, rest_vertices):
        rates[name] = float(inside.mean(axis=1).mean()) if inside.shape[1] else float("nan")
    return rates


def _limbs_inside(vertices, faces, weights, limbs, rest_vertices):
    """Per limb, ``(name, indices (K,), inside (T, K) bool)``: the limb's counted vertices (with
    ``rest_vertices``, those outside the body at rest; the rest test runs once, not per frame) and,
    per frame, which of them lie inside the rest of the body. Arguments as
    :func:`penetration_rate`; ``vertices`` may be ``(V, 3)`` (then ``T = 1``)."""
    frames = np.asarray(
        vertices.detach().cpu().numpy() if isinstance(vertices, torch.Tensor) else vertices,
        dtype=np.float64,
    )
    frames = frames[None] if frames.ndim == 2 else frames
    if frames.ndim != 3 or frames.shape[2] != 3:
        raise ValueError(f"vertices must be (V, 3) or (T, V, 3), got {frames.shape}")
    faces = as_face_array(faces, frames.shape[1])
    weights = np.asarray(weights, dtype=np.float64)
    if weights.shape != (frames.shape[1], len(CANONICAL22)):
        raise ValueError(f"weights must be ({frames.shape[1]}, 22), got {weights.shape}")
    rest = None if rest_vertices is None else np.asarray(rest_vertices, dtype=np.float64)
    owner = weights.argmax(1)
    for name, joints in (DEFAULT_LIMBS if limbs is None else limbs).items():
        unknown = [j for j in joints if j not in CANONICAL22]
        if unknown:
            raise ValueError(f"limb {name!r}: unknown joints {unknown}")
        in_limb = np.isin(owner, [CANONICAL22.index(j) for j in joints])
        counted = np.ones(int(in_limb.sum()), dtype=bool)
        if rest is not None and in_limb.any():
            counted = ~_inside_body(rest, faces, in_limb)
        inside = np.array(
            [_inside_body(frame, faces, in_limb)[counted] for frame in frames]
            if counted.any()
            else np.zeros((len(frames), 0), dtype=bool)
        )
        yield name, np.flatnonzero(in_limb)[counted], inside


def _inside_body(vertices: np.ndarray, faces: np.ndarray, in_limb: np.ndarray) -> np.ndarray:
    """``(K,)`` bool: which of the limb's ``K`` vertices lie inside the rest of the body (the mesh
    without the limb's faces, its holes capped; winding number >= 1)."""
    body_vertices, body_closed = cap_holes(vertices, faces[~in_limb[faces].any(1)])
    return ray_winding_numbers(vertices[in_limb], body_vertices, body_closed) >= 1


def limb_vertices_inside(
    vertices,
    faces,
    weights,
    limbs: Mapping[str, Sequence[str]] | None = None,
    rest_vertices=None,
) -> np.ndarray:
    """The vertices of posed meshes that :func:`penetration_rate` counts as inside the body (a
    limb vertex inside the rest of the body; with ``rest_vertices``, only one that is outside it in
    the rest pose); every other vertex is ``False``.

    Args:
        vertices: ``(V, 3)`` or ``(T, V, 3)`` metres; faces, weights, limbs, rest_vertices: as
            :func:`penetration_rate`.

    Returns:
        ``(V,)`` bool for one mesh, ``(T, V)`` for a stack.
    """
    single = np.ndim(vertices) == 2
    num_frames = 1 if single else len(vertices)
    out = np.zeros((num_frames, np.shape(vertices)[-2]), dtype=bool)
    for _, indices, inside in _limbs_inside(vertices, faces, weights, limbs, rest_vertices):
        out[:, indices] = inside
    return out[0] if single else out
