"""Quaternion and rotation math, batched, in PyTorch.

Conventions (see the package docstring):

* Quaternions are ``(w, x, y, z)``, shape ``(..., 4)``, unit norm.
* Rotation matrices act on **column vectors**: ``v' = R @ v``; shape ``(..., 3, 3)``.
* ``quat_mul(a, b)`` is the rotation "first ``b``, then ``a``" (same as ``Ra @ Rb``).
* Euler angles follow BVH: for a channel order such as ``"ZXY"`` the local rotation is
  ``R = Rz(a0) @ Rx(a1) @ Ry(a2)`` (intrinsic, applied left to right as listed).

Every function works in float32 and float64 and is differentiable (where the map is smooth).
"""

from __future__ import annotations

import math

import numpy as np
import torch

Tensor = torch.Tensor
Array = Tensor | np.ndarray

__all__ = [
    "quat_identity",
    "quat_normalize",
    "quat_mul",
    "quat_conjugate",
    "quat_inverse",
    "quat_rotate",
    "quat_to_matrix",
    "matrix_to_quat",
    "quat_from_axis_angle",
    "quat_to_axis_angle",
    "quat_from_euler",
    "quat_to_euler",
    "quat_to_6d",
    "quat_from_6d",
    "matrix_to_6d",
    "matrix_from_6d",
    "quat_angle",
    "quat_slerp",
    "quat_between",
    "quat_canonical",
    "quat_swing_twist",
    "frame_rotation",
]


def quat_identity(shape: tuple[int, ...] = (), dtype=torch.float32, device=None) -> Tensor:
    """Identity quaternions.

    Args:
        shape: leading shape; the result has shape ``(*shape, 4)``.

    Returns:
        ``(*shape, 4)`` wxyz, all ``(1, 0, 0, 0)``.
    """
    q = torch.zeros(*shape, 4, dtype=dtype, device=device)
    q[..., 0] = 1.0
    return q


def quat_normalize(q: Tensor, eps: float = 1e-12) -> Tensor:
    """Scale quaternions to unit norm.

    Args:
        q: ``(..., 4)`` wxyz, any norm > 0.

    Returns:
        ``(..., 4)`` unit wxyz.
    """
    return q / q.norm(dim=-1, keepdim=True).clamp_min(eps)


def quat_canonical(q: Tensor) -> Tensor:
    """Pick the representative with ``w >= 0`` (``q`` and ``-q`` are the same rotation).

    Args:
        q: ``(..., 4)`` wxyz.
    """
    return torch.where(q[..., :1] < 0, -q, q)


def quat_mul(a: Tensor, b: Tensor) -> Tensor:
    """Hamilton product ``a * b`` (rotate by ``b`` first, then by ``a``).

    Args:
        a: ``(..., 4)`` wxyz.
        b: ``(..., 4)`` wxyz; broadcast against ``a``.

    Returns:
        ``(..., 4)`` wxyz.
    """
    aw, ax, ay, az = a.unbind(-1)
    bw, bx, by, bz = b.unbind(-1)
    return torch.stack(
        (
            aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
        ),
        dim=-1,
    )


def quat_conjugate(q: Tensor) -> Tensor:
    """Conjugate ``(w, -x, -y, -z)``; the inverse of a unit quaternion.

    Args:
        q: ``(..., 4)`` wxyz.
    """
    return q * q.new_tensor([1.0, -1.0, -1.0, -1.0])


def quat_inverse(q: Tensor) -> Tensor:
    """Inverse of any non-zero quaternion: ``conj(q) / |q|^2``.

    Args:
        q: ``(..., 4)`` wxyz.
    """
    return quat_conjugate(q) / (q * q).sum(-1, keepdim=True)


