"""Inverse kinematics: analytic two-bone limbs, full-body damped least squares, foot planting.

Three tools, all batched over frames and working on NumPy (float64 in, float64 out) or torch:

* :func:`two_bone_ik` -- the closed-form solution for a limb (upper, lower, end joint): the end
  joint reaches a target exactly while both bone lengths stay fixed and the middle joint (knee,
  elbow) bends towards a *pole* direction. An unreachable target gives the fully extended limb
  pointing at it.
* :func:`solve_ik` -- several position targets at once for any joints (full-body fixes), by
  damped least squares on the geometric Jacobian, with the input pose as a null-space prior:
  the targets are met and, among the poses that meet them, the one closest to the input is taken.
* :func:`apply_foot_contact_ik` -- the IK post-process of Skeleton-Aware Networks (Aberman et al.
  2020) that the contact-aware paper (Villegas et al. 2021, Sec. 4 "Baselines", Table 1 rows
  "SAN + IK" and "Efull + IK") applies to network outputs: feet are held still while in contact,
  with smooth blending into the free frames, and the legs are re-solved with :func:`two_bone_ik`.

Rotations are local, unit wxyz; ``quat_mul(a, b)`` applies ``b`` first (see
:mod:`retarget_lib.core.rotations`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np
import torch

from ..core.kinematics import forward_kinematics
from ..core.motion import Motion
from ..core.rotations import (
    frame_rotation,
    quat_between,
    quat_canonical,
    quat_conjugate,
    quat_from_axis_angle,
    quat_mul,
    quat_rotate,
    quat_to_axis_angle,
)
from ..core.skeleton import FOOT_CONTACT_JOINTS, Skeleton

Tensor = torch.Tensor
Array = Tensor | np.ndarray

__all__ = [
    "LIMBS",
    "limb_chain",
    "two_bone_positions",
    "two_bone_ik",
    "MIN_BEND_PLANE_DEG",
    "solve_ik",
    "foot_contact_targets",
    "apply_foot_contact_ik",
]

#: the two-bone chains (upper, lower, end) of the canonical 22 joints
LIMBS: dict[str, tuple[str, str, str]] = {
    "left_leg": ("LeftUpLeg", "LeftLeg", "LeftFoot"),
    "right_leg": ("RightUpLeg", "RightLeg", "RightFoot"),
    "left_arm": ("LeftArm", "LeftForeArm", "LeftHand"),
    "right_arm": ("RightArm", "RightForeArm", "RightHand"),
}


_EPS = 1e-9


def limb_chain(skeleton: Skeleton, limb: str) -> tuple[int, int, int]:
    """Joint indices ``(upper, lower, end)`` of a limb.

    Args:
        skeleton: any skeleton with the canonical joint names.
        limb: a key of :data:`LIMBS` (``"left_leg"``, ``"right_arm"``, ...).
    """
    return tuple(skeleton.index(n) for n in LIMBS[limb])  # type: ignore[return-value]


# ----------------------------------------------------------------------------- small helpers
def _to_torch(x: Array) -> Tensor:
    return torch.from_numpy(np.asarray(x, dtype=np.float64)) if isinstance(x, np.ndarray) else x


def _unit(v: Tensor) -> Tensor:
    return v / v.norm(dim=-1, keepdim=True).clamp_min(_EPS)


def _dot(a: Tensor, b: Tensor) -> Tensor:
    return (a * b).sum(-1, keepdim=True)


def _any_perpendicular(n: Tensor) -> Tensor:
    """A unit vector perpendicular to each unit ``n`` ``(..., 3)``."""
    x = torch.zeros_like(n)
    x[..., 0] = 1.0
    y = torch.zeros_like(n)
    y[..., 1] = 1.0
    seed = torch.where(n[..., :1].abs() < 0.9, x, y)
    return _unit(torch.linalg.cross(n, seed, dim=-1))


def _perpendicular_part(v: Tensor, n: Tensor, fallback: Tensor) -> Tensor:
    """Unit component of ``v`` perpendicular to unit ``n``; ``fallback`` where ``v`` is parallel."""
    p = v - _dot(v, n) * n
    ok = p.norm(dim=-1, keepdim=True) > 1e-6 * v.norm(dim=-1, keepdim=True).clamp_min(_EPS)
    return torch.where(ok, _unit(p), fallback)


def _normal(u: Tensor, v: Tensor, min_sin: float = 1e-7) -> tuple[Tensor, Tensor]:
    """Unit ``u x v`` and whether it is well defined: the angle between unit ``u`` and ``v`` has a
    sine above ``min_sin``."""
    n = torch.linalg.cross(u, v, dim=-1)
    ok = n.norm(dim=-1, keepdim=True) > min_sin * v.norm(dim=-1, keepdim=True).clamp_min(_EPS)
    return _unit(n), ok


#: a limb bent less than this (degrees) has no bend plane :func:`two_bone_ik` can carry over: the
#: plane of a nearly straight limb is the rig's modelling noise, not a knee's direction. Measured on
#: mannequin-x (an SMPL-X calibration whose thigh leans 3 degrees outwards at rest): the synthetic
#: walk's stance leg, bent 3.3 degrees before the solve, had its plane (the frontal one) carried
#: onto the pole's (the sagittal one), and every thigh and shin came out twisted 110 degrees about
#: the bone with the kneecap facing sideways (joint positions exact; the skinned thighs of a bulky
#: target crossing each other when the clip was copied onto it).
MIN_BEND_PLANE_DEG = 10.0


# ----------------------------------------------------------------------------- two-bone IK
def two_bone_positions(
    a: Array, b: Array, c: Array, target: Array, pole: Array | None = None
) -> tuple[Array, Array]:
    """New middle and end joint positions of a two-bone chain (law of cosines).

    The chain keeps its bone lengths ``|b - a|`` and ``|c - b|``. The end lands on ``target`` when
    ``|target - a|`` is within ``[| l1 - l2 |, l1 + l2]``, otherwise at the nearest reachable
    distance along the same line (fully extended towards a far target). The middle joint lies in
    the plane spanned by ``target - a`` and ``pole``, on the ``pole`` side.

    Args:
        a: ``(..., 3)`` upper joint (hip, shoulder); it does not move.
        b: ``(..., 3)`` current middle joint (knee, elbow).
        c: ``(..., 3)`` current end joint (ankle, wrist).
        target: ``(..., 3)`` desired end position.
        pole: ``(..., 3)`` bend direction (world), e.g. forward for a knee; ``None`` keeps the
            current bend plane (``b - a``).

    Returns:
        ``(b_new, c_new)``, each ``(..., 3)``, same type as ``a``.
    """
    as_numpy = isinstance(a, np.ndarray)
    a, b, c, target = (_to_torch(x) for x in (a, b, c, target))
    pole = b - a if pole is None else _to_torch(pole)
    l1 = (b - a).norm(dim=-1, keepdim=True)
    l2 = (c - b).norm(dim=-1, keepdim=True)
    to_t = target - a
    n = torch.where(to_t.norm(dim=-1, keepdim=True) > _EPS, _unit(to_t), _unit(c - a))
    d = to_t.norm(dim=-1, keepdim=True).clamp((l1 - l2).abs(), l1 + l2)
    m = _perpendicular_part(pole, n, _perpendicular_part(b - a, n, _any_perpendicular(n)))
    cos_a = ((l1 * l1 + d * d - l2 * l2) / (2.0 * l1 * d).clamp_min(_EPS)).clamp(-1.0, 1.0)
    sin_a = (1.0 - cos_a * cos_a).clamp_min(0.0).sqrt()
    b_new = a + l1 * (cos_a * n + sin_a * m)
    c_new = a + d * n
    if as_numpy:
        return b_new.numpy(), c_new.numpy()
    return b_new, c_new


def two_bone_ik(
    rotations: Array,
    offsets: Array,
    parents: Sequence[int],
    root_positions: Array,
    chain: tuple[int, int, int],
    target: Array,
    pole: Array | None = None,
    end_rotation: Array | None = None,
) -> Array:
    """Analytic IK for one limb, batched over frames.

    The middle joint bends as a hinge: its rotation changes only about the axis normal to the
    limb's plane, and the upper joint rotates the whole (re-bent) limb rigidly so that the middle
    joint points to the ``pole`` side (:func:`two_bone_positions`). A limb bent less than
    :data:`MIN_BEND_PLANE_DEG` before the solve has no plane to carry: its upper joint takes the
    minimal swing onto the new direction (no twist about the bone). Joints outside the chain keep
    their local rotations.

    Args:
        rotations: ``(..., J, 4)`` local rotations, wxyz.
        offsets: ``(J, 3)`` rest offsets.
        parents: ``J`` parent indices.
        root_positions: ``(..., 3)``.
        chain: ``(upper, lower, end)`` joint indices, e.g. :func:`limb_chain` ``(sk, "left_leg")``;
            ``lower`` must be a child of ``upper`` and ``end`` a child of ``lower``.
        target: ``(..., 3)`` world target for the end joint.
        pole: ``(..., 3)`` world bend direction of the middle joint; ``None`` keeps the current
            bend plane.
        end_rotation: ``(..., 4)`` desired *global* rotation of the end joint (e.g. a planted
            foot); ``None`` keeps the end joint's local rotation.

    Returns:
        ``(..., J, 4)`` new local rotations, same type as ``rotations``.
    """
    as_numpy = isinstance(rotations, np.ndarray)
    rot = _to_torch(rotations)
    offsets, root_positions, target = (_to_torch(x) for x in (offsets, root_positions, target))
    up, mid, end = chain
    if parents[mid] != up or parents[end] != mid:
        raise ValueError(f"chain {chain} is not a parent->child->grandchild chain")
    pos, grot = forward_kinematics(rot, offsets, parents, root_positions)
    a, b, c = pos[..., up, :], pos[..., mid, :], pos[..., end, :]
    b_new, c_new = two_bone_positions(a, b, c, target, None if pole is None else _to_torch(pole))
    u0, u1 = _unit(b - a), _unit(b_new - a)
    # limb-plane normals, oriented like upper x lower, before and after; a straight limb (before:
    # bent less than MIN_BEND_PLANE_DEG) borrows the other configuration's normal carried over by
    # the minimal swing u0 -> u1, so the upper bone turns without a twist
    swing = quat_between(u0, u1)
    n0, ok0 = _normal(u0, c - b, math.sin(math.radians(MIN_BEND_PLANE_DEG)))
    n1, ok1 = _normal(u1, c_new - b_new)
    h0 = torch.where(
        ok0, n0, torch.where(ok1, quat_rotate(quat_conjugate(swing), n1), _any_perpendicular(u0))
    )
    h1 = torch.where(ok1, n1, quat_rotate(swing, h0))
    r_up = frame_rotation(u0, h0, u1, h1)
    g_up = quat_mul(r_up, grot[..., up, :])
    bent = quat_rotate(r_up, c - b)
    g_mid = quat_mul(quat_between(bent, c_new - b_new), quat_mul(r_up, grot[..., mid, :]))
    out = rot.clone()
    p_up = parents[up]
    identity = torch.zeros_like(g_up) + g_up.new_tensor([1.0, 0.0, 0.0, 0.0])
    g_parent = grot[..., p_up, :] if p_up >= 0 else identity
    out[..., up, :] = quat_canonical(quat_mul(quat_conjugate(g_parent), g_up))
    out[..., mid, :] = quat_canonical(quat_mul(quat_conjugate(g_up), g_mid))
    if end_rotation is not None:
        out[..., end, :] = quat_canonical(quat_mul(quat_conjugate(g_mid), _to_torch(end_rotation)))
    return out.numpy() if as_numpy else out


# ----------------------------------------------------------------------------- full-body IK
def _ancestors(parents: Sequence[int], j: int) -> set[int]:
    out = set()
    while j >= 0:
        out.add(j)
        j = parents[j]
    return out


def _skew(v: Tensor) -> Tensor:
    """``(..., 3) -> (..., 3, 3)`` cross-product matrix: ``skew(v) @ w = v x w``."""
    z = torch.zeros_like(v[..., 0])
    x, y, w = v.unbind(-1)
    return torch.stack((z, -w, y, w, z, -x, -y, x, z), dim=-1).reshape(v.shape + (3,))


def _dls_step(
    pos: Tensor,
    r: Tensor,
    dev: Tensor,
    tj: list[int],
    free: list[int],
    anc: Tensor,
    inv_w: Tensor,
    move_root: bool,
    gain: Tensor,
    mu: float,
) -> Tensor:
    """One damped least-squares step with a null-space pull towards the input pose.

    Args:
        pos: ``(T, J, 3)`` current joint positions.
        r: ``(T, K, 3)`` target residuals (current - target).
        dev: ``(T, P)`` current deviation from the input pose (``P = 3F (+3)``).
        tj: ``K`` target joints; free: ``F`` free joints; anc: ``(K, F)`` ancestor mask.
        inv_w: ``(P,)`` inverse stiffness.
        move_root: whether the last 3 parameters are the root translation.
        gain: ``(T, 1)`` fraction of the deviation to remove this step.
        mu: damping.

    Returns:
        ``(T, P)`` step ``-g d + W^-1 J^T (J W^-1 J^T + mu^2 I)^-1 (g J d - r)``.
    """
    T, K, F = r.shape[0], len(tj), len(free)
    lever = pos[:, tj].unsqueeze(2) - pos[:, free].unsqueeze(1)  # (T, K, F, 3)
    jac = -_skew(lever) * anc[None, :, :, None, None]  # (T, K, F, 3, 3)
    jac = jac.permute(0, 1, 3, 2, 4).reshape(T, 3 * K, 3 * F)
    if move_root:
        eye = torch.eye(3, dtype=pos.dtype).repeat(K, 1).expand(T, -1, -1)
        jac = torch.cat((jac, eye), dim=-1)
    jw = jac * inv_w
    lhs = jw @ jac.transpose(1, 2) + mu * mu * torch.eye(3 * K, dtype=pos.dtype)
    rhs = gain * (jac @ dev.unsqueeze(-1)).squeeze(-1) - r.reshape(T, 3 * K)
    y = torch.linalg.solve(lhs, rhs).unsqueeze(-1)
    return -gain * dev + (jw.transpose(1, 2) @ y).squeeze(-1)


def solve_ik(
    rotations: Array,
    offsets: Array,
    parents: Sequence[int],
    root_positions: Array,
    targets: Mapping[int, Array],
    free_joints: Sequence[int] | None = None,
    move_root: bool = True,
    joint_weights: Mapping[int, float] | None = None,
    root_weight: float = 1.0,
    iterations: int = 30,
    damping: float = 1e-2,
    tol: float = 1e-7,
    max_step: float = 0.5,
) -> tuple[Array, Array]:
    """Full-body IK: reach several position targets while staying close to the input pose.

    Damped least squares on the geometric Jacobian: joint positions are linearised in world-axis
    rotation increments ``w_j`` of the free joints (``d x_e / d w_j = -[x_e - x_j]_x`` for every
    ancestor ``j`` of target joint ``e``) and in the root translation. Each step is

    ``D = -g d + W^-1 J^T (J W^-1 J^T + mu^2 I)^-1 (g J d - r)``

    with ``r`` the target residuals and ``d`` the deviation from the input pose (rotation vectors
    in world axes, root offset in metres): the targets are met with the least ``W``-weighted
    motion, and the fraction ``g`` of the deviation that lies in the Jacobian's null space is
    given back, so among the poses that meet the targets the one nearest the input is preferred.
    ``g = 0.5`` once a frame is within 1 cm of its targets, 0 before, and 0 during the last third
    of the iterations (a plain Gauss-Newton polish to ``tol``). ``mu`` halves every iteration
    from ``damping``. Frames are solved independently (batched).

    Args:
        rotations: ``(T, J, 4)`` input local rotations (the prior), wxyz.
        offsets: ``(J, 3)`` rest offsets.
        parents: ``J`` parent indices.
        root_positions: ``(T, 3)`` input root positions.
        targets: ``{joint index: (T, 3) world target}``.
        free_joints: joints allowed to rotate (default: all).
        move_root: also let the root translate.
        joint_weights: stiffness per free joint (default 1; larger moves less).
        root_weight: stiffness of the root translation (per metre, against radians).
        iterations: iterations (fewer when the polish reaches ``tol``).
        damping: initial damping ``mu`` (metres).
        tol: residual (metres) at which the polish stops.
        max_step: largest rotation increment of any joint per iteration (radians); larger steps
            are scaled down as a whole.

    Returns:
        ``(rotations (T, J, 4), root_positions (T, 3))``, same type as the inputs.
    """
    as_numpy = isinstance(rotations, np.ndarray)
    q_in, off, root_in = (_to_torch(x) for x in (rotations, offsets, root_positions))
    free = list(range(len(parents))) if free_joints is None else list(free_joints)
    tj = list(targets)
    tgt = torch.stack([_to_torch(targets[e]) for e in tj], dim=1)  # (T, K, 3)
    anc = torch.tensor(
        [[float(f in _ancestors(parents, e)) for f in free] for e in tj], dtype=q_in.dtype
    )
    stiff = [(joint_weights or {}).get(f, 1.0) for f in free for _ in range(3)]
    inv_w = 1.0 / torch.tensor(stiff + ([root_weight] * 3 if move_root else []), dtype=q_in.dtype)
    par_free = torch.tensor([max(parents[f], 0) for f in free])
    is_root = torch.tensor([parents[f] < 0 for f in free]).unsqueeze(-1)
    identity = q_in.new_tensor([1.0, 0.0, 0.0, 0.0])
    q, root = q_in.clone(), root_in.clone()
    F = len(free)
    for it in range(iterations):
        polish = it >= iterations - iterations // 3
        pos, grot = forward_kinematics(q, off, parents, root)
        r = pos[:, tj] - tgt
        err = r.norm(dim=-1).amax(-1, keepdim=True)  # (T, 1)
        if polish and err.max() < tol:
            break
        g_par = torch.where(is_root, identity, grot[:, par_free])  # (T, F, 4)
        moved = quat_to_axis_angle(quat_mul(q[:, free], quat_conjugate(q_in[:, free])))
        dev = quat_rotate(g_par, moved).reshape(len(q), 3 * F)
        if move_root:
            dev = torch.cat((dev, root - root_in), dim=-1)
        gain = torch.zeros_like(err) if polish else 0.5 * (err < 0.01).to(q.dtype)
        mu = max(damping * 0.5**it, 1e-9)
        step = _dls_step(pos, r, dev, tj, free, anc, inv_w, move_root, gain, mu)
        rot_step = step[:, : 3 * F].reshape(-1, F, 3)
        biggest = rot_step.norm(dim=-1).amax(-1, keepdim=True).clamp_min(_EPS)
        scale = (max_step / biggest).clamp(max=1.0)
        local = quat_rotate(quat_conjugate(g_par), rot_step * scale.unsqueeze(-1))
        q[:, free] = quat_mul(quat_from_axis_angle(local), q[:, free])
        if move_root:
            root = root + step[:, 3 * F :] * scale
    q = quat_canonical(q)
    return (q.numpy(), root.numpy()) if as_numpy else (q, root)


# ----------------------------------------------------------------------------- foot contacts
def _segments(mask: np.ndarray) -> list[tuple[int, int]]:
    """``[start, stop)`` runs of ``True`` in a 1-D bool array."""
    m = np.concatenate(([False], mask.astype(bool), [False]))
    edges = np.flatnonzero(m[1:] != m[:-1])
    return list(zip(edges[::2], edges[1::2], strict=False))


def _falloff(x: np.ndarray) -> np.ndarray:
    """SAN's blend weight ``2x^3 - 3x^2 + 1`` on ``[0, 1]`` (1 at the contact, 0 at ``x = 1``)."""
    x = np.clip(x, 0.0, 1.0)
    return 2 * x**3 - 3 * x**2 + 1


