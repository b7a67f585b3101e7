"""Interpenetration: colliding triangles, cone distance fields and the energy ``E_int`` of Villegas
et al. 2021 (Sec. 3.3, Eqs. 4-5), plus per-limb penetration metrics.

**Detection** (no gradient): the intersecting triangle pairs ``F = {(r, i)}`` of each frame come
from :mod:`retarget_lib.geometry.collision` (the paper's BVH [29] and an exact triangle-triangle test).

**Energy** (differentiable). Each triangle ``i`` carries a cone-shaped local distance field
``psi_i`` (:func:`cone_distance_field`, after Tzionas et al. 2016): positive for points behind the
triangle (penetrating the surface), zero in front of it and outside the cone. For each colliding
pair, Eq. 4 penalises the vertices of one triangle inside the other's field::

    E_int = sum_{(r,i) in F} w_ri ( sum_{v_j in f_r} ||-psi_i(v_j) n_j||^2 + sum_{v_k in f_i} ||-psi_r(v_k) n_k||^2 )

with area-weighted unit vertex normals ``n_j`` (so each term equals ``psi^2``; the normals give the
penalty its direction in the paper's notation). Eq. 5's geodesic weights
``w_ri = min_{v_j in f_r, v_k in f_i} D(v_j, v_k) / eta`` (``eta`` = the largest geodesic distance
on the mesh) make touching folds near joints (armpits, crotch) cheap and penetrations between
distant body parts expensive.

**Metrics.** :func:`interpenetration_score` is the paper's Sec. 4 score (Eq. 4 on
height-normalised vertices); :func:`penetration_rate` is the per-limb share of vertices inside the
rest of the body (winding number by signed ray crossings), as reported by later work (R2ET,
MeshRet).

Units: metres; ``psi`` is a length (metres), ``E_int`` is in square metres.
"""

from __future__ import annotations

from typing import Mapping, NamedTuple, Sequence

import numpy as np
import scipy.sparse
import torch
import trimesh
from scipy.sparse.csgraph import connected_components, dijkstra

from ..core.skeleton import CANONICAL22
from .collision import TriangleBVH, as_face_array, as_vertex_array, colliding_triangle_pairs

Tensor = torch.Tensor

__all__ = [
    "DEFAULT_LIMBS",
    "PADDING_PAIR",
    "InterpenetrationEnergy",
    "PairPlan",
    "cap_holes",
    "circumcircle",
    "cone_distance_field",
    "GeodesicDistances",
    "geodesic_distances",
    "geodesic_pair_weights",
    "interpenetration_energy",
    "limb_vertices_inside",
    "interpenetration_score",
    "penetration_rate",
    "plan_energy",
    "ray_winding_numbers",
    "vertex_normals",
]

#: default cone parameters (:func:`cone_distance_field`): quadratic zone and apex height in metres,
#: base radius in circumradii
SIGMA = 0.01
CONE_HEIGHT = 0.1
RADIUS_SCALE = 1.0

#: limbs of :func:`penetration_rate`: name -> canonical joints whose dominant-weight vertices form it
DEFAULT_LIMBS: dict[str, tuple[str, ...]] = {
    "left_arm": ("LeftArm", "LeftForeArm", "LeftHand"),
    "right_arm": ("RightArm", "RightForeArm", "RightHand"),
    "left_leg": ("LeftUpLeg", "LeftLeg", "LeftFoot", "LeftToeBase"),
    "right_leg": ("RightUpLeg", "RightLeg", "RightFoot", "RightToeBase"),
}


def _pair_codes(pairs: np.ndarray, num_faces: int) -> np.ndarray:
    """One integer per face pair ``(r, i)``, ``r < i``: ``r * F + i``."""
    return pairs[:, 0] * num_faces + pairs[:, 1]


def _as_pairs(pairs, num_faces: int) -> np.ndarray:
    pairs = np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
    if len(pairs) and (pairs.min() < 0 or pairs.max() >= num_faces):
        raise ValueError(f"pairs index faces outside 0..{num_faces - 1}")
    return pairs


# ----------------------------------------------------------------------------- geodesic weights (Eq. 5)
def geodesic_distances(vertices, faces) -> np.ndarray:
    """All-pairs geodesic distances, approximated by shortest paths along mesh edges (Dijkstra).

    For pictures and small meshes; Eq. 5 needs only the distances between colliding faces, which
    :class:`GeodesicDistances` computes on demand.

    Args:
        vertices: ``(V, 3)`` metres (the rest pose for a skinned character).
        faces: ``(F, 3)`` int triangles.

    Returns:
        ``(V, V)`` float32 metres; ``inf`` between vertices of disconnected parts (separate
        pieces of a mesh). Memory is ``4 V^2`` bytes (36 MB for 3,000 vertices, 716 MB for 13,000).
    """
    vertices = as_vertex_array(vertices)
    faces = as_face_array(faces, len(vertices))
    graph = _edge_graph(vertices, faces)
    out = np.empty((len(vertices), len(vertices)), dtype=np.float32)
    for start in range(0, len(vertices), 512):
        rows = np.arange(start, min(start + 512, len(vertices)))
        out[rows] = dijkstra(graph, directed=False, indices=rows)
    return out


