"""The adversarial term La (Kim et al. 2020, Eq. 21), and the NKN baseline's vanilla GAN
(Villegas et al. 2018: sigmoid cross-entropy).

**Eq. 21** prints ``(h^A)² + (1 − h^B)²`` inside ``min_G max_D`` (Eq. 6). Read as a min-max, G
minimises ``(1 − h^B)²`` (fake scores → 1) and D pushes real scores up and fake scores away
from 1; the bounded least-squares form of that game is standard LSGAN with labels real = 1,
fake = 0: D minimises ``(h_real − 1)² + h_fake²``, G minimises ``(h_fake − 1)²``.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Literal

import torch
import torch.nn.functional as F

from .tensors import MotionTensors, Reduction, per_sample, reduce_elements
from .terms import reconstruction_loss

Tensor = torch.Tensor

__all__ = [
    "adversarial_loss",
    "adversarial_loss_discriminator",
    "adversarial_loss_generator",
    "sigmoid_ce_discriminator_loss",
    "sigmoid_ce_generator_loss",
]


# --------------------------------------------------------------------------------------------
# La
# --------------------------------------------------------------------------------------------


def adversarial_loss_generator(h_fake: Tensor, reduction: Reduction = "mean") -> Tensor:
    """Generator side of the least-squares adversarial loss (Eq. 21, case ``A ≠ B``): ``(h^B −
    1)²``.

    **Reading of Eq. 21.** The paper prints ``La = (h^A)² + (1 − h^B)²`` (real scores ``h^A``,
    fake ``h^B``) inside ``min_G max_D`` (Eq. 6). Only ``(1 − h^B)²`` depends on G, so G
    minimises it: fake scores are pushed to **1**, the "real" label. D maximises the printed
    expression, i.e. drives ``h^A`` up and ``h^B`` away from 1 — unbounded as printed. Its
    bounded least-squares form is standard LSGAN (Mao et al. 2017) with labels real = 1,
    fake = 0 (:func:`adversarial_loss_discriminator`); the authors' code does the same.

    Reduction: mean over all score elements (batch × patches/frames), or per sample.

    Args:
        h_fake: ``(B, ...)`` discriminator scores ``h^B_{2:T}`` of the retargeted motion (Eq. 20).
    """
    return reduce_elements((h_fake - 1.0) ** 2, reduction)


def adversarial_loss_discriminator(
    h_real: Tensor, h_fake: Tensor, fake_mask: Tensor | None = None
) -> Tensor:
    """Discriminator side of Eq. 21 (LSGAN, real → 1, fake → 0): ``(h_real − 1)² + h_fake²``.

    See :func:`adversarial_loss_generator` for how this maps onto the printed equation. No 1/2
    factor (the paper has none).

    Reduction: each of the two terms is a mean over its own score elements; then summed.

    Args:
        h_real: ``(B, ...)`` scores of real clips performed by the target character (Eq. 19;
            Sec. 5: "we sampled the motion clips performed by the character, which was taken as
            the target by the generator").
        h_fake: ``(B', ...)`` scores of retargeted clips (Eq. 20), generator detached.
        fake_mask: optional ``(B',)`` bool: which fake samples count (e.g. ``~same_character``:
            when ``A = B`` the output should equal real motion, so calling it fake is moot). If
            no sample is selected the fake term is 0.
    """
    real = ((h_real - 1.0) ** 2).mean()
    fake = h_fake**2
    if fake_mask is None:
        return real + fake.mean()
    per_sample = reduce_elements(fake, "per_sample")
    w = fake_mask.to(per_sample.dtype)
    return real + (per_sample * w).sum() / w.sum().clamp_min(1.0)


def adversarial_loss(
    h_fake: Tensor,
    x_a: MotionTensors,
    x_b_hat: MotionTensors,
    same_character: Tensor,
    gan: Literal["lsgan", "sigmoid_ce"] = "lsgan",
    reduction: Reduction = "mean",
    quaternion_weight: float = 1.0,
    joints: Sequence[int] | None = None,
    gan_weight: float = 1.0,
) -> Tensor:
    """Generator's ``La`` with Eq. 21's two cases chosen per sample, averaged over the batch.

    For sample ``i``: ``‖x^A − x̂^B‖²`` (:func:`reconstruction_loss`) if ``same_character[i]``
    (the target is the source, 50 % of pairs in the paper), else the GAN term
    (:func:`adversarial_loss_generator`, or :func:`sigmoid_ce_generator_loss` for NKN).
    Each per-sample value is a mean over that sample's elements; the result is their batch mean.

    Args:
        h_fake: ``(B, ...)`` scores of ``x̂^B`` (entries of same-character samples are ignored).
        x_a: source motion (``p (B,T,J,3)``, ``q (B,T,J,4)``, ``r (B,T,3)``).
        x_b_hat: retargeted motion, same shapes.
        same_character: ``(B,)`` bool, ``True`` where ``A = B``.
        gan: ``"lsgan"`` (TDCN) or ``"sigmoid_ce"`` (NKN baseline).
        reduction: ``"mean"`` or ``"frame_sum"`` (see the module docstring): how each sample's
            reconstruction error is reduced; the GAN scores are one per frame pair either way.
        quaternion_weight, joints: of the reconstruction (:func:`reconstruction_loss`).
        gan_weight: multiplies the GAN case only (NKN's released code weighs its GAN 0.001
            against its reconstruction; Eq. 21 and TDCN's code: 1).
    """
    if reduction not in ("mean", "frame_sum"):
        raise ValueError(f"reduction must be 'mean' or 'frame_sum', got {reduction!r}")
    if gan == "lsgan":
        adv = adversarial_loss_generator(h_fake, "per_sample")
    elif gan == "sigmoid_ce":
        adv = sigmoid_ce_generator_loss(h_fake, "per_sample")
    else:
        raise ValueError(f"gan must be 'lsgan' or 'sigmoid_ce', got {gan!r}")
    rec = reconstruction_loss(x_a, x_b_hat, per_sample(reduction), quaternion_weight, joints)
    same = torch.as_tensor(same_character, dtype=torch.bool, device=rec.device)
    if same.shape != rec.shape:
        raise ValueError(f"same_character must be ({rec.shape[0]},), got {tuple(same.shape)}")
    return torch.where(same, rec, gan_weight * adv).mean()


# --------------------------------------------------------------------------------------------
# NKN baseline (Villegas et al. 2018): vanilla GAN
# --------------------------------------------------------------------------------------------


def sigmoid_ce_generator_loss(h_fake: Tensor, reduction: Reduction = "mean") -> Tensor:
    """NKN's (vanilla GAN) generator loss, non-saturating: ``−log σ(h_fake)``.

    TDCN replaces this by least squares (Sec. 4.2 (i)); kept for the NKN baselines.

    Args:
        h_fake: ``(B, ...)`` discriminator **logits** of retargeted motion.
        reduction: mean over all elements, or per sample.
    """
    return reduce_elements(F.softplus(-h_fake), reduction)  # = BCE(σ(h), 1), numerically stable


def sigmoid_ce_discriminator_loss(h_real: Tensor, h_fake: Tensor) -> Tensor:
    """NKN's discriminator loss: ``−log σ(h_real) − log(1 − σ(h_fake))`` (real → 1, fake → 0).

    Reduction: each term a mean over its own elements; then summed.

    Args:
        h_real: ``(B, ...)`` logits of real motion.
        h_fake: ``(B', ...)`` logits of retargeted motion.
    """
    return F.softplus(-h_real).mean() + F.softplus(h_fake).mean()
