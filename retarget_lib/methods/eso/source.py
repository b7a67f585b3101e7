"""What ESO needs from a source motion for one target: the network's input features, the source's
motion quantities (Eweak's targets), the leg ratio and the source's foot contacts."""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np
import torch

from ...core.measures import estimated_standing_height
from ...core.motion import Motion
from ...core.quantities import MotionQuantities, motion_quantities
from ...core.quantities import leg_ratio as skeleton_leg_ratio
from ...core.transfer import transfer_rotations
from ...geometry.contacts import detect_foot_contacts
from ...models.georet import motion_features

Tensor = torch.Tensor

__all__ = ["EsoSource", "eso_source"]


class EsoSource(NamedTuple):
    """Everything ESO needs from a source motion for one target (:func:`eso_source`).

    Attributes:
        features: ``(1, T, 267)`` network input :func:`~retarget_lib.models.georet.motion_features`.
        quantities: source :class:`~retarget_lib.losses.contact.MotionQuantities` (``(T, ...)``).
        leg_ratio: ``h_legs_B / h_legs_A``.
        foot_contacts: ``(T, 4)`` bool source foot contacts.
    """

    features: Tensor
    quantities: MotionQuantities
    leg_ratio: float
    foot_contacts: np.ndarray


def eso_source(
    motion: Motion, target: Any, foot_contacts: np.ndarray | None = None, rest_aligned: bool = False
) -> EsoSource:
    """Prepare a canonical-22 source motion for :func:`encoder_space_optimization` on ``target``.

    Args:
        motion: source motion (metres).
        target: a ``Character``-like object (``.skeleton``).
        foot_contacts: ``(T, 4)`` bool; default
            :func:`retarget_lib.geometry.contacts.detect_foot_contacts` on the source.
        rest_aligned: Eweak's ``θ^A`` (and a residual network's base) are the source rotations
            re-expressed on the target's rest pose
            (:func:`~retarget_lib.core.transfer.transfer_rotations`): pass ``model.residual``
            (see :func:`~retarget_lib.methods.contact.eweak_rotations`).
    """
    rot, root, off = motion.torch(torch.float32)
    height = motion.skeleton.height()
    quantities = motion_quantities(rot, root, off, height, motion.skeleton.parents)
    if rest_aligned:
        aligned = transfer_rotations(motion.rotations, motion.skeleton, target.skeleton)
        quantities = quantities._replace(rotations=torch.as_tensor(aligned, dtype=torch.float32))
    if foot_contacts is None:
        foot_contacts = detect_foot_contacts(
            quantities.positions.double().numpy(),
            motion.skeleton,
            estimated_standing_height(motion.skeleton),
        )
    features = motion_features(rot[None], root[None], off, motion.skeleton.parents, height)
    return EsoSource(
        features,
        quantities,
        skeleton_leg_ratio(motion.skeleton, target.skeleton),
        np.asarray(foot_contacts, dtype=bool),
    )
