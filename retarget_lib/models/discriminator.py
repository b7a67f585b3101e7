"""The patch discriminator of TDCN (Kim et al. 2020, Sec. 4.1, Fig. 3; Table 4 A4).

"Its structure is similar to the generator's shown in Figure 2b, but the receptive field is
limited to 31 frames" (Sec. 4.1): a PatchGAN over time [IZZE17] that scores every 31-frame window
of the motion features ``(l_t, δ_t, B)`` (Eqs. 18-20; :func:`features.discriminator_features`)
instead of the whole clip.

Choices where the paper is silent (Fig. 3's dilations are not in the text):

* Body: the generator's :class:`~retarget_lib.models.tdcn.DilatedStack` — "3d1" first conv and
  residual blocks of (k=3 dilated conv → 1×1 conv), each followed by BatchNorm + LeakyReLU(0.2);
  no dropout (Sec. 5 gives dropout for the generator only).
* 31 frames: block dilations ``(2, 4, 8)`` → ``1 + 2·(1 + 2 + 4 + 8) = 31``.
* 81 frames (A4: "we added a convolution layer to our discriminator such that it sees the same
  number of frames (81 frames) as the generator"): one more block, dilation 25 →
  ``1 + 2·(1 + 2 + 4 + 8 + 25) = 81``.
* Head: a linear (1×1) layer to one raw score per window (no sigmoid: the least-squares targets
  of Eq. 21 belong to the loss code).
* Width 256 at the paper profile.

For the record, the authors' released code (medialab-ku/retargetting-tdcn) differs from the
paper text here: filter widths ``[3, 3, 3]`` (dilations 1, 3, 9 → a 27-frame receptive field),
InstanceNorm instead of BatchNorm, width 256, and end-effector motions as input. We follow the
paper (31 frames); ``norm="instance"`` is available but makes every score depend on the whole
clip (instance statistics), so the 31-frame locality no longer holds.
* Padding: **valid** convolutions — every score is computed from a genuine window of the clip, so
  ``T`` input frames give ``T - RF + 1`` scores. Edge-padding would score windows made of repeated
  frames, which real data never contain. A clip shorter than the receptive field (e.g. the
  80 feature frames of an 81-frame training clip under the 81-frame A4 discriminator) is
  edge-padded up to exactly one window and gets one score that sees the whole clip.
"""

from __future__ import annotations

from collections.abc import Sequence

import torch
from torch import nn

from .features import discriminator_features, discriminator_input_channels
from .tdcn import DEFAULT_SLOPE, DilatedStack, FrameHead, edge_pad

Tensor = torch.Tensor

__all__ = ["PatchDiscriminator", "DISCRIMINATOR_DILATIONS"]

#: block dilations per receptive field (first conv: k=3, d=1; block convs: k=3)
DISCRIMINATOR_DILATIONS: dict[int, tuple[int, ...]] = {31: (2, 4, 8), 81: (2, 4, 8, 25)}


class PatchDiscriminator(nn.Module):
    """Per-window ("patch") discriminator over motion features (Fig. 3).

    Args:
        in_channels: feature channels (default :func:`features.discriminator_input_channels` = 43).
        channels: width of every layer.
        receptive_field: 31 (ours) or 81 (A4); ignored when ``dilations`` is given.
        dilations: explicit block dilations (overrides ``receptive_field``).
        dropout: dropout after each layer (default 0).
        norm: ``"batch"`` (default), ``"instance"`` (released code; not local) or ``"none"``.
        slope: LeakyReLU slope.

    Attributes:
        height_normalized_inputs: ``True`` — feed it ``discriminator_features(..., normalize=True)``
            (Sec. 4.2 (ii)).
    """

    height_normalized_inputs = True

    def __init__(
        self,
        in_channels: int | None = None,
        channels: int = 256,
        receptive_field: int = 31,
        dilations: Sequence[int] | None = None,
        dropout: float = 0.0,
        norm: bool | str = "batch",
        slope: float = DEFAULT_SLOPE,
    ):
        super().__init__()
        if dilations is None:
            if receptive_field not in DISCRIMINATOR_DILATIONS:
                raise ValueError(
                    f"receptive_field must be one of {sorted(DISCRIMINATOR_DILATIONS)}, "
                    f"or pass dilations explicitly; got {receptive_field}"
                )
            dilations = DISCRIMINATOR_DILATIONS[receptive_field]
        self.in_channels = discriminator_input_channels() if in_channels is None else in_channels
        self.body = DilatedStack(
            self.in_channels,
            channels,
            dilations,
            3,
            3,
            dropout,
            causal=False,
            dense=False,
            norm=norm,
            slope=slope,
            padding="valid",
        )
        self.head = FrameHead(channels, 1, hidden=0, slope=slope)

    @staticmethod
    def features(positions: Tensor, root_positions: Tensor, offsets: Tensor) -> Tensor:
        """The input this discriminator expects (Eqs. 19-20): height-normalised ``(l, δ, B)``.

        Args:
            positions: ``(B, T, J, 3)`` root-relative joint positions.
            root_positions: ``(B, T, 3)``.
            offsets: ``(B, J, 3)`` or ``(J, 3)`` rest offsets of the performing skeleton.

        Returns:
            ``(B, 2(J-1) + 1, T-1)`` (:func:`features.discriminator_features`).
        """
        return discriminator_features(positions, root_positions, offsets, normalize=True)

    @property
    def receptive_field(self) -> int:
        """Frames seen by one score (31 or 81)."""
        return self.body.receptive_field

    def forward(self, features: Tensor) -> Tensor:
        """Raw scores of every window (Eqs. 19-20: ``h_{2:T}``).

        Args:
            features: ``(B, C, T)`` from :func:`features.discriminator_features` (``T`` = clip
                frames - 1).

        Returns:
            ``(B, max(T - RF + 1, 1))`` unbounded scores (real → 1, fake → 0 under Eq. 21's
            least-squares loss, which the loss module applies).
        """
        if features.shape[-1] == 0:
            raise ValueError(
                "discriminator features need at least one frame pair (clips of >= 2 frames)"
            )
        missing = self.receptive_field - features.shape[-1]
        if missing > 0:
            features = edge_pad(features, missing // 2, missing - missing // 2)
        h = self.body.forward_time_major(features)
        return self.head(h).squeeze(-1)
