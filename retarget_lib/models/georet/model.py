"""The geometry-conditioned RNN (Villegas et al. 2021, Eqs. 12-19) and its residual variant
(ours)."""

from __future__ import annotations

from collections.abc import Sequence

import torch
from torch import nn
from torch.nn import functional as F

from ...core.kinematics import align_local_rotations, forward_kinematics
from ...core.rotations import matrix_from_6d, matrix_to_quat, quat_identity
from ...core.skeleton import CANONICAL22, CANONICAL22_PARENTS, J
from ..compiling import compile_frame_step
from ..features import batched_offsets
from .parts import (
    NUM_JOINTS,
    DecoderGates,
    DecoderState,
    GeoRetOutput,
    PointNetEncoder,
    ResidualBase,
    TargetContext,
    Tensor,
    _heights,
    gru_update,
)

__all__ = ["GeometryConditionedRNN"]


IDENTITY = (1.0, 0.0, 0.0, 0.0)  # wxyz

#: the joints a ``lower_body_from_base`` network leaves as its base: the hips (the root's rotation)
#: and both legs. Measured with the residual network trained with them free, on 12 pairs of the
#: Mixamo-convention contact table (scratch, issue 24): its output with these joints and the root
#: path swapped for copy's had 1.07x copy's global position error (the network's own: 2.5x) at the
#: same interpenetration (0.99 against 1.02; copy 8.0), and better foot contacts (0.996 against
#: 0.943); the legs and root it learned made every foot measure worse than its base on the synthetic
#: Table 1 and the real-character table too.
LOWER_BODY: tuple[int, ...] = (J["Hips"],) + tuple(
    J[n]
    for n in CANONICAL22
    if n.startswith(("Left", "Right")) and ("Leg" in n or "Foot" in n or "Toe" in n)
)


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
        lower_body_from_base: (``residual`` only; ours) the hips' rotation, the legs and the root
            path are the base's (the rest-compensated copy and the leg-scaled root): the network,
            and ESO through it, correct the spine, neck, head and arms only (see
            :data:`LOWER_BODY`).
        root_residual: (paper form only; ours) the velocity head's output is added to
            ``o^(A→B)``, the source's root velocity times the leg ratio (the base's
            ``root_velocity``), as the residual variant's is and as the NKN Baseline's root steps
            are (``model.root_residual`` of :class:`~retarget_lib.models.nkn.NKNGenerator`): a head
            predicting the velocity outright drifts on the capacity check (a source standing still
            walks off: docs/reproduction.md, section 5). The rotations stay the paper's.
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
        lower_body_from_base: bool = False,
        root_residual: bool = False,
    ):
        super().__init__()
        self.residual = bool(residual)
        if lower_body_from_base and not self.residual:
            raise ValueError("lower_body_from_base needs a residual network (its base)")
        if root_residual and self.residual:
            raise ValueError(
                "root_residual is for the paper form: a residual network already adds o^(A→B)"
            )
        self.root_residual = bool(root_residual)
        self.lower_body_from_base = bool(lower_body_from_base)
        fixed = torch.zeros(joints, 1, dtype=torch.bool)
        if self.lower_body_from_base:
            fixed[list(LOWER_BODY)] = True
        self.register_buffer("_fixed_joints", fixed, persistent=False)
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
        if self.residual or self.root_residual:
            if base is None:
                raise ValueError(
                    "a residual or root_residual GeometryConditionedRNN needs the frame's base "
                    "(a ResidualBase)"
                )
            if self.lower_body_from_base:  # residual implied; these joints are the base's
                rotations = torch.where(
                    self._fixed_joints, rotations.new_tensor(IDENTITY), rotations
                )
                velocity = torch.zeros_like(velocity)
            if self.residual:
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
