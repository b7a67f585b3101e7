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

The package: :mod:`.blocks` (normalisation, padding, convolution units and stacks, the frame
head) and :mod:`.generator` (:class:`TDCNGenerator`).
"""

from __future__ import annotations

from .blocks import (
    DEFAULT_SLOPE,
    ConvUnit,
    DilatedStack,
    FrameHead,
    ResidualBlock,
    edge_pad,
    normalize_quaternions,
    quaternion_norm,
)
from .generator import GeneratorOutput, TDCNGenerator, init_identity_head

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
    "DEFAULT_SLOPE",
]