def quat_rotate(q: Tensor, v: Tensor) -> Tensor:
    """Rotate 3-vectors by unit quaternions: ``q v q*``.

    Uses ``v' = v + 2 w (u x v) + 2 u x (u x v)`` with ``u = (x, y, z)``.

    Args:
        q: ``(..., 4)`` unit wxyz.
        v: ``(..., 3)``; broadcast against ``q``.

    Returns:
        ``(..., 3)`` rotated vectors.
    """
    w = q[..., :1]
    u = q[..., 1:]
    uv = _cross(u, v)
    return v + 2.0 * (w * uv + _cross(u, uv))


def _cross(a: Tensor, b: Tensor) -> Tensor:
    """Broadcasting cross product over the last axis (``torch.cross`` does not broadcast)."""
    ax, ay, az = a.unbind(-1)
    bx, by, bz = b.unbind(-1)
    return torch.stack((ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx), dim=-1)


def quat_to_matrix(q: Tensor) -> Tensor:
    """Unit quaternion to rotation matrix (column-vector convention).

    Args:
        q: ``(..., 4)`` unit wxyz.

    Returns:
        ``(..., 3, 3)``.
    """
    w, x, y, z = q.unbind(-1)
    xx, yy, zz = x * x, y * y, z * z
    xy, xz, yz = x * y, x * z, y * z
    wx, wy, wz = w * x, w * y, w * z
    m = torch.stack(
        (
            1 - 2 * (yy + zz),
            2 * (xy - wz),
            2 * (xz + wy),
            2 * (xy + wz),
            1 - 2 * (xx + zz),
            2 * (yz - wx),
            2 * (xz - wy),
            2 * (yz + wx),
            1 - 2 * (xx + yy),
        ),
        dim=-1,
    )
    return m.reshape(q.shape[:-1] + (3, 3))


def matrix_to_quat(m: Tensor) -> Tensor:
    """Rotation matrix to unit quaternion with ``w >= 0``.

    Numerically stable branch selection (Shepperd's method): for each matrix the largest of
    ``w, x, y, z`` is recovered from the diagonal and the rest from off-diagonal sums.

    Args:
        m: ``(..., 3, 3)`` rotation matrices.

    Returns:
        ``(..., 4)`` unit wxyz, ``w >= 0``.
    """
    m00, m01, m02 = m[..., 0, 0], m[..., 0, 1], m[..., 0, 2]
    m10, m11, m12 = m[..., 1, 0], m[..., 1, 1], m[..., 1, 2]
    m20, m21, m22 = m[..., 2, 0], m[..., 2, 1], m[..., 2, 2]
    # 4 * squares of each component, one candidate per branch.
    cand = torch.stack(
        (
            1.0 + m00 + m11 + m22,
            1.0 + m00 - m11 - m22,
            1.0 - m00 + m11 - m22,
            1.0 - m00 - m11 + m22,
        ),
        dim=-1,
    )
    best = cand.argmax(dim=-1, keepdim=True)
    s = torch.sqrt(cand.gather(-1, best).clamp_min(1e-12)) * 2.0  # = 4 * |component|
    s = s.squeeze(-1)
    q_w = torch.stack((s / 4, (m21 - m12) / s, (m02 - m20) / s, (m10 - m01) / s), -1)
    q_x = torch.stack(((m21 - m12) / s, s / 4, (m01 + m10) / s, (m02 + m20) / s), -1)
    q_y = torch.stack(((m02 - m20) / s, (m01 + m10) / s, s / 4, (m12 + m21) / s), -1)
    q_z = torch.stack(((m10 - m01) / s, (m02 + m20) / s, (m12 + m21) / s, s / 4), -1)
    allq = torch.stack((q_w, q_x, q_y, q_z), dim=-2)  # (..., 4 branches, 4)
    q = allq.gather(-2, best.unsqueeze(-1).expand(*best.shape[:-1], 1, 4)).squeeze(-2)
    return quat_canonical(quat_normalize(q))


