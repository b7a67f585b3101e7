"""The TDCN generator (Kim et al. 2020, Eqs. 4-5) and its residual variant (ours): features,
the dilated stack, the heads, and retargeting a batch of clips."""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import torch
from torch import nn

from ...core.kinematics import align_local_rotations
from ...core.measures import leg_length
from ...core.retarget_pose import retarget_alignment
from ...core.rotations import quat_conjugate, quat_mul
from ...core.skeleton import CANONICAL22_PARENTS
from ..features import (
    GENERATOR_LAYOUT,
    NUM_JOINTS,
    FeatureNormalizer,
    generator_features,
    generator_input_channels,
    positions_in_frame,
    residual_generator_features,
    residual_input_channels,
    source_local_positions,
)
from .blocks import DEFAULT_SLOPE, DilatedStack, FrameHead, Tensor, normalize_quaternions

__all__ = ["GeneratorOutput", "TDCNGenerator", "init_identity_head", "leg_scaled_root"]


class GeneratorOutput(NamedTuple):
    """What a generator's ``generate`` returns (shared by TDCN and the NKN baselines).

    Attributes:
        rotations: ``(B, T, J, 4)`` raw (unnormalised) quaternions q̂ (Eq. 22 needs the norm).
        root_positions: ``(B, T, 3)`` root positions r̂ (metres).
        root_velocities: ``(B, T, 3)`` per-frame root offsets the model predicted and integrated
            (NKN baselines), or ``None`` when the model outputs positions directly (TDCN).
    """

    rotations: Tensor
    root_positions: Tensor
    root_velocities: Tensor | None = None


def init_identity_head(linear: nn.Linear, num_joints: int, std: float = 0.002) -> None:
    """Start a ``(J·4 + k)``-output layer at identity quaternions and zero extras.

    Weights ~ N(0, ``std``) and bias ``(1,0,0,0)`` per joint, ``0`` for the rest — as the authors'
    released code initialises its final ``RootLinear``.
    """
    with torch.no_grad():
        nn.init.normal_(linear.weight, std=std)
        linear.bias.zero_()
        linear.bias[0 : 4 * num_joints : 4] = 1.0


def leg_scaled_root(root_positions: Tensor, offsets_src: Tensor, offsets_tgt: Tensor) -> Tensor:
    """The source's root scaled by the leg-length ratio ``leg(s̄B) / leg(s̄A)``: the root of
    ``copy``, of the synthetic ground truth and of Villegas et al.'s ``o^(A→B)`` (Eq. 8).

    Args:
        root_positions: ``(B, T, 3)`` source root positions (metres).
        offsets_src, offsets_tgt: ``(B, J, 3)`` or ``(J, 3)`` rest offsets.

    Returns:
        ``(B, T, 3)`` root positions for the target (metres).
    """
    b = root_positions.shape[0]
    ratio = leg_length(offsets_tgt.expand(b, -1, -1)) / leg_length(offsets_src.expand(b, -1, -1))
    return root_positions * ratio.view(b, 1, 1)