def _locked_displacement(
    x: np.ndarray, contact: np.ndarray, blend: int
) -> tuple[np.ndarray, np.ndarray]:
    """Displacement that pins one joint during each contact run, blended out around it.

    In a run the joint is moved to the run's mean position (as in SAN). In the ``blend`` free
    frames on either side the correction of the nearest run edge fades with :func:`_falloff`;
    between two close runs the two fading corrections are combined with weights summing to
    at most 1.

    Args:
        x: ``(T, 3)`` joint positions.
        contact: ``(T,)`` bool.
        blend: frames of fade-in / fade-out.

    Returns:
        ``(displacement (T, 3), weight (T,))`` with weight 1 in contact, fading to 0.
    """
    T = len(x)
    disp = np.zeros_like(x)
    weight = np.zeros(T)
    num = np.zeros_like(x)
    den = np.zeros(T)
    frames = np.arange(T)
    for s, e in _segments(contact):
        anchor = x[s:e].mean(axis=0)
        disp[s:e] = anchor - x[s:e]
        weight[s:e] = 1.0
        for edge, dist in ((s, s - frames), (e - 1, frames - (e - 1))):
            f = np.where((dist > 0) & ~contact, _falloff(dist / (blend + 1.0)), 0.0)
            num += f[:, None] * (anchor - x[edge])
            den += f
    free = ~contact.astype(bool)
    norm = np.maximum(den, 1.0)
    disp[free] = num[free] / norm[free, None]
    weight[free] = np.minimum(den[free], 1.0)
    return disp, weight