def _edge_graph(vertices: np.ndarray, faces: np.ndarray) -> scipy.sparse.csr_matrix:
    """Sparse ``(V, V)`` matrix of edge lengths (each undirected edge once)."""
    edges = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    edges = np.unique(np.sort(edges, axis=1), axis=0)
    length = np.linalg.norm(vertices[edges[:, 0]] - vertices[edges[:, 1]], axis=1)
    n = len(vertices)
    return scipy.sparse.csr_matrix((length, (edges[:, 0], edges[:, 1])), shape=(n, n))


class GeodesicDistances:
    """Eq. 5's geodesic distances ``D`` on one mesh, computed when asked and kept.

    The same edge-path distances as :func:`geodesic_distances`, without the ``V x V`` table: Eq. 5
    needs, per colliding pair, the smallest distance between a vertex of one face and a vertex of
    the other, which is one multi-source Dijkstra from the first face's three vertices (about 3 ms
    on a 13,000-vertex body) read at the other's. Each face's search is cached (``4 V`` bytes), so
    a pair that collides in many frames costs one search. Building it costs a few searches (the
    diameter ``eta``) instead of ``V`` of them (34 s and 716 MB for the 13,380-vertex MakeHuman body).

    ``eta`` (the paper's ``max_{a,b} D(v_a, v_b)``) is the exact largest finite distance, found
    per connected piece from eccentricity bounds (:meth:`_piece_diameter`) with tens of searches;
    it equals the all-pairs table's largest entry (``tests/test_penetration.py``).

    Args:
        vertices: ``(V, 3)`` metres (the rest pose).
        faces: ``(F, 3)`` int triangles.
    """

    def __init__(self, vertices, faces):
        vertices = as_vertex_array(vertices)
        self.faces = as_face_array(faces, len(vertices))
        self.num_vertices = len(vertices)
        self.graph = _edge_graph(vertices, self.faces)
        self._from_face: dict[int, np.ndarray] = {}
        self.eta = self._diameter()

    def _diameter(self) -> float:
        pieces, label = connected_components(self.graph, directed=False)
        sizes = np.bincount(label, minlength=pieces)
        best = max((self._piece_diameter(np.flatnonzero(label == piece)) for piece in np.flatnonzero(sizes > 1)),
                   default=0.0)
        return best if best > 0 else 1.0

    def _piece_diameter(self, members: np.ndarray) -> float:
        """The exact largest distance within one connected piece, by eccentricity bounds (Takes and
        Kosters 2011, "Determining the diameter of small world networks"): each search from a vertex
        ``u`` bounds every vertex's eccentricity to ``[max(d, e_u - d), e_u + d]``; searches
        alternate between the vertex with the largest upper bound and the one with the smallest
        lower bound until no vertex can exceed the largest eccentricity found (tens of searches on a
        body mesh)."""
        lower, upper = np.zeros(len(members)), np.full(len(members), np.inf)
        open_ = np.ones(len(members), dtype=bool)
        best, pick = 0.0, 0
        for step in range(len(members)):
            d = dijkstra(self.graph, directed=False, indices=members[pick])[members]
            ecc = float(d.max())
            best = max(best, ecc)
            lower, upper = np.maximum(lower, np.maximum(d, ecc - d)), np.minimum(upper, ecc + d)
            open_[pick] = False
            open_ &= upper > best * (1 + 1e-12)
            if not open_.any():
                break
            pick = int(np.argmax(np.where(open_, upper, -np.inf)) if step % 2 else np.argmin(np.where(open_, lower, np.inf)))
        return best

    def from_face(self, face: int) -> np.ndarray:
        """``(V,)`` float32 distance from the nearest vertex of ``face`` to every vertex (metres;
        ``inf`` on other pieces)."""
        face = int(face)
        if face not in self._from_face:
            self._from_face[face] = dijkstra(self.graph, directed=False, indices=self.faces[face],
                                             min_only=True).astype(np.float32)
        return self._from_face[face]

    def between_faces(self, pairs) -> np.ndarray:
        """``(P,)`` float64 ``min_{v_j in f_r, v_k in f_i} D(v_j, v_k)`` of face pairs ``(r, i)``."""
        pairs = _as_pairs(pairs, len(self.faces))
        out = np.empty(len(pairs))
        for k, (r, i) in enumerate(pairs):
            out[k] = self.from_face(r)[self.faces[i]].min()
        return out

    @property
    def searched_faces(self) -> int:
        """How many faces have been searched from (and kept)."""
        return len(self._from_face)

    @property
    def cached_bytes(self) -> int:
        """Memory held by the cached searches."""
        return sum(d.nbytes for d in self._from_face.values())


