"""Rest-pose transfer: the ground-truth retargeting of synthetic motion (the copy baselines built on
it are methods: :mod:`retarget_lib.methods.copy`, :mod:`retarget_lib.methods.copy_rest`).

Ground truth of the synthetic data: the target performs the source's motion with the same *global*
bone directions and twists, rest-pose differences compensated, and the root trajectory scaled by
the leg-length ratio -- what Mixamo produces when one animation is applied to many characters.

Why copying local rotations is a baseline and not the answer: a local rotation is relative to the
rest pose, and rest poses differ (A-pose vs T-pose arms, a curved vs straight spine, splayed
feet). Copying ``q_j`` from an A-pose character onto a T-pose character raises every arm by the
A/T angle difference. Rest-compensation fixes exactly that: per joint a constant rotation ``C_j``
maps the target's rest bone direction onto the source's, and ``G^B_j = G^A_j C_j`` for every
global rotation ``G``; in local terms ``q^B_j = C_p^-1 q^A_j C_j`` (``p`` = parent). Both
characters then point every bone the same way in the world (TDCN's and NKN's evaluation compare
against this kind of target).
"""

from __future__ import annotations

import numpy as np
import torch

from .kinematics import align_local_rotations
from .motion import Motion
from .quantities import leg_ratio
from .rotations import (
    frame_rotation,
    quat_between,
    quat_canonical,
    quat_conjugate,
    quat_from_axis_angle,
    quat_identity,
    quat_rotate,
)
from .skeleton import (
    CANONICAL22,
    CANONICAL22_PARENTS,
    FOOT_CONTACT_JOINTS,
    J,
    JointSetError,
    Skeleton,
    canonical22_skeleton,
)

__all__ = [
    "PRIMARY_CHILD",
    "ACROSS_PAIR",
    "FOOT_JOINTS_AS_REST",
    "keep_feet_as_rest",
    "rest_alignment",
    "transfer_rotations",
    "retarget_ground_truth",
    "canonical_rest_skeleton",
    "change_rest_pose",
    "random_rest_rotations",
]

#: the child whose bone defines each canonical joint's rest direction (-1: leaf, uses its parent's)
PRIMARY_CHILD: tuple[int, ...] = tuple(
    {
        "Hips": J["Spine"],
        "Spine": J["Spine1"],
        "Spine1": J["Spine2"],
        "Spine2": J["Neck"],
        "Neck": J["Head"],
        "LeftUpLeg": J["LeftLeg"],
        "LeftLeg": J["LeftFoot"],
        "LeftFoot": J["LeftToeBase"],
        "RightUpLeg": J["RightLeg"],
        "RightLeg": J["RightFoot"],
        "RightFoot": J["RightToeBase"],
        "LeftShoulder": J["LeftArm"],
        "LeftArm": J["LeftForeArm"],
        "LeftForeArm": J["LeftHand"],
        "RightShoulder": J["RightArm"],
        "RightArm": J["RightForeArm"],
        "RightForeArm": J["RightHand"],
    }.get(name, -1)
    for name in CANONICAL22
)

#: joints with several children: their rest frame also uses the left-minus-right child offset
ACROSS_PAIR: dict[int, tuple[int, int]] = {
    J["Hips"]: (J["LeftUpLeg"], J["RightUpLeg"]),
    J["Spine2"]: (J["LeftShoulder"], J["RightShoulder"]),
}


#: the joints whose rest orientation is "standing flat on the floor" on every character (the foot
#: contact joints, heels and toes): their rest alignment is the identity when
#: :func:`keep_feet_as_rest` is asked for
FOOT_JOINTS_AS_REST: tuple[int, ...] = tuple(J[n] for n in FOOT_CONTACT_JOINTS)


def keep_feet_as_rest(alignment: torch.Tensor) -> torch.Tensor:
    """Rest alignments with the feet and toes set to the identity (a copy, ``alignment`` unchanged).

    Every character, real or ours, is modelled standing flat-footed: the direction of its
    ankle->toe bone is where the rigger put two joints on the foot, not a pose. Compensating it
    (``G^B = G^A C``) tilts the target's foot by the angle between the two characters' foot
    bones, so where the source stands flat the target's heel or toe leaves the floor. With ``C = 1``
    the feet copy the source's rotation from its rest (``G^B_foot = G^A_foot``): flat where the
    source's are flat. Measured on the real-character set (``retarget evaluate --table real``, TDCN
    default): floating feet 1.73 -> 1.04 % of height, foot-contact mismatch 0.117 -> 0.078,
    jitter 0.31 -> 0.11 (the tilt the network varied frame to frame); on the varied-rest Table 4,
    whose synthetic characters splay their feet in the rest pose on purpose, 0.040 -> 0.041.

    Args:
        alignment: ``(..., 22, 4)`` wxyz rest alignments (:func:`rest_alignment`, or a network's).

    Returns:
        ``(..., 22, 4)`` with the :data:`FOOT_JOINTS_AS_REST` rows ``(1, 0, 0, 0)``.
    """
    out = alignment.clone()
    out[..., list(FOOT_JOINTS_AS_REST), :] = quat_identity(dtype=out.dtype, device=out.device)
    return out


def _check(skeleton: Skeleton) -> None:
    if not skeleton.is_canonical22():
        raise JointSetError(
            "rest alignment needs the canonical 22 joints; fold the motion first "
            "with retarget_lib.io.joint_maps.to_canonical22"
        )


