"""Quantities read from a motion by both the networks and the losses (plain tensors, no models).

TDCN (Kim et al. 2020): the height-normalised joint and root displacements ``l``, ``m``, ``δ``
(Eqs. 9-12, 15-18) and the discriminator's inputs ``(l, δ, B)`` (Eqs. 19/20) — the networks build
their features from them (:mod:`retarget_lib.models.features`) and the height loss compares them
(:func:`retarget_lib.losses.tdcn.height_loss`).

Contact-aware retargeting (Villegas et al. 2021): the root velocity ``o`` (Eqs. 8, 17-18), frame
velocities, the leg-length ratio ``h_legs_B / h_legs_A`` (also the ground truth's root scale,
:func:`retarget_lib.core.transfer.retarget_ground_truth`), and :class:`MotionQuantities`, what
Eskel and Efoot read from a motion (:mod:`retarget_lib.losses.contact`). The heights and the
feet's rest heights they use are those of :mod:`retarget_lib.core.measures`.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple, cast

import numpy as np
import torch

from .kinematics import forward_kinematics
from .measures import skeleton_leg_length
from .skeleton import CANONICAL22_PARENTS, FOOT_CONTACT_JOINTS, J, Skeleton

Tensor = torch.Tensor
Scalar = float | Tensor

__all__ = [
    "DiscriminatorInputs",
    "normalized_joint_displacements",
    "normalized_root_distances",
    "normalized_root_displacements",
    "discriminator_inputs",
    "FOOT_CONTACT_IDS",
    "leg_ratio",
    "hip_facing",
    "forward_root_velocity",
    "frame_velocities",
    "MotionQuantities",
    "motion_quantities",
]


# --------------------------------------------------------------------------- TDCN (Kim et al. 2020)
class DiscriminatorInputs(NamedTuple):
    """What the discriminator sees of one motion (Eqs. 19/20).

    Attributes:
        l: ``(B, T-1, J)`` per-joint frame-to-frame displacement magnitudes over ``H`` (Eq. 11/12).
        delta: ``(B, T-1)`` root displacement magnitudes over ``H`` (Eq. 18).
        bones: ``(B, J)`` bone lengths in metres (``B^A``/``B^B`` of Eqs. 19/20), not normalised.
    """

    l: Tensor  # noqa: E741 (the paper's symbol; a public field name)
    delta: Tensor
    bones: Tensor


def _heights(h, batch: int, like: Tensor) -> Tensor:
    """``h`` (float, 0-d or ``(B,)``) as a ``(B,)`` tensor of ``like``'s dtype/device."""
    h = torch.as_tensor(h, dtype=like.dtype, device=like.device)
    if h.dim() == 0:
        h = h.expand(batch)
    if h.shape != (batch,):
        raise ValueError(f"height must be a float or shape ({batch},), got {tuple(h.shape)}")
    return h


def normalized_joint_displacements(p: Tensor, h) -> Tensor:
    """``l_t = ‖p_t − p_{t−1}‖ / H`` for ``t = 2..T`` (Eqs. 9-12).

    Args:
        p: ``(B, T, J, 3)`` root-relative joint positions, metres.
        h: character heights ``H``, float or ``(B,)``, metres.

    Returns:
        ``(B, T-1, J)`` dimensionless.
    """
    _check_last("p", p, 3, 4)
    if p.shape[1] < 2:
        raise ValueError(f"need T >= 2 frames for displacements, got T={p.shape[1]}")
    d = p[:, 1:] - p[:, :-1]
    return torch.linalg.vector_norm(d, dim=-1) / _heights(h, p.shape[0], p)[:, None, None]


def normalized_root_distances(r: Tensor, h) -> Tensor:
    """``m_t = ‖r_t‖ / H`` for ``t = 1..T`` (Eqs. 15-16; motion assumed around the origin).

    Args:
        r: ``(B, T, 3)`` root positions, metres.
        h: float or ``(B,)`` heights, metres.

    Returns:
        ``(B, T)``.
    """
    _check_last("r", r, 3, 3)
    return torch.linalg.vector_norm(r, dim=-1) / _heights(h, r.shape[0], r)[:, None]


def normalized_root_displacements(r: Tensor, h) -> Tensor:
    """``δ_t = ‖r_t − r_{t−1}‖ / H`` for ``t = 2..T`` (Eq. 18).

    Args:
        r: ``(B, T, 3)`` root positions, metres.
        h: float or ``(B,)`` heights, metres.

    Returns:
        ``(B, T-1)``.
    """
    _check_last("r", r, 3, 3)
    if r.shape[1] < 2:
        raise ValueError(f"need T >= 2 frames for displacements, got T={r.shape[1]}")
    return normalized_root_distances(r[:, 1:] - r[:, :-1], h)


