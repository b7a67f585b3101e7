"""Geodesic distances on a mesh and Eq. 5's pair weights (Villegas et al. 2021, Sec. 3.3).

``w_ri = min_{v_j in f_r, v_k in f_i} D(v_j, v_k) / eta`` (``eta`` = the largest geodesic distance
on the mesh) makes touching folds near joints (armpits, crotch) cheap and penetrations between
distant body parts expensive in the interpenetration energy
(:mod:`retarget_lib.geometry.penetration`). ``D`` is approximated by shortest paths along mesh edges
(Dijkstra): :func:`geodesic_distances` for a whole ``V x V`` table, :class:`GeodesicDistances` for
the distances between colliding faces, searched when first needed.

Units: metres.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse
from scipy.sparse.csgraph import connected_components, dijkstra

from .collision import as_face_array, as_face_pairs, as_vertex_array

__all__ = ["GeodesicDistances", "geodesic_distances", "geodesic_pair_weights"]


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
    diameter ``eta``) instead of ``V`` of them (34 s and 716 MB for the 13,380-vertex MakeHuman
    body).

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
        best = max(
            (
                self._piece_diameter(np.flatnonzero(label == piece))
                for piece in np.flatnonzero(sizes > 1)
            ),
            default=0.0,
        )
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
            pick = int(
                np.argmax(np.where(open_, upper, -np.inf))
                if step % 2
                else np.argmin(np.where(open_, lower, np.inf))
            )
        return best

    def from_face(self, face: int) -> np.ndarray:
        """``(V,)`` float32 distance from the nearest vertex of ``face`` to every vertex (metres;
        ``inf`` on other pieces)."""
        face = int(face)
        if face not in self._from_face:
            self._from_face[face] = dijkstra(
                self.graph, directed=False, indices=self.faces[face], min_only=True
            ).astype(np.float32)
        return self._from_face[face]

    def between_faces(self, pairs) -> np.ndarray:
        """``(P,)`` float64 ``min_{v_j in f_r, v_k in f_i} D(v_j, v_k)`` of face pairs ``(r,
        i)``."""
        pairs = as_face_pairs(pairs, len(self.faces))
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


def geodesic_pair_weights(
    pairs, faces, geodesic: np.ndarray | GeodesicDistances, eta: float | None = None
) -> np.ndarray:
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
    pairs = as_face_pairs(pairs, len(faces))
    if isinstance(geodesic, GeodesicDistances):
        if len(geodesic.faces) != len(faces) or not np.array_equal(geodesic.faces, faces):
            raise ValueError("geodesic was built on other faces")
        dmin = geodesic.between_faces(pairs)
        eta = geodesic.eta if eta is None else eta
    else:
        if (
            geodesic.ndim != 2
            or geodesic.shape[0] != geodesic.shape[1]
            or faces.max(initial=-1) >= len(geodesic)
        ):
            raise ValueError(
                f"geodesic must be (V, V) over the faces' vertices, got {geodesic.shape}"
            )
        if eta is None:
            finite = geodesic[np.isfinite(geodesic)]
            eta = float(finite.max()) if finite.size else 1.0
        fr, fi = faces[pairs[:, 0]], faces[pairs[:, 1]]
        dmin = (
            geodesic[fr[:, :, None], fi[:, None, :]]
            .reshape(len(pairs), 9)
            .min(1)
            .astype(np.float64)
        )
    if eta <= 0:
        raise ValueError(f"eta must be positive, got {eta}")
    return np.where(np.isfinite(dmin), np.minimum(dmin / eta, 1.0), 1.0)