def rest_alignment(source: Skeleton, target: Skeleton) -> np.ndarray:
    """Per-joint constant rotations that compensate rest-pose differences.

    ``C_j`` maps the target's rest bone direction of joint ``j`` (towards
    :data:`PRIMARY_CHILD`) onto the source's, by the shortest arc; for the hips and the chest
    (:data:`ACROSS_PAIR`) it maps the whole rest frame (bone + left-right axis). A leaf (head,
    hands, toes) has no bone of its own and uses its parent's ``C``. Then ``G^B_j = G^A_j C_j``
    gives both characters the same global bone directions.

    Args:
        source: canonical-22 skeleton ``A``.
        target: canonical-22 skeleton ``B``.

    Returns:
        ``(22, 4)`` wxyz; identity rows where the rest poses agree (e.g. uniform scaling).
    """
    _check(source)
    _check(target)
    off_a, off_b = torch.from_numpy(source.offsets), torch.from_numpy(target.offsets)
    out = quat_identity((22,), dtype=torch.float64)
    for j, child in enumerate(PRIMARY_CHILD):
        if child < 0:
            out[j] = out[CANONICAL22_PARENTS[j]]
        elif j in ACROSS_PAIR:
            left, right = ACROSS_PAIR[j]
            out[j] = torch.as_tensor(
                frame_rotation(
                    off_b[child],
                    off_b[left] - off_b[right],
                    off_a[child],
                    off_a[left] - off_a[right],
                )
            )
        else:
            out[j] = quat_between(off_b[child], off_a[child])
    return quat_canonical(out).numpy()


def transfer_rotations(
    rotations: np.ndarray, source: Skeleton, target: Skeleton, feet_as_rest: bool = False
) -> np.ndarray:
    """Local rotations of ``source`` -> local rotations of ``target`` with the same global bone
    directions and twists: ``q^B_j = C_p^-1 q^A_j C_j`` (:func:`rest_alignment`).

    Args:
        rotations: ``(..., 22, 4)`` local rotations on ``source``, wxyz.
        source: the skeleton ``rotations`` belong to.
        target: the skeleton to express them on.
        feet_as_rest: leave the feet's rest difference alone (:func:`keep_feet_as_rest`): what
            the methods do on a user's characters; the synthetic ground truth compensates it.

    Returns:
        ``(..., 22, 4)`` local rotations on ``target``, float64.
    """
    c = torch.from_numpy(rest_alignment(source, target))
    if feet_as_rest:
        c = keep_feet_as_rest(c)
    q = torch.from_numpy(np.asarray(rotations, dtype=np.float64))
    return quat_canonical(align_local_rotations(q, c, CANONICAL22_PARENTS)).numpy()


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
    at exactly the same place in every frame. It is the inverse view of
    :func:`transfer_rotations` (``R_j = C_j⁻¹``): the rest pose is a convention of the file, not
    of the motion, which is why a retargeter must compensate it (A-pose arms, splayed CMU legs).

    Args:
        rotations: ``(..., T, J, 4)`` local unit quaternions (wxyz).
        offsets: ``(..., J, 3)`` rest offsets.
        turns: ``(..., J, 4)`` unit ``R_j``; identity rows leave a joint's rest frame alone.
        parents: ``J`` parent indices (root first, ``-1``).

    Returns:
        ``(rotations' (..., T, J, 4), offsets' (..., J, 3))``.
    """
    moved = torch.cat(
        (offsets[..., :1, :], quat_rotate(turns[..., list(parents[1:]), :], offsets[..., 1:, :])),
        -2,
    )
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

    Every global bone direction and twist of the source is reproduced (:func:`transfer_rotations`;
    an A-pose source and a T-pose target end up with the same world-space arms), and the root
    trajectory is multiplied by ``target.leg_length() / source.leg_length()`` (like Mixamo, and
    like TDCN's root-velocity normalisation by leg length, Sec. 4.1). Nothing else is adjusted:
    when limb *proportions* differ the target's feet may slide or float a little -- exactly the
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


def _canonical_direction(j: int) -> np.ndarray | None:
    """Canonical rest direction of joint ``j``'s offset (``None``: keep the character's own)."""
    name = CANONICAL22[j]
    if name in ("Spine1", "Spine2", "Head"):
        return np.array([0.0, 1.0, 0.0])
    if name.endswith(("Leg", "Foot")) and not name.endswith("UpLeg"):
        return np.array([0.0, -1.0, 0.0])
    if name.endswith(("Arm", "Hand")):
        return np.array([1.0 if name.startswith("Left") else -1.0, 0.0, 0.0])
    return None


def canonical_rest_skeleton(skeleton: Skeleton) -> Skeleton:
    """The same character with its bones in canonical rest directions (the authoring frame).

    Bone lengths are kept. Spine, neck and head bones point up (+Y), thighs and shins down, the
    clavicle-arm-forearm-hand chains sideways (T-pose); the pelvis and chest are turned rigidly so
    that their spine bone points up and their left-right axis along +X (the hip and shoulder
    offsets keep their shape); feet keep the character's own rest direction.

    Args:
        skeleton: canonical-22 skeleton.

    Returns:
        the reference :class:`Skeleton`.
    """
    off = skeleton.offsets.copy()
    for j in range(22):
        direction = _canonical_direction(j)
        if direction is not None:
            off[j] = np.linalg.norm(skeleton.offsets[j]) * direction
    for j, (left, right) in ACROSS_PAIR.items():
        up = skeleton.offsets[PRIMARY_CHILD[j]]
        across = skeleton.offsets[left] - skeleton.offsets[right]
        e1 = up / np.linalg.norm(up)
        e2 = across - (across @ e1) * e1
        e2 /= np.linalg.norm(e2)
        frame = np.stack((e2, e1, np.cross(e2, e1)), axis=0)  # rows: where x, y, z come from
        for child in (c for c, p in enumerate(CANONICAL22_PARENTS) if p == j):
            off[child] = frame @ skeleton.offsets[child]
    return canonical22_skeleton(off)
