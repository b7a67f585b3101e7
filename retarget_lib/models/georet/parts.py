"""The parts of the geometry-conditioned RNN (Villegas et al. 2021, Sec. 3.2, App. B.1): the
motion features, the rest mesh normalised for PointNet (Eq. 19) and its encoder, the decoder's state
and GRU update, and posing the outputs by forward kinematics."""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
import torch
from torch import nn

from ...core.kinematics import forward_kinematics
from ...core.measures import mesh_ground, mesh_standing_height, nkn_height
from ...core.quantities import forward_root_velocity
from ...core.rotations import quat_to_matrix
from ...core.skeleton import CANONICAL22_PARENTS
from ..features import batched_offsets

__all__ = [
    "MOTION_FEATURES",
    "MOTION_FEATURE_LAYOUT",
    "GeoRetOutput",
    "ResidualBase",
    "PosedOutput",
    "TargetContext",
    "DecoderState",
    "DecoderGates",
    "gru_update",
    "PointNetEncoder",
    "motion_features",
    "normalize_rest_vertices",
    "batch_meshes",
    "pose_outputs",
]


Tensor = torch.Tensor


NUM_JOINTS = 22


#: width of ``m_t``: 22×3 positions + 22×9 rotation matrices + 3 root velocity (App. B)
MOTION_FEATURES = 3 * NUM_JOINTS + 9 * NUM_JOINTS + 3


#: slices of :func:`motion_features`' channels
MOTION_FEATURE_LAYOUT: dict[str, slice] = {
    "positions": slice(0, 3 * NUM_JOINTS),
    "rotations": slice(3 * NUM_JOINTS, 12 * NUM_JOINTS),
    "root_velocity": slice(12 * NUM_JOINTS, 12 * NUM_JOINTS + 3),
}


def _heights(height: float | Tensor | None, offsets: Tensor) -> Tensor:
    """``(B,)`` heights: given (float or ``(B,)``) or the NKN height
    :func:`~retarget_lib.core.measures.nkn_height` of ``(B, 22, 3)`` offsets."""
    if height is None:
        return nkn_height(offsets)
    h = torch.as_tensor(height, dtype=offsets.dtype, device=offsets.device)
    return h.expand(offsets.shape[0]) if h.dim() == 0 else h


def motion_features(
    rotations: Tensor,
    root_positions: Tensor,
    offsets: Tensor | np.ndarray,
    parents: Sequence[int] = CANONICAL22_PARENTS,
    height: float | Tensor | None = None,
) -> Tensor:
    """``m_t`` for every frame (App. B): ``[p_t / h, θ_t (3×3, row-major), o_t / h]``.

    Args:
        rotations: ``(B, T, 22, 4)`` local unit wxyz.
        root_positions: ``(B, T, 3)`` metres.
        offsets: ``(22, 3)`` or ``(B, 22, 3)`` rest offsets (metres).
        parents: joint parents.
        height: the character height ``h`` (float or ``(B,)``); default
            :func:`~retarget_lib.core.measures.nkn_height` of ``offsets``.

    Returns:
        ``(B, T, 267)``; slices in :data:`MOTION_FEATURE_LAYOUT`.
    """
    if rotations.dim() != 4 or rotations.shape[-2:] != (NUM_JOINTS, 4):
        raise ValueError(f"rotations must be (B, T, 22, 4), got {tuple(rotations.shape)}")
    b, t = rotations.shape[:2]
    off = batched_offsets(
        torch.as_tensor(offsets, dtype=rotations.dtype, device=rotations.device), b
    )
    h = _heights(height, off).view(b, 1, 1)
    local = forward_kinematics(rotations, off.unsqueeze(1), parents, None).positions
    mats = quat_to_matrix(rotations).reshape(b, t, 9 * NUM_JOINTS)
    vel = forward_root_velocity(root_positions)
    return torch.cat((local.reshape(b, t, 3 * NUM_JOINTS) / h, mats, vel / h), dim=-1)


def normalize_rest_vertices(vertices: Tensor) -> Tensor:
    """Centre rest vertices on their footprint and divide by the mesh's standing height.

    Origin: the bounding box's x and z centre at its lowest y
    (:func:`~retarget_lib.core.measures.mesh_ground`); scale: the box's y extent
    (:func:`~retarget_lib.core.measures.mesh_standing_height`, at least 1e-6 m).

    Args:
        vertices: ``(..., V, 3)`` rest vertices (metres, y up).

    Returns:
        ``(..., V, 3)`` unitless; y runs from 0 (soles) to 1 (top of the head).
    """
    lo, hi = vertices.amin(dim=-2, keepdim=True), vertices.amax(dim=-2, keepdim=True)
    ground = mesh_ground(vertices)[..., None, None]
    origin = torch.cat(
        ((lo[..., :1] + hi[..., :1]) / 2, ground, (lo[..., 2:] + hi[..., 2:]) / 2), -1
    )
    extent = mesh_standing_height(vertices)[..., None, None].clamp_min(1e-6)
    return (vertices - origin) / extent


