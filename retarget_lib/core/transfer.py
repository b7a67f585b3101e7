"""Rest-pose transfer: the ground-truth retargeting of synthetic motion (the copy baselines built on
it are methods: :mod:`retarget_lib.methods.copy`, :mod:`retarget_lib.methods.copy_rest`).

Ground truth of the synthetic data: the target performs the source's rotation **deltas from the
retarget pose** (:mod:`retarget_lib.core.retarget_pose`), and the root trajectory scaled by the
leg-length ratio -- what Mixamo produces when one animation is applied to many characters, and
what Unreal's IK Retargeter does between rigs of different conventions.

Why copying local rotations is a baseline and not the answer: a local rotation is relative to the
rest pose, and rest *conventions* differ (A-pose vs T-pose arms, splayed CMU legs, a rig lying
down). Copying ``q_j`` from an A-pose character onto a T-pose character raises every arm by the
A/T angle difference. Per joint a constant rotation ``C_j = (P^A_j)^-1 P^B_j`` built from the two
retarget poses ``P`` removes the convention and keeps each character's own shape (a forearm's
droop, a spine's tilt); ``G^B_j = G^A_j C_j`` for every global rotation ``G``, in local terms
``q^B_j = C_p^-1 q^A_j C_j`` (``p`` = parent). Two T-pose binds have ``C = 1``: they retarget by
copying their local rotations, as Mixamo's do.
"""

from __future__ import annotations

import numpy as np
import torch

from .kinematics import align_local_rotations
from .motion import Motion
from .quantities import leg_ratio
from .retarget_pose import PRIMARY_CHILD, pose_offsets, rest_alignment, retarget_alignment
from .rotations import quat_canonical, quat_conjugate, quat_from_axis_angle
from .skeleton import CANONICAL22_PARENTS, J, Skeleton

__all__ = [
    "ACROSS_PAIR",
    "transfer_rotations",
    "transfer_rotations_tensor",
    "retarget_ground_truth",
    "change_rest_pose",
    "random_rest_rotations",
]

#: joints whose whole frame a random rest change turns (the hips and the chest)
ACROSS_PAIR: dict[int, tuple[int, int]] = {
    J["Hips"]: (J["LeftUpLeg"], J["RightUpLeg"]),
    J["Spine2"]: (J["LeftShoulder"], J["RightShoulder"]),
}


def transfer_rotations(
    rotations: np.ndarray,
    source: Skeleton,
    target: Skeleton,
    source_pose: np.ndarray | None = None,
    target_pose: np.ndarray | None = None,
) -> np.ndarray:
    """Local rotations of ``source`` -> local rotations of ``target`` performing the same
    rotation deltas from the retarget pose: ``q^B_j = C_p^-1 q^A_j C_j`` with
    ``C = (P^A)^-1 P^B`` (:func:`~retarget_lib.core.retarget_pose.rest_alignment`).

    Args:
        rotations: ``(..., 22, 4)`` local rotations on ``source``, wxyz.
        source: the skeleton ``rotations`` belong to.
        target: the skeleton to express them on.
        source_pose, target_pose: ``(22, 4)`` retarget poses when already known (a mesh's
            soles, :func:`~retarget_lib.core.retarget_pose.retarget_pose`); default from the
            skeletons alone.

    Returns:
        ``(..., 22, 4)`` local rotations on ``target``, float64.
    """
    c = torch.from_numpy(rest_alignment(source, target, source_pose, target_pose))
    q = torch.from_numpy(np.asarray(rotations, dtype=np.float64))
    return quat_canonical(align_local_rotations(q, c, CANONICAL22_PARENTS)).numpy()


def transfer_rotations_tensor(
    rotations: torch.Tensor, offsets_src: torch.Tensor, offsets_tgt: torch.Tensor
) -> torch.Tensor:
    """:func:`transfer_rotations` for batches of tensors (training).

    Args:
        rotations: ``(B, T, 22, 4)`` local rotations on the source skeletons.
        offsets_src: ``(B, 22, 3)`` their rest offsets.
        offsets_tgt: ``(B, 22, 3)`` the target skeletons' rest offsets.

    Returns:
        ``(B, T, 22, 4)`` local rotations on the targets (raw product, unit for unit input).
    """
    c = retarget_alignment(offsets_src, offsets_tgt).to(rotations.dtype)
    return align_local_rotations(rotations, c.unsqueeze(-3), CANONICAL22_PARENTS)


