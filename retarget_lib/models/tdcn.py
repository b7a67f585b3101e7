"""The TDCN generator of Kim, Park & Lee 2020 (Sec. 3.2, Fig. 2b) and its shared building blocks.

Architecture (Fig. 2b, Sec. 3.2)::

    features (B, C_in, T)            p_t, q_t, r_t of the source + s̄B  (Sec. 3.1; features.py)
      │ edge padding: (RF-1)/2 copies of frame 1 on the left, of frame T on the right (Sec. 3.1);
      │               causal (A5): RF-1 copies of frame 1 on the left only
      ▼
    "3d1, C"   conv k=3, dilation 1                          ┐
    block 1:   conv k=3, dilation 3   → "1d1" conv k=1   (+ residual)
    block 2:   conv k=3, dilation 9   → "1d1"            (+ residual)   seven "yellow" layers,
    block 3:   conv k=3, dilation 27  → "1d1"            (+ residual)   each → BatchNorm →
                                                                         LeakyReLU → Dropout
      ▼
    extra conv (cyan, 1×1, C → C/2) → LeakyReLU → linear → q̂ (J×4, raw) and r̂ (3)

Each block is wrapped by a skip connection that "slices the residuals symmetrically" (centre
crop of the block input to the block output length; for the causal variant the *last* frames are
kept so that output ``t`` only sees inputs ``<= t``). Valid (unpadded) convolutions after the
initial edge padding give exactly one output per input frame. Receptive field
``1 + 2·(1 + 3 + 9 + 27) = 81`` frames (Sec. 3.2).

Choices where the paper is silent (all are arguments of :class:`TDCNGenerator`). Where the
authors' released code (github.com/medialab-ku/retargetting-tdcn, "released code" below) settles
a detail, we follow it unless it contradicts the paper's text:

* LeakyReLU slope 0.2 and BatchNorm momentum 0.1 (released code); dropout 0.1 (Sec. 5; the
  released config uses 0.2).
* The cyan "additional convolutional layer" is 1×1 (so the receptive field stays 81) with
  ``C/2`` outputs (512 at C=1024, the released code's ``out_features``) and a LeakyReLU but no
  BatchNorm/dropout (the paper lists those only for the seven yellow layers; the released code
  has no nonlinearity there, which makes it collapse into the final linear layer).
* The final linear layer starts like the released code's: weights ~ N(0, 0.002), bias = the
  identity quaternion ``(1, 0, 0, 0)`` per joint and 0 for r̂. An untrained generator therefore
  outputs near-identity rotations with norm ≈ 1 (Eq. 22 and the normalisation before FK are well
  conditioned from step 0).
* Skips are identity, as the text says; the released code passes each residual through a 1×1
  conv (``skip_projection=True`` reproduces that).
* q̂ is returned *raw*: the regularisation loss (Eq. 22) needs ``||q̂||``. Use
  :func:`normalize_quaternions` (or ``forward(..., normalize=True)``) before FK.

Variants (arguments only):

* ``causal=True`` — Table 4 A5 ("ours w/ causal conv"): left-only padding, right-aligned
  residual slices (the released code's ``causal_shift``).
* ``dense=True`` — Table 4 A1 ("typical dense convolutional network", 6.5× the parameters):
  every dilated convolution ``k=3, d`` is replaced by a dense (dilation-1) convolution with the
  same span, ``k = 2d + 1`` → kernels 7, 19, 55 (the released code's ``dense`` flag does the
  same). Layer count, widths and the 81-frame receptive field are unchanged. The blocks then
  hold ``(7+19+55 + 3·1)·C² = 84C²`` weights instead of ``(3·3 + 3·1)·C² = 12C²``; with the
  input layer and the head the measured ratio is **6.45× at C=1024** (89.35 M vs 13.85 M
  parameters; the paper says 6.5×) and 5.69× at C=256. (With projection skips it would be
  ≈5.5×, which suggests the paper counted identity skips.)

Speed. :meth:`TDCNGenerator.fuse_for_inference` folds each BatchNorm into its convolution
(inference only) and switches the eval forward to a time-major GEMM path: every ``k``-tap
convolution is ``k`` ``addmm`` calls on contiguous time slices of a ``(T, C)`` matrix (no im2col
copies), with bias, LeakyReLU and residual adds in place. On 2 cores (AVX-512), 1,000 frames,
batch 1, features + network + FK: ≈ 88 ms fused vs ≈ 96 ms unfused at C=1024, ≈ 10 ms vs
≈ 13.5 ms at C=256 (the plain conv body alone: 87 ms / 9.7 ms) — the network is GEMM-bound.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import torch
import torch.nn.functional as F
from torch import nn

from ..core.kinematics import align_local_rotations
from ..core.measures import leg_length
from ..core.rotations import quat_conjugate, quat_mul, quat_normalize
from ..core.skeleton import CANONICAL22_PARENTS
from ..core.transfer import keep_feet_as_rest
from .features import (
    NUM_JOINTS,
    FeatureNormalizer,
    generator_features,
    generator_input_channels,
    residual_generator_features,
    residual_input_channels,
)

Tensor = torch.Tensor

__all__ = [
    "ConvUnit",
    "ResidualBlock",
    "DilatedStack",
    "FrameHead",
    "GeneratorOutput",
    "TDCNGenerator",
    "normalize_quaternions",
    "quaternion_norm",
    "edge_pad",
    "init_identity_head",
]

DEFAULT_SLOPE = 0.2


def _norm_kind(norm: bool | str) -> str:
    if norm is True:
        return "batch"
    if norm is False or norm is None:
        return "none"
    if norm not in ("batch", "instance", "none"):
        raise ValueError(f"norm must be 'batch', 'instance' or 'none', got {norm!r}")
    return norm


def normalize_quaternions(q: Tensor) -> Tensor:
    """Unit quaternions from raw network outputs (before FK, Eq. 3).

    Args:
        q: ``(..., 4)`` raw wxyz.

    Returns:
        ``(..., 4)`` unit wxyz.
    """
    return quat_normalize(q, eps=1e-8)


def quaternion_norm(q: Tensor) -> Tensor:
    """``||q̂||`` per joint and frame, the quantity penalised by Eq. 22 (``(1 - ||q̂||)²``).

    Args:
        q: ``(..., 4)``.

    Returns:
        ``(...)``.
    """
    return q.norm(dim=-1)


def edge_pad(x: Tensor, left: int, right: int, time_dim: int = -1) -> Tensor:
    """Replicate the first frame ``left`` times and the last ``right`` times (TDCN Sec. 3.1).

    Works for any length ``T >= 1`` (unlike reflection padding).

    Args:
        x: tensor with time on ``time_dim`` (``(B, C, T)`` by default).
        left, right: number of copies.

    Returns:
        ``x`` with ``T + left + right`` frames.
    """
    if left == 0 and right == 0:
        return x
    parts = []
    if left:
        first = x.narrow(time_dim, 0, 1)
        parts.append(
            first.expand(*[left if d == (time_dim % x.dim()) else -1 for d in range(x.dim())])
        )
    parts.append(x)
    if right:
        last = x.narrow(time_dim, x.shape[time_dim] - 1, 1)
        parts.append(
            last.expand(*[right if d == (time_dim % x.dim()) else -1 for d in range(x.dim())])
        )
    return torch.cat(parts, time_dim)


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


class ConvUnit(nn.Module):
    """One yellow layer of Fig. 2b: ``Conv1d → BatchNorm1d → LeakyReLU → Dropout``.

    Args:
        in_channels, out_channels: widths.
        kernel: filter size (frames).
        dilation: dilation factor.
        dropout: dropout probability (0 disables).
        norm: ``"batch"`` (or ``True``), ``"instance"`` or ``"none"`` (or ``False``); with a
            norm the conv has no bias of its own. Instance norm pools over the whole clip, so it
            makes the receptive field unbounded and cannot be fused.
        slope: LeakyReLU negative slope.
    """

    def __init__(
        self,
        in_channels: int,
        out_channels: int,
        kernel: int,
        dilation: int = 1,
        dropout: float = 0.0,
        norm: bool | str = True,
        slope: float = DEFAULT_SLOPE,
    ):
        super().__init__()
        norm = _norm_kind(norm)
        self.conv = nn.Conv1d(
            in_channels, out_channels, kernel, dilation=dilation, bias=norm == "none"
        )
        self.norm = {
            "batch": lambda: nn.BatchNorm1d(out_channels),
            "instance": lambda: nn.InstanceNorm1d(out_channels, affine=True),
            "none": nn.Identity,
        }[norm]()
        self.dropout = nn.Dropout(dropout) if dropout > 0 else nn.Identity()
        self.slope = float(slope)
        self.fused = False

    @property
    def span(self) -> int:
        """Frames lost by this valid convolution: ``dilation · (kernel - 1)``."""
        return self.conv.dilation[0] * (self.conv.kernel_size[0] - 1)

    def forward(self, x: Tensor) -> Tensor:
        """Args: x ``(B, C_in, T)``. Returns: ``(B, C_out, T - span)``."""
        return self.dropout(F.leaky_relu(self.norm(self.conv(x)), self.slope))

    @torch.no_grad()
    def fuse(self) -> None:
        """Fold the (eval-mode) BatchNorm into the convolution; cache per-tap GEMM weights."""
        if self.fused:
            return
        conv = self.conv
        if isinstance(self.norm, nn.InstanceNorm1d):
            raise ValueError("instance norm depends on the whole clip and cannot be fused")
        if isinstance(self.norm, nn.BatchNorm1d):
            bn = self.norm
            scale = bn.weight / torch.sqrt(bn.running_var + bn.eps)
            bias = bn.bias - bn.running_mean * scale
            if conv.bias is not None:
                bias = bias + conv.bias * scale
            fused = nn.Conv1d(
                conv.in_channels,
                conv.out_channels,
                conv.kernel_size[0],
                dilation=conv.dilation[0],
                bias=True,
            ).to(conv.weight)
            fused.weight.copy_(conv.weight * scale.view(-1, 1, 1))
            fused.bias.copy_(bias)
            self.conv, self.norm = fused, nn.Identity()
        elif conv.bias is None:
            conv.bias = nn.Parameter(conv.weight.new_zeros(conv.out_channels))
        self.dropout = nn.Identity()
        # (K, C_out, C_in): tap k is a contiguous (C_out, C_in) matrix; .t() is a free view for BLAS
        self.register_buffer(
            "taps", self.conv.weight.detach().permute(2, 0, 1).contiguous(), persistent=False
        )
        self.fused = True

    def forward_time_major(self, h: Tensor) -> Tensor:
        """Fused eval path on one sequence.

        Args:
            h: ``(T, C_in)`` contiguous.

        Returns:
            ``(T - span, C_out)`` after bias and LeakyReLU.
        """
        d = self.conv.dilation[0]
        t_out = h.shape[0] - self.span
        out = torch.addmm(self.conv.bias, h[:t_out], self.taps[0].t())
        for k in range(1, self.taps.shape[0]):
            out.addmm_(h[k * d : k * d + t_out], self.taps[k].t())
        return F.leaky_relu_(out, self.slope)


class ResidualBlock(nn.Module):
    """One ResNet-style block of Fig. 2b: ``k``-tap dilated conv → "1d1" conv, plus a skip.

    The skip "slices the residuals symmetrically" (Sec. 3.2): the block input is centre-cropped
    to the output length (causal: its last frames are kept).

    Args:
        channels: width ``C``.
        kernel: filter size of the temporal conv.
        dilation: its dilation.
        dropout, norm, slope: see :class:`ConvUnit`.
        causal: right-aligned residual slice.
        skip_projection: pass the sliced residual through a 1×1 conv (with bias) before adding
            it, as the authors' released code does; ``False`` (default) = the identity skip
            described in Sec. 3.2.
    """

    def __init__(
        self,
        channels: int,
        kernel: int,
        dilation: int,
        dropout: float = 0.0,
        norm: bool | str = True,
        slope: float = DEFAULT_SLOPE,
        causal: bool = False,
        skip_projection: bool = False,
    ):
        super().__init__()
        self.temporal = ConvUnit(channels, channels, kernel, dilation, dropout, norm, slope)
        self.pointwise = ConvUnit(channels, channels, 1, 1, dropout, norm, slope)
        self.skip = nn.Conv1d(channels, channels, 1) if skip_projection else None
        self.causal = causal

    @property
    def span(self) -> int:
        return self.temporal.span

    def _crop(self, x: Tensor, t_out: int, time_dim: int) -> Tensor:
        start = x.shape[time_dim] - t_out if self.causal else (x.shape[time_dim] - t_out) // 2
        return x.narrow(time_dim, start, t_out)

    def forward(self, x: Tensor) -> Tensor:
        """Args: x ``(B, C, T)``. Returns: ``(B, C, T - span)``."""
        y = self.pointwise(self.temporal(x))
        res = self._crop(x, y.shape[-1], -1)
        return y + (res if self.skip is None else self.skip(res))

    def forward_time_major(self, h: Tensor) -> Tensor:
        """Fused eval path. Args: h ``(T, C)``. Returns: ``(T - span, C)``."""
        y = self.pointwise.forward_time_major(self.temporal.forward_time_major(h))
        res = self._crop(h, y.shape[0], 0)
        if self.skip is None:
            return y.add_(res)
        return y.add_(self.skip.bias).addmm_(res, self.skip.weight[:, :, 0].t())


class DilatedStack(nn.Module):
    """The conv body shared by the TDCN generator, the patch discriminator and the conv NKN
    baselines.

    ``first`` conv (``first_kernel``, dilation 1) then one :class:`ResidualBlock` per entry of
    ``dilations`` (Fig. 2b; Fig. 3 for the discriminator). Receptive field
    ``1 + (first_kernel - 1) + Σ (kernel - 1)·d``.

    Args:
        in_channels: input channels.
        channels: width ``C`` of every layer ("3d1, 1024" in the paper).
        dilations: dilation of each block's temporal conv (generator: ``(3, 9, 27)`` = ``3^i``).
        kernel: temporal filter size in the blocks.
        first_kernel: filter size of the first conv.
        dropout: dropout after every layer.
        causal: output ``t`` sees only inputs ``<= t`` (A5).
        dense: replace each dilated ``kernel``-tap conv by a dense one with the same span
            (``(kernel - 1)·d + 1`` taps, dilation 1) — A1 / Baseline-dense.
        norm: ``"batch"`` (default), ``"instance"`` or ``"none"`` after every conv.
        slope: LeakyReLU slope.
        skip_projection: 1×1 conv on each residual (released code) instead of the identity.
        padding: ``"edge"`` — replicate the first/last frame so that ``T`` inputs give ``T``
            outputs (Sec. 3.1); ``"valid"`` — no padding, ``T - RF + 1`` outputs.
    """

    def __init__(
        self,
        in_channels: int,
        channels: int,
        dilations: Sequence[int] = (3, 9, 27),
        kernel: int = 3,
        first_kernel: int = 3,
        dropout: float = 0.0,
        causal: bool = False,
        dense: bool = False,
        norm: bool | str = True,
        slope: float = DEFAULT_SLOPE,
        skip_projection: bool = False,
        padding: str = "edge",
    ):
        super().__init__()
        if padding not in ("edge", "valid"):
            raise ValueError(f"padding must be 'edge' or 'valid', got {padding!r}")
        self.in_channels, self.channels = in_channels, channels
        self.dilations, self.kernel = tuple(int(d) for d in dilations), int(kernel)
        self.causal, self.dense, self.padding = bool(causal), bool(dense), padding
        self.first = ConvUnit(in_channels, channels, first_kernel, 1, dropout, norm, slope)
        blocks = []
        for d in self.dilations:
            k, dil = ((kernel - 1) * d + 1, 1) if dense else (kernel, d)
            blocks.append(
                ResidualBlock(channels, k, dil, dropout, norm, slope, causal, skip_projection)
            )
        self.blocks = nn.ModuleList(blocks)

    @property
    def receptive_field(self) -> int:
        """Input frames that influence one output frame."""
        return 1 + self.first.span + sum(b.span for b in self.blocks)

    @property
    def pad_amounts(self) -> tuple[int, int]:
        """``(left, right)`` edge padding applied by ``forward`` (``(0, 0)`` for ``"valid"``)."""
        if self.padding == "valid":
            return 0, 0
        n = self.receptive_field - 1
        return (n, 0) if self.causal else (n // 2, n - n // 2)

    @property
    def fused(self) -> bool:
        return self.first.fused

    def forward(self, x: Tensor) -> Tensor:
        """Args: x ``(B, C_in, T)``. Returns: ``(B, C, T)`` (edge) or ``(B, C, T - RF + 1)``
        (valid)."""
        x = edge_pad(x, *self.pad_amounts)
        h = self.first(x)
        for block in self.blocks:
            h = block(h)
        return h

    def forward_time_major(self, x: Tensor) -> Tensor:
        """Same as :meth:`forward` but returns ``(B, T_out, C)``; uses the GEMM path when fused.

        Args:
            x: ``(B, C_in, T)``.
        """
        if not (self.fused and not self.training):
            return self.forward(x).transpose(1, 2)
        left, right = self.pad_amounts
        outs = []
        for xb in x:  # loop over the (small) batch, never over frames
            h = edge_pad(xb.t(), left, right, time_dim=0).contiguous()
            h = self.first.forward_time_major(h)
            for block in self.blocks:
                h = block.forward_time_major(h)
            outs.append(h)
        return torch.stack(outs)

    def fuse_for_inference(self) -> DilatedStack:
        """Fold BatchNorm into the convs and drop dropout (eval-only afterwards). Returns
        ``self``."""
        self.eval()
        for m in self.modules():
            if isinstance(m, ConvUnit):
                m.fuse()
        return self


class FrameHead(nn.Module):
    """The cyan layer and the final fully-connected layer of Fig. 2b, applied per frame.

    ``1×1 conv → LeakyReLU → linear``; both are 1×1 so the receptive field is unchanged.

    Args:
        channels: input width.
        out_channels: outputs per frame.
        hidden: width of the cyan layer (default ``channels``); ``0`` skips it (linear only).
        slope: LeakyReLU slope.
    """

    def __init__(
        self,
        channels: int,
        out_channels: int,
        hidden: int | None = None,
        slope: float = DEFAULT_SLOPE,
    ):
        super().__init__()
        hidden = channels if hidden is None else hidden
        self.extra = nn.Linear(channels, hidden) if hidden else None
        self.out = nn.Linear(hidden or channels, out_channels)
        self.slope = float(slope)

    def forward(self, h: Tensor) -> Tensor:
        """Args: h ``(B, T, C)`` time-major. Returns: ``(B, T, out_channels)``."""
        if self.extra is not None:
            h = F.leaky_relu(self.extra(h), self.slope)
        return self.out(h)


def init_identity_head(linear: nn.Linear, num_joints: int, std: float = 0.002) -> None:
    """Start a ``(J·4 + k)``-output layer at identity quaternions and zero extras.

    Weights ~ N(0, ``std``) and bias ``(1,0,0,0)`` per joint, ``0`` for the rest — as the authors'
    released code initialises its final ``RootLinear``.
    """
    with torch.no_grad():
        nn.init.normal_(linear.weight, std=std)
        linear.bias.zero_()
        linear.bias[0 : 4 * num_joints : 4] = 1.0


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
    ):
        super().__init__()
        self.num_joints = num_joints
        self.residual = bool(residual)
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
        return self._run(self.normalizer(features), normalize)

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
        normalizer: nn.Module | None = None,
        feet_as_rest: bool = False,
    ) -> GeneratorOutput:
        """Retarget with raw outputs, for training (Eqs. 4-5).

        Args:
            rotations: ``(B, T, J, 4)`` source local quaternions.
            root_positions: ``(B, T, 3)`` source root positions.
            offsets_src: ``(B, J, 3)`` or ``(J, 3)`` source rest offsets.
            offsets_tgt: ``(B, J, 3)`` or ``(J, 3)`` target rest offsets.
            positions: optional precomputed ``(B, T, J, 3)`` source ``p``.
            normalizer: overrides ``self.normalizer``.
            feet_as_rest: see :meth:`retarget`.

        Returns:
            :class:`GeneratorOutput` with raw q̂ ``(B, T, J, 4)``, r̂ ``(B, T, 3)``, no velocities.
        """
        norm = self.normalizer if normalizer is None else normalizer
        if not self.residual:
            x = generator_features(
                rotations, root_positions, offsets_src, offsets_tgt, positions, self.parents
            )
            q, r = self._run(norm(x), normalize=False)
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
        align = quat_mul(raw[:b], quat_conjugate(normalize_quaternions(raw[b:])))
        if feet_as_rest:
            align = keep_feet_as_rest(align)
        q, r = self.compose_residual(align, rotations, root_positions, offsets_src, offsets_tgt)
        return GeneratorOutput(q, r, None)

    def compose_residual(
        self,
        align: Tensor,
        rotations: Tensor,
        root_positions: Tensor,
        offsets_src: Tensor,
        offsets_tgt: Tensor,
    ) -> tuple[Tensor, Tensor]:
        """The residual variant's output: a correction of "copy" (our variant, not the paper).

        The alignments are ``C_j(t) = N_j(x, s̄A → s̄B) ⊗ unit(N_j(x, s̄A → s̄A))⁻¹``: the head's
        raw quaternion for the target, "minus" the one it gives for the source's own skeleton
        (both from one batched pass, :meth:`generate`). Retargeting onto the source's own skeleton
        is therefore the identity for *any* input, by construction, and whatever the network does
        regardless of the target cancels. The output is

        ``q̂_j = unit(C_p(j))⁻¹ ⊗ q^A_j ⊗ C_j``  and  ``r̂ = r^A · leg(s̄B) / leg(s̄A)``

        (:func:`~retarget_lib.core.kinematics.align_local_rotations`). With ``C = 1`` — the head's
        initialisation — this is the "copy" baseline, and the same-skeleton case (``A = B``) is
        already the identity. A constant ``C_j`` is exactly a rest-pose alignment
        (:func:`retarget_lib.core.transfer.transfer_rotations`), so the rest-pose difference of two
        characters is a constant for the network to learn. Since ``‖q̂_j‖ = ‖C_j‖`` the
        regulariser Eq. 22 still sees the raw norm.

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
        b = rotations.shape[0]
        ratio = leg_length(offsets_tgt.expand(b, -1, -1)) / leg_length(
            offsets_src.expand(b, -1, -1)
        )
        return align_local_rotations(rotations, align, self.parents), root_positions * ratio.view(
            b, 1, 1
        )

    def retarget(
        self,
        rotations: Tensor,
        root_positions: Tensor,
        offsets_src: Tensor,
        offsets_tgt: Tensor,
        normalizer: nn.Module | None = None,
        feet_as_rest: bool = False,
    ) -> tuple[Tensor, Tensor]:
        """Features → padding → network → unit quaternions and root positions.

        Call in eval mode (and under ``torch.inference_mode()`` for speed); any clip length works.

        Args:
            rotations: ``(B, T, J, 4)`` source local quaternions (wxyz).
            root_positions: ``(B, T, 3)`` source root positions.
            offsets_src: ``(B, J, 3)`` or ``(J, 3)`` source rest offsets.
            offsets_tgt: ``(B, J, 3)`` or ``(J, 3)`` target rest offsets.
            normalizer: overrides ``self.normalizer``.
            feet_as_rest: residual form only: the feet's alignments are the identity
                (:func:`~retarget_lib.core.transfer.keep_feet_as_rest`: flat where the source's
                are flat); the ``tdcn`` method asks for it, training does not.

        Returns:
            ``(q̂ (B, T, J, 4) unit, r̂ (B, T, 3))`` for the target skeleton.
        """
        out = self.generate(
            rotations,
            root_positions,
            offsets_src,
            offsets_tgt,
            normalizer=normalizer,
            feet_as_rest=feet_as_rest,
        )
        return normalize_quaternions(out.rotations), out.root_positions