def batch_meshes(
    vertices: Sequence[np.ndarray | Tensor],
    weights: Sequence[np.ndarray | Tensor],
    dtype: torch.dtype = torch.float32,
) -> tuple[Tensor, Tensor]:
    """Stack meshes with different vertex counts by repeating vertices (cyclically) up to the
    largest.

    Repeating vertices changes neither :func:`normalize_rest_vertices` nor the max-pool of
    :class:`PointNetEncoder`, so every mesh keeps its own embedding.

    Args:
        vertices: ``B`` arrays ``(V_b, 3)``.
        weights: ``B`` arrays ``(V_b, 22)``.

    Returns:
        ``(B, V_max, 3)`` and ``(B, V_max, 22)``.
    """
    if len(vertices) != len(weights) or not vertices:
        raise ValueError(
            f"need the same non-zero number of vertex and weight arrays, got "
            f"{len(vertices)} and {len(weights)}"
        )
    n = max(len(v) for v in vertices)
    out_v, out_w = [], []
    for v, w in zip(vertices, weights, strict=False):
        v, w = torch.as_tensor(v, dtype=dtype), torch.as_tensor(w, dtype=dtype)
        if len(v) != len(w):
            raise ValueError(f"a mesh has {len(v)} vertices but {len(w)} weight rows")
        idx = torch.arange(n, device=v.device) % len(v)
        out_v.append(v[idx])
        out_w.append(w[idx])
    return torch.stack(out_v), torch.stack(out_w)


class PointNetEncoder(nn.Module):
    """``e = max_v f_vert([v̄_v, w_v])`` (Eq. 19): a per-vertex two-layer MLP, then a max-pool.

    Args:
        in_features: 3 (normalised rest position) + 22 (skinning weights).
        hidden: units of both layers (App. B.1: 256); also the embedding size.
    """

    def __init__(self, in_features: int = 3 + NUM_JOINTS, hidden: int = 256):
        super().__init__()
        self.in_features = in_features
        self.mlp = nn.Sequential(
            nn.Linear(in_features, hidden), nn.ReLU(), nn.Linear(hidden, hidden), nn.ReLU()
        )

    def forward(self, vertices: Tensor, weights: Tensor) -> Tensor:
        """Embed rest meshes of any vertex count.

        Args:
            vertices: ``(B, V, 3)`` rest vertices in metres (normalised here,
                :func:`normalize_rest_vertices`).
            weights: ``(B, V, 22)`` skinning weights.

        Returns:
            ``(B, hidden)``.
        """
        if (
            vertices.dim() != 3
            or vertices.shape[-1] != 3
            or weights.shape[:2] != vertices.shape[:2]
        ):
            raise ValueError(
                f"vertices must be (B, V, 3) and weights (B, V, J); got "
                f"{tuple(vertices.shape)} and {tuple(weights.shape)}"
            )
        if 3 + weights.shape[-1] != self.in_features:
            raise ValueError(
                f"expected {self.in_features - 3} skinning weights per vertex, "
                f"got {weights.shape[-1]}"
            )
        x = torch.cat((normalize_rest_vertices(vertices), weights.to(vertices.dtype)), dim=-1)
        return self.mlp(x).amax(dim=1)


class GeoRetOutput(NamedTuple):
    """What :meth:`GeometryConditionedRNN.forward` returns.

    Attributes:
        rotations: ``(B, T, 22, 4)`` local unit wxyz ``θ^B`` (``w ≥ 0``).
        root_velocity: ``(B, T, 3)`` ``o^B_t`` (metres per frame; frame ``t`` → ``t + 1``).
        local_positions: ``(B, T, 22, 3)`` ``p^B_t`` = FK relative to the root (metres).
        geometry: ``(B, G)`` the target's embedding ``e^B``.
    """

    rotations: Tensor
    root_velocity: Tensor
    local_positions: Tensor
    geometry: Tensor


class ResidualBase(NamedTuple):
    """What a residual network corrects (our variant, ``residual=True``): Eweak's targets (Eq. 8).

    Attributes:
        rotations: ``(B, T, 22, 4)`` Eweak's ``θ^A`` (wxyz): the source's local rotations
            re-expressed on the target's rest pose
            (:func:`~retarget_lib.methods.contact.eweak_rotations`).
        root_velocity: ``(B, T, 3)`` ``o^(A→B)``, the source's root velocity times the leg ratio
            (metres per frame).
    """

    rotations: Tensor
    root_velocity: Tensor

    def frame(self, t: int) -> ResidualBase:
        """Frame ``t``: ``rotations (B, 22, 4)``, ``root_velocity (B, 3)``."""
        return ResidualBase(self.rotations[:, t], self.root_velocity[:, t])


