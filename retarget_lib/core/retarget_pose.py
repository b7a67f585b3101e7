"""The retarget pose: one canonical T-pose for every rig, and the rest alignment built on it.

Rigs disagree on what their zero rotations mean. Mixamo binds every character in its T-pose; a
MakeHuman or VRM rig may rest in an A-pose; a research mocap file may rest lying down (its spine
along +X) or with splayed legs. Copying local rotations between two such rigs copies the
*convention* along with the motion; aligning every bone of the target to the source's global
direction (what this library did before) removes the convention but also the character's own
shape: a forearm that droops 6 degrees, a spine tilted 7 degrees, toes at 45-63 degrees, which
Mixamo's own retargeting keeps (it copies local rotations between its T-pose binds).

Animation tools solve this with a **retarget pose** (Unreal's IK Retargeter poses both rigs in one
reference pose and copies rotations as deltas from it; Mixamo's auto-rigger normalises every
upload to its T-pose). Here it is the canonical T-pose, reached from the rest pose by rotating as
few joints as possible:

* the **body** (``Hips``) turns, as a whole frame, so that the spine (hips -> neck) points up
  (+Y), the hips' left-right axis along +X and so the character faces +Z;
* down each chain, a chain's root first, a bone whose direction (after its parents' turns) is more
  than :data:`TOLERANCE_DEG` (legs: :data:`LEG_TOLERANCE_DEG`) from its canonical direction
  turns onto it by the shortest arc (a left bone and its right partner decide together, by the
  mean of their two angles: a convention is symmetric, and a rig turned on one side only would
  stand crooked): the neck bone up, thighs
  and shins down, upper arms and forearms sideways (+X on the left); the chest turns as a frame
  (its neck bone up, its shoulders along +X), and the clavicles only beyond
  :data:`CLAVICLE_TOLERANCE_DEG` (a raised or swept clavicle is shape). The lower spine's
  segments are never turned one by one: the body turn already stands the hips -> neck line up,
  and a spine's S-curve (SMPL-X's lumbar bone leans 17 degrees back, MakeHuman's 20) is shape;
  turning one segment of it would lean the whole upper body. A bone within the tolerance **keeps
  its own direction**, so Mixamo's T-pose binds keep their shape and need no turn at all;
* the **feet** stand flat: each foot keeps its rest orientation relative to the body (undoing the
  turns of thigh and shin: a rig that stands at rest stands on flat feet), unless its foot bone is
  more than :data:`FOOT_TOLERANCE_DEG` from a flat foot's (:data:`FOOT_SLOPE_DEG` below the
  horizontal, forward): a foot pointing down or backwards at rest (a rig whose zero pose is not a
  standing one) turns onto it. With a rest mesh the sole decides instead
  (:func:`flatten_soles`): a foot whose sole slopes more than :data:`TOLERANCE_DEG` is pitched
  flat;
* the head, hands and toes (leaves) follow their parents.

A pose is given by the *global* rotations ``P_j`` that take each joint's rest frame to its frame in
the retarget pose (``(..., 22, 4)`` wxyz). Two characters ``A`` and ``B`` then retarget by
copying the source's rotation **deltas from the retarget pose**: ``G^B_j = G^A_j (P^A_j)^-1
P^B_j`` for the global rotations ``G`` of every frame, i.e. the per-joint rest alignment
``C_j = (P^A_j)^-1 P^B_j`` (:func:`rest_alignment`) and, in local terms,
``q^B_j = C_p^-1 q^A_j C_j``. Two Mixamo-style T-pose rigs have ``P = 1`` and retarget by copying
their local rotations; an A-pose rig and a T-pose rig get their arms lined up; a lying rig is
stood up. This module is the one place the retarget pose is defined: the ``copy-rest`` method, the
residual networks' base, ESO's references, the ground rule's foot heights, the leg length, the
synthetic motions' authoring frame and their ground truth all read it.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence

import numpy as np
import torch

from .rotations import (
    frame_rotation,
    quat_angle,
    quat_between,
    quat_canonical,
    quat_conjugate,
    quat_identity,
    quat_mul,
    quat_rotate,
)
from .skeleton import (
    CANONICAL22,
    CANONICAL22_PARENTS,
    J,
    JointSetError,
    Skeleton,
    canonical22_skeleton,
)

Tensor = torch.Tensor

__all__ = [
    "TOLERANCE_DEG",
    "LEG_TOLERANCE_DEG",
    "CLAVICLE_TOLERANCE_DEG",
    "FOOT_TOLERANCE_DEG",
    "FOOT_SLOPE_DEG",
    "PRIMARY_CHILD",
    "retarget_pose_rotations",
    "retarget_pose",
    "pose_offsets",
    "pose_local_rotations",
    "retarget_pose_skeleton",
    "rest_alignment",
    "retarget_alignment",
    "flatten_soles",
]

#: a bone within this angle of its canonical direction keeps its own (Mixamo's T-pose binds: a
#: forearm 6 degrees below the horizontal, a spine tilted 7 degrees; A-poses rest 25-50 degrees
#: below it, CMU's legs splay 20 degrees)
TOLERANCE_DEG = 15.0
#: the legs' tighter tolerance: legs carry the body, and a standing rig's feet are under its hips.
#: A thigh that splays or a knee that bends 7-12 degrees at rest (MakeHuman, Quaternius, the
#: mannequin's 7-degree shin) is the modelling pose, not the body: kept, it would walk with its
#: feet that much apart or its knees bent, where a rig authored standing straight does not
LEG_TOLERANCE_DEG = 5.0
#: the clavicle's wider tolerance: shoulders are raised, lowered or swept by build, not convention
CLAVICLE_TOLERANCE_DEG = 45.0
#: a flat foot's ankle -> toe bone points forward and this far below the horizontal (real rigs lie
#: between CMU's 10 and Mixamo's 45-63 degrees; the synthetic characters' 21)
FOOT_SLOPE_DEG = 35.0
#: a foot bone within this angle of a flat foot's direction keeps its rest orientation
FOOT_TOLERANCE_DEG = 40.0

#: the child whose bone defines each canonical joint's direction (-1: a leaf, which follows its
#: parent)
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

_UP = (0.0, 1.0, 0.0)
_DOWN = (0.0, -1.0, 0.0)
_LEFT = (1.0, 0.0, 0.0)
_RIGHT = (-1.0, 0.0, 0.0)
#: the bones turned onto a canonical direction: joint -> (direction of its primary bone, tolerance)
_BONES: dict[int, tuple[tuple[float, float, float], float]] = {
    J["Neck"]: (_UP, TOLERANCE_DEG),
    J["LeftUpLeg"]: (_DOWN, LEG_TOLERANCE_DEG),
    J["LeftLeg"]: (_DOWN, LEG_TOLERANCE_DEG),
    J["RightUpLeg"]: (_DOWN, LEG_TOLERANCE_DEG),
    J["RightLeg"]: (_DOWN, LEG_TOLERANCE_DEG),
    J["LeftShoulder"]: (_LEFT, CLAVICLE_TOLERANCE_DEG),
    J["LeftArm"]: (_LEFT, TOLERANCE_DEG),
    J["LeftForeArm"]: (_LEFT, TOLERANCE_DEG),
    J["RightShoulder"]: (_RIGHT, CLAVICLE_TOLERANCE_DEG),
    J["RightArm"]: (_RIGHT, TOLERANCE_DEG),
    J["RightForeArm"]: (_RIGHT, TOLERANCE_DEG),
}
_FEET = (J["LeftFoot"], J["RightFoot"])
#: each left joint that turns and its right partner: a rig's convention is symmetric, so the two
#: sides are turned or kept together (by the mean of their two angles), never one alone
_MIRRORED: dict[int, int] = {
    J[f"Left{part}"]: J[f"Right{part}"]
    for part in ("UpLeg", "Leg", "Foot", "Shoulder", "Arm", "ForeArm")
}
_SPINE_TO_NECK = [J[n] for n in ("Spine", "Spine1", "Spine2", "Neck")]
#: a bone shorter than this (metres) has no direction (CMU's zero-length neck and hip bones)
_MIN_BONE = 1e-6


def _flat_foot_direction(dtype: torch.dtype) -> Tensor:
    s = math.radians(FOOT_SLOPE_DEG)
    return torch.tensor([0.0, -math.sin(s), math.cos(s)], dtype=dtype)


def _turn_if_beyond(turn: Tensor, tolerance_deg: float, valid: Tensor | None = None) -> Tensor:
    """``turn`` where its angle exceeds the tolerance (and ``valid``), else the identity."""
    beyond = quat_angle(turn) > math.radians(tolerance_deg)
    if valid is not None:
        beyond = beyond & valid
    return torch.where(beyond[..., None], turn, quat_identity(dtype=turn.dtype))


def _frame_turn(up: Tensor, across: Tensor) -> Tensor:
    """The rotation taking ``up`` to +Y and ``across`` (its half-plane) to +X."""
    y = torch.tensor(_UP, dtype=up.dtype).expand_as(up)
    x = torch.tensor(_LEFT, dtype=up.dtype).expand_as(up)
    turn = frame_rotation(up, across, y, x)
    assert isinstance(turn, Tensor)  # tensors in, a tensor out
    return turn


def retarget_pose_rotations(offsets: Tensor) -> Tensor:
    """The retarget pose of canonical-22 rest offsets, from the skeleton alone (module docstring).

    Differentiable almost everywhere and batched: the residual networks' training calls it on
    every batch of (augmented) skeletons.

    Args:
        offsets: ``(..., 22, 3)`` rest offsets (metres, +Y up; the root row is ignored).

    Returns:
        ``(..., 22, 4)`` wxyz global rotations ``P_j``: joint ``j``'s frame in the retarget pose
        is its rest frame turned by ``P_j``; the identity everywhere for a rig already in it.
    """
    off = torch.as_tensor(offsets)
    if off.shape[-2:] != (22, 3):
        raise JointSetError(f"the retarget pose needs (..., 22, 3) offsets, got {tuple(off.shape)}")
    dtype = off.dtype if off.is_floating_point() else torch.float64
    off = off.to(dtype)
    batch = off.shape[:-2]
    out: list[Tensor] = [quat_identity(batch, dtype=dtype)] * 22
    # the body: hips -> neck up, the hips' left-right axis along +X
    up = off[..., _SPINE_TO_NECK, :].sum(-2)
    across = off[..., J["LeftUpLeg"], :] - off[..., J["RightUpLeg"], :]
    body = _turn_if_beyond(_frame_turn(up, across), TOLERANCE_DEG)
    out[0] = body
    flat = _flat_foot_direction(dtype)

    def candidate(j: int) -> tuple[Tensor, Tensor, Tensor, float]:
        """Joint ``j``'s shortest-arc turn, the frame it turns (its parent's, or the body's for a
        foot), whether its bone has a direction, and its tolerance."""
        if j in _FEET:  # flat: the rest orientation relative to the body, unless far from flat
            base, direction, tolerance = body, flat, FOOT_TOLERANCE_DEG
        else:
            base = out[CANONICAL22_PARENTS[j]]
            direction = torch.tensor(_BONES[j][0], dtype=dtype)
            tolerance = _BONES[j][1]
        bone = quat_rotate(base, off[..., PRIMARY_CHILD[j], :])
        turn = quat_between(bone, direction.expand_as(bone))
        return turn, base, bone.norm(dim=-1) > _MIN_BONE, tolerance

    for j in range(1, 22):
        parent = out[CANONICAL22_PARENTS[j]]
        if j == J["Spine2"]:  # the chest, as a frame: its neck bone up, its shoulders along +X
            neck = off[..., J["Neck"], :]
            neck = torch.where(
                neck.norm(dim=-1, keepdim=True) > _MIN_BONE, neck, neck + off[..., J["Head"], :]
            )
            chest_across = off[..., J["LeftShoulder"], :] - off[..., J["RightShoulder"], :]
            wide = chest_across.norm(dim=-1) > _MIN_BONE
            turn = _frame_turn(quat_rotate(parent, neck), quat_rotate(parent, chest_across))
            out[j] = quat_mul(_turn_if_beyond(turn, TOLERANCE_DEG, wide), parent)
        elif j in _MIRRORED:  # a left joint and its right partner: one decision for both
            k = _MIRRORED[j]
            (turn_l, base_l, valid_l, tolerance), (turn_r, base_r, valid_r, _) = (
                candidate(j),
                candidate(k),
            )
            angles = torch.stack((quat_angle(turn_l), quat_angle(turn_r)), -1)
            valid = torch.stack((valid_l, valid_r), -1)
            mean = (angles * valid).sum(-1) / valid.sum(-1).clamp_min(1)
            beyond = mean > math.radians(tolerance)
            for joint, turn, base, ok in (
                (j, turn_l, base_l, valid_l),
                (k, turn_r, base_r, valid_r),
            ):
                keep = torch.where((beyond & ok)[..., None], turn, quat_identity(dtype=dtype))
                out[joint] = quat_mul(keep, base)
        elif j in _MIRRORED.values():  # a right joint: decided with its left partner
            continue
        elif j in _BONES:  # the neck
            turn, base, valid, tolerance = candidate(j)
            out[j] = quat_mul(_turn_if_beyond(turn, tolerance, valid), base)
        else:  # a leaf follows its parent
            out[j] = parent
    return quat_canonical(torch.stack(out, -2))


def pose_offsets(offsets: Tensor, pose: Tensor, parents: Sequence[int] = CANONICAL22_PARENTS):
    """The rest offsets of the same character re-rested in a pose (``s̄'_c = P_p(c) s̄_c``; the
    root's own offset is kept): a skeleton whose rest pose *is* that pose.

    Args:
        offsets: ``(..., J, 3)`` rest offsets.
        pose: ``(..., J, 4)`` global rotations ``P`` (:func:`retarget_pose_rotations`).
        parents: ``J`` parents.

    Returns:
        ``(..., J, 3)``.
    """
    return torch.cat(
        (offsets[..., :1, :], quat_rotate(pose[..., list(parents[1:]), :], offsets[..., 1:, :])),
        -2,
    )


def pose_local_rotations(pose: Tensor, parents: Sequence[int] = CANONICAL22_PARENTS) -> Tensor:
    """The local rotations that put a skeleton in a pose given by global rotations:
    ``q_j = P_p(j)^-1 P_j`` (``P`` of the root's parent = 1).

    Args:
        pose: ``(..., J, 4)`` global rotations (:func:`retarget_pose_rotations`).
        parents: ``J`` parents.

    Returns:
        ``(..., J, 4)`` wxyz: with these local rotations, forward kinematics on the *original*
        offsets gives the pose (e.g. to skin a mesh into it).
    """
    pose = torch.as_tensor(pose)
    parent = torch.cat(
        (quat_identity(pose.shape[:-2] + (1,), dtype=pose.dtype), pose[..., list(parents[1:]), :]),
        -2,
    )
    return quat_canonical(quat_mul(quat_conjugate(parent), pose))


def _check(skeleton: Skeleton) -> None:
    if not skeleton.is_canonical22():
        raise JointSetError(
            "the retarget pose needs the canonical 22 joints; fold the motion first "
            "with retarget_lib.io.joint_maps.to_canonical22"
        )


def flatten_soles(
    skeleton: Skeleton, pose: np.ndarray, rest_vertices: np.ndarray, weights: np.ndarray
) -> np.ndarray:
    """Pitch each foot of a retarget pose so that its sole is flat (the mesh's word on "feet
    flat", where there is a mesh).

    The foot's vertices (skinned at least half to the foot and its toe) are carried rigidly with
    the foot into the pose; the sole's slope is the rise from the lowest point of the back third
    (heel) to the lowest point of the front third (ball) along the foot's horizontal direction. A
    slope beyond :data:`TOLERANCE_DEG` is turned flat about the foot's horizontal side axis (the
    toe follows); a sole within it keeps the rig's own (a heeled shoe).

    Args:
        skeleton: canonical-22 skeleton.
        pose: ``(22, 4)`` global rotations (:func:`retarget_pose_rotations`).
        rest_vertices: ``(V, 3)`` rest mesh, same frame as the skeleton's rest pose.
        weights: ``(V, 22)`` skinning weights.

    Returns:
        ``(22, 4)`` the pose with the feet (and toes) re-pitched where needed.
    """
    pose_t = torch.as_tensor(np.asarray(pose, dtype=np.float64))
    rest = skeleton.rest_positions()
    verts = np.asarray(rest_vertices, dtype=np.float64)
    w = np.asarray(weights, dtype=np.float64)
    out = pose_t.clone()
    for foot in _FEET:
        toe = PRIMARY_CHILD[foot]
        mask = (w[:, foot] + w[:, toe]) >= 0.5
        if mask.sum() < 6:
            continue
        local = torch.from_numpy(verts[mask] - rest[foot])
        posed = quat_rotate(pose_t[foot], local).numpy()  # relative to the ankle
        bone = quat_rotate(pose_t[foot], torch.from_numpy(skeleton.offsets[toe])).numpy()
        forward = np.array([bone[0], 0.0, bone[2]])
        if np.linalg.norm(forward) < 1e-9:
            continue
        forward /= np.linalg.norm(forward)
        along = posed @ forward
        lo, hi = along.min(), along.max()
        heel, ball = along <= lo + (hi - lo) / 3, along >= hi - (hi - lo) / 3
        h, b = (
            np.argmin(np.where(heel, posed[:, 1], np.inf)),
            np.argmin(np.where(ball, posed[:, 1], np.inf)),
        )
        rise, run = posed[b, 1] - posed[h, 1], along[b] - along[h]
        slope = math.atan2(rise, run)
        if abs(math.degrees(slope)) <= TOLERANCE_DEG or run <= 0:
            continue
        side = np.cross(forward, np.array(_UP))  # a turn by +a about it raises the toe end
        turn = torch.as_tensor(
            np.concatenate([[math.cos(-slope / 2)], side * math.sin(-slope / 2)])
        )
        out[foot] = quat_mul(turn, pose_t[foot])
        out[toe] = quat_mul(turn, pose_t[toe])
    return quat_canonical(out).numpy()


def skeleton_pose_rotations(offsets: np.ndarray) -> np.ndarray:
    """:func:`retarget_pose_rotations` of one skeleton's ``(22, 3)`` rest offsets, as ``(22, 4)``
    float64, remembered per offsets: building a training set asks it of the same few skeletons
    thousands of times (every clip pair's alignment and leg ratio)."""
    key = np.ascontiguousarray(offsets, dtype=np.float64)
    return _pose_of_offsets(key.tobytes()).copy()


@functools.lru_cache(maxsize=512)
def _pose_of_offsets(key: bytes) -> np.ndarray:
    offsets = torch.from_numpy(np.frombuffer(key, dtype=np.float64).reshape(-1, 3).copy())
    return retarget_pose_rotations(offsets).numpy()


def retarget_pose(
    skeleton: Skeleton,
    rest_vertices: np.ndarray | None = None,
    weights: np.ndarray | None = None,
) -> np.ndarray:
    """A character's retarget pose (module docstring): ``(22, 4)`` wxyz global rotations ``P``.

    Args:
        skeleton: canonical-22 skeleton.
        rest_vertices: ``(V, 3)`` its rest mesh, if it has one (then ``weights`` too): the soles
            decide whether the feet are flat (:func:`flatten_soles`).
        weights: ``(V, 22)`` skinning weights.

    Returns:
        ``(22, 4)`` float64.
    """
    _check(skeleton)
    pose = skeleton_pose_rotations(skeleton.offsets)
    if rest_vertices is not None and weights is not None and len(rest_vertices):
        pose = flatten_soles(skeleton, pose, rest_vertices, weights)
    return pose


def retarget_pose_skeleton(skeleton: Skeleton, pose: np.ndarray | None = None) -> Skeleton:
    """The same character re-rested in its retarget pose (bone lengths and root offset kept): the
    frame the synthetic motions are authored in, and whose zero rotations stand in the canonical
    T-pose.

    Args:
        skeleton: canonical-22 skeleton.
        pose: its ``(22, 4)`` retarget pose (default :func:`retarget_pose` of the skeleton alone).
    """
    p = retarget_pose(skeleton) if pose is None else np.asarray(pose, dtype=np.float64)
    off = pose_offsets(torch.from_numpy(skeleton.offsets.astype(np.float64)), torch.from_numpy(p))
    return canonical22_skeleton(off.numpy())


def rest_alignment(
    source: Skeleton,
    target: Skeleton,
    source_pose: np.ndarray | None = None,
    target_pose: np.ndarray | None = None,
) -> np.ndarray:
    """Per-joint rest alignments ``C_j = (P^A_j)^-1 P^B_j`` from the two retarget poses: with
    ``G^B_j = G^A_j C_j`` the target performs the source's rotation deltas from the retarget pose.

    Args:
        source: canonical-22 skeleton ``A``.
        target: canonical-22 skeleton ``B``.
        source_pose, target_pose: ``(22, 4)`` retarget poses if already known (with a mesh's
            soles, :func:`retarget_pose`); default from each skeleton alone.

    Returns:
        ``(22, 4)`` wxyz float64; the identity where the two retarget poses agree (two T-pose
        binds of any shape, a uniform scaling).
    """
    pa = retarget_pose(source) if source_pose is None else source_pose
    pb = retarget_pose(target) if target_pose is None else target_pose
    return _alignment(torch.as_tensor(pa), torch.as_tensor(pb)).numpy()


def _alignment(pose_src: Tensor, pose_tgt: Tensor) -> Tensor:
    return quat_canonical(quat_mul(quat_conjugate(pose_src), pose_tgt))


def retarget_alignment(offsets_src: Tensor, offsets_tgt: Tensor) -> Tensor:
    """:func:`rest_alignment` for batches of offset tensors (skeletons alone): the residual
    networks' base and the training data's rest changes.

    Args:
        offsets_src: ``(..., 22, 3)`` source rest offsets.
        offsets_tgt: ``(..., 22, 3)`` target rest offsets (broadcast against the source's).

    Returns:
        ``(..., 22, 4)`` wxyz in the offsets' dtype.
    """
    return _alignment(retarget_pose_rotations(offsets_src), retarget_pose_rotations(offsets_tgt))
