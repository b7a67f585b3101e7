"""The geometry-conditioned RNN of Villegas et al. 2021 (Sec. 3.2, Fig. 3, App. B, Eqs. 12-19).

Per frame ``t``::

    h^enc_t = f_enc(m^A_t, h^enc_(t−1))                                  (12)  2-layer GRU, 512
    h^dec_t = f_dec([h^enc_t, p^B_(t−1), o^B_(t−1), s̄^B, e^B], h^dec_(t−1)) (13)  2-layer GRU, 512
    θ^B_t   = f_θ(h^dec_t)                                               (14)  linear → 6D → wxyz
    p^B_t   = FK(θ^B_t, s̄^B)                                             (15)  root-relative joints
    o^B_t   = f_o(h^dec_t)                                               (17)  linear, root velocity
    g^B_t   = p^B_t + r^B_t,   r^B_t = r^B_(t−1) + o^B_(t−1)              (18)
    e^B     = max_v f_vert([v̄^B_v, w^B_v])                               (19)  PointNet

Choices the paper leaves open (decided here):

* **Input** ``m^A_t ∈ R^267`` (:func:`motion_features`): the source's joint positions relative to
  the root (FK with the root at the origin, the root's rotation applied; 22×3), its local
  rotations as row-major 3×3 matrices (22×9) and its root velocity
  ``o^A_t = r_(t+1) − r_t`` (3; :func:`~retarget_lib.core.quantities.forward_root_velocity`).
  Positions and velocity are divided by the source height ``h_A`` (NKN/TDCN ``H``).
* **Scale.** Everything the decoder sees about the target is divided by ``h_B``: ``p^B_(t−1)``,
  ``o^B_(t−1)``, the rest offsets ``s̄^B`` (all 22 rows, the root row being the hips' rest
  position) and the vertices of the PointNet input; ``f_o`` predicts ``o^B / h_B``. One model
  therefore serves characters of any height (1.2-2.1 m in our data).
* **PointNet input** (:func:`normalize_rest_vertices`): rest vertices centred on the mesh's
  bounding-box footprint (x, z centre, lowest y: :func:`~retarget_lib.core.measures.mesh_ground`)
  and divided by the mesh's standing height (its bounding-box y extent,
  :func:`~retarget_lib.core.measures.mesh_standing_height`), concatenated with the 22 skinning
  weights. Both the normalisation and
  the max-pool ignore vertex order and duplicates, so meshes of different sizes can be batched by
  repeating vertices (:func:`batch_meshes`).
* **Rotations.** ``f_θ`` outputs the continuous 6D representation (Zhou et al. 2019), turned into
  a rotation matrix by Gram-Schmidt and then into a unit ``w ≥ 0`` quaternion; its bias starts at
  the identity (output = rest pose).
* **Root trajectory.** ``o^B_t`` is the displacement from frame ``t`` to ``t + 1``, so frame
  ``t``'s root is ``r^B_t = r^B_0 + Σ_(k<t) o^B_k`` with a caller-given start ``r^B_0``
  (:func:`pose_outputs`; e.g. the source's first root position times the leg ratio). The step API
  carries ``(p_(t−1), o_(t−1), r_(t−1))`` in :class:`DecoderState`; before frame 0 they are the
  target's rest pose, zero and the start, so frame 0 sits at the start.
* **Dropout** (0.1, App. B.1) acts between the stacked GRU layers of both RNNs.

FK and skinning are not part of the module: callers use :func:`pose_outputs` (FK + root
integration) and :func:`retarget_lib.core.skinning.linear_blend_skinning` with its global rotations.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
import torch
from torch import nn
from torch.nn import functional as F

from ..core.kinematics import align_local_rotations, forward_kinematics
from ..core.measures import mesh_ground, mesh_standing_height, nkn_height
from ..core.quantities import forward_root_velocity
from ..core.rotations import matrix_from_6d, matrix_to_quat, quat_identity, quat_to_matrix
from ..core.skeleton import CANONICAL22_PARENTS
from .compiling import compile_frame_step
from .features import batched_offsets

Tensor = torch.Tensor

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
    "GeometryConditionedRNN",
    "motion_features",
    "normalize_rest_vertices",
    "batch_meshes",
    "pose_outputs",
]

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


class GeometryConditionedRNN(nn.Module):
    """Geometry-conditioned encoder-decoder RNN (Villegas et al. 2021, Sec. 3.2, App. B).

    Args:
        joints: ``J`` (22).
        hidden: GRU width of encoder and decoder (App. B.1: 512).
        layers: stacked GRU layers of each RNN (2).
        geometry: PointNet width / embedding size (256).
        dropout: between stacked GRU layers (0.1).
        parents: joint parents for FK.
        residual: our variant (not the paper's): the rotation head predicts per-joint alignments
            ``C_j`` and the output is ``θ^B_j = C_p⁻¹ θ^A_j C_j``
            (:func:`~retarget_lib.core.kinematics.align_local_rotations`), the velocity head a
            correction of ``o^(A→B)``; both start at exactly no change (biases at the identity,
            head weights zero, as the last layer of a residual branch is usually initialised), so
            the untrained network *is* its base, the rest-compensated copy (Eweak = 0). The
            paper-form heads start small (weights scaled by 0.01). Needs a :class:`ResidualBase` in
            every call.
    """

    def __init__(
        self,
        joints: int = NUM_JOINTS,
        hidden: int = 512,
        layers: int = 2,
        geometry: int = 256,
        dropout: float = 0.1,
        parents: Sequence[int] = CANONICAL22_PARENTS,
        residual: bool = False,
    ):
        super().__init__()
        self.residual = bool(residual)
        if joints != len(parents):
            raise ValueError(f"{joints} joints but {len(parents)} parents")
        self.joints, self.hidden, self.layers = joints, hidden, layers
        self.parents = tuple(parents)
        in_features = 12 * joints + 3
        self.encoder = nn.GRU(
            in_features, hidden, layers, batch_first=True, dropout=dropout if layers > 1 else 0.0
        )
        self.pointnet = PointNetEncoder(3 + joints, geometry)
        dec_in = hidden + 3 * joints + 3 + 3 * joints + geometry
        self.decoder = nn.ModuleList(
            [nn.GRUCell(dec_in if i == 0 else hidden, hidden) for i in range(layers)]
        )
        self.dropout = nn.Dropout(dropout)
        self.rotation_head = nn.Linear(hidden, 6 * joints)  # f_θ, 6D per joint
        self.velocity_head = nn.Linear(hidden, 3)  # f_o, o^B / h_B
        with (
            torch.no_grad()
        ):  # residual: heads at exactly zero, so the untrained network is its base
            for head in (self.rotation_head, self.velocity_head):
                head.weight.mul_(0.0 if self.residual else 0.01)
            self.rotation_head.bias.copy_(torch.tensor([1.0, 0, 0, 0, 1.0, 0]).repeat(joints))
            self.velocity_head.bias.zero_()

    # ------------------------------------------------------------------ step API (ESO)
    def encode(self, source: Tensor) -> Tensor:
        """``h^enc`` for every frame (Eq. 12).

        Args:
            source: ``(B, T, 267)`` :func:`motion_features` of the source.

        Returns:
            ``(B, T, hidden)`` top-layer encoder states.
        """
        if source.dim() != 3 or source.shape[-1] != self.encoder.input_size:
            raise ValueError(
                f"source must be (B, T, {self.encoder.input_size}), got {tuple(source.shape)}"
            )
        return self.encoder(source)[0]

    def geometry(self, vertices: Tensor, weights: Tensor) -> Tensor:
        """``e^B`` (Eq. 19) of ``(B, V, 3)`` rest vertices (metres) and ``(B, V, 22)`` weights →
        ``(B, G)``."""
        return self.pointnet(vertices, weights)

    def target_context(
        self,
        offsets: Tensor,
        vertices: Tensor,
        weights: Tensor,
        height: float | Tensor | None = None,
    ) -> TargetContext:
        """The decoder's per-sequence inputs ``s̄^B / h_B`` and ``e^B``.

        Args:
            offsets: ``(B, 22, 3)`` or ``(22, 3)`` target rest offsets (metres).
            vertices: ``(B, V, 3)`` target rest vertices (metres).
            weights: ``(B, V, 22)`` skinning weights.
            height: ``h_B`` (default :func:`~retarget_lib.core.measures.nkn_height`).
        """
        b = vertices.shape[0]
        dtype = self.rotation_head.weight.dtype
        off = batched_offsets(torch.as_tensor(offsets, dtype=dtype, device=vertices.device), b)
        h = _heights(height, off)
        skel = (off / h.view(b, 1, 1)).reshape(b, 3 * self.joints)
        return TargetContext(off, h, skel, self.geometry(vertices.to(dtype), weights.to(dtype)))

    def initial_state(self, context: TargetContext, start: Tensor | None = None) -> DecoderState:
        """State before frame 0: zero hidden, rest-pose ``p``, zero ``o``, root at ``start``.

        Args:
            context: :meth:`target_context`.
            start: ``(B, 3)`` or ``(3,)`` frame 0's root position (default: origin).
        """
        off = context.offsets
        b = off.shape[0]
        identity = quat_identity((b, self.joints), off.dtype, off.device)
        rest = forward_kinematics(identity, off, self.parents, None).positions
        root = (
            off.new_zeros(b, 3)
            if start is None
            else torch.as_tensor(start, dtype=off.dtype).expand(b, 3)
        )
        return DecoderState(
            off.new_zeros(self.layers, b, self.hidden), rest, off.new_zeros(b, 3), root, identity
        )

    def compile_decoder(self) -> None:
        """Compile :meth:`decode_step` with ``torch.compile`` (inductor; needs a C++ compiler on the
        CPU).

        One frame of the decoder is a few hundred small tensor operations (two GRU cells, the 6D
        rotation head, the residual alignment, FK by depth level), run ``T`` times per clip, so the
        eager step is dominated by per-operation overhead; compiled, they fuse into a few kernels.
        Measured on the fast contact training step of ``contact_residual`` (idle 2-core machine):
        0.91 → 0.55 s per step with 2 threads, 1.02 → 0.75 s with 1 (``retarget bench --only
        contact-training``), after a one-off compilation of about a minute (cached on disk by
        inductor afterwards). The weights,
        the ``state_dict`` and the checkpoints are the same modules either way.
        """
        self.decode_step = compile_frame_step(self.decode_step)

    def decoder_gates(self, state: DecoderState, context: TargetContext) -> DecoderGates:
        """The parts of a decoder step (Eq. 13) that ``h^enc_t`` and ``o^B_(t−1)`` do not change.

        A GRU layer's gates are sums of an input product ``W_ih x + b_ih`` and a hidden product
        ``W_hh h + b_hh``. Of layer 0's input ``x = [h^enc_t, p^B_(t−1), o^B_(t−1), s̄^B, e^B]``
        only ``h^enc_t`` and ``o^B_(t−1)`` vary while ESO optimises one frame (Eq. 11), and no
        layer's ``h^dec_(t−1)`` does, so those products are computed once per frame: about two
        thirds of the decoder's multiply-adds.

        Args:
            state: :class:`DecoderState` before frame ``t``.
            context: :meth:`target_context`.

        Returns:
            :class:`DecoderGates`.
        """
        b = state.hidden.shape[1]
        cell = self.decoder[0]
        _, positions, _, rest = self._input_columns()
        fixed = torch.cat((context.skeleton, context.geometry), dim=-1)
        input0 = F.linear(
            state.local_positions.reshape(b, -1) / context.height.view(b, 1),
            cell.weight_ih[:, positions],
        ) + F.linear(fixed, cell.weight_ih[:, rest], cell.bias_ih)
        hidden = torch.stack(
            [F.linear(state.hidden[i], c.weight_hh, c.bias_hh) for i, c in enumerate(self.decoder)]
        )
        return DecoderGates(input0, hidden)

    def _input_columns(self) -> tuple[slice, slice, slice, slice]:
        """Layer 0's input columns of ``h^enc_t``, ``p^B_(t−1)``, ``o^B_(t−1)`` and ``[s̄^B,
        e^B]``."""
        h, p = self.hidden, 3 * self.joints
        return slice(0, h), slice(h, h + p), slice(h + p, h + p + 3), slice(h + p + 3, None)

    def decode_step(
        self,
        h_enc: Tensor,
        state: DecoderState,
        context: TargetContext,
        base: ResidualBase | None = None,
        gates: DecoderGates | None = None,
    ) -> tuple[Tensor, Tensor, DecoderState]:
        """One decoder step (Eqs. 13-15, 17-18).

        Args:
            h_enc: ``(B, hidden)`` ``h^enc_t``.
            state: :class:`DecoderState` before frame ``t``.
            context: :meth:`target_context`.
            base: frame ``t`` of the :class:`ResidualBase` (``residual`` models only).
            gates: :meth:`decoder_gates` of ``state`` and ``context`` when the caller keeps them
                (ESO: once per frame); computed here otherwise. ``state.root_velocity`` may differ
                from the one they were computed with: they do not depend on it.

        Returns:
            ``(θ_t (B, 22, 4) unit wxyz, o_t (B, 3) metres per frame, state after frame t)``; the
            new state's ``root_position`` is frame ``t``'s root ``r_t``.
        """
        b = h_enc.shape[0]
        h = context.height.view(b, 1)
        gates = self.decoder_gates(state, context) if gates is None else gates
        encoder, _, velocity_in, _ = self._input_columns()
        w0 = self.decoder[0].weight_ih
        gi = (
            gates.input0
            + F.linear(h_enc, w0[:, encoder])
            + F.linear(state.root_velocity / h, w0[:, velocity_in])
        )
        hidden: list[Tensor] = []
        for i, cell in enumerate(self.decoder):
            if hidden:
                gi = F.linear(self.dropout(hidden[-1]), cell.weight_ih, cell.bias_ih)
            hidden.append(gru_update(gi, gates.hidden[i], state.hidden[i]))
        x = hidden[-1]
        rotations = matrix_to_quat(matrix_from_6d(self.rotation_head(x).view(b, self.joints, 6)))
        velocity = self.velocity_head(x) * h
        if self.residual:
            if base is None:
                raise ValueError(
                    "a residual GeometryConditionedRNN needs the ResidualBase of the frame"
                )
            rotations = align_local_rotations(
                base.rotations.to(rotations.dtype), rotations, self.parents
            )
            velocity = velocity + base.root_velocity.to(velocity.dtype)
        local, global_rotations = forward_kinematics(rotations, context.offsets, self.parents, None)
        return (
            rotations,
            velocity,
            DecoderState(torch.stack(hidden), local, velocity, state.next_root(), global_rotations),
        )

    # ------------------------------------------------------------------ whole sequences
    def forward(
        self,
        source_features: Tensor,
        target_offsets: Tensor,
        target_vertices: Tensor,
        target_weights: Tensor,
        target_height: float | Tensor | None = None,
        base: ResidualBase | None = None,
    ) -> GeoRetOutput:
        """Retarget a batch of clips (Eqs. 12-19), decoding frame by frame.

        Args:
            source_features: ``(B, T, 267)`` :func:`motion_features` of the source.
            target_offsets: ``(B, 22, 3)`` or ``(22, 3)`` target rest offsets (metres).
            target_vertices: ``(B, V, 3)`` target rest vertices (metres), any ``V``.
            target_weights: ``(B, V, 22)`` skinning weights.
            target_height: ``h_B`` (default from the offsets).
            base: the :class:`ResidualBase` (``residual`` models only).

        Returns:
            :class:`GeoRetOutput`; global joints via :func:`pose_outputs`.
        """
        h_enc = self.encode(source_features)
        context = self.target_context(
            target_offsets, target_vertices, target_weights, target_height
        )
        state = self.initial_state(context)
        rots, vels, locs = [], [], []
        for t in range(h_enc.shape[1]):  # autoregressive: needs p_(t−1), o_(t−1)
            rot, vel, state = self.decode_step(
                h_enc[:, t], state, context, None if base is None else base.frame(t)
            )
            rots.append(rot)
            vels.append(vel)
            locs.append(state.local_positions)
        return GeoRetOutput(
            torch.stack(rots, 1), torch.stack(vels, 1), torch.stack(locs, 1), context.geometry
        )