def geodesic_pair_weights(pairs, faces, geodesic: "np.ndarray | GeodesicDistances",
                          eta: float | None = None) -> np.ndarray:
    """Eq. 5: ``w_ri = eta^-1 min_{v_j in f_r, v_k in f_i} D(v_j, v_k)``.

    Args:
        pairs: ``(P, 2)`` int face pairs.
        faces: ``(F, 3)`` int triangles.
        geodesic: the distances ``D``: a :class:`GeodesicDistances` of the mesh, or a ``(V, V)``
            table (:func:`geodesic_distances`).
        eta: the normalisation; ``None`` = the largest finite distance (the paper's
            ``max_{a,b} D(v_a, v_b)``: the table's largest finite entry, or ``geodesic.eta``).

    Returns:
        ``(P,)`` float64 weights in ``[0, 1]``; pairs on disconnected parts (infinite distance)
        get 1, the weight of the most distant pair.
    """
    faces = as_face_array(faces)
    pairs = _as_pairs(pairs, len(faces))
    if isinstance(geodesic, GeodesicDistances):
        if len(geodesic.faces) != len(faces) or not np.array_equal(geodesic.faces, faces):
            raise ValueError("geodesic was built on other faces")
        dmin = geodesic.between_faces(pairs)
        eta = geodesic.eta if eta is None else eta
    else:
        if geodesic.ndim != 2 or geodesic.shape[0] != geodesic.shape[1] or faces.max(initial=-1) >= len(geodesic):
            raise ValueError(f"geodesic must be (V, V) over the faces' vertices, got {geodesic.shape}")
        if eta is None:
            finite = geodesic[np.isfinite(geodesic)]
            eta = float(finite.max()) if finite.size else 1.0
        fr, fi = faces[pairs[:, 0]], faces[pairs[:, 1]]
        dmin = geodesic[fr[:, :, None], fi[:, None, :]].reshape(len(pairs), 9).min(1).astype(np.float64)
    if eta <= 0:
        raise ValueError(f"eta must be positive, got {eta}")
    return np.where(np.isfinite(dmin), np.minimum(dmin / eta, 1.0), 1.0)


def cone_distance_field(points: Tensor, triangles: Tensor, sigma: float = SIGMA, height: float = CONE_HEIGHT,
                        radius_scale: float = RADIUS_SCALE) -> Tensor:
    """Cone-shaped local distance field ``psi`` of triangles (after Tzionas et al. 2016, IJCV).

    Geometry, for a triangle with circumcentre ``c``, circumradius ``R`` and unit normal ``n``
    (counter-clockwise vertices, pointing out of the body): the cone's axis is the normal line
    through ``c``, its apex lies ``height`` in *front* of the triangle, its surface passes through
    the circle of radius ``radius_scale * R`` around ``c`` in the triangle's plane, and it opens
    *behind* the triangle, into the body — the layout of torch-mesh-isect's
    ``conical_distance_field`` (which uses one ``sigma`` for both lengths). For a point ``p`` at
    depth ``d = -(p - c) . n`` behind the plane and distance ``rho`` from the axis::

        r(d)   = radius_scale * R * (1 + d / height)           cone radius at depth d
        U(d)   = 0 (d <= 0);  d^2 / (2 sigma) (0 < d < sigma);  d - sigma / 2 (d >= sigma)
        psi(p) = U(d) * max(0, 1 - (rho / r(d))^2)

    ``U`` is quadratic near the surface (no jolt when a vertex first crosses) and linear deeper,
    so ``psi`` grows like the penetration depth; the radial factor fades it to zero on the cone's
    surface and is smooth on the axis. Differences from torch-mesh-isect (same idea, not the same
    formula): there the intensity is also positive in front of the triangle
    (``penalize_outside``), the radial factor is ``1 - rho / r``, and the product is squared once
    more before Eq. 4 squares it again; here ``psi`` is a length and ``E_int`` an area.

    Args:
        points: ``(..., 3)`` points (metres).
        triangles: ``(..., 3, 3)`` triangles (vertex, xyz), broadcast against ``points``.
        sigma: metres, width of the quadratic zone of ``U``.
        height: metres, height of the cone's apex in front of the triangle (larger = a cone
            closer to a cylinder).
        radius_scale: the cone's radius in the triangle's plane, in circumradii.

    Returns:
        ``(...)`` ``psi >= 0`` (metres), differentiable in ``points`` and ``triangles``.
    """
    _check_cone(sigma, height, radius_scale)
    if points.shape[-1] != 3 or triangles.shape[-2:] != (3, 3):
        raise ValueError(f"points must be (..., 3) and triangles (..., 3, 3), got "
                         f"{tuple(points.shape)} and {tuple(triangles.shape)}")
    centre, radius, normal = circumcircle(triangles)
    rel = points - centre
    elevation = (rel * normal).sum(-1)
    radial_sq = (rel - elevation.unsqueeze(-1) * normal).square().sum(-1)
    d = (-elevation).clamp(min=0.0)
    intensity = torch.where(d < sigma, d.square() / (2.0 * sigma), d - 0.5 * sigma)
    cone_radius = radius_scale * radius * (1.0 + d / height)
    falloff = (1.0 - radial_sq / cone_radius.square().clamp(min=torch.finfo(radius.dtype).tiny)).clamp(min=0.0)
    return intensity * falloff