def foot_contact_targets(
    positions: np.ndarray, skeleton: Skeleton, contacts: np.ndarray, blend_frames: int = 5
) -> dict[str, np.ndarray]:
    """Where each ankle and toe should be so that feet stay still while in contact.

    Each contact joint is pinned to its mean position over each contact run (SAN's IK
    post-process) and eased back to its own path over ``blend_frames`` free frames. A foot joint
    that is not pinned follows the other joint of the same foot (the foot moves rigidly, e.g. the
    ankle follows a planted toe while the heel is lifting), and the pair is kept one foot length
    apart by moving the less firmly pinned joint.

    Args:
        positions: ``(T, J, 3)`` world joint positions.
        skeleton: the motion's skeleton (canonical joint names).
        contacts: ``(T, 2)`` bool per foot ``(left, right)`` (ankle and toe together) or ``(T, 4)``
            bool per joint in :data:`FOOT_CONTACT_JOINTS` order.
        blend_frames: fade length in frames.

    Returns:
        ``{joint name: (T, 3) target}`` for the four :data:`FOOT_CONTACT_JOINTS`.
    """
    contacts = np.asarray(contacts, dtype=bool)
    if contacts.ndim != 2 or contacts.shape[1] not in (2, 4) or contacts.shape[0] != len(positions):
        raise ValueError(
            f"contacts must be (T, 2) or (T, 4) with T={len(positions)}, got {contacts.shape}"
        )
    if contacts.shape[1] == 2:
        contacts = np.concatenate((contacts, contacts), axis=1)
    out = {}
    for side in (0, 1):
        heel, toe = FOOT_CONTACT_JOINTS[side], FOOT_CONTACT_JOINTS[side + 2]
        xh, xt = positions[:, skeleton.index(heel)], positions[:, skeleton.index(toe)]
        dh, wh = _locked_displacement(xh, contacts[:, side], blend_frames)
        dt, wt = _locked_displacement(xt, contacts[:, side + 2], blend_frames)
        heel_goal = xh + dh + (1.0 - wh)[:, None] * dt
        toe_goal = xt + dt + (1.0 - wt)[:, None] * dh
        # keep the foot's length: the more firmly pinned joint stays, the other slides along
        length = np.linalg.norm(skeleton.offsets[skeleton.index(toe)])
        along = toe_goal - heel_goal
        along /= np.maximum(np.linalg.norm(along, axis=-1, keepdims=True), 1e-12)
        toe_first = (wt >= wh)[:, None]  # ties: the toe (ball of the foot) holds
        out[heel] = np.where(toe_first, toe_goal - length * along, heel_goal)
        out[toe] = np.where(toe_first, toe_goal, heel_goal + length * along)
    return out