class TDCNGenerator(nn.Module):
    """TDCN retargeting generator (Kim et al. 2020, Sec. 3, Fig. 2).

    Args:
        channels: width (paper: 1024; the fast profile uses 256).
        dropout: dropout after each of the seven yellow layers (paper: 0.1).
        dilations: block dilations (paper: ``3^i`` = 3, 9, 27).
        kernel: temporal filter size (paper: 3).
        causal: A5 (Table 4) — use past frames only.
        dense: A1 (Table 4) — dense instead of dilated convs, same receptive field.
        num_joints: ``J`` (22).
        in_channels: input channels (default ``10J + 3``,
            :func:`features.generator_input_channels`).
        slope: LeakyReLU slope.
        head_hidden: width of the cyan 1×1 layer (default ``channels // 2``: 512 at the paper
            width, the released code's ``out_features``).
        skip_projection: 1×1 conv on the residuals (released code) instead of identity skips.
        parents: skeleton parents for :meth:`generate`'s FK.
        residual: the residual variant (ours, :meth:`compose_residual`).
        standardized_root: the root head outputs a z-score of the root position, turned into metres
            with the input normalizer's root-channel mean and std (the authors' released code: its
            network's root output is compared with standardised targets and de-standardised for
            use). Without it the head regresses metres from a bias initialised at 0, which a
            short run cannot move to the hips' height. The paper does not say; paper form only.
        root_residual: the head's root output is added to the source's root scaled by the leg
            ratio (:func:`leg_scaled_root`), the root rule of the residual NKN Baseline
            (:class:`~retarget_lib.models.nkn.NKNGenerator`); the head starts at 0, i.e. at
            ``copy``'s root. Ours, not the paper (Eq. 2's head regresses the root outright);
            paper form only (the residual variant's root is not learned).
        positions_frame: the axes of the input ``p`` (:data:`~retarget_lib.models.features.
            POSITION_FRAMES`): ``"world"`` (Eq. 1, the root's rotation applied) or ``"root"``
            (the root's rotation removed, the authors' released code; audit T5). Paper form only.

    Attributes:
        normalizer: :class:`~retarget_lib.models.features.FeatureNormalizer` applied to the input
            features (identity unless fitted; saved in the state dict).
    """

    def __init__(
        self,
        channels: int = 1024,
        dropout: float = 0.1,
        dilations: Sequence[int] = (3, 9, 27),
        kernel: int = 3,
        causal: bool = False,
        dense: bool = False,
        num_joints: int = NUM_JOINTS,
        in_channels: int | None = None,
        slope: float = DEFAULT_SLOPE,
        head_hidden: int | None = None,
        skip_projection: bool = False,
        parents: Sequence[int] = CANONICAL22_PARENTS,
        residual: bool = False,
        standardized_root: bool = False,
        root_residual: bool = False,
        positions_frame: str = "world",
    ):
        super().__init__()
        if positions_frame not in ("world", "root"):
            raise ValueError(f"positions_frame must be world or root, got {positions_frame!r}")
        if residual and positions_frame != "world":
            raise ValueError("positions_frame is for the paper form (the residual's p is Eq. 1's)")
        if residual and (standardized_root or root_residual):
            raise ValueError(
                "standardized_root and root_residual are for the paper form: "
                "the residual variant's root is not learned"
            )
        if standardized_root and root_residual:
            raise ValueError("root_residual adds metres to the source's root: no standardized_root")
        self.num_joints = num_joints
        self.residual = bool(residual)
        self.standardized_root = bool(standardized_root)
        self.root_residual = bool(root_residual)
        self.positions_frame = positions_frame
        default_in = (residual_input_channels if self.residual else generator_input_channels)(
            num_joints
        )
        self.in_channels = default_in if in_channels is None else in_channels
        self.parents = tuple(parents)
        self.normalizer = FeatureNormalizer(self.in_channels)
        self.body = DilatedStack(
            self.in_channels,
            channels,
            dilations,
            kernel,
            3,
            dropout,
            causal,
            dense,
            norm="batch",
            slope=slope,
            skip_projection=skip_projection,
            padding="edge",
        )
        head_hidden = channels // 2 if head_hidden is None else head_hidden
        self.head = FrameHead(
            channels, 4 * num_joints + (0 if self.residual else 3), head_hidden, slope
        )
        init_identity_head(self.head.out, num_joints)

    @property
    def receptive_field(self) -> int:
        """81 for the paper's configuration (dense and causal variants too)."""
        return self.body.receptive_field

    @property
    def causal(self) -> bool:
        return self.body.causal

    @property
    def fused(self) -> bool:
        return self.body.fused

    def fuse_for_inference(self) -> TDCNGenerator:
        """Fold BatchNorm into the convs, drop dropout, switch to the GEMM eval path.

        In place and irreversible (the model can no longer be trained; load weights *before*
        fusing). Returns ``self`` in eval mode.
        """
        self.body.fuse_for_inference()
        return self.eval()

    def train(self, mode: bool = True) -> TDCNGenerator:
        if mode and self.fused:
            raise RuntimeError("this TDCNGenerator was fused for inference and cannot be trained")
        return super().train(mode)

    def forward(self, features: Tensor, normalize: bool = False) -> tuple[Tensor, Tensor]:
        """Run the network (Eq. 2) on unpadded features; edge padding is applied inside.

        Args:
            features: ``(B, C_in, T)`` from :func:`~retarget_lib.models.features.generator_features`
                (raw; ``self.normalizer`` is applied here).
            normalize: return unit quaternions instead of raw ones.

        Returns:
            ``(q̂ (B, T, J, 4), r̂ (B, T, 3))``; q̂ raw unless ``normalize``.
        """
        q, r = self._run(self.normalizer(features), normalize)
        return q, self._root_in_metres(r, self.normalizer)

    def _root_in_metres(self, r: Tensor, normalizer: FeatureNormalizer) -> Tensor:
        """The root head's ``(B, T, 3)`` output in metres: itself, or with ``standardized_root``
        the z-score times the normalizer's root std plus its mean (the identity while unfitted)."""
        if not self.standardized_root:
            return r
        root = GENERATOR_LAYOUT["r"]
        return r * normalizer.std[root] + normalizer.mean[root]

    def _run(self, x: Tensor, normalize: bool) -> tuple[Tensor, Tensor]:
        h = self.body.forward_time_major(x)  # (B, T, C)
        out = self.head(h)
        b, t, _ = out.shape
        q = out[..., : 4 * self.num_joints].reshape(b, t, self.num_joints, 4)
        r = out[..., 4 * self.num_joints :]
        return (normalize_quaternions(q) if normalize else q), r

    def generate(
        self,
        rotations: Tensor,
        root_positions: Tensor,
        offsets_src: Tensor,
        offsets_tgt: Tensor,
        positions: Tensor | None = None,
        normalizer: FeatureNormalizer | None = None,
    ) -> GeneratorOutput:
        """Retarget with raw outputs, for training (Eqs. 4-5).

        Args:
            rotations: ``(B, T, J, 4)`` source local quaternions.
            root_positions: ``(B, T, 3)`` source root positions.
            offsets_src: ``(B, J, 3)`` or ``(J, 3)`` source rest offsets.
            offsets_tgt: ``(B, J, 3)`` or ``(J, 3)`` target rest offsets.
            positions: optional precomputed ``(B, T, J, 3)`` source ``p``.
            normalizer: overrides ``self.normalizer``.

        Returns:
            :class:`GeneratorOutput` with raw q̂ ``(B, T, J, 4)``, r̂ ``(B, T, 3)``, no velocities.
        """
        norm = self.normalizer if normalizer is None else normalizer
        if not self.residual:
            x = self.input_features(rotations, root_positions, offsets_src, offsets_tgt, positions)
            q, r = self._run(norm(x), normalize=False)
            r = self._root_in_metres(r, norm)
            if self.root_residual:
                r = r + leg_scaled_root(root_positions, offsets_src, offsets_tgt)
            return GeneratorOutput(q, r, None)
        b = rotations.shape[0]
        off_a, off_b = offsets_src.expand(b, -1, -1), offsets_tgt.expand(b, -1, -1)
        # one pass over the batch twice: towards the target, and towards the source itself
        x = residual_generator_features(
            rotations.repeat(2, 1, 1, 1),
            root_positions.repeat(2, 1, 1),
            off_a.repeat(2, 1, 1),
            torch.cat([off_b, off_a]),
            None if positions is None else positions.repeat(2, 1, 1, 1),
            self.parents,
        )
        raw, _ = self._run(norm(x), normalize=False)
        correction = quat_mul(raw[:b], quat_conjugate(normalize_quaternions(raw[b:])))
        base = retarget_alignment(off_a, off_b).to(correction.dtype)  # (B, J, 4): copy-rest
        align = quat_mul(base.unsqueeze(1), correction)
        q, r = self.compose_residual(align, rotations, root_positions, offsets_src, offsets_tgt)
        return GeneratorOutput(q, r, None)

    def input_features(
        self,
        rotations: Tensor,
        root_positions: Tensor,
        offsets_src: Tensor,
        offsets_tgt: Tensor,
        positions: Tensor | None = None,
    ) -> Tensor:
        """The paper form's raw input ``[p, q, r, s̄B]`` (Eq. 2,
        :func:`~retarget_lib.models.features.generator_features`) with ``p`` in this model's
        ``positions_frame``; what :meth:`generate` feeds the normalizer and the training code fits
        it on.

        Args:
            rotations: ``(B, T, J, 4)`` source local quaternions.
            root_positions: ``(B, T, 3)`` source root positions.
            offsets_src, offsets_tgt: ``(B, J, 3)`` or ``(J, 3)`` rest offsets.
            positions: optional precomputed ``(B, T, J, 3)`` ``p`` in world axes.

        Returns:
            ``(B, 10J + 3, T)``.
        """
        if positions is None:
            positions = source_local_positions(rotations, offsets_src, self.parents)
        p = positions_in_frame(positions, self.positions_frame, rotations[..., 0, :])
        return generator_features(
            rotations, root_positions, offsets_src, offsets_tgt, p, self.parents
        )

    def compose_residual(
        self,
        align: Tensor,
        rotations: Tensor,
        root_positions: Tensor,
        offsets_src: Tensor,
        offsets_tgt: Tensor,
    ) -> tuple[Tensor, Tensor]:
        """The residual variant's output: a correction of copy-rest (our variant, not the paper).

        The alignments are ``C_j(t) = R_j(s̄A, s̄B) ⊗ N_j(x, s̄A → s̄B) ⊗ unit(N_j(x, s̄A → s̄A))⁻¹``
        (:meth:`generate`): ``R = (P^A)⁻¹ P^B`` is the rest alignment of the two retarget poses
        (:func:`~retarget_lib.core.retarget_pose.retarget_alignment`, the ``copy-rest`` method),
        and the network's correction is its head's raw quaternion for the target "minus" the one it
        gives for the source's own skeleton (both from one batched pass). Retargeting onto the
        source's own skeleton is therefore the identity for *any* input, by construction
        (``R = 1`` there too), and whatever the network does regardless of the target cancels. The
        output is

        ``q̂_j = unit(C_p(j))⁻¹ ⊗ q^A_j ⊗ C_j``  and  ``r̂ = r^A · leg(s̄B) / leg(s̄A)``

        (:func:`~retarget_lib.core.kinematics.align_local_rotations`). With the correction 1 — the
        head's initialisation — this is the copy-rest baseline (the rotation deltas from the
        retarget pose, :func:`retarget_lib.core.transfer.transfer_rotations`): the rig conventions
        are removed analytically, and the network learns only what the motion and the body need on
        top. Since ``‖q̂_j‖ = ‖C_j‖`` the regulariser Eq. 22 still sees the raw norm.

        The root is not learned: it is the source's trajectory scaled by the leg-length ratio, as
        Mixamo, the synthetic ground truth and Villegas et al.'s ``o^(A→B)`` (Eq. 8) scale it.
        (Learning it against Lh's root term and the discriminator's ``δ``, which normalise by the
        full height ``H`` (Eqs. 15-18), moved it towards the height ratio instead: on the TDCN test
        pairs the root then carried most of the error.)

        Args:
            align: ``(B, T, J, 4)`` raw ``C``.
            rotations: ``(B, T, J, 4)`` source local quaternions.
            root_positions: ``(B, T, 3)`` source root positions.
            offsets_src, offsets_tgt: ``(B, J, 3)`` or ``(J, 3)``.

        Returns:
            ``(q̂ (B, T, J, 4) raw, r̂ (B, T, 3))``.
        """
        return align_local_rotations(rotations, align, self.parents), leg_scaled_root(
            root_positions, offsets_src, offsets_tgt
        )

    def retarget(
        self,
        rotations: Tensor,
        root_positions: Tensor,
        offsets_src: Tensor,
        offsets_tgt: Tensor,
        normalizer: FeatureNormalizer | None = None,
    ) -> tuple[Tensor, Tensor]:
        """Features → padding → network → unit quaternions and root positions.

        Call in eval mode (and under ``torch.inference_mode()`` for speed); any clip length works.

        Args:
            rotations: ``(B, T, J, 4)`` source local quaternions (wxyz).
            root_positions: ``(B, T, 3)`` source root positions.
            offsets_src: ``(B, J, 3)`` or ``(J, 3)`` source rest offsets.
            offsets_tgt: ``(B, J, 3)`` or ``(J, 3)`` target rest offsets.
            normalizer: overrides ``self.normalizer``.

        Returns:
            ``(q̂ (B, T, J, 4) unit, r̂ (B, T, 3))`` for the target skeleton.
        """
        out = self.generate(
            rotations,
            root_positions,
            offsets_src,
            offsets_tgt,
            normalizer=normalizer,
        )
        return normalize_quaternions(out.rotations), out.root_positions