def quat_from_axis_angle(axis_angle: Tensor) -> Tensor:
    """Axis-angle (rotation vector, radians) to quaternion.

    Args:
        axis_angle: ``(..., 3)``; direction = axis, norm = angle in radians.

    Returns:
        ``(..., 4)`` unit wxyz. Smooth at zero (uses ``sinc``).
    """
    angle = axis_angle.norm(dim=-1, keepdim=True)
    half = 0.5 * angle
    # sin(half)/angle = 0.5 * sinc(half/pi) (torch.sinc is the normalised sinc)
    k = 0.5 * torch.sinc(half / math.pi)
    return torch.cat((torch.cos(half), axis_angle * k), dim=-1)


def quat_to_axis_angle(q: Tensor) -> Tensor:
    """Quaternion to rotation vector (radians), angle in ``[0, pi]``.

    Args:
        q: ``(..., 4)`` unit wxyz.

    Returns:
        ``(..., 3)`` axis * angle.
    """
    q = quat_canonical(q)
    v = q[..., 1:]
    s = v.norm(dim=-1, keepdim=True)
    half = torch.atan2(s, q[..., :1])
    # angle/s = 2*half/sin(half)  -> 2 / sinc(half/pi) ; stable near 0
    k = 2.0 / torch.sinc(half / math.pi)
    return v * k


def quat_angle(q: Tensor) -> Tensor:
    """Rotation angle in radians, in ``[0, pi]`` (``E(.)`` of TDCN Eq. 8/23).

    Args:
        q: ``(..., 4)`` wxyz (normalised internally).

    Returns:
        ``(...)`` angles.
    """
    q = quat_normalize(q)
    return 2.0 * torch.atan2(q[..., 1:].norm(dim=-1), q[..., 0].abs())


_AXES = {"X": 0, "Y": 1, "Z": 2}


def _axis_quat(angle: Tensor, axis: int) -> Tensor:
    half = 0.5 * angle
    zeros = torch.zeros_like(half)
    comps = [torch.cos(half), zeros, zeros, zeros]
    comps[1 + axis] = torch.sin(half)
    return torch.stack(comps, dim=-1)


def quat_from_euler(angles: Tensor, order: str, degrees: bool = False) -> Tensor:
    """Euler angles in a BVH channel order to quaternions.

    ``order="ZXY"`` with angles ``(a, b, c)`` gives ``Rz(a) @ Rx(b) @ Ry(c)``: the angles are
    listed in the order the channels appear in the BVH file.

    Args:
        angles: ``(..., 3)`` angles in ``order``.
        order: any permutation of ``"XYZ"`` (case-insensitive).
        degrees: whether ``angles`` are in degrees.

    Returns:
        ``(..., 4)`` unit wxyz.
    """
    order = order.upper()
    if sorted(order) != ["X", "Y", "Z"]:
        raise ValueError(f"Euler order must be a permutation of XYZ, got {order!r}")
    if degrees:
        angles = angles * (math.pi / 180.0)
    q = _axis_quat(angles[..., 0], _AXES[order[0]])
    for i in (1, 2):
        q = quat_mul(q, _axis_quat(angles[..., i], _AXES[order[i]]))
    return q


