"""Folding any joint set onto the canonical 22 joints and back: name maps, :func:`to_canonical22`,
:func:`from_canonical22`.

Supported joint sets: Mixamo with fingers, CMU 31 joints, the 21-joint Biovision/MotionBuilder
layout of ``Boxing_Toes.bvh``, SMPL-X body joints (:data:`NAME_MAPS`).
"""

from __future__ import annotations

from typing import Sequence

import numpy as np
import torch

from .motion import Motion
from .rotations import matrix_to_quat, quat_between, quat_canonical, quat_conjugate, quat_mul, quat_rotate
from .skeleton import CANONICAL22, CANONICAL22_PARENTS, J, JointSetError, Skeleton, canonical22_skeleton


#: Mixamo: names are canonical once the ``mixamorig:`` (or ``mixamorig1:`` ...) prefix is removed.
MIXAMO_MAP: dict[str, str] = {n: n for n in CANONICAL22}

#: CMU (cgspeed BVH conversion, 31 joints). Folded: LHipJoint, RHipJoint, Neck1, fingers, thumbs.
CMU_MAP: dict[str, str] = {
    "Hips": "Hips", "LowerBack": "Spine", "Spine": "Spine1", "Spine1": "Spine2",
    "Neck": "Neck", "Head": "Head",
    "LeftUpLeg": "LeftUpLeg", "LeftLeg": "LeftLeg", "LeftFoot": "LeftFoot", "LeftToeBase": "LeftToeBase",
    "RightUpLeg": "RightUpLeg", "RightLeg": "RightLeg", "RightFoot": "RightFoot",
    "RightToeBase": "RightToeBase",
    "LeftShoulder": "LeftShoulder", "LeftArm": "LeftArm", "LeftForeArm": "LeftForeArm",
    "LeftHand": "LeftHand",
    "RightShoulder": "RightShoulder", "RightArm": "RightArm", "RightForeArm": "RightForeArm",
    "RightHand": "RightHand",
}

#: Biovision / MotionBuilder 21-joint layout (``Boxing_Toes.bvh``). It has two spine joints, so
#: ``Spine2`` is *inserted* halfway along the Chest->Neck bone (identity rotation).
BIOVISION_MAP: dict[str, str] = {
    "Hips": "Hips", "Ab": "Spine", "Chest": "Spine1", "Neck": "Neck", "Head": "Head",
    "LeftHip": "LeftUpLeg", "LeftKnee": "LeftLeg", "LeftAnkle": "LeftFoot", "LeftToes": "LeftToeBase",
    "RightHip": "RightUpLeg", "RightKnee": "RightLeg", "RightAnkle": "RightFoot",
    "RightToes": "RightToeBase",
    "LeftCollar": "LeftShoulder", "LeftShoulder": "LeftArm", "LeftElbow": "LeftForeArm",
    "LeftWrist": "LeftHand",
    "RightCollar": "RightShoulder", "RightShoulder": "RightArm", "RightElbow": "RightForeArm",
    "RightWrist": "RightHand",
}

#: SMPL-X body joints (the first 22 of SMPL-X / SMPL), one-to-one.
SMPLX_BODY_NAMES: tuple[str, ...] = (
    "pelvis", "left_hip", "right_hip", "spine1", "left_knee", "right_knee", "spine2",
    "left_ankle", "right_ankle", "spine3", "left_foot", "right_foot", "neck", "left_collar",
    "right_collar", "head", "left_shoulder", "right_shoulder", "left_elbow", "right_elbow",
    "left_wrist", "right_wrist",
)
SMPLX_MAP: dict[str, str] = {
    "pelvis": "Hips", "spine1": "Spine", "spine2": "Spine1", "spine3": "Spine2", "neck": "Neck",
    "head": "Head",
    "left_hip": "LeftUpLeg", "left_knee": "LeftLeg", "left_ankle": "LeftFoot", "left_foot": "LeftToeBase",
    "right_hip": "RightUpLeg", "right_knee": "RightLeg", "right_ankle": "RightFoot",
    "right_foot": "RightToeBase",
    "left_collar": "LeftShoulder", "left_shoulder": "LeftArm", "left_elbow": "LeftForeArm",
    "left_wrist": "LeftHand",
    "right_collar": "RightShoulder", "right_shoulder": "RightArm", "right_elbow": "RightForeArm",
    "right_wrist": "RightHand",
}

NAME_MAPS: dict[str, dict[str, str]] = {
    "mixamo": MIXAMO_MAP, "cmu": CMU_MAP, "biovision": BIOVISION_MAP, "smplx": SMPLX_MAP,
}


def strip_prefix(name: str) -> str:
    """Remove a namespace prefix such as ``mixamorig:`` / ``mixamorig1:`` / ``Armature|``."""
    for sep in (":", "|"):
        if sep in name:
            name = name.rsplit(sep, 1)[1]
    return name