def apply_foot_contact_ik(motion: Motion, contacts: np.ndarray, blend_frames: int = 5) -> Motion:
    """Plant the feet during contact and re-solve the legs (SAN's IK post-process).

    This is the "+ IK" of the contact-aware paper's baselines (Villegas et al. 2021, Sec. 4,
    Table 1: "SAN + IK", "Efull + IK"). Targets come from :func:`foot_contact_targets`; each
    leg is solved with :func:`two_bone_ik` (knee keeps its current bend plane) and the foot is
    turned with the smallest rotation that points it from the ankle target to the toe target,
    so during a contact run both ankle and toe stay exactly fixed (when reachable). The root is
    not moved: a target beyond the leg's reach leaves the leg fully extended towards it.

    Args:
        motion: a motion on the canonical 22 joints.
        contacts: ``(T, 2)`` bool (left, right foot) or ``(T, 4)`` bool per joint in
            :data:`FOOT_CONTACT_JOINTS` order.
        blend_frames: frames over which each correction fades in and out.

    Returns:
        a new :class:`Motion` (root trajectory unchanged, leg rotations changed).
    """
    sk = motion.skeleton
    pos, grot = motion.fk()
    goals = foot_contact_targets(pos, sk, contacts, blend_frames)
    rot = torch.from_numpy(motion.rotations.copy())
    root = torch.from_numpy(motion.root_positions)
    off = torch.from_numpy(sk.offsets)
    for side, limb in (("Left", "left_leg"), ("Right", "right_leg")):
        ankle, toe = sk.index(f"{side}Foot"), sk.index(f"{side}ToeBase")
        aim = quat_between(
            torch.from_numpy(pos[:, toe] - pos[:, ankle]),
            torch.from_numpy(goals[f"{side}ToeBase"] - goals[f"{side}Foot"]),
        )
        foot_rot = quat_mul(aim, torch.from_numpy(grot[:, ankle]))
        rot = two_bone_ik(
            rot,
            off,
            sk.parents,
            root,
            limb_chain(sk, limb),
            torch.from_numpy(goals[f"{side}Foot"]),
            None,
            foot_rot,
        )
    return motion.copy(rotations=rot.numpy(), meta=dict(motion.meta, foot_contact_ik=True))