class TargetContext(NamedTuple):
    """The per-sequence constants of the decoder (:meth:`GeometryConditionedRNN.target_context`).

    Attributes:
        offsets: ``(B, 22, 3)`` target rest offsets ``s̄^B`` (metres).
        height: ``(B,)`` ``h_B`` (metres).
        skeleton: ``(B, 66)`` ``s̄^B / h_B`` flattened.
        geometry: ``(B, G)`` ``e^B``.
    """

    offsets: Tensor
    height: Tensor
    skeleton: Tensor
    geometry: Tensor


class DecoderState(NamedTuple):
    """The decoder's recurrent state before frame ``t``.

    Attributes:
        hidden: ``(layers, B, H)`` ``h^dec_(t−1)``.
        local_positions: ``(B, 22, 3)`` ``p^B_(t−1)`` (metres).
        root_velocity: ``(B, 3)`` ``o^B_(t−1)`` (metres per frame); ESO optimises it (Eq. 11).
        root_position: ``(B, 3)`` ``r^B_(t−1)``; frame ``t``'s root is ``root_position +
            root_velocity``.
        global_rotations: ``(B, 22, 4)`` frame ``t−1``'s global joint rotations (FK), kept for
            skinning; the global joints are ``local_positions + root_position``.
    """

    hidden: Tensor
    local_positions: Tensor
    root_velocity: Tensor
    root_position: Tensor
    global_rotations: Tensor

    def next_root(self) -> Tensor:
        """``r^B_t = r^B_(t−1) + o^B_(t−1)`` (Eq. 18), ``(B, 3)``."""
        return self.root_position + self.root_velocity


class DecoderGates(NamedTuple):
    """:meth:`GeometryConditionedRNN.decoder_gates`: the gate products of one decoder step that do
    not depend on ``h^enc_t`` or ``o^B_(t−1)``.

    Attributes:
        input0: ``(B, 3H)`` layer 0's ``W_ih x + b_ih`` over the inputs ``p^B_(t−1)``, ``s̄^B``,
            ``e^B``.
        hidden: ``(layers, B, 3H)`` every layer's ``W_hh h^dec_(t−1) + b_hh``.
    """

    input0: Tensor
    hidden: Tensor


def gru_update(gi: Tensor, gh: Tensor, h: Tensor) -> Tensor:
    """A GRU cell's new state from its gate products (the formula of :class:`torch.nn.GRUCell`).

    ``r = σ(i_r + h_r)``, ``z = σ(i_z + h_z)``, ``n = tanh(i_n + r ⊙ h_n)``, ``h' = (1 − z) ⊙ n + z
    ⊙ h``.

    Args:
        gi: ``(B, 3H)`` ``W_ih x + b_ih``, gates in the order r, z, n.
        gh: ``(B, 3H)`` ``W_hh h + b_hh``.
        h: ``(B, H)`` the previous state.

    Returns:
        ``(B, H)``.
    """
    i_r, i_z, i_n = gi.chunk(3, dim=-1)
    h_r, h_z, h_n = gh.chunk(3, dim=-1)
    r = torch.sigmoid(i_r + h_r)
    z = torch.sigmoid(i_z + h_z)
    n = torch.tanh(i_n + r * h_n)
    return n + z * (h - n)


class PosedOutput(NamedTuple):
    """:func:`pose_outputs`: global joints ``g`` ``(B, T, 22, 3)``, their rotations ``(B, T, 22,
    4)`` (for skinning) and the root trajectory ``(B, T, 3)``, metres."""

    positions: Tensor
    global_rotations: Tensor
    root_positions: Tensor


def pose_outputs(
    rotations: Tensor,
    root_velocity: Tensor,
    offsets: Tensor | np.ndarray,
    parents: Sequence[int] = CANONICAL22_PARENTS,
    start: Tensor | None = None,
) -> PosedOutput:
    """The FK layer (Eq. 15) with the integrated root (Eq. 18): ``r_t = start + Σ_(k<t) o_k``.

    Args:
        rotations: ``(B, T, 22, 4)`` local unit wxyz.
        root_velocity: ``(B, T, 3)`` ``o_t`` (frame ``t`` → ``t + 1``), metres per frame.
        offsets: ``(22, 3)`` or ``(B, 22, 3)`` target rest offsets.
        parents: joint parents.
        start: ``(B, 3)`` or ``(3,)`` root position of frame 0 (default: the origin).

    Returns:
        :class:`PosedOutput`.
    """
    b = rotations.shape[0]
    off = batched_offsets(
        torch.as_tensor(offsets, dtype=rotations.dtype, device=rotations.device), b
    )
    steps = torch.cumsum(root_velocity, dim=1) - root_velocity  # exclusive: Σ_(k<t) o_k
    if start is not None:
        steps = steps + torch.as_tensor(
            start, dtype=rotations.dtype, device=rotations.device
        ).reshape(-1, 1, 3)
    pos, grot = forward_kinematics(rotations, off.unsqueeze(1), parents, steps)
    return PosedOutput(pos, grot, steps)