def detect_convention(joint_names: Sequence[str]) -> str:
    """Guess which name map fits a joint set: ``"cmu"``, ``"biovision"``, ``"smplx"`` or ``"mixamo"``.

    Args:
        joint_names: names as in the file (prefixes allowed).
    """
    names = {strip_prefix(n) for n in joint_names}
    if {"LHipJoint", "LowerBack"} & names:
        return "cmu"
    if {"Ab", "Chest", "LeftCollar"} <= names:
        return "biovision"
    if {"pelvis", "spine3", "left_collar"} <= names:
        return "smplx"
    return "mixamo"


def canonical_name_map(joint_names: Sequence[str], convention: str | None = None) -> dict[int, int]:
    """Map source joint indices to canonical indices.

    Args:
        joint_names: the source names (prefixes allowed).
        convention: a key of :data:`NAME_MAPS`, or ``None`` to detect it.

    Returns:
        ``{source index: canonical index}`` for every source joint that is kept.

    Raises:
        JointSetError: an unknown ``convention`` (the known ones are named), or naming the
            canonical joints that no source joint maps to.
    """
    convention = convention or detect_convention(joint_names)
    if convention not in NAME_MAPS:
        raise JointSetError(f"unknown joint-name convention {convention!r}; known: {', '.join(NAME_MAPS)}")
    table = NAME_MAPS[convention]
    out: dict[int, int] = {}
    for i, n in enumerate(joint_names):
        c = table.get(strip_prefix(n))
        if c is not None:
            out[i] = J[c]
    found = set(out.values())
    optional = {J["Spine2"]} if convention == "biovision" else set()
    missing = [CANONICAL22[c] for c in range(22) if c not in found and c not in optional]
    if missing:
        raise JointSetError(
            f"cannot map onto the canonical 22 joints ({convention} naming): missing {missing}; "
            f"joints present: {list(joint_names)}"
        )
    return out


def to_canonical22(motion: Motion, convention: str | None = None,
                   joint_map: dict[int, int] | None = None) -> Motion:
    """Fold a motion on any supported joint set onto the canonical 22 joints.

    Kept joints keep their world positions. Removed joints are folded into their kept ancestors:

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
      bending: up to 2.2 cm at the head in ``01_01.bvh``);
    * the 21-joint Biovision layout gets ``Spine2`` inserted halfway along Chest->Neck.

    Args:
        motion: any :class:`~retarget_lib.core.motion.Motion`.
        convention: a key of :data:`NAME_MAPS`, or ``None`` to detect it from the names.
        joint_map: ``{motion joint index: canonical index}`` to use instead of a name
            convention (e.g. a glTF rig's map from :func:`~retarget_lib.io.rig_maps.map_joints`).

    Returns:
        A new Motion on :data:`CANONICAL22` with the same fps and frame count.

    Raises:
        JointSetError: if required joints are missing (named in the message).
    """
    sk = motion.skeleton
    if sk.is_canonical22():
        return motion.copy()
    if joint_map is None:
        convention = convention or detect_convention(sk.joint_names)
        cmap = canonical_name_map(sk.joint_names, convention)
    else:
        cmap, convention = dict(joint_map), "joint_map"
    src_of = {c: s for s, c in cmap.items()}
    gpos, grot = motion.fk()
    rest = sk.rest_positions()
    T = motion.num_frames
    new_rest = np.zeros((22, 3))
    target_pos = np.zeros((T, 22, 3))
    orig_rot = np.zeros((T, 22, 4))
    for c, s in src_of.items():
        new_rest[c] = rest[s]
        target_pos[:, c] = gpos[:, s]
        orig_rot[:, c] = grot[:, s]
    if J["Spine2"] not in src_of:  # biovision: insert Spine2 halfway along Chest -> Neck
        chest, neck = src_of[J["Spine1"]], src_of[J["Neck"]]
        new_rest[J["Spine2"]] = 0.5 * (rest[chest] + rest[neck])
        target_pos[:, J["Spine2"]] = 0.5 * (gpos[:, chest] + gpos[:, neck])
        orig_rot[:, J["Spine2"]] = grot[:, chest]
    offsets = new_rest.copy()
    for c, p in enumerate(CANONICAL22_PARENTS):
        if p >= 0:
            offsets[c] = new_rest[c] - new_rest[p]
    # BVH rest rotations are identity, so rest offsets are in world axes for every joint.
    new_grot = fit_global_rotations(orig_rot, target_pos, offsets, CANONICAL22_PARENTS)
    g = torch.from_numpy(new_grot)
    local = g.clone()
    par = torch.tensor(CANONICAL22_PARENTS[1:])
    local[:, 1:] = quat_mul(quat_conjugate(g[:, par]), g[:, 1:])
    meta = dict(motion.meta, folded_from=convention)
    return Motion(canonical22_skeleton(offsets), quat_canonical(local).numpy(),
                  target_pos[:, 0].copy(), motion.fps, name=motion.name, meta=meta)


