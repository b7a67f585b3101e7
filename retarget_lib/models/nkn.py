"""The NKN baselines of TDCN's Table 4 (Villegas, Yang, Ceylan, Lee: "Neural Kinematic Networks for
Unsupervised Motion Retargetting", CVPR 2018), as summarised in TDCN Secs. 2, 4.1 and 6.

Generator (:class:`NKNGenerator`, "Baseline")::

    encoder GRU  over  x_t = [p_t (3J), v_t (3)]                   source, per frame
    decoder GRU  sees  [h_enc_t, s̄B (3J), p̂_{t-1} (3J), v̂_{t-1} (3)]  (zeros at t = 1)
    linear       →     q̂_t (J×4, raw) and v̂_t (3)
    FK           p̂_t = f_FK(normalise(q̂_t), s̄B)  (fed back to the next step)
    root         r̂_t = r̂_0 + Σ_{k<=t} v̂_k

``v_t = r_t - r_{t-1}`` (``v_1 = 0``) is the root *offset* per frame. Because NKN predicts offsets
and integrates them, root errors accumulate over long clips — the reason TDCN gives for the
baselines' degradation on long sequences (Sec. 6.1). The start point ``r̂_0`` is the source's
first root position scaled by the leg ratio ``h_legs_B / h_legs_A``
(:func:`~retarget_lib.core.measures.leg_length`; NKN leaves the first frame's placement to the
data; this choice puts it where the ground truth, which scales the root path by the leg ratio,
starts).

Variants (Sec. 6, all with ``backbone`` / ``normalize_root``):

* ``Baseline``          — ``backbone="gru"``.
* ``Baseline-dense``    — ``backbone="dense"``: encoder and decoder GRUs replaced by dense
  convolution stacks (:class:`~retarget_lib.models.tdcn.DilatedStack` with ``dense=True``, the
  A1 construction, 81-frame receptive field each).
* ``Baseline-dilated``  — ``backbone="dilated"``: the GRUs replaced by TDCNs (the same
  ``DilatedStack`` as the generator, dilations 3, 9, 27).
  A convolutional decoder computes every frame in parallel, so it cannot see its own previous
  output: the conv decoders see ``[encoder features, s̄B]`` only.
* ``Baseline-height``   — same network as Baseline plus TDCN's height loss ``L_h`` "where the
  root-position offsets are normalized" (Sec. 6): ``normalize_root=True`` feeds ``v_t / H(s̄A)``
  and the network predicts ``v̂_t / H(s̄B)`` (multiplied back by ``H(s̄B)`` before integration);
  ``height_loss=True`` tells the training code to add ``L_h``.

Discriminator (:class:`NKNDiscriminator`): NKN's discriminator scores the *whole* sequence with
a sigmoid cross-entropy loss (TDCN Sec. 4.1/4.2: "the entire sequence of motions was input to the
discriminator", inputs not height-normalised). Kept simple here: strided 1D convs
(k=4, stride 2, widths 32-64-128-256, LeakyReLU 0.2, BatchNorm from the second layer, as in the
public NKN ports) over ``[p_t - p_{t-1} (3J), v_t (3), s̄ (3(J-1))]`` in metres (the skeleton
condition is concatenated to the input rather than to every hidden layer), then a mean over time
and a linear layer → one logit per clip. The sigmoid cross-entropy belongs to the loss code.
"""

from __future__ import annotations

from collections.abc import Sequence

import torch
from torch import nn

from ..core.kinematics import forward_kinematics
from ..core.measures import leg_length, nkn_height
from ..core.skeleton import CANONICAL22_PARENTS
from .compiling import compile_frame_step
from .features import (
    NUM_JOINTS,
    FeatureNormalizer,
    batched_offsets,
    from_facing_frame,
    hip_facing,
    nkn_input_channels,
    nkn_source_features,
    positions_in_frame,
    root_velocities,
    source_local_positions,
)
from .tdcn import (
    DEFAULT_SLOPE,
    DilatedStack,
    GeneratorOutput,
    edge_pad,
    init_identity_head,
    normalize_quaternions,
)

Tensor = torch.Tensor

__all__ = [
    "NKNGenerator",
    "NKNDiscriminator",
    "nkn_discriminator_features",
    "NKN_BACKBONES",
    "NKN_ROOT_FRAMES",
    "NKN_ROOT_HEIGHTS",
]

