"""Loss functions on plain tensors. :mod:`.tdcn` — TDCN's six training losses (Kim et al. 2020,
Eqs. 6-23) and the NKN baseline's vanilla-GAN losses; :mod:`.contact` — the contact-aware
energies of Villegas et al. 2021 (Eqs. 1-3, 6-9; Eint is :mod:`retarget_lib.geometry.penetration`).
The motion quantities they compare (normalised displacements, root velocities, ...) are in
:mod:`retarget_lib.core.quantities`."""

from .contact import (
                      TABLE3_ROWS,
                      ContactEnergyWeights,
                      end_effector_energy,
                      eso_self_contact_energy,
                      foot_contact_energy,
                      full_energy,
                      geometry_energy,
                      self_contact_energy,
                      skeleton_energy,
                      weak_energy,
)
from .tdcn import (
                      TERM_WEIGHTS,
                      MotionTensors,
                      NonFiniteLossError,
                      PositionScale,
                      TDCNLossWeights,
                      adversarial_loss,
                      adversarial_loss_discriminator,
                      adversarial_loss_generator,
                      bone_direction_loss,
                      check_finite,
                      cycle_loss,
                      height_loss,
                      orientation_loss,
                      reconstruction_loss,
                      regularization_loss,
                      sigmoid_ce_discriminator_loss,
                      sigmoid_ce_generator_loss,
                      smooth_l1,
                      total_generator_loss,
                      twist_loss,
                      twist_penalty,
)

__all__ = [
    "ContactEnergyWeights", "TABLE3_ROWS", "end_effector_energy", "eso_self_contact_energy",
    "foot_contact_energy", "full_energy", "geometry_energy", "self_contact_energy", "skeleton_energy",
    "weak_energy",
    "MotionTensors", "NonFiniteLossError", "PositionScale", "TDCNLossWeights", "TERM_WEIGHTS", "adversarial_loss", "bone_direction_loss",
    "adversarial_loss_discriminator", "adversarial_loss_generator", "check_finite", "cycle_loss",
    "height_loss", "orientation_loss", "reconstruction_loss", "regularization_loss",
    "sigmoid_ce_discriminator_loss", "sigmoid_ce_generator_loss", "smooth_l1", "total_generator_loss",
    "twist_loss", "twist_penalty",
]