def _check_cone(sigma: float, height: float, radius_scale: float) -> None:
    if min(sigma, height, radius_scale) <= 0:
        raise ValueError(f"sigma, height and radius_scale must be positive, got {sigma}, {height}, {radius_scale}")


def circumcircle(triangles: Tensor) -> tuple[Tensor, Tensor, Tensor]:
    """Circumcircle and normal of triangles (differentiable).

    Args:
        triangles: ``(..., 3, 3)`` (vertex, xyz), metres.

    Returns:
        Circumcentre ``(..., 3)``, circumradius ``(...)`` and unit normal ``(..., 3)`` (right-hand
        rule on the vertex order).
    """
    a = triangles[..., 0, :]
    e1, e2 = triangles[..., 1, :] - a, triangles[..., 2, :] - a
    m = torch.cross(e1, e2, dim=-1)
    m_sq = m.square().sum(-1, keepdim=True).clamp(min=torch.finfo(m.dtype).tiny)
    offset = (e1.square().sum(-1, keepdim=True) * torch.cross(e2, m, dim=-1)
              + e2.square().sum(-1, keepdim=True) * torch.cross(m, e1, dim=-1)) / (2.0 * m_sq)
    return a + offset, offset.norm(dim=-1), m / m_sq.sqrt()


# ----------------------------------------------------------------------------- the energy (Eq. 4)
def vertex_normals(vertices: Tensor, faces) -> Tensor:
    """Area-weighted unit vertex normals.

    Args:
        vertices: ``(..., V, 3)`` metres.
        faces: ``(F, 3)`` int triangles (counter-clockwise seen from outside).

    Returns:
        ``(..., V, 3)`` unit normals (zero for vertices in no face).
    """
    faces = as_face_array(faces, vertices.shape[-2])
    nv = vertices.shape[-2]
    return _normals_at(vertices, faces, _vertex_face_csr(faces, nv), np.arange(nv))


def _vertex_face_csr(faces: np.ndarray, num_vertices: int) -> tuple[np.ndarray, np.ndarray]:
    """The faces around each vertex: ``ptr (V + 1,)`` and face ids, vertex ``v``'s being
    ``ids[ptr[v]:ptr[v + 1]]``."""
    corners = faces.ravel()
    ptr = np.concatenate([[0], np.cumsum(np.bincount(corners, minlength=num_vertices))])
    return ptr, np.argsort(corners, kind="stable") // 3


