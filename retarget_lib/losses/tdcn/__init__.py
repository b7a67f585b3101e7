"""TDCN loss functions (Kim, Park, Kwon, Han, Eurographics 2020, Sec. 4.2, Eqs. 6-23), and the NKN
baseline's vanilla GAN: small differentiable functions on plain tensors — no model objects — so
that notebook 03 can evaluate each term on hand-made motions and the trainer can combine them.

:mod:`.tensors` — the motion container, the reductions and the finite check; :mod:`.terms` — Lc,
Lt, Lh, Ld, Lr, Lo (with the notation, paper → here); :mod:`.adversarial` — La (Eq. 21) and NKN's
sigmoid cross-entropy; :mod:`.total` — Eq. 6's weights and weighted total.
"""

from .adversarial import (
    adversarial_loss,
    adversarial_loss_discriminator,
    adversarial_loss_generator,
    sigmoid_ce_discriminator_loss,
    sigmoid_ce_generator_loss,
)
from .tensors import (
    MotionTensors,
    NonFiniteLossError,
    PositionScale,
    check_finite,
    per_sample,
    smooth_l1,
)
from .terms import (
    CODE_END_EFFECTOR_IDS,
    bone_axes,
    bone_direction_loss,
    cycle_loss,
    height_loss,
    orientation_loss,
    reconstruction_loss,
    regularization_loss,
    root_smoothness_loss,
    twist_angle,
    twist_loss,
    twist_penalty,
)
from .total import TERM_WEIGHTS, TDCNLossWeights, total_generator_loss

__all__ = [
    "CODE_END_EFFECTOR_IDS",
    "MotionTensors",
    "NonFiniteLossError",
    "PositionScale",
    "TDCNLossWeights",
    "TERM_WEIGHTS",
    "check_finite",
    "per_sample",
    "smooth_l1",
    "cycle_loss",
    "reconstruction_loss",
    "twist_penalty",
    "twist_loss",
    "twist_angle",
    "bone_axes",
    "height_loss",
    "adversarial_loss_generator",
    "adversarial_loss_discriminator",
    "adversarial_loss",
    "bone_direction_loss",
    "regularization_loss",
    "root_smoothness_loss",
    "orientation_loss",
    "sigmoid_ce_generator_loss",
    "sigmoid_ce_discriminator_loss",
    "total_generator_loss",
]