def discriminator_inputs(p: Tensor, r: Tensor, offsets: Tensor, h) -> DiscriminatorInputs:
    """The discriminator's inputs ``(l, δ, B)`` for one motion (Eqs. 11/12, 18, 19/20).

    Args:
        p: ``(B, T, J, 3)`` root-relative joint positions (real ``p^A`` or generated ``p̂^B``).
        r: ``(B, T, 3)`` root positions.
        offsets: ``(J, 3)`` or ``(B, J, 3)`` rest offsets of the character performing ``p``.
        h: that character's ``H``, float or ``(B,)``.

    Returns:
        :class:`DiscriminatorInputs`: ``l (B, T-1, J)``, ``delta (B, T-1)``, ``bones (B, J)``.
        ``bones[:, j] = ‖offsets[j]‖`` in metres, un-normalised (the paper normalises only ``l``
        and ``δ``; Sec. 4.2 (ii)); entry 0 is the root's rest-position norm, as in
        :meth:`Skeleton.bone_lengths` and the authors' code.
    """
    batch = p.shape[0]
    offsets = torch.as_tensor(offsets, dtype=p.dtype, device=p.device)
    if offsets.dim() == 2:
        offsets = offsets.expand(batch, *offsets.shape)
    if offsets.shape != (batch, p.shape[2], 3):
        raise ValueError(
            f"offsets must be (J,3) or (B,J,3) with J={p.shape[2]}, got {tuple(offsets.shape)}"
        )
    return DiscriminatorInputs(
        normalized_joint_displacements(p, h),
        normalized_root_displacements(r, h),
        torch.linalg.vector_norm(offsets, dim=-1),
    )


def _check_last(name: str, x: Tensor, channels: int, ndim: int) -> None:
    if x.dim() != ndim or x.shape[-1] != channels:
        raise ValueError(f"{name} must have {ndim} dims ending in {channels}, got {tuple(x.shape)}")


# ------------------------------------------------------------- contact-aware (Villegas et al. 2021)
#: canonical ids of the Efoot joints, in :data:`retarget_lib.core.skeleton.FOOT_CONTACT_JOINTS`
#: order
FOOT_CONTACT_IDS: tuple[int, ...] = tuple(J[n] for n in FOOT_CONTACT_JOINTS)


def leg_ratio(source: Skeleton, target: Skeleton) -> float:
    """``h_legs_B / h_legs_A``, the factor turning ``o^A`` into ``o^(A→B)`` (Eq. 8), with ``h_legs``
    the leg length in the retarget pose
    (:func:`~retarget_lib.core.measures.skeleton_leg_length`)."""
    return skeleton_leg_length(target) / skeleton_leg_length(source)


def hip_facing(left_hip: Tensor, right_hip: Tensor) -> Tensor:
    """A body's horizontal facing direction from its hips: ``forward = (left − right hip) × up``,
    in the ground plane (+Y up; a body whose left hip is at +X faces +Z). The one facing rule,
    read by :meth:`Motion.facing() <retarget_lib.core.motion.Motion.facing>` and the NKN
    baseline's facing frame (:func:`~retarget_lib.models.features.to_facing_frame`).

    Args:
        left_hip: ``(..., 3)`` left up-leg joint positions (metres; root-relative or world).
        right_hip: ``(..., 3)`` right up-leg joint positions, same frame.

    Returns:
        ``(..., 2)`` unit ``(f_x, f_z)`` (a zero hip axis gives a zero vector).
    """
    across = left_hip - right_hip
    fwd = torch.stack((-across[..., 2], across[..., 0]), -1)  # (a × +Y) in the xz plane
    return fwd / fwd.norm(dim=-1, keepdim=True).clamp_min(1e-9)


def forward_root_velocity(root_positions: Tensor) -> Tensor:
    """Root velocity ``o_t = r_(t+1) − r_t`` (Eqs. 8, 17-18: ``o_(t−1)`` moves frame ``t−1`` to
    ``t``).

    The last frame repeats the previous velocity (a one-frame clip gets zero).

    Args:
        root_positions: ``(..., T, 3)`` metres.

    Returns:
        ``(..., T, 3)`` metres per frame; ``r_t = r_0 + Σ_(k<t) o_k``.
    """
    if root_positions.shape[-2] < 2:
        return torch.zeros_like(root_positions)
    step = root_positions.diff(dim=-2)
    return torch.cat((step, step[..., -1:, :]), dim=-2)


def frame_velocities(positions: Tensor) -> Tensor:
    """Backward-difference velocities ``ġ_t = g_t − g_(t−1)``, zero at the first frame (Eqs. 6, 9).

    Args:
        positions: ``(..., T, J, 3)`` metres.

    Returns:
        ``(..., T, J, 3)`` metres per frame.
    """
    return torch.cat((torch.zeros_like(positions[..., :1, :, :]), positions.diff(dim=-3)), dim=-3)


class MotionQuantities(NamedTuple):
    """What Eskel and Efoot read from one motion (source ``A`` or output ``B``).

    Attributes:
        rotations: ``(..., T, 22, 4)`` local rotations, unit wxyz.
        root_velocity: ``(..., T, 3)`` ``o_t`` (:func:`forward_root_velocity`), metres per frame.
        positions: ``(..., T, 22, 3)`` global joint positions ``g`` (metres).
        height: character height ``h`` (metres), a float or ``(...)`` tensor.
    """

    rotations: Tensor
    root_velocity: Tensor
    positions: Tensor
    height: Scalar


def motion_quantities(
    rotations: Tensor,
    root_positions: Tensor,
    offsets: Tensor | np.ndarray,
    height: Scalar,
    parents: Sequence[int] = CANONICAL22_PARENTS,
) -> MotionQuantities:
    """:class:`MotionQuantities` of a motion: FK for ``g`` and :func:`forward_root_velocity`.

    Args:
        rotations: ``(..., T, 22, 4)`` local unit wxyz.
        root_positions: ``(..., T, 3)`` metres.
        offsets: ``(22, 3)`` or ``(..., 1, 22, 3)`` rest offsets (metres).
        height: the character's height ``h`` (metres), float or ``(...)``.
        parents: joint parents.
    """
    positions = cast(
        Tensor, forward_kinematics(rotations, offsets, parents, root_positions).positions
    )
    return MotionQuantities(rotations, forward_root_velocity(root_positions), positions, height)