def change_rest_pose(
    rotations: torch.Tensor,
    offsets: torch.Tensor,
    turns: torch.Tensor,
    parents: tuple[int, ...] = CANONICAL22_PARENTS,
) -> tuple[torch.Tensor, torch.Tensor]:
    """The same motion on the same character with a different rest pose.

    Every child offset of joint ``j`` is turned by ``R_j`` (``s̄'_c = R_p(c) s̄_c``; the root's
    own offset is kept), and the local rotations become ``q'_j = R_p(j) q_j R_j⁻¹`` (``R`` of the
    root's parent = 1): then ``G'_j = G_j R_j⁻¹`` and ``G'_j s̄'_c = G_j s̄_c``, so every joint is
    at exactly the same place in every frame: the rest pose is a convention of the file, not of the
    motion. (A retargeter compensates only the part of such a change that the retarget pose sees,
    :func:`transfer_rotations`: a turn within its tolerance is read as the character's shape.)

    Args:
        rotations: ``(..., T, J, 4)`` local unit quaternions (wxyz).
        offsets: ``(..., J, 3)`` rest offsets.
        turns: ``(..., J, 4)`` unit ``R_j``; identity rows leave a joint's rest frame alone.
        parents: ``J`` parent indices (root first, ``-1``).

    Returns:
        ``(rotations' (..., T, J, 4), offsets' (..., J, 3))``.
    """
    moved = pose_offsets(offsets, turns, parents)
    return align_local_rotations(rotations, quat_conjugate(turns).unsqueeze(-3), parents), moved


def random_rest_rotations(
    offsets: torch.Tensor, max_degrees: float, generator: torch.Generator | None = None
) -> torch.Tensor:
    """Random rest-pose changes ``R`` for :func:`change_rest_pose` (training augmentation).

    Each joint with a bone (:data:`PRIMARY_CHILD`) swings it by an angle uniform in
    ``[0, max_degrees]`` about a random axis perpendicular to the bone (a turn about the bone
    itself would move no joint); the hips and the chest turn their whole frame about a random
    axis. Leaves (head, hands, toes) keep theirs.

    Args:
        offsets: ``(B, J, 3)`` canonical-22 rest offsets.
        max_degrees: largest swing.
        generator: torch RNG (default the global one).

    Returns:
        ``(B, J, 4)`` unit wxyz, float32.
    """
    b = offsets.shape[0]
    has_bone = torch.tensor([c >= 0 for c in PRIMARY_CHILD])
    bone = offsets[:, [max(c, 0) for c in PRIMARY_CHILD]]  # (B, J, 3)
    axis = torch.randn(b, len(PRIMARY_CHILD), 3, generator=generator)
    swing = axis - bone * (axis * bone).sum(-1, keepdim=True) / (bone * bone).sum(
        -1, keepdim=True
    ).clamp_min(1e-12)
    frame_joint = torch.zeros(len(PRIMARY_CHILD), dtype=torch.bool)
    frame_joint[list(ACROSS_PAIR)] = True
    axis = torch.where(frame_joint[:, None], axis, swing)
    axis = axis / axis.norm(dim=-1, keepdim=True).clamp_min(1e-12)
    angle = torch.rand(b, len(PRIMARY_CHILD), 1, generator=generator) * np.radians(max_degrees)
    return quat_from_axis_angle(axis * angle * has_bone[:, None])


def retarget_ground_truth(motion: Motion, target_skeleton: Skeleton) -> Motion:
    """The ground-truth retargeting of a synthetic motion onto another character (see the module
    docstring).

    The target performs the source's rotation deltas from the retarget pose
    (:func:`transfer_rotations`: an A-pose source and a T-pose target end up with the same
    world-space arms, two T-pose binds copy their local rotations), and the root
    trajectory is multiplied by the ratio of the two leg lengths
    (:func:`~retarget_lib.core.quantities.leg_ratio`; like Mixamo, and like TDCN's root-velocity
    normalisation by leg length, Sec. 4.1). Nothing else is adjusted: when limb *proportions*
    differ the target's feet may slide or float a little -- exactly the
    contact errors that the contact-aware method (Villegas et al. 2021) is designed to remove.

    Args:
        motion: source motion on the canonical 22 joints.
        target_skeleton: canonical-22 target character.

    Returns:
        the target's :class:`Motion` (same frames and fps).
    """
    rot = transfer_rotations(motion.rotations, motion.skeleton, target_skeleton)
    root = motion.root_positions * leg_ratio(motion.skeleton, target_skeleton)
    return motion.copy(
        skeleton=target_skeleton.copy(),
        rotations=rot,
        root_positions=root,
        meta=dict(motion.meta, retargeted="ground_truth"),
    )
