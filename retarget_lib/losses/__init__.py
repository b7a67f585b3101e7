"""Loss functions on plain tensors. :mod:`.tdcn` — TDCN's six training losses (Kim et al. 2020,
Eqs. 6-23) and the NKN baseline's vanilla-GAN losses; :mod:`.contact` — the contact-aware
energies of Villegas et al. 2021 (Eqs. 1-3, 6-9; Eint is :mod:`retarget_lib.geometry.penetration`)."""

from .contact import (ContactEnergyWeights, MotionQuantities, TABLE3_ROWS, end_effector_energy,
                      eso_self_contact_energy, foot_contact_energy, full_energy, geometry_energy,
                      motion_quantities, self_contact_energy, skeleton_energy, weak_energy)
from .tdcn import (DiscriminatorInputs, MotionTensors, NonFiniteLossError, TDCNLossWeights,
                   TERM_WEIGHTS, adversarial_loss, adversarial_loss_discriminator,
                   adversarial_loss_generator, check_finite, cycle_loss, discriminator_inputs,
                   height_loss, normalized_joint_displacements, normalized_root_displacements,
                   normalized_root_distances, reconstruction_loss, regularization_loss,
                   orientation_loss, sigmoid_ce_discriminator_loss, sigmoid_ce_generator_loss,
                   smooth_l1, total_generator_loss, twist_loss, twist_penalty)

__all__ = [
    "ContactEnergyWeights", "MotionQuantities", "TABLE3_ROWS", "end_effector_energy",
    "eso_self_contact_energy", "foot_contact_energy", "full_energy", "geometry_energy",
    "motion_quantities", "self_contact_energy", "skeleton_energy", "weak_energy",
    "DiscriminatorInputs", "MotionTensors", "NonFiniteLossError", "TDCNLossWeights",
    "TERM_WEIGHTS", "adversarial_loss", "adversarial_loss_discriminator",
    "adversarial_loss_generator", "check_finite", "cycle_loss", "discriminator_inputs",
    "height_loss", "normalized_joint_displacements", "normalized_root_displacements",
    "normalized_root_distances", "reconstruction_loss", "regularization_loss", "orientation_loss",
    "sigmoid_ce_discriminator_loss", "sigmoid_ce_generator_loss", "smooth_l1",
    "total_generator_loss", "twist_loss", "twist_penalty",
]