def fit_global_rotations(rotations: np.ndarray, positions: np.ndarray, offsets: np.ndarray,
                         parents: Sequence[int]) -> np.ndarray:
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
        d = pos[:, kids] - pos[:, j:j + 1]  # (T, k, 3)
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


def from_canonical22(motion: Motion, skeleton: Skeleton, convention: str | None = None,
                     joint_map: dict[int, int] | None = None) -> Motion:
    """Put a canonical-22 motion back on a full joint set (the inverse of :func:`to_canonical22`).

    Used to write a retargeted motion with the target file's own joints, names and rest offsets.
    Each kept joint gets the product of the canonical local rotations along its canonical path
    from its kept parent; joints that were folded away (CMU ``LHipJoint``, ``Neck1``, fingers,
    ``*_End``) get identity. This reproduces the canonical world positions exactly when
    ``motion.skeleton`` is ``to_canonical22`` of ``skeleton``'s rest pose and the folded joints sit on
    straight rest chains, as in Mixamo and CMU rigs; for the Biovision layout the inserted
    ``Spine2`` is merged into the chest (its rotation moves the neck and collars slightly). Joints
    above the hips (an Unreal ``root``) keep identity and follow the hips' translation.

    Args:
        motion: canonical-22 motion (e.g. a retargeting result).
        skeleton: the full target skeleton (e.g. ``load_bvh(target).skeleton``).
        convention: a key of :data:`NAME_MAPS`, or ``None`` to detect it.
        joint_map: ``{skeleton joint index: canonical index}`` to use instead of a name convention.

    Returns:
        A Motion on ``skeleton`` with ``motion``'s frames, fps and root positions.
    """
    if not motion.skeleton.is_canonical22():
        raise JointSetError("from_canonical22 needs a canonical-22 motion")
    if joint_map is None:
        convention = convention or detect_convention(skeleton.joint_names)
        cmap = canonical_name_map(skeleton.joint_names, convention)
    else:
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
    return Motion(skeleton.copy(), out, root, motion.fps, name=motion.name,
                  meta={"converted_from": "canonical22"})


def _snap(v: np.ndarray) -> np.ndarray:
    """The signed coordinate axis nearest to ``v``."""
    axis = np.zeros(3)
    k = int(np.argmax(np.abs(v)))
    axis[k] = np.sign(v[k]) or 1.0
    return axis


def upright_rotation(hips: np.ndarray, head: np.ndarray, left_hip: np.ndarray, right_hip: np.ndarray) -> np.ndarray:
    """``(3, 3)`` the quarter turns that stand a rest pose up in the library's axes: its hips-to-head
    direction onto +Y and its right-to-left hip direction onto +X (so that it faces +Z), each
    snapped to the nearest coordinate axis first; the identity for a rest pose that already does,
    or when the hips lie on the up axis (nothing to tell the facing by).

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
    """A canonical-22 motion whose **rest pose** is turned to stand up (:func:`upright_rotation`),
    every frame's world pose unchanged.

    Some mocap files define their rest pose lying down or turned (a BVH whose rest skeleton lies
    along +X, the frames' root rotation standing it up). Rotation-copying methods carry the root
    rotation over, so such a rest pose would lay the target down. With ``R`` the turn, the rest
    offsets become ``R o`` and the global rotations ``G R^-1``: the root's local rotation is
    ``q_0 R^-1``, every other joint's ``R q_j R^-1``; world positions stay the same.
    """
    if not motion.skeleton.is_canonical22():
        raise JointSetError("stand_upright needs a canonical-22 motion")
    rest = motion.skeleton.rest_positions()
    turn = upright_rotation(rest[J["Hips"]], rest[J["Head"]], rest[J["LeftUpLeg"]], rest[J["RightUpLeg"]])
    if np.array_equal(turn, np.eye(3)):
        return motion
    q_turn = matrix_to_quat(torch.from_numpy(turn))
    rot = torch.from_numpy(motion.rotations)
    turned = quat_mul(quat_mul(q_turn.expand_as(rot), rot), quat_conjugate(q_turn).expand_as(rot))
    turned[:, 0] = quat_mul(rot[:, 0], quat_conjugate(q_turn).expand_as(rot[:, 0]))
    offsets = motion.skeleton.offsets @ turn.T
    offsets[0] = 0.0
    offsets[0, 1] = -canonical22_skeleton(offsets).rest_positions()[:, 1].min()  # the turned rest stands on y = 0
    return motion.copy(skeleton=canonical22_skeleton(offsets), rotations=turned.numpy(),
                       meta=dict(motion.meta, rest_turned=turn.tolist()))

