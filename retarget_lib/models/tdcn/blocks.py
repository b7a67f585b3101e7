"""The TDCN's building blocks (Kim et al. 2020, Sec. 3-4): quaternion normalisation, edge
padding, the dilated convolution unit, residual block and stack, and the per-frame output head."""

from __future__ import annotations

from collections.abc import Sequence

import torch
import torch.nn.functional as F
from torch import nn

from ...core.rotations import quat_normalize

__all__ = [
    "ConvUnit",
    "ResidualBlock",
    "DilatedStack",
    "FrameHead",
    "normalize_quaternions",
    "quaternion_norm",
    "edge_pad",
]


Tensor = torch.Tensor


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
