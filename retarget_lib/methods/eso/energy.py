"""``Efull(t)`` (Eq. 1), the terms of one frame's energy that depend on that frame (Sec. 3.3):
decode frame ``t`` from the variables, pose it, weigh the terms (:data:`TERMS`)."""

from __future__ import annotations

from typing import cast

import torch

from ...geometry.penetration import plan_energy
from ...losses.contact import (
    ContactEnergyWeights,
    end_effector_energy_per_frame,
    eso_self_contact_energy,
    foot_contact_energy_per_frame,
    reach_hold_energy,
    self_contact_energy,
    weak_energy,
)
from ...models.georet import GeometryConditionedRNN
from .frame import Constants, FrameInputs, Pose, decode

Tensor = torch.Tensor

__all__ = ["TERMS", "frame_terms"]

#: energy terms logged per frame and iteration (``j2j_distance`` is a diagnostic, not in the total)
TERMS: tuple[str, ...] = ("j2j", "hold", "int", "foot", "ee", "weak", "j2j_distance")


def frame_terms(
    model: GeometryConditionedRNN,
    weights: ContactEnergyWeights,
    blend: float,
    cone: dict[str, float],
    constants: Constants,
    frame: FrameInputs,
    h_enc: Tensor,
    o_prev: Tensor,
) -> tuple[Tensor, Pose]:
    """Decode frame ``t`` from ``h^enc_t`` with ``o_(t−1)`` swapped into the state, pose it (FK,
    LBS of the ``U`` vertices the energy reads) and weigh ``Efull(t)``'s terms.

    Tensor operations only, so :func:`torch.compile` can fuse a whole step (``compile=True`` in
    :func:`encoder_space_optimization`).

    Returns:
        ``((len(TERMS) + 1,)`` the weighted :data:`TERMS` and the total last, the pose).
    """
    w = weights
    pose = decode(
        model,
        constants,
        frame.state,
        frame.gates,
        frame.base,
        h_enc,
        o_prev,
        frame.rest_vertices,
        frame.skin_weights,
    )
    rot, pos, verts = pose.rotations, pose.positions, pose.vertices
    terms = dict.fromkeys(TERMS, pos.new_zeros(()))
    if verts is not None and w.j2j_weight > 0:
        relaxed = eso_self_contact_energy(
            verts[0], frame.pairs, frame.initial_vertices, blend, frame.pair_mask
        )
        terms["j2j"] = w.lambda_j2j * w.in_units("j2j", relaxed)
        terms["j2j_distance"] = self_contact_energy(verts[0], frame.pairs, frame.pair_mask).detach()
    if w.hold > 0:
        drift = reach_hold_energy(pos[0], frame.initial_positions, frame.hold)
        terms["hold"] = w.hold * w.in_units("hold", drift)
    if verts is not None and frame.eint is not None:
        terms["int"] = w.int_weight * w.in_units("int", plan_energy(verts, frame.eint, cone)[0])
    window = torch.stack((frame.previous[0], pos[0]))[None]  # (1, 2, 22, 3)
    if w.foot_weight > 0:
        foot = foot_contact_energy_per_frame(
            window, frame.foot_contacts, constants.ground_heights, constants.height
        )[0, 1]
        terms["foot"] = w.foot_weight * w.in_units("foot", foot)
    if w.omega > 0:
        terms["ee"] = (
            w.omega
            * end_effector_energy_per_frame(
                window,
                frame.src_positions,
                constants.height,
                w.ee_source_height(constants.height, constants.source_height, constants.leg_ratio),
            )[0, 1]
        )
    unit = w.length_unit
    terms["weak"] = weak_energy(
        rot,
        frame.src_rotations,
        o_prev / unit,
        frame.src_prev_velocity / unit,
        constants.leg_ratio,
        w.rho,
    )[0]
    total = cast(Tensor, sum(v for k, v in terms.items() if k != "j2j_distance"))
    return torch.stack([terms[k] for k in TERMS] + [total]), pose