NKN_BACKBONES = ("gru", "dense", "dilated")
NKN_ROOT_FRAMES = ("world", "facing")
NKN_ROOT_HEIGHTS = ("step", "floor")


class NKNGenerator(nn.Module):
    """Encoder-decoder retargeting network of Villegas et al. 2018 and its Table 4 variants.

    Args:
        hidden: GRU hidden size / conv width (NKN: 512).
        backbone: ``"gru"`` (Baseline), ``"dense"`` (Baseline-dense) or ``"dilated"``
            (Baseline-dilated).
        num_layers: stacked GRU layers per RNN (GRU backbone only).
        normalize_root: root offsets divided by the character height (Baseline-height).
        root_frame: ``"world"`` (root offsets in world axes) or ``"facing"``: in and out in each
            frame's facing frame (:func:`~retarget_lib.models.features.to_facing_frame`, from the
            source's hips; the target keeps the source's heading), so a walk is the same numbers
            whichever way it heads (the authors' code; audit N1).
        root_height: ``"step"`` (NKN: the vertical root offset is predicted and integrated like
            the horizontal ones) or ``"floor"``: the vertical channel carries the root's height
            over the floor in leg lengths, in (``r_y / h_legs(s̄A)``) and out (added to the
            source's: ``r̂_y = (r_y / h_legs(s̄A) + out_y) · h_legs(s̄B)``), so the height cannot
            drift over a long clip (audit N1, docs/reproduction.md).
        standardized_root: the root head outputs z-scores: its three channels are multiplied by the
            input normalizer's std of the same three root channels (needs ``normalize_inputs``;
            the authors' code de-standardises its root output with the data's std). In metres the
            head's steps are 1-2 cm a frame, the size of one Adam update of its weights (audit N8).
        root_residual: the head's root steps are added to the source's steps times the leg ratio
            ``h_legs(s̄B) / h_legs(s̄A)`` (in the model's root frame; with ``root_height="floor"``
            the horizontal ones), as ``"floor"`` does for the height: an untrained head gives
            the ground truth's root rule and the network learns the corrections. Ours, not the
            authors' (audit N1, docs/reproduction.md): their network predicts the steps outright,
            and under this machine's budget ours regresses them to the mean (0.36 cm a frame
            forward for a source that stands still).
        positions_frame: the axes of the joint positions the encoder reads and the GRU decoder
            feeds back (:data:`~retarget_lib.models.features.POSITION_FRAMES`): ``"world"`` (the
            root's rotation applied, as TDCN's Eq. 1) or ``"facing"`` (each frame's facing frame,
            the authors' code; audit N4).
        height_loss: flag for the training code: add TDCN's ``L_h`` (Baseline-height).
        dropout: dropout (GRU: on the decoder input and between stacked layers; conv: after
            every layer). Default 0 for the GRU, 0.1 for the conv backbones (TDCN's rate).
        dilations: block dilations of the conv backbones.
        num_joints: ``J``.
        parents: skeleton parents.

    Attributes:
        normalizer: :class:`~retarget_lib.models.features.FeatureNormalizer` on the encoder input
            (identity unless fitted).
    """

    def __init__(
        self,
        hidden: int = 512,
        backbone: str = "gru",
        num_layers: int = 1,
        normalize_root: bool = False,
        root_frame: str = "world",
        root_height: str = "step",
        standardized_root: bool = False,
        root_residual: bool = False,
        positions_frame: str = "world",
        height_loss: bool = False,
        dropout: float | None = None,
        dilations: Sequence[int] = (3, 9, 27),
        num_joints: int = NUM_JOINTS,
        parents: Sequence[int] = CANONICAL22_PARENTS,
        slope: float = DEFAULT_SLOPE,
    ):
        super().__init__()
        if backbone not in NKN_BACKBONES:
            raise ValueError(f"backbone must be one of {NKN_BACKBONES}, got {backbone!r}")
        self.backbone, self.hidden, self.num_joints = backbone, hidden, num_joints
        self.parents = tuple(parents)
        if root_frame not in NKN_ROOT_FRAMES:
            raise ValueError(f"root_frame must be one of {NKN_ROOT_FRAMES}, got {root_frame!r}")
        self.normalize_root, self.height_loss = bool(normalize_root), bool(height_loss)
        self.root_frame = root_frame
        if positions_frame not in ("world", "facing"):
            raise ValueError(f"positions_frame must be world or facing, got {positions_frame!r}")
        self.positions_frame = positions_frame
        if root_height not in NKN_ROOT_HEIGHTS:
            raise ValueError(f"root_height must be one of {NKN_ROOT_HEIGHTS}, got {root_height!r}")
        self.root_height = root_height
        self.standardized_root = bool(standardized_root)
        self.root_residual = bool(root_residual)
        dropout = (0.0 if backbone == "gru" else 0.1) if dropout is None else float(dropout)
        c_in, c_skel, c_out = nkn_input_channels(num_joints), 3 * num_joints, 4 * num_joints + 3
        self.normalizer = FeatureNormalizer(c_in)
        if backbone == "gru":
            self.encoder = nn.GRU(
                c_in,
                hidden,
                num_layers,
                batch_first=True,
                dropout=dropout if num_layers > 1 else 0.0,
            )
            dec_in = hidden + c_skel + 3 * num_joints + 3
            self.decoder = nn.ModuleList(
                [nn.GRUCell(dec_in if i == 0 else hidden, hidden) for i in range(num_layers)]
            )
            self.dropout = nn.Dropout(dropout) if dropout > 0 else nn.Identity()
        else:
            dense = backbone == "dense"
            self.encoder = DilatedStack(
                c_in, hidden, dilations, dropout=dropout, dense=dense, slope=slope
            )
            self.decoder = DilatedStack(
                hidden + c_skel, hidden, dilations, dropout=dropout, dense=dense, slope=slope
            )
        self.out = nn.Linear(hidden, c_out)
        init_identity_head(self.out, num_joints)

    @property
    def receptive_field(self) -> int | None:
        """Frames seen per output: ``None`` (unbounded) for the GRU, else encoder + decoder."""
        if self.backbone == "gru":
            return None
        return self.encoder.receptive_field + self.decoder.receptive_field - 1

    def forward(
        self,
        rotations: Tensor,
        root_positions: Tensor,
        offsets_src: Tensor,
        offsets_tgt: Tensor,
        positions: Tensor | None = None,
    ) -> GeneratorOutput:
        """Retarget with raw outputs (for training).

        Args:
            rotations: ``(B, T, J, 4)`` source local quaternions (wxyz).
            root_positions: ``(B, T, 3)`` source root positions.
            offsets_src: ``(B, J, 3)`` or ``(J, 3)`` source rest offsets.
            offsets_tgt: ``(B, J, 3)`` or ``(J, 3)`` target rest offsets.
            positions: optional precomputed source ``p`` ``(B, T, J, 3)``.

        Returns:
            :class:`~retarget_lib.models.tdcn.GeneratorOutput`: raw q̂ ``(B, T, J, 4)``, r̂
            ``(B, T, 3)`` = ``r̂_0 + cumsum(v̂)``, and the predicted offsets v̂ ``(B, T, 3)`` in
            metres per frame (with ``root_height="floor"``: ``r̂_y`` as above and ``v̂_y`` its
            per-frame steps, 0 at the first frame).
        """
        b, t, j, _ = rotations.shape
        off_src = batched_offsets(offsets_src.to(rotations.dtype), b)
        off_tgt = batched_offsets(offsets_tgt.to(rotations.dtype), b)
        if positions is None:
            positions = source_local_positions(rotations, off_src, self.parents)
        h_tgt = nkn_height(off_tgt)
        facing = hip_facing(positions) if self.root_frame == "facing" else None
        x = self.normalizer(self.source_features(positions, root_positions, off_src, facing))
        if self.backbone == "gru":
            q, v = self._decode_gru(x, off_tgt)
        else:
            q, v = self._decode_conv(x, off_tgt)
        if self.standardized_root:  # z-scores of the root channels -> their units
            v = v * self.normalizer.std[-3:]
        leg_src, leg_tgt = leg_length(off_src).view(b, 1), leg_length(off_tgt).view(b, 1)
        height = None
        if self.root_height == "floor":  # the vertical channel is a height, not a step
            height = (v[..., 1] + root_positions[..., 1] / leg_src) * leg_tgt
            v = v * v.new_tensor([1.0, 0.0, 1.0])
        if self.normalize_root:
            v = v * h_tgt.view(b, 1, 1)
        if self.root_residual:  # on the source's steps in the same frame, scaled by the legs
            steps = root_velocities(root_positions, facing)
            if height is not None:
                steps = steps * steps.new_tensor([1.0, 0.0, 1.0])
            v = v + steps * (leg_tgt / leg_src).view(b, 1, 1)
        if facing is not None:
            v = from_facing_frame(v, facing)
        path = (root_positions[:, 0] * (leg_tgt / leg_src)).unsqueeze(1) + v.cumsum(1)
        if height is not None:
            path = torch.stack((path[..., 0], height, path[..., 2]), -1)
            v = torch.stack((v[..., 0], root_velocities(path)[..., 1], v[..., 2]), -1)
        return GeneratorOutput(q, path, v)

    generate = forward

    def source_features(
        self,
        positions: Tensor,
        root_positions: Tensor,
        offsets_src: Tensor,
        facing: Tensor | None = None,
    ) -> Tensor:
        """The encoder input before the normaliser (:func:`nkn_source_features` with this model's
        root options).

        Args:
            positions: ``(B, T, J, 3)`` source ``p``.
            root_positions: ``(B, T, 3)``.
            offsets_src: ``(B, J, 3)`` source offsets.
            facing: ``(B, T, 2)`` (:func:`hip_facing` of ``positions``); computed when the model
                works in the facing frame and it is not given.

        Returns:
            ``(B, 3J + 3, T)``.
        """
        if self.root_frame == "facing" and facing is None:
            facing = hip_facing(positions)
        height = nkn_height(offsets_src) if self.normalize_root else None
        floor = None
        if self.root_height == "floor":
            floor = root_positions[..., 1] / leg_length(offsets_src).view(-1, 1)
        p = positions_in_frame(positions, self.positions_frame)
        return nkn_source_features(p, root_positions, height, facing, floor)

    def _split(self, out: Tensor) -> tuple[Tensor, Tensor]:
        j = self.num_joints
        return out[..., : 4 * j].reshape(*out.shape[:-1], j, 4), out[..., 4 * j :]

    def _decode_conv(self, x: Tensor, off_tgt: Tensor) -> tuple[Tensor, Tensor]:
        b, _, t = x.shape
        enc = self.encoder(x)  # (B, H, T)
        skel = off_tgt.reshape(b, -1, 1).expand(b, off_tgt.shape[1] * 3, t)
        dec = self.decoder.forward_time_major(torch.cat([enc, skel], 1))  # (B, T, H)
        return self._split(self.out(dec))

    def _decode_gru(self, x: Tensor, off_tgt: Tensor) -> tuple[Tensor, Tensor]:
        b, _, t = x.shape
        j = self.num_joints
        enc, _ = self.encoder(x.transpose(1, 2))  # (B, T, H)
        skel = off_tgt.reshape(b, 3 * j)
        states = [x.new_zeros(b, self.hidden) for _ in self.decoder]
        prev = x.new_zeros(b, 3 * j + 3)  # p̂_{t-1}, v̂_{t-1}; zeros at t = 1 (as NKN)
        qs, vs = [], []
        for step in range(t):  # autoregressive: each step needs the previous FK output
            q, v, prev, states = self.decode_step(enc[:, step], skel, prev, states, off_tgt)
            qs.append(q)
            vs.append(v)
        return torch.stack(qs, 1), torch.stack(vs, 1)

    def decode_step(
        self,
        enc_t: Tensor,
        skel: Tensor,
        prev: Tensor,
        states: list[Tensor],
        off_tgt: Tensor,
    ) -> tuple[Tensor, Tensor, Tensor, list[Tensor]]:
        """One frame of the GRU decoder: stacked cells, the output head, FK of the new pose.

        Args:
            enc_t: ``(B, H)`` encoder output of this frame.
            skel: ``(B, 3J)`` flattened target offsets.
            prev: ``(B, 3J + 3)`` previous frame's ``p̂`` (root-relative, flattened) and ``v̂``.
            states: per decoder layer ``(B, H)``.
            off_tgt: ``(B, J, 3)`` target offsets.

        Returns:
            raw ``q̂ (B, J, 4)``, ``v̂ (B, 3)``, the next ``prev`` and the new states.
        """
        inp = self.dropout(torch.cat([enc_t, skel, prev], -1))
        new: list[Tensor] = []
        for i, cell in enumerate(self.decoder):
            new.append(cell(inp if i == 0 else self.dropout(new[i - 1]), states[i]))
        q, v = self._split(self.out(new[-1]))
        p = forward_kinematics(normalize_quaternions(q), off_tgt, self.parents, None).positions
        p = positions_in_frame(p, self.positions_frame)
        return q, v, torch.cat([p.reshape(p.shape[0], -1), v], -1), new

    def compile_decoder(self) -> None:
        """Compile :meth:`decode_step` with ``torch.compile`` (inductor; needs a C++ compiler on the
        CPU). The GRU backbone runs it once per frame, a few hundred small operations each (the
        cells, the head, FK joint by joint), so the eager step is dominated by per-operation
        overhead. The convolutional backbones have no per-frame loop: nothing to compile. Weights,
        ``state_dict`` and checkpoints are the same either way.

        Measured on the fast Baseline training step (idle 2-core machine, 2 threads, batch 16;
        ``retarget bench --only training``): 0.715 → 0.253 s per step (22.4 → 63.2 windows/s, 2.8x).
        A whole 2000-step Baseline run took 694 s including its compilation (8 s beyond the
        steps)."""
        if self.backbone != "gru":
            return
        self.decode_step = compile_frame_step(self.decode_step)

    def retarget(
        self,
        rotations: Tensor,
        root_positions: Tensor,
        offsets_src: Tensor,
        offsets_tgt: Tensor,
    ) -> tuple[Tensor, Tensor]:
        """Unit quaternions ``(B, T, J, 4)`` and root positions ``(B, T, 3)`` for the target.

        Args: as :meth:`forward`.
        """
        out = self.forward(rotations, root_positions, offsets_src, offsets_tgt)
        return normalize_quaternions(out.rotations), out.root_positions