def _faces_around(faces: np.ndarray, csr: tuple[np.ndarray, np.ndarray],
                  corners: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The faces around each of the ``corners (U,)`` vertices, padded to the largest count ``M``:
    ``(U, M, 3)`` their vertex ids and ``(U, M)`` bool, which slots hold a face (a padding slot
    repeats the corner's first face)."""
    ptr, ids = csr
    counts = ptr[corners + 1] - ptr[corners]
    slots = np.arange(counts.max(initial=0))
    present = slots[None] < counts[:, None]
    first = np.minimum(ptr[corners], len(ids) - 1)[:, None]
    face = ids[np.where(present, ptr[corners][:, None] + slots[None], first)] if len(ids) else \
        np.zeros(present.shape, np.int64)
    return faces[face], present


def _area_weighted_normals(vertices: Tensor, around: Tensor, present: Tensor) -> Tensor:
    """``(..., U, 3)`` unit normals summed from the faces around each corner (``around (U, M, 3)``,
    ``present (U, M)``, :func:`_faces_around`), each face weighted by its area. Gathers and sums
    only (no scatter), so a compiled step has no atomic writes."""
    tri = vertices[..., around, :]  # (..., U, M, 3, 3)
    face_normal = torch.cross(tri[..., 1, :] - tri[..., 0, :], tri[..., 2, :] - tri[..., 0, :], dim=-1)
    summed = (face_normal * present.to(vertices.dtype)[..., None]).sum(-2)
    return summed / summed.norm(dim=-1, keepdim=True).clamp(min=1e-12)


def _normals_at(vertices: Tensor, faces: np.ndarray, csr: tuple[np.ndarray, np.ndarray],
                needed: np.ndarray) -> Tensor:
    """``(..., U, 3)`` area-weighted unit normals of the ``needed (U,)`` vertices, from their own
    faces only (a colliding frame needs a few hundred vertices' normals, not all of them)."""
    around, present = _faces_around(faces, csr, needed)
    device = vertices.device
    return _area_weighted_normals(vertices, torch.as_tensor(around, device=device),
                                  torch.as_tensor(present, device=device))


class PairPlan(NamedTuple):
    """Eq. 4's index arrays for fixed colliding pairs (:meth:`InterpenetrationEnergy.plan`), so an
    optimisation that keeps its pairs for many steps does the NumPy bookkeeping once and each step
    is tensor operations only (:func:`plan_energy`; ``torch.compile`` can fuse them).

    Vertex ids index the vertices handed to :func:`plan_energy`: the whole mesh, or the subset the
    plan was made for (``vertex_index``).

    Attributes:
        frame: ``(P,)`` int64, the batch element of each pair.
        tri_r, tri_i: ``(P, 3)`` int64 vertex ids of each pair's two triangles.
        around: ``(U, M, 3)`` int64 vertex ids of the faces around each pair corner (its normal),
            padded to the largest count ``M``.
        present: ``(U, M)`` bool, the slots of ``around`` that hold a face.
        corner_r, corner_i: ``(P, 3)`` int64 each triangle vertex's corner (``0..U-1``).
        weights: ``(P,)`` ``w_ri`` (Eq. 5; 0 on padding pairs).
    """

    frame: Tensor
    tri_r: Tensor
    tri_i: Tensor
    around: Tensor
    present: Tensor
    corner_r: Tensor
    corner_i: Tensor
    weights: Tensor


def plan_energy(vertices: Tensor, plan: PairPlan, cone: Mapping[str, float]) -> Tensor:
    """Eq. 4 per batch element for the pairs of ``plan`` (detection and bookkeeping done).

    Args:
        vertices: ``(B, V, 3)`` metres (differentiable), indexed as the plan's vertex ids.
        plan: :class:`PairPlan`.
        cone: keyword arguments of :func:`cone_distance_field`.

    Returns:
        ``(B,)`` square metres.
    """
    normals = _area_weighted_normals(vertices, plan.around, plan.present)
    fr = plan.frame[:, None]
    terms = _pair_terms(vertices[fr, plan.tri_r], vertices[fr, plan.tri_i], normals[fr, plan.corner_r],
                        normals[fr, plan.corner_i], cone)
    in_frame = (plan.frame[:, None] == torch.arange(vertices.shape[0], device=vertices.device)).to(vertices.dtype)
    return ((terms * plan.weights.to(vertices.dtype))[:, None] * in_frame).sum(0)  # (B,): a sum per frame


def _pair_terms(tri_r: Tensor, tri_i: Tensor, normals_r: Tensor, normals_i: Tensor, cone: dict) -> Tensor:
    """Eq. 4's bracket for each pair: ``sum_j ||-psi_i(v_j) n_j||^2 + sum_k ||-psi_r(v_k) n_k||^2``.

    Args:
        tri_r, tri_i: ``(..., P, 3, 3)`` the two triangles of each pair.
        normals_r, normals_i: ``(..., P, 3, 3)`` their vertices' normals.
        cone: keyword arguments of :func:`cone_distance_field`.

    Returns:
        ``(..., P)`` square metres.
    """
    psi_i = cone_distance_field(tri_r, tri_i.unsqueeze(-3), **cone)  # (..., P, 3)
    psi_r = cone_distance_field(tri_i, tri_r.unsqueeze(-3), **cone)
    return ((-psi_i.unsqueeze(-1) * normals_r).square().sum((-1, -2))
            + (-psi_r.unsqueeze(-1) * normals_i).square().sum((-1, -2)))


def interpenetration_energy(vertices: Tensor, faces, pairs, pair_weights=None, normals: Tensor | None = None,
                            sigma: float = SIGMA, height: float = CONE_HEIGHT,
                            radius_scale: float = RADIUS_SCALE) -> Tensor:
    """Eq. 4, ``E_int``, for given colliding pairs (the same pairs for every leading index).

    Args:
        vertices: ``(..., V, 3)`` metres (differentiable).
        faces: ``(F, 3)`` int triangles.
        pairs: ``(P, 2)`` colliding face pairs ``(r, i)`` (:func:`colliding_triangle_pairs`).
        pair_weights: ``(P,)`` ``w_ri`` (Eq. 5, :func:`geodesic_pair_weights`); ``None`` = all 1
            (the paper's "E_int without w_ri" ablation).
        normals: ``(..., V, 3)`` per-vertex unit normals; ``None`` = :func:`vertex_normals` of
            ``vertices``.
        sigma, height, radius_scale: cone parameters (:func:`cone_distance_field`).

    Returns:
        ``(...)`` energy in square metres.
    """
    faces_np = as_face_array(faces, vertices.shape[-2])
    pairs = _as_pairs(pairs, len(faces_np))
    if normals is not None and normals.shape != vertices.shape:
        raise ValueError(f"normals must match vertices {tuple(vertices.shape)}, got {tuple(normals.shape)}")
    if not len(pairs):
        return vertices.sum((-1, -2)) * 0.0
    needed, local = np.unique(faces_np[pairs], return_inverse=True)  # pair corners -> needed vertices
    local = torch.as_tensor(local.reshape(len(pairs), 2, 3), device=vertices.device)
    if normals is None:
        normals = _normals_at(vertices, faces_np, _vertex_face_csr(faces_np, vertices.shape[-2]), needed)
    else:
        normals = normals[..., torch.as_tensor(needed, device=vertices.device), :]
    idx_r = torch.as_tensor(faces_np[pairs[:, 0]], device=vertices.device)
    idx_i = torch.as_tensor(faces_np[pairs[:, 1]], device=vertices.device)
    terms = _pair_terms(vertices[..., idx_r, :], vertices[..., idx_i, :], normals[..., local[:, 0], :],
                        normals[..., local[:, 1], :], dict(sigma=sigma, height=height, radius_scale=radius_scale))
    if pair_weights is None:
        return terms.sum(-1)
    weights = torch.as_tensor(np.asarray(pair_weights), dtype=vertices.dtype, device=vertices.device)
    if weights.shape != (len(pairs),):
        raise ValueError(f"pair_weights must be ({len(pairs)},), got {tuple(weights.shape)}")
    return (terms * weights).sum(-1)


#: the face pair :meth:`InterpenetrationEnergy.plan` pads with (zero weight): its vertices must be
#: among those a padded plan is evaluated on
PADDING_PAIR = (0, 1)


class InterpenetrationEnergy:
    """``E_int`` (Eq. 4) of one character mesh, detection included.

    Caches what every frame reuses: the faces, the :class:`TriangleBVH` (ordered on the rest pose),
    and Eq. 5's geodesic distances ``geodesic`` (a :class:`GeodesicDistances` of the rest pose,
    searched per colliding face when first needed) with the mesh's diameter ``eta``.

    Args:
        faces: ``(F, 3)`` int triangles.
        rest_vertices: ``(V, 3)`` rest pose (metres).
        geodesic_weights: use Eq. 5's ``w_ri``; ``False`` = uniform weights (ablation).
        sigma, height, radius_scale: cone parameters (:func:`cone_distance_field`).
        ignore_rest_intersections: leave the face pairs that already intersect in the rest pose
            out of every frame's detection (:attr:`rest_pairs`): on a real character they are the
            mesh's own construction (a jacket over a shirt, a belt through the trunk; 7 of the 11
            real characters have 8 to 1,790 such pairs, the synthetic characters none), not a
            pose's penetration, and Eq. 4 would push them apart in every frame. The contact
            method sets it; the default counts every intersection (Eq. 4 as printed).
    """

    def __init__(self, faces, rest_vertices, geodesic_weights: bool = True, sigma: float = SIGMA,
                 height: float = CONE_HEIGHT, radius_scale: float = RADIUS_SCALE,
                 ignore_rest_intersections: bool = False):
        rest = as_vertex_array(rest_vertices)
        self.faces = as_face_array(faces, len(rest))
        self.num_vertices = len(rest)
        _check_cone(sigma, height, radius_scale)
        self.cone = dict(sigma=float(sigma), height=float(height), radius_scale=float(radius_scale))
        self.bvh = TriangleBVH(self.faces, rest)
        self.geodesic: GeodesicDistances | None = None
        self.eta: float | None = None
        if geodesic_weights:
            self.geodesic = GeodesicDistances(rest, self.faces)
            self.eta = self.geodesic.eta
        self._vertex_faces = _vertex_face_csr(self.faces, self.num_vertices)
        #: ``(R, 2)`` face pairs intersecting in the rest pose, left out of :meth:`pairs` (empty
        #: unless ``ignore_rest_intersections``)
        self.rest_pairs = np.zeros((0, 2), np.int64)
        if ignore_rest_intersections:
            self.rest_pairs = colliding_triangle_pairs(rest, self.faces, self.bvh)

    def pairs(self, vertices, workers: int = 1) -> np.ndarray:
        """Colliding face pairs of one frame (but :attr:`rest_pairs`).

        Args:
            vertices: ``(V, 3)`` metres (NumPy or tensor; no gradient).
            workers: threads detecting (:func:`~retarget_lib.geometry.collision.colliding_triangle_pairs`).

        Returns:
            ``(P, 2)`` int64 ``(r, i)``, ``r < i``.
        """
        vertices = as_vertex_array(vertices)
        if len(vertices) != self.num_vertices:
            raise ValueError(f"expected {self.num_vertices} vertices, got {len(vertices)}")
        found = colliding_triangle_pairs(vertices, self.faces, self.bvh, workers)
        if len(self.rest_pairs) and len(found):
            found = found[~np.isin(_pair_codes(found, len(self.faces)), _pair_codes(self.rest_pairs, len(self.faces)))]
        return found

    def pair_weights(self, pairs: np.ndarray) -> np.ndarray:
        """``(P,)`` Eq. 5 weights of ``pairs`` (all 1 without geodesic weights)."""
        if self.geodesic is None:
            return np.ones(len(pairs))
        return geodesic_pair_weights(pairs, self.faces, self.geodesic, self.eta)

    def support(self, pairs: np.ndarray) -> np.ndarray:
        """``(U,)`` sorted ids of the vertices Eq. 4 reads for these colliding face pairs: every
        vertex of every face around a corner of a pair (the corners' area-weighted normals)."""
        corners = np.unique(self.faces[_as_pairs(pairs, len(self.faces))])
        return np.unique(_faces_around(self.faces, self._vertex_faces, corners)[0])

    def penetrating_faces(self, vertices) -> np.ndarray:
        """Sorted face indices involved in any collision of one frame ``(V, 3)``."""
        return np.unique(self.pairs(vertices))

    def __call__(self, vertices) -> Tensor:
        """Detect per frame (no gradient), then Eq. 4 (differentiable), summed per frame.

        Args:
            vertices: ``(V, 3)``, ``(B, V, 3)`` or any ``(..., V, 3)`` metres; a tensor (gradients
                flow to it) or a NumPy array (evaluated in float64).

        Returns:
            ``()``, ``(B,)`` or ``(...)`` energy in square metres, one value per frame.
        """
        if not isinstance(vertices, torch.Tensor):
            vertices = torch.as_tensor(np.asarray(vertices, dtype=np.float64))
        if vertices.dim() < 2 or vertices.shape[-2:] != (self.num_vertices, 3):
            raise ValueError(f"vertices must be (..., {self.num_vertices}, 3), got {tuple(vertices.shape)}")
        batch = vertices.reshape(-1, self.num_vertices, 3)
        per_frame = [self.pairs(f) for f in batch.detach().cpu().numpy()]
        return self.energy_of_pairs(batch, per_frame).reshape(vertices.shape[:-2])

    def plan(self, per_frame: Sequence[np.ndarray], vertex_index: np.ndarray | None = None,
             min_pairs: int = 0, device: torch.device | str | None = None) -> PairPlan:
        """Eq. 4's :class:`PairPlan` for given colliding pairs of each batch element.

        Args:
            per_frame: ``B`` arrays ``(P_b, 2)`` of colliding face pairs (:meth:`pairs`).
            vertex_index: ``(V,)`` int, where each mesh vertex sits in the vertices the plan will be
                evaluated on (a subset holding at least :meth:`support` of the pairs); default the
                whole mesh.
            min_pairs: pad with zero-weight pairs (:data:`PADDING_PAIR`, frame 0) to at least this many
                (fixed minimum sizes keep a compiled energy from specialising on 0 or 1 pairs).
            device: of the tensors.

        Returns:
            :class:`PairPlan`.
        """
        frame = np.repeat(np.arange(len(per_frame)), [len(p) for p in per_frame])
        pairs = np.concatenate([_as_pairs(p, len(self.faces)) for p in per_frame]) if len(per_frame) else \
            np.zeros((0, 2), np.int64)
        weights = self.pair_weights(pairs)
        pad = max(min_pairs - len(pairs), 0)
        if pad:
            if len(self.faces) < 2:
                raise ValueError("padding needs a mesh of at least two faces")
            pairs = np.concatenate([pairs, np.tile([PADDING_PAIR], (pad, 1))])
            frame = np.concatenate([frame, np.zeros(pad, np.int64)])
            weights = np.concatenate([weights, np.zeros(pad)])
        corners, local = np.unique(self.faces[pairs], return_inverse=True)  # pair corners -> normals
        local = local.reshape(len(pairs), 2, 3)
        around, present = _faces_around(self.faces, self._vertex_faces, corners)
        where = np.arange(self.num_vertices) if vertex_index is None else np.asarray(vertex_index)
        as_tensor = lambda a, dtype=torch.int64: torch.as_tensor(a, dtype=dtype, device=device)  # noqa: E731
        return PairPlan(as_tensor(frame), as_tensor(where[self.faces[pairs[:, 0]]]),
                        as_tensor(where[self.faces[pairs[:, 1]]]), as_tensor(where[around]),
                        as_tensor(present, torch.bool), as_tensor(local[:, 0]), as_tensor(local[:, 1]),
                        as_tensor(weights, torch.float64))

    def energy_of_pairs(self, batch: Tensor, per_frame: Sequence[np.ndarray]) -> Tensor:
        """Eq. 4 per frame for given colliding pairs (detection skipped, e.g. pairs found once and
        reused for a few optimisation steps; :meth:`plan` once and :func:`plan_energy` per step
        skips the bookkeeping too).

        Args:
            batch: ``(B, V, 3)`` metres (differentiable).
            per_frame: ``B`` arrays ``(P_b, 2)`` of colliding face pairs (:meth:`pairs`).

        Returns:
            ``(B,)`` square metres.
        """
        nb = batch.shape[0]
        if len(per_frame) != nb:
            raise ValueError(f"need one pair array per frame: {nb} frames, {len(per_frame)} arrays")
        if not sum(len(p) for p in per_frame):
            return batch.new_zeros(nb) + batch.sum((-1, -2)) * 0.0
        return plan_energy(batch, self.plan(per_frame, device=batch.device), self.cone)


def interpenetration_score(energy: InterpenetrationEnergy, vertices, height: float) -> float:
    """The paper's interpenetration metric (Sec. 4): Eq. 4 on height-normalised vertices, averaged
    over frames.

    The cone lengths are normalised with the body, so ``psi`` scales with length and the score is
    exactly ``mean_t E_int(v_t) / height^2`` — comparable across characters of any size. Whether
    ``w_ri`` is used follows ``energy``.

    Args:
        energy: the character's :class:`InterpenetrationEnergy`.
        vertices: ``(T, V, 3)`` metres (NumPy or tensor).
        height: character height (metres; the library's ``Character.height``).

    Returns:
        The mean normalised energy (unitless).
    """
    if height <= 0:
        raise ValueError(f"height must be positive, got {height}")
    if len(vertices.shape if isinstance(vertices, torch.Tensor) else np.shape(vertices)) != 3:
        raise ValueError(f"vertices must be (T, V, 3), got {tuple(vertices.shape)}")
    with torch.no_grad():
        values = energy(vertices if isinstance(vertices, torch.Tensor) else np.asarray(vertices, dtype=np.float64))
    return float(values.mean()) / height ** 2


# ----------------------------------------------------------------------------- penetration rate
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
    graph = scipy.sparse.coo_matrix((np.ones(len(boundary)), (boundary[:, 0], boundary[:, 1])), shape=(nv, nv))
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


def penetration_rate(vertices, faces, weights, limbs: Mapping[str, Sequence[str]] | None = None
                     ) -> dict[str, float]:
    """Per-limb penetration rate: the share of a limb's vertices inside the rest of the body.

    Definition: a vertex belongs to the limb whose joints hold its largest skinning weight
    (:data:`DEFAULT_LIMBS`: each arm = Arm, ForeArm, Hand; each leg = UpLeg, Leg, Foot, ToeBase).
    The limb's *body* is the mesh without the limb's faces (every face with a limb vertex; the
    other limbs stay part of it), with the hole this leaves closed by :func:`cap_holes`. A limb
    vertex is *inside* when the body's winding number at it (:func:`ray_winding_numbers`) is at
    least 1 — inside the torso, a leg, the other arm, or several of them at once. The rate is
    (inside vertices) / (limb vertices), averaged over frames.

    Args:
        vertices: ``(V, 3)`` or ``(T, V, 3)`` metres.
        faces: ``(F, 3)`` int triangles, closed mesh, counter-clockwise seen from outside.
        weights: ``(V, 22)`` skinning weights on the canonical 22 joints.
        limbs: ``{name: joint names}``; ``None`` = :data:`DEFAULT_LIMBS`.

    Returns:
        ``{limb: rate in [0, 1]}`` (``nan`` for a limb with no vertex).
    """
    frames = np.asarray(vertices.detach().cpu().numpy() if isinstance(vertices, torch.Tensor) else vertices,
                        dtype=np.float64)
    frames = frames[None] if frames.ndim == 2 else frames
    if frames.ndim != 3 or frames.shape[2] != 3:
        raise ValueError(f"vertices must be (V, 3) or (T, V, 3), got {frames.shape}")
    faces = as_face_array(faces, frames.shape[1])
    weights = np.asarray(weights, dtype=np.float64)
    if weights.shape != (frames.shape[1], len(CANONICAL22)):
        raise ValueError(f"weights must be ({frames.shape[1]}, 22), got {weights.shape}")
    owner = weights.argmax(1)
    rates = {}
    for name, joints in (DEFAULT_LIMBS if limbs is None else limbs).items():
        unknown = [j for j in joints if j not in CANONICAL22]
        if unknown:
            raise ValueError(f"limb {name!r}: unknown joints {unknown}")
        in_limb = np.isin(owner, [CANONICAL22.index(j) for j in joints])
        if not in_limb.any():
            rates[name] = float("nan")
            continue
        rates[name] = float(np.mean([_inside_body(frame, faces, in_limb) for frame in frames]))
    return rates


def _inside_body(vertices: np.ndarray, faces: np.ndarray, in_limb: np.ndarray) -> np.ndarray:
    """``(K,)`` bool: which of the limb's ``K`` vertices lie inside the rest of the body (the mesh
    without the limb's faces, its holes capped; winding number >= 1)."""
    body_vertices, body_closed = cap_holes(vertices, faces[~in_limb[faces].any(1)])
    return ray_winding_numbers(vertices[in_limb], body_vertices, body_closed) >= 1


def limb_vertices_inside(vertices, faces, weights, limbs: Mapping[str, Sequence[str]] | None = None) -> np.ndarray:
    """``(V,)`` bool: the vertices of one posed mesh that :func:`penetration_rate` counts as inside
    the body (a limb vertex inside the rest of the body); every other vertex is ``False``.

    Args:
        vertices: ``(V, 3)`` metres; faces, weights, limbs: as :func:`penetration_rate`.
    """
    vertices = np.asarray(vertices, dtype=np.float64)
    faces = as_face_array(faces, len(vertices))
    owner = np.asarray(weights).argmax(1)
    out = np.zeros(len(vertices), dtype=bool)
    for joints in (DEFAULT_LIMBS if limbs is None else limbs).values():
        in_limb = np.isin(owner, [CANONICAL22.index(j) for j in joints])
        if in_limb.any():
            out[np.flatnonzero(in_limb)[_inside_body(vertices, faces, in_limb)]] = True
    return out
