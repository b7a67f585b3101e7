"""The skinned character: a canonical-22 skeleton with a mesh and skinning weights."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import torch

from .kinematics import forward_kinematics
from .skeleton import Skeleton
from .skinning import linear_blend_skinning, subsample_mesh

#: bulk below which a character counts as "skinny", and at or above which as "bulky"
SKINNY_BELOW, BULKY_FROM = 0.85, 1.25


@dataclass
class Character:
    """A skinned character on the canonical 22 joints.

    Attributes:
        name: identifier (e.g. ``"ada"``, ``"mannequin-x"``, a shape file's stem).
        skeleton: canonical-22 :class:`~retarget_lib.core.skeleton.Skeleton`, offsets in metres; the
            root's offset is its rest position (feet on ``y = 0``).
        rest_vertices: ``(V, 3)`` float64 mesh vertices in the world rest pose (metres), i.e. with
            the root at its rest position.
        faces: ``(F, 3)`` int64 triangles (counter-clockwise seen from outside).
        weights: ``(V, 22)`` float64 skinning weights, rows summing to 1.
        bulk: body girth relative to an average build (1.0; also used when unknown).
        style: descriptive tags: rest pose, angles in degrees, scale, length factors, source ...
    """

    name: str
    skeleton: Skeleton
    rest_vertices: np.ndarray
    faces: np.ndarray
    weights: np.ndarray
    bulk: float = 1.0
    style: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.rest_vertices = np.asarray(self.rest_vertices, dtype=np.float64)
        self.faces = np.asarray(self.faces, dtype=np.int64)
        self.weights = np.asarray(self.weights, dtype=np.float64)
        if not self.skeleton.is_canonical22():
            raise ValueError(
                f"character {self.name!r}: skeleton must be on the canonical 22 joints"
            )
        nv = len(self.rest_vertices)
        if self.rest_vertices.shape != (nv, 3) or self.weights.shape != (nv, 22):
            raise ValueError(
                f"character {self.name!r}: rest_vertices {self.rest_vertices.shape} and "
                f"weights {self.weights.shape} must be (V, 3) and (V, 22)"
            )
        if self.faces.ndim != 2 or self.faces.shape[1] != 3:
            raise ValueError(
                f"character {self.name!r}: faces must be (F, 3), got {self.faces.shape}"
            )

    @property
    def height(self) -> float:
        """NKN/TDCN height ``H`` in metres (:meth:`~retarget_lib.core.skeleton.Skeleton.height`)."""
        return self.skeleton.height()

    @property
    def body_type(self) -> str:
        """``"skinny"`` (bulk < 0.85), ``"bulky"`` (bulk >= 1.25) or ``"average"``."""
        if self.bulk < SKINNY_BELOW:
            return "skinny"
        return "bulky" if self.bulk >= BULKY_FROM else "average"

    @property
    def num_vertices(self) -> int:
        return len(self.rest_vertices)

    def rest_joint_positions(self) -> np.ndarray:
        """``(22, 3)`` world joint positions in the rest pose (metres)."""
        return self.skeleton.rest_positions()

    def copy(self) -> Character:
        return Character(
            self.name,
            self.skeleton.copy(),
            self.rest_vertices.copy(),
            self.faces.copy(),
            self.weights.copy(),
            self.bulk,
            dict(self.style),
        )

    def decimated(self, vertices: int) -> Character:
        """A copy whose mesh is reduced to about ``vertices`` vertices, skinning weights carried
        (:func:`~retarget_lib.core.skinning.subsample_mesh`); the skeleton is the same.

        Args:
            vertices: the vertex count wanted (the result is within a few percent of it).
        """
        small = self.copy()
        small.rest_vertices, small.faces, small.weights = subsample_mesh(
            self.rest_vertices, self.faces, self.weights, vertices
        )
        return small

    def skinned(self, rotations, root_positions):
        """Pose the mesh: forward kinematics then linear blend skinning.

        Args:
            rotations: ``(..., 22, 4)`` local joint rotations, unit wxyz (NumPy or torch).
            root_positions: ``(..., 3)`` root positions in metres.

        Returns:
            ``(..., V, 3)`` posed vertices; NumPy float64 for NumPy input, else a tensor in the
            rotations' dtype (differentiable).
        """
        as_numpy = isinstance(rotations, np.ndarray)
        rot = torch.from_numpy(np.asarray(rotations, dtype=np.float64)) if as_numpy else rotations
        root = torch.as_tensor(
            np.asarray(root_positions)
            if isinstance(root_positions, np.ndarray)
            else root_positions,
            dtype=rot.dtype,
            device=rot.device,
        )
        pos, grot = forward_kinematics(rot, self.skeleton.offsets, self.skeleton.parents, root)
        out = linear_blend_skinning(
            self.rest_vertices, self.weights, self.rest_joint_positions(), grot, pos
        )
        return out.numpy() if as_numpy else out