def nkn_discriminator_features(
    positions: Tensor, root_positions: Tensor, offsets: Tensor
) -> Tensor:
    """NKN discriminator input: ``[p_t - p_{t-1}, r_t - r_{t-1}, s̄ (non-root rows)]`` in metres.

    Args:
        positions: ``(B, T, J, 3)`` root-relative joint positions.
        root_positions: ``(B, T, 3)``.
        offsets: ``(B, J, 3)`` or ``(J, 3)`` rest offsets of the performing skeleton.

    Returns:
        ``(B, 3J + 3 + 3(J-1), T-1)``.
    """
    b, t, j, _ = positions.shape
    off = batched_offsets(offsets.to(positions.dtype), b)
    d = positions.diff(dim=1).reshape(b, t - 1, 3 * j)
    v = root_velocities(root_positions)[:, 1:]
    skel = off[:, 1:].reshape(b, 1, -1).expand(b, t - 1, 3 * (j - 1))
    return torch.cat([d, v, skel], -1).transpose(1, 2)


class NKNDiscriminator(nn.Module):
    """Whole-clip discriminator of the NKN baseline (sigmoid cross-entropy on its logit).

    Args:
        in_channels: default ``3J + 3 + 3(J-1)`` (:func:`nkn_discriminator_features`).
        widths: channels of the strided conv layers.
        slope: LeakyReLU slope.

    Attributes:
        height_normalized_inputs: ``False`` (NKN does not height-normalise, TDCN Sec. 4.2 (ii)).
    """

    height_normalized_inputs = False

    def __init__(
        self,
        in_channels: int | None = None,
        widths: Sequence[int] = (32, 64, 128, 256),
        slope: float = DEFAULT_SLOPE,
        num_joints: int = NUM_JOINTS,
    ):
        super().__init__()
        self.in_channels = 6 * num_joints if in_channels is None else in_channels
        layers, c = [], self.in_channels
        for i, w in enumerate(widths):
            layers += [nn.Conv1d(c, w, 4, stride=2, padding=1, bias=i == 0)]
            if i > 0:
                layers.append(nn.BatchNorm1d(w))
            layers.append(nn.LeakyReLU(slope))
            c = w
        self.body = nn.Sequential(*layers)
        self.out = nn.Linear(c, 1)
        self.min_frames = 2 ** len(widths)

    @staticmethod
    def features(positions: Tensor, root_positions: Tensor, offsets: Tensor) -> Tensor:
        """See :func:`nkn_discriminator_features`."""
        return nkn_discriminator_features(positions, root_positions, offsets)

    def forward(self, features: Tensor) -> Tensor:
        """Args: features ``(B, C, T)`` (any ``T >= 1``). Returns: ``(B, 1)`` raw logits."""
        if features.shape[-1] == 0:
            raise ValueError(
                "discriminator features need at least one frame pair (clips of >= 2 frames)"
            )
        missing = self.min_frames - features.shape[-1]
        if missing > 0:  # each stride-2 layer halves T; edge-pad very short clips
            features = edge_pad(features, missing // 2, missing - missing // 2)
        return self.out(self.body(features).mean(-1))
