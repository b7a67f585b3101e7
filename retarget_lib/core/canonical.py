"""Folding a joint set onto the canonical 22 joints and back, given which joint is which:
:func:`fold_to_canonical22`, :func:`unfold_from_canonical22`; and standing a rest pose up.

Which file joint stands for which canonical joint is found by name in
:mod:`retarget_lib.io.rig_maps` (the one table of rig conventions and its detector); a motion on
any named joint set is folded by :func:`retarget_lib.io.joint_maps.to_canonical22`. This module
only takes index maps ``{joint index: canonical index}``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import torch

from .kinematics import align_local_rotations
from .motion import Motion
from .retarget_pose import pose_offsets, retarget_pose_rotations
from .rotations import (
    matrix_to_quat,
    quat_between,
    quat_canonical,
    quat_conjugate,
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
from .virtual_joints import MAY_BE_ABSENT, with_virtual_joints


def _reordering(skeleton: Skeleton, joint_map: Mapping[int, int]) -> list[int] | None:
    """``[joint index of canonical c for c in 0..21]`` when ``joint_map`` maps the skeleton's joints
    one-to-one onto the canonical 22 with the canonical tree (each joint's parent maps to its
    canonical parent: SMPL-X body joints, a 22-joint rig in another order), else None."""
    every = list(range(22))
    if (
        skeleton.num_joints != 22
        or sorted(joint_map) != every
        or sorted(joint_map.values()) != every
    ):
        return None
    mapped_parent = [-1 if p < 0 else joint_map[p] for p in skeleton.parents]
    if any(mapped_parent[j] != CANONICAL22_PARENTS[c] for j, c in joint_map.items()):
        return None
    file_of = {c: j for j, c in joint_map.items()}
    return [file_of[c] for c in range(22)]


def fold_to_canonical22(
    motion: Motion, joint_map: Mapping[int, int], label: str = "joint_map"
) -> Motion:
    """Fold a motion onto the canonical 22 joints.

    A joint set that is the canonical 22 in another order or under other names (same tree) is only
    reordered. Otherwise the canonical joints the motion lacks (``joint_map`` leaves them out; only
    those of :data:`~retarget_lib.core.virtual_joints.MAY_BE_ABSENT`) are first inserted as virtual
    joints (:func:`~retarget_lib.core.virtual_joints.with_virtual_joints`: on the bone between
    their neighbours, a toe at its foot; Biovision's Spine2 lands halfway along Chest -> Neck). Kept
    joints keep their world positions. Removed joints are folded into their kept ancestors:

    * leaves (fingers, ``*_End``, thumbs) are dropped;
    * a removed joint between two kept ones (CMU ``LHipJoint``, ``Neck1``) is absorbed: the kept
      child's rest offset becomes the rest-pose sum along the removed chain, and every kept
      joint's global rotation is re-fitted so that it maps its kept children's rest offsets onto
      their actual world positions (Wahba/Kabsch fit; for a single child the swing that aligns the
      bone, keeping the original twist). This is exact when every folded bone keeps its rest length
      and every kept joint's kept children move rigidly together: removed joints that do not rotate
      (CMU ``LHipJoint`` in the cgspeed files), or a zero-offset rotating joint on its kept parent's
      only path to kept children (a twist joint). Otherwise it is the least-squares compromise;
      for a single child the residual is the change of the folded bone's length (CMU ``Neck1``
      bending: up to 2.2 cm at the head in ``01_01.bvh``).

    Args:
        motion: a :class:`~retarget_lib.core.motion.Motion` on any joints, ``rotations (T, J, 4)``.
        joint_map: ``{motion joint index: canonical index}`` of the canonical joints it has (from
            :func:`~retarget_lib.io.rig_maps.map_joints`).
        label: the rig naming the map came from, kept as ``meta["folded_from"]``.

    Returns:
        A new Motion on :data:`~retarget_lib.core.skeleton.CANONICAL22` (``rotations (T, 22, 4)``)
        with the same fps and frame count.

    Raises:
        JointSetError: ``joint_map`` lacks a canonical joint that cannot be inserted.
    """
    missing = [
        CANONICAL22[c]
        for c in range(22)
        if c not in joint_map.values() and CANONICAL22[c] not in MAY_BE_ABSENT
    ]
    if missing:
        raise JointSetError(
            f"fold_to_canonical22: the joint map lacks {missing}, which cannot be inserted"
        )
    meta = dict(motion.meta, folded_from=label)
    order = _reordering(motion.skeleton, joint_map)
    if order is not None:
        return Motion(
            canonical22_skeleton(motion.skeleton.offsets[order]),
            motion.rotations[:, order].copy(),
            motion.root_positions.copy(),
            motion.fps,
            name=motion.name,
            meta=meta,
        )
    augmented, full = with_virtual_joints(motion, joint_map)
    sk = augmented.skeleton
    src_of = {c: s for s, c in full.items()}
    gpos, grot = augmented.fk()
    rest = sk.rest_positions()
    T = motion.num_frames
    new_rest = np.zeros((22, 3))
    target_pos = np.zeros((T, 22, 3))
    orig_rot = np.zeros((T, 22, 4))
    for c, s in src_of.items():
        new_rest[c] = rest[s]
        target_pos[:, c] = gpos[:, s]
        orig_rot[:, c] = grot[:, s]
    offsets = new_rest.copy()
    for c, p in enumerate(CANONICAL22_PARENTS):
        if p >= 0:
            offsets[c] = new_rest[c] - new_rest[p]
    # rest rotations are identity, so rest offsets are in world axes for every joint.
    new_grot = fit_global_rotations(orig_rot, target_pos, offsets, CANONICAL22_PARENTS)
    g = torch.from_numpy(new_grot)
    local = g.clone()
    par = torch.tensor(CANONICAL22_PARENTS[1:])
    local[:, 1:] = quat_mul(quat_conjugate(g[:, par]), g[:, 1:])
    return Motion(
        canonical22_skeleton(offsets),
        quat_canonical(local).numpy(),
        target_pos[:, 0].copy(),
        motion.fps,
        name=motion.name,
        meta=meta,
    )


def fit_global_rotations(
    rotations: np.ndarray, positions: np.ndarray, offsets: np.ndarray, parents: Sequence[int]
) -> np.ndarray:
    """Re-fit each joint's global rotation so that it maps its children's rest offsets onto their
    actual world positions (used when joints are folded away).

    For joint ``j`` with children ``c`` (non-zero offsets ``o_c``) and targets ``d_c = x_c - x_j``
    this solves Wahba's problem ``max_R sum_c d_c . (R o_c)`` (the least-squares fit of the
    children's positions):

    * children spanning two or three directions determine ``R``: the SVD (Kabsch) solution for
      ``M = sum_c d_c o_c^T``, equal to the original ``G_j`` whenever ``G_j`` already fits;
    * children on one line ``u`` (typically a single child) determine only the bone direction:
      ``R = S G_j`` with ``S`` the shortest rotation taking ``G_j u`` onto
      ``w = sum_c (o_c . u) d_c``, so the bone points exactly at its target and ``G_j``'s twist
      about the bone is kept.

    Leaves keep ``G_j``.

    Args:
        rotations: ``(T, J, 4)`` original global rotations, wxyz.
        positions: ``(T, J, 3)`` world positions to reproduce.
        offsets: ``(J, 3)`` rest offsets (world axes in the rest pose).
        parents: ``J`` parents.

    Returns:
        ``(T, J, 4)`` global rotations, wxyz, float64.
    """
    rot = torch.from_numpy(np.asarray(rotations, dtype=np.float64))
    pos = torch.from_numpy(np.asarray(positions, dtype=np.float64))
    off = torch.from_numpy(np.asarray(offsets, dtype=np.float64))
    out = rot.clone()
    for j in range(len(parents)):
        kids = [c for c, p in enumerate(parents) if p == j and off[c].norm() > 1e-9]
        if not kids:
            continue
        d = pos[:, kids] - pos[:, j : j + 1]  # (T, k, 3)
        o = off[kids]  # (k, 3)
        sv = torch.linalg.svdvals(o)
        if len(kids) == 1 or sv[1] <= 1e-3 * sv[0]:  # all children on one line
            axis = o[o.norm(dim=-1).argmax()]
            axis = axis / axis.norm()
            w = torch.einsum("k,tki->ti", o @ axis, d)  # (T, 3)
            out[:, j] = quat_mul(quat_between(quat_rotate(rot[:, j], axis), w), rot[:, j])
            continue
        m = torch.einsum("tki,kj->tij", d, o)
        u, _, vh = torch.linalg.svd(m)
        det = torch.det(u @ vh)
        fix = torch.ones_like(u[..., 0, :])
        fix[:, 2] = det
        r = (u * fix.unsqueeze(-2)) @ vh
        out[:, j] = matrix_to_quat(r)
    return quat_canonical(out).numpy()


def unfold_from_canonical22(
    motion: Motion, skeleton: Skeleton, joint_map: Mapping[int, int]
) -> Motion:
    """Put a canonical-22 motion back on a full joint set (the inverse of
    :func:`fold_to_canonical22`).

    Used to write a retargeted motion with the target file's own joints, names and rest offsets.
    Each kept joint gets the product of the canonical local rotations along its canonical path
    from its kept parent; joints that were folded away (CMU ``LHipJoint``, ``Neck1``, fingers,
    ``*_End``) get identity. This reproduces the canonical world positions exactly when
    ``motion.skeleton`` is the fold of ``skeleton``'s rest pose and the folded joints sit on
    straight rest chains, as in Mixamo and CMU rigs; a canonical joint the rig lacks (Biovision's
    ``Spine2``, a joint map's ``null``) is merged into the joint above it (its rotation moves the
    rig's next joints slightly). Joints above the hips (an Unreal ``root``) keep identity and follow
    the hips' translation.

    Args:
        motion: canonical-22 motion (e.g. a retargeting result), ``rotations (T, 22, 4)``.
        skeleton: the full target skeleton (e.g. ``load_bvh(target).skeleton``), ``J`` joints.
        joint_map: ``{skeleton joint index: canonical index}`` of the canonical joints it has (from
            :func:`~retarget_lib.io.rig_maps.map_joints`).

    Returns:
        A Motion on ``skeleton`` (``rotations (T, J, 4)``) with ``motion``'s frames, fps and root
        positions.
    """
    if not motion.skeleton.is_canonical22():
        raise JointSetError("unfold_from_canonical22 needs a canonical-22 motion")
    cmap = dict(joint_map)
    rot22 = torch.from_numpy(motion.rotations)
    world = [rot22[:, 0]]  # canonical global rotations, parents first
    for k in range(1, 22):
        world.append(quat_mul(world[CANONICAL22_PARENTS[k]], rot22[:, k]))
    T = motion.num_frames
    out = np.zeros((T, skeleton.num_joints, 4))
    out[..., 0] = 1.0
    for j, c in cmap.items():
        # nearest kept ancestor in the target; the joints between keep identity, so j's local
        # rotation is the ancestor's global rotation undone, then c's: conj(G_stop) G_c (the
        # product of the canonical rotations below ``stop`` when it is a canonical ancestor of c;
        # a rig may also hang c elsewhere, e.g. Rigify's clavicles under the joint mapped to Neck)
        a = skeleton.parents[j]
        while a >= 0 and a not in cmap:
            a = skeleton.parents[a]
        q = world[c] if a < 0 else quat_mul(quat_conjugate(world[cmap[a]]), world[c])
        out[:, j] = q.numpy()
    # a root above the hips (an Unreal ``root``, an armature joint) keeps its rest rotation and
    # carries the hips: it sits at the hips' position minus their rest offset from it
    hips = next(j for j, c in cmap.items() if c == J["Hips"])
    rest = skeleton.rest_positions()
    root = motion.root_positions - (rest[hips] - rest[0])
    return Motion(
        skeleton.copy(),
        out,
        root,
        motion.fps,
        name=motion.name,
        meta={"converted_from": "canonical22"},
    )


def _snap(v: np.ndarray) -> np.ndarray:
    """The signed coordinate axis nearest to ``v``."""
    axis = np.zeros(3)
    k = int(np.argmax(np.abs(v)))
    axis[k] = np.sign(v[k]) or 1.0
    return axis


def upright_rotation(
    hips: np.ndarray, head: np.ndarray, left_hip: np.ndarray, right_hip: np.ndarray
) -> np.ndarray:
    """``(3, 3)`` the quarter turns that stand a rest pose up in the library's axes: its
    hips-to-head direction onto +Y and its right-to-left hip direction onto +X (so that it faces
    +Z), each snapped to the nearest coordinate axis first; the identity for a rest pose that
    already does, or when the hips lie on the up axis (nothing to tell the facing by).

    Args:
        hips, head, left_hip, right_hip: ``(3,)`` rest positions of those joints.
    """
    up = _snap(head - hips)
    across = left_hip - right_hip
    across = across - (across @ up) * up
    left = _snap(across) if np.linalg.norm(across) > 0 else np.array([1.0, 0.0, 0.0])
    if abs(left @ up) > 0.5:
        return np.eye(3)
    # rows: the rest pose's left, up and forward (left x up, as +X x +Y = +Z)
    return np.stack([left, up, np.cross(left, up)])


def stand_upright(motion: Motion) -> Motion:
    """A canonical-22 motion whose **rest pose** is turned to stand up, every frame's world pose
    unchanged: the body turn of its retarget pose
    (:func:`~retarget_lib.core.retarget_pose.retarget_pose_rotations`, joint 0: spine up, hips
    along +X, facing +Z) applied to the whole rest.

    Some mocap files define their rest pose lying down or turned (a BVH whose rest skeleton lies
    along +X, the frames' root rotation standing it up). Rotation-copying methods carry the root
    rotation over, so such a rest pose would lay the target down. With ``R`` the turn, the rest
    offsets become ``R o`` and the global rotations ``G R^-1``: the root's local rotation is
    ``q_0 R^-1``, every other joint's ``R q_j R^-1``; world positions stay the same. A rest pose
    within the retarget pose's tolerance of upright is left alone (the same object is returned).
    """
    if not motion.skeleton.is_canonical22():
        raise JointSetError("stand_upright needs a canonical-22 motion")
    off = torch.from_numpy(motion.skeleton.offsets.astype(np.float64))
    turn = retarget_pose_rotations(off)[0]
    if torch.equal(turn, torch.tensor([1.0, 0.0, 0.0, 0.0], dtype=turn.dtype)):
        return motion
    turns = turn.expand(22, 4)
    rotations = align_local_rotations(
        torch.from_numpy(motion.rotations), quat_conjugate(turns), CANONICAL22_PARENTS
    )
    offsets = pose_offsets(off, turns).numpy()
    offsets[0] = 0.0
    offsets[0, 1] = (
        -canonical22_skeleton(offsets).rest_positions()[:, 1].min()
    )  # the turned rest stands on y = 0
    return motion.copy(
        skeleton=canonical22_skeleton(offsets),
        rotations=quat_canonical(rotations).numpy(),
        meta=dict(motion.meta, rest_turned=turn.tolist()),
    )