def quat_to_euler(q: Tensor, order: str, degrees: bool = False) -> Tensor:
    """Quaternions to Euler angles in a BVH channel order (inverse of :func:`quat_from_euler`).

    For ``R = R_i(a) R_j(b) R_k(c)`` (``order = ijk``), the middle angle is in
    ``[-pi/2, pi/2]``; at gimbal lock ``c`` is set to 0.

    Args:
        q: ``(..., 4)`` unit wxyz.
        order: permutation of ``"XYZ"``.
        degrees: return degrees instead of radians.

    Returns:
        ``(..., 3)`` angles in ``order``.
    """
    order = order.upper()
    i, j, k = (_AXES[c] for c in order)
    m = quat_to_matrix(q)
    # parity: +1 for cyclic (XYZ, YZX, ZXY), -1 otherwise
    sign = 1.0 if (j - i) % 3 == 1 else -1.0
    # For R = Ri(a) Rj(b) Rk(c):  R[i, k] = sign * sin(b)
    sb = (sign * m[..., i, k]).clamp(-1.0, 1.0)
    # atan2 instead of asin: full precision near the poles
    b = torch.atan2(sb, torch.hypot(m[..., i, i], m[..., i, j]))
    a = torch.atan2(-sign * m[..., j, k], m[..., k, k])
    c = torch.atan2(-sign * m[..., i, j], m[..., i, i])
    lock = torch.hypot(m[..., i, i], m[..., i, j]) < torch.finfo(m.dtype).eps ** 0.5
    if lock.any():
        # c := 0, then R = Ri(a) Rj(b): a from the j-axis block
        a_lock = torch.atan2(sign * m[..., k, j], m[..., j, j])
        a = torch.where(lock, a_lock, a)
        c = torch.where(lock, torch.zeros_like(c), c)
    out = torch.stack((a, b, c), dim=-1)
    if degrees:
        out = out * (180.0 / math.pi)
    return out


def matrix_to_6d(m: Tensor) -> Tensor:
    """Rotation matrix to the continuous 6D representation (first two columns, Zhou et al. 2019).

    Args:
        m: ``(..., 3, 3)``.

    Returns:
        ``(..., 6)`` = ``[col0, col1]``.
    """
    return torch.cat((m[..., :, 0], m[..., :, 1]), dim=-1)


def matrix_from_6d(d6: Tensor) -> Tensor:
    """6D representation to rotation matrix by Gram-Schmidt.

    Args:
        d6: ``(..., 6)`` (any two non-parallel 3-vectors).

    Returns:
        ``(..., 3, 3)`` rotation matrices.
    """
    a1, a2 = d6[..., :3], d6[..., 3:]
    b1 = a1 / a1.norm(dim=-1, keepdim=True).clamp_min(1e-12)
    a2 = a2 - (b1 * a2).sum(-1, keepdim=True) * b1
    b2 = a2 / a2.norm(dim=-1, keepdim=True).clamp_min(1e-12)
    b3 = _cross(b1, b2)
    return torch.stack((b1, b2, b3), dim=-1)


def quat_to_6d(q: Tensor) -> Tensor:
    """Quaternion to 6D representation. ``q: (..., 4)`` wxyz → ``(..., 6)``."""
    return matrix_to_6d(quat_to_matrix(q))


def quat_from_6d(d6: Tensor) -> Tensor:
    """6D representation to quaternion. ``d6: (..., 6)`` → ``(..., 4)`` wxyz, ``w >= 0``."""
    return matrix_to_quat(matrix_from_6d(d6))


def quat_slerp(q0: Tensor, q1: Tensor, t: Tensor | float) -> Tensor:
    """Spherical linear interpolation along the shorter arc.

    Args:
        q0: ``(..., 4)`` unit wxyz at ``t = 0``.
        q1: ``(..., 4)`` unit wxyz at ``t = 1``.
        t: scalar or ``(...)`` tensor broadcastable to the leading shape.

    Returns:
        ``(..., 4)`` unit wxyz.
    """
    t = torch.as_tensor(t, dtype=q0.dtype, device=q0.device)
    if t.dim() > 0:
        t = t.unsqueeze(-1)
    dot = (q0 * q1).sum(-1, keepdim=True)
    q1 = torch.where(dot < 0, -q1, q1)
    dot = dot.abs().clamp(max=1.0)
    theta = torch.acos(dot)
    sin_t = torch.sin(theta)
    small = sin_t < 1e-6
    safe = torch.where(small, torch.ones_like(sin_t), sin_t)
    w0 = torch.where(small, 1.0 - t, torch.sin((1.0 - t) * theta) / safe)
    w1 = torch.where(small, t, torch.sin(t * theta) / safe)
    return quat_normalize(w0 * q0 + w1 * q1)


