"""Interpenetration: the energy ``E_int`` of Villegas et al. 2021 (Sec. 3.3, Eq. 4) and the paper's
interpenetration score (Sec. 4).

**Detection** (no gradient): the intersecting triangle pairs ``F = {(r, i)}`` of each frame come
from :mod:`retarget_lib.geometry.collision` (the paper's BVH [29] and an exact triangle-triangle
test).

**Energy** (differentiable). Each triangle ``i`` carries a cone-shaped local distance field
``psi_i`` (:func:`~retarget_lib.geometry.cone_field.cone_distance_field`, after Tzionas et al.
2016): positive for points behind the triangle (penetrating the surface), zero in front of it and
outside the cone. For each colliding pair, Eq. 4 penalises the vertices of one triangle inside the
other's field::

    E_int = sum_{(r,i) in F} w_ri ( sum_{v_j in f_r} ||-psi_i(v_j) n_j||^2 + sum_{v_k in f_i}
    ||-psi_r(v_k) n_k||^2 )

with area-weighted unit vertex normals ``n_j`` (:mod:`retarget_lib.geometry.normals`; so each term
equals ``psi^2``; the normals give the penalty its direction in the paper's notation). Eq. 5's
geodesic weights ``w_ri`` (:mod:`retarget_lib.geometry.geodesic`) make touching folds near joints
(armpits, crotch) cheap and penetrations between distant body parts expensive.

**Metric.** :func:`interpenetration_score` is the paper's Sec. 4 score (Eq. 4 on height-normalised
vertices); the per-limb penetration rate of later work is
:mod:`retarget_lib.geometry.penetration_rate`.

Units: metres; ``psi`` is a length (metres), ``E_int`` is in square metres.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import NamedTuple

import numpy as np
import torch

from .collision import (
    TriangleBVH,
    as_face_array,
    as_face_pairs,
    as_vertex_array,
    colliding_triangle_pairs,
)
from .cone_field import CONE_HEIGHT, RADIUS_SCALE, SIGMA, check_cone, cone_distance_field
from .geodesic import GeodesicDistances, geodesic_pair_weights
from .normals import area_weighted_normals, faces_around, normals_at, vertex_face_csr

Tensor = torch.Tensor

__all__ = [
    "PADDING_PAIR",
    "InterpenetrationEnergy",
    "PairPlan",
    "interpenetration_energy",
    "interpenetration_score",
    "plan_energy",
]


def _pair_codes(pairs: np.ndarray, num_faces: int) -> np.ndarray:
    """One integer per face pair ``(r, i)``, ``r < i``: ``r * F + i``."""
    return pairs[:, 0] * num_faces + pairs[:, 1]


# ----------------------------------------------------------------------------- the energy (Eq. 4)
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
    normals = area_weighted_normals(vertices, plan.around, plan.present)
    fr = plan.frame[:, None]
    terms = _pair_terms(
        vertices[fr, plan.tri_r],
        vertices[fr, plan.tri_i],
        normals[fr, plan.corner_r],
        normals[fr, plan.corner_i],
        cone,
    )
    in_frame = (plan.frame[:, None] == torch.arange(vertices.shape[0], device=vertices.device)).to(
        vertices.dtype
    )
    return ((terms * plan.weights.to(vertices.dtype))[:, None] * in_frame).sum(
        0
    )  # (B,): a sum per frame


def _pair_terms(
    tri_r: Tensor, tri_i: Tensor, normals_r: Tensor, normals_i: Tensor, cone: dict
) -> Tensor:
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
    return (-psi_i.unsqueeze(-1) * normals_r).square().sum((-1, -2)) + (
        -psi_r.unsqueeze(-1) * normals_i
    ).square().sum((-1, -2))


def interpenetration_energy(
    vertices: Tensor,
    faces,
    pairs,
    pair_weights=None,
    normals: Tensor | None = None,
    sigma: float = SIGMA,
    height: float = CONE_HEIGHT,
    radius_scale: float = RADIUS_SCALE,
) -> Tensor:
    """Eq. 4, ``E_int``, for given colliding pairs (the same pairs for every leading index).

    Args:
        vertices: ``(..., V, 3)`` metres (differentiable).
        faces: ``(F, 3)`` int triangles.
        pairs: ``(P, 2)`` colliding face pairs ``(r, i)`` (:func:`colliding_triangle_pairs`).
        pair_weights: ``(P,)`` ``w_ri`` (Eq. 5, :func:`geodesic_pair_weights`); ``None`` = all 1
            (the paper's "E_int without w_ri" ablation).
        normals: ``(..., V, 3)`` per-vertex unit normals; ``None`` =
            :func:`~retarget_lib.geometry.normals.vertex_normals` of ``vertices``.
        sigma, height, radius_scale: cone parameters (:func:`cone_distance_field`).

    Returns:
        ``(...)`` energy in square metres.
    """
    faces_np = as_face_array(faces, vertices.shape[-2])
    pairs = as_face_pairs(pairs, len(faces_np))
    if normals is not None and normals.shape != vertices.shape:
        raise ValueError(
            f"normals must match vertices {tuple(vertices.shape)}, got {tuple(normals.shape)}"
        )
    if not len(pairs):
        return vertices.sum((-1, -2)) * 0.0
    needed, local = np.unique(
        faces_np[pairs], return_inverse=True
    )  # pair corners -> needed vertices
    local = torch.as_tensor(local.reshape(len(pairs), 2, 3), device=vertices.device)
    if normals is None:
        normals = normals_at(
            vertices, faces_np, vertex_face_csr(faces_np, vertices.shape[-2]), needed
        )
    else:
        normals = normals[..., torch.as_tensor(needed, device=vertices.device), :]
    idx_r = torch.as_tensor(faces_np[pairs[:, 0]], device=vertices.device)
    idx_i = torch.as_tensor(faces_np[pairs[:, 1]], device=vertices.device)
    terms = _pair_terms(
        vertices[..., idx_r, :],
        vertices[..., idx_i, :],
        normals[..., local[:, 0], :],
        normals[..., local[:, 1], :],
        dict(sigma=sigma, height=height, radius_scale=radius_scale),
    )
    if pair_weights is None:
        return terms.sum(-1)
    weights = torch.as_tensor(
        np.asarray(pair_weights), dtype=vertices.dtype, device=vertices.device
    )
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

    def __init__(
        self,
        faces,
        rest_vertices,
        geodesic_weights: bool = True,
        sigma: float = SIGMA,
        height: float = CONE_HEIGHT,
        radius_scale: float = RADIUS_SCALE,
        ignore_rest_intersections: bool = False,
    ):
        rest = as_vertex_array(rest_vertices)
        self.faces = as_face_array(faces, len(rest))
        self.num_vertices = len(rest)
        check_cone(sigma, height, radius_scale)
        self.cone = dict(sigma=float(sigma), height=float(height), radius_scale=float(radius_scale))
        self.bvh = TriangleBVH(self.faces, rest)
        self.geodesic: GeodesicDistances | None = None
        self.eta: float | None = None
        if geodesic_weights:
            self.geodesic = GeodesicDistances(rest, self.faces)
            self.eta = self.geodesic.eta
        self._vertex_faces = vertex_face_csr(self.faces, self.num_vertices)
        #: ``(R, 2)`` face pairs intersecting in the rest pose, left out of :meth:`pairs` (empty
        #: unless ``ignore_rest_intersections``)
        self.rest_pairs = np.zeros((0, 2), np.int64)
        if ignore_rest_intersections:
            self.rest_pairs = colliding_triangle_pairs(rest, self.faces, self.bvh)

    def pairs(self, vertices, workers: int = 1) -> np.ndarray:
        """Colliding face pairs of one frame (but :attr:`rest_pairs`).

        Args:
            vertices: ``(V, 3)`` metres (NumPy or tensor; no gradient).
            workers: threads detecting
                (:func:`~retarget_lib.geometry.collision.colliding_triangle_pairs`).

        Returns:
            ``(P, 2)`` int64 ``(r, i)``, ``r < i``.
        """
        vertices = as_vertex_array(vertices)
        if len(vertices) != self.num_vertices:
            raise ValueError(f"expected {self.num_vertices} vertices, got {len(vertices)}")
        found = colliding_triangle_pairs(vertices, self.faces, self.bvh, workers)
        if len(self.rest_pairs) and len(found):
            found = found[
                ~np.isin(
                    _pair_codes(found, len(self.faces)),
                    _pair_codes(self.rest_pairs, len(self.faces)),
                )
            ]
        return found

    def pair_weights(self, pairs: np.ndarray) -> np.ndarray:
        """``(P,)`` Eq. 5 weights of ``pairs`` (all 1 without geodesic weights)."""
        if self.geodesic is None:
            return np.ones(len(pairs))
        return geodesic_pair_weights(pairs, self.faces, self.geodesic, self.eta)

    def support(self, pairs: np.ndarray) -> np.ndarray:
        """``(U,)`` sorted ids of the vertices Eq. 4 reads for these colliding face pairs: every
        vertex of every face around a corner of a pair (the corners' area-weighted normals)."""
        corners = np.unique(self.faces[as_face_pairs(pairs, len(self.faces))])
        return np.unique(faces_around(self.faces, self._vertex_faces, corners)[0])

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
            raise ValueError(
                f"vertices must be (..., {self.num_vertices}, 3), got {tuple(vertices.shape)}"
            )
        batch = vertices.reshape(-1, self.num_vertices, 3)
        per_frame = [self.pairs(f) for f in batch.detach().cpu().numpy()]
        return self.energy_of_pairs(batch, per_frame).reshape(vertices.shape[:-2])

    def plan(
        self,
        per_frame: Sequence[np.ndarray],
        vertex_index: np.ndarray | None = None,
        min_pairs: int = 0,
        device: torch.device | str | None = None,
    ) -> PairPlan:
        """Eq. 4's :class:`PairPlan` for given colliding pairs of each batch element.

        Args:
            per_frame: ``B`` arrays ``(P_b, 2)`` of colliding face pairs (:meth:`pairs`).
            vertex_index: ``(V,)`` int, where each mesh vertex sits in the vertices the plan will be
                evaluated on (a subset holding at least :meth:`support` of the pairs); default the
                whole mesh.
            min_pairs: pad with zero-weight pairs (:data:`PADDING_PAIR`, frame 0) to at least this
                many (fixed minimum sizes keep a compiled energy from specialising on 0 or 1 pairs).
            device: of the tensors.

        Returns:
            :class:`PairPlan`.
        """
        frame = np.repeat(np.arange(len(per_frame)), [len(p) for p in per_frame])
        pairs = (
            np.concatenate([as_face_pairs(p, len(self.faces)) for p in per_frame])
            if len(per_frame)
            else np.zeros((0, 2), np.int64)
        )
        weights = self.pair_weights(pairs)
        pad = max(min_pairs - len(pairs), 0)
        if pad:
            if len(self.faces) < 2:
                raise ValueError("padding needs a mesh of at least two faces")
            pairs = np.concatenate([pairs, np.tile([PADDING_PAIR], (pad, 1))])
            frame = np.concatenate([frame, np.zeros(pad, np.int64)])
            weights = np.concatenate([weights, np.zeros(pad)])
        corners, local = np.unique(
            self.faces[pairs], return_inverse=True
        )  # pair corners -> normals
        local = local.reshape(len(pairs), 2, 3)
        around, present = faces_around(self.faces, self._vertex_faces, corners)
        where = np.arange(self.num_vertices) if vertex_index is None else np.asarray(vertex_index)
        as_tensor = lambda a, dtype=torch.int64: torch.as_tensor(a, dtype=dtype, device=device)  # noqa: E731
        return PairPlan(
            as_tensor(frame),
            as_tensor(where[self.faces[pairs[:, 0]]]),
            as_tensor(where[self.faces[pairs[:, 1]]]),
            as_tensor(where[around]),
            as_tensor(present, torch.bool),
            as_tensor(local[:, 0]),
            as_tensor(local[:, 1]),
            as_tensor(weights, torch.float64),
        )

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
        values = energy(
            vertices
            if isinstance(vertices, torch.Tensor)
            else np.asarray(vertices, dtype=np.float64)
        )
    return float(values.mean()) / height**2