def quat_between(u: Tensor, v: Tensor) -> Tensor:
    """Shortest-arc rotation taking direction ``u`` to direction ``v``.

    Args:
        u: ``(..., 3)`` non-zero.
        v: ``(..., 3)`` non-zero; broadcast against ``u``.

    Returns:
        ``(..., 4)`` unit wxyz with ``quat_rotate(q, u/|u|) == v/|v|``. For opposite vectors
        a rotation by pi about an axis orthogonal to ``u`` is returned.
    """
    u = u / u.norm(dim=-1, keepdim=True).clamp_min(1e-12)
    v = v / v.norm(dim=-1, keepdim=True).clamp_min(1e-12)
    u, v = torch.broadcast_tensors(u, v)
    w = 1.0 + (u * v).sum(-1, keepdim=True)
    axis = _cross(u, v)
    # opposite vectors: any axis orthogonal to u
    ortho = _cross(u, torch.zeros_like(u) + u.new_tensor([1.0, 0.0, 0.0]))
    alt = _cross(u, torch.zeros_like(u) + u.new_tensor([0.0, 1.0, 0.0]))
    ortho = torch.where(ortho.norm(dim=-1, keepdim=True) < 1e-6, alt, ortho)
    opposite = w < 1e-7
    q = torch.where(opposite, torch.cat((torch.zeros_like(w), ortho), -1), torch.cat((w, axis), -1))
    return quat_normalize(q)


def quat_swing_twist(q: Tensor, axis: Tensor) -> tuple[Tensor, Tensor]:
    """Decompose ``q = swing * twist`` with ``twist`` about ``axis``.

    Args:
        q: ``(..., 4)`` unit wxyz.
        axis: ``(..., 3)`` unit twist axis (in the frame ``q`` acts on).

    Returns:
        ``(swing, twist)``, each ``(..., 4)`` unit wxyz.
    """
    axis = axis / axis.norm(dim=-1, keepdim=True).clamp_min(1e-12)
    proj = (q[..., 1:] * axis).sum(-1, keepdim=True) * axis
    twist = torch.cat((q[..., :1], proj), dim=-1)
    n = twist.norm(dim=-1, keepdim=True)
    twist = torch.where(
        n < 1e-9, quat_identity(q.shape[:-1], q.dtype, q.device), twist / n.clamp_min(1e-12)
    )
    swing = quat_mul(q, quat_conjugate(twist))
    return swing, twist


def frame_rotation(u0: Array, v0: Array, u1: Array, v1: Array) -> Array:
    """The rotation taking direction ``u0`` exactly onto ``u1`` and the half-plane of ``v0``
    (seen from ``u0``) onto that of ``v1``; ``v`` need not be orthogonal to ``u`` (Gram-Schmidt).

    Args:
        u0, v0: ``(..., 3)`` source frame vectors (not parallel).
        u1, v1: ``(..., 3)`` target frame vectors (not parallel).

    Returns:
        ``(..., 4)`` wxyz, same type as ``u0``.
    """
    as_numpy = isinstance(u0, np.ndarray)

    def unit(v):
        return v / v.norm(dim=-1, keepdim=True).clamp_min(1e-9)

    def frame(u, v):
        e1 = unit(u)
        e2 = unit(v - (v * e1).sum(-1, keepdim=True) * e1)
        return torch.stack((e1, e2, torch.linalg.cross(e1, e2, dim=-1)), dim=-1)

    u0, v0, u1, v1 = (
        torch.from_numpy(np.asarray(x, dtype=np.float64)) if isinstance(x, np.ndarray) else x
        for x in (u0, v0, u1, v1)
    )
    q = matrix_to_quat(frame(u1, v1) @ frame(u0, v0).transpose(-1, -2))
    return q.numpy() if as_numpy else q
