"""Forward kinematics: local joint rotations + rest offsets + root positions → global joints.

For joint ``j`` with parent ``p`` (TDCN Eqs. 1 and 3, ``f_FK``)::

    G_j = G_p * q_j                    (global rotation, quaternion product)
    x_j = x_p + rotate(G_p, offset_j)  (global position)
    x_root = root_position,  G_root = q_root

The root's offset is its *rest* position and is not added: the root is placed by
``root_positions`` (as BVH position channels do).

How it is fast (see ``retarget bench``): the data are laid out structure-of-arrays,
``(component, joint, batch)``, with joints sorted by tree depth so that every depth level is a
contiguous slice. Each level is then a few fused multiply-adds over long contiguous rows: the
quaternion product is ``a*b = a_w b + a_x P_x(b) + a_y P_y(b) + a_z P_z(b)`` with signed
permutations ``P`` of ``b`` (small per-level copies: full-size temporaries cost more in
page faults than they save), and cross products use index
permutations instead of ``torch.cross``. The canonical 22 joints need 7 levels instead of 21
sequential joint steps.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache
from typing import NamedTuple, cast

import numpy as np
import torch

from .rotations import quat_conjugate, quat_mul, quat_normalize

Tensor = torch.Tensor

__all__ = ["FKResult", "forward_kinematics", "local_positions", "align_local_rotations"]


class FKResult(NamedTuple):
    """Output of :func:`forward_kinematics`.

    Attributes:
        positions: ``(..., J, 3)`` global joint positions.
        rotations: ``(..., J, 4)`` global joint rotations, wxyz.
    """

    positions: Tensor | np.ndarray
    rotations: Tensor | np.ndarray


@dataclass(frozen=True)
class _Plan:
    order: tuple[int, ...]  # joint indices sorted by depth
    inverse: tuple[int, ...]  # position of each joint in ``order``
    levels: tuple[tuple[int, int, tuple[int, ...]], ...]  # (start, end, parent slots) per depth


@lru_cache(maxsize=64)
def _plan(parents: tuple[int, ...]) -> _Plan:
    depth = [0] * len(parents)
    for j, p in enumerate(parents):
        if j == 0 and p != -1 or j > 0 and not 0 <= p < j:
            raise ValueError(
                f"parents must start with -1 and precede children; joint {j} has parent {p}"
            )
        if p >= 0:
            depth[j] = depth[p] + 1
    order = tuple(sorted(range(len(parents)), key=lambda j: (depth[j], j)))
    inverse = tuple(order.index(j) for j in range(len(parents)))
    levels = []
    for d in range(1, max(depth) + 1):
        slots = [k for k, j in enumerate(order) if depth[j] == d]
        levels.append((slots[0], slots[-1] + 1, tuple(inverse[parents[order[k]]] for k in slots)))
    return _Plan(order, inverse, tuple(levels))


# a * b = a_w * b + a_x * (S_x ⊙ b[P_x]) + a_y * (S_y ⊙ b[P_y]) + a_z * (S_z ⊙ b[P_z])
_PERM = ((1, 0, 3, 2), (2, 3, 0, 1), (3, 2, 1, 0))
_SIGN = ((-1.0, 1.0, -1.0, 1.0), (-1.0, 1.0, 1.0, -1.0), (-1.0, -1.0, 1.0, 1.0))


def forward_kinematics(
    rotations: Tensor | np.ndarray,
    offsets: Tensor | np.ndarray,
    parents: Sequence[int],
    root_positions: Tensor | np.ndarray | None = None,
) -> FKResult:
    """Global joint positions and rotations from local rotations.

    Batched over any leading dims and differentiable w.r.t. rotations, offsets and root positions.
    NumPy inputs give NumPy outputs (computed in float64).

    Args:
        rotations: ``(..., J, 4)`` local rotations, unit wxyz.
        offsets: ``(J, 3)`` or ``(..., J, 3)`` rest offsets in the parent frame (row 0 unused).
        parents: ``J`` parent indices, root first with ``-1``.
        root_positions: ``(..., 3)`` root positions; ``None`` puts the root at the origin
            (root-relative positions, TDCN's ``p_t``).

    Returns:
        :class:`FKResult` ``(positions (..., J, 3), rotations (..., J, 4))``.
    """
    as_numpy = isinstance(rotations, np.ndarray)
    q = (
        torch.from_numpy(np.asarray(rotations, dtype=np.float64))
        if as_numpy
        else torch.as_tensor(rotations)
    )
    dtype, device = q.dtype, q.device
    off_t = torch.as_tensor(offsets, dtype=dtype, device=device)
    parents = tuple(int(p) for p in parents)
    nj = len(parents)
    if q.shape[-2:] != (nj, 4):
        raise ValueError(f"rotations must be (..., {nj}, 4), got {tuple(q.shape)}")
    if off_t.shape[-2:] != (nj, 3):
        raise ValueError(f"offsets must be (..., {nj}, 3), got {tuple(off_t.shape)}")
    lead = torch.broadcast_shapes(q.shape[:-2], off_t.shape[:-2])
    root = (
        None
        if root_positions is None
        else torch.as_tensor(root_positions, dtype=dtype, device=device)
    )
    if root is not None:
        lead = torch.broadcast_shapes(lead, root.shape[:-1])
    n = math.prod(lead)
    plan = _plan(parents)
    order = torch.tensor(plan.order, device=device)

    # (component, joint, batch) layout, joints sorted by depth
    # rows of the (J*4, N) transpose picked straight into component-major, depth-sorted order
    rows = (order.unsqueeze(0) * 4 + torch.arange(4, device=device).unsqueeze(1)).reshape(-1)
    lq = q.expand(lead + (nj, 4)).reshape(n, nj * 4).t().contiguous()
    lq = lq.index_select(0, rows).view(4, nj, n)  # (4, J, N)
    if off_t.dim() == 2:
        off = off_t.index_select(0, order).t().unsqueeze(-1)  # (3, J, 1)
    else:
        off = off_t.expand(lead + (nj, 3)).reshape(n, nj * 3).t().reshape(nj, 3, n)
        off = off.index_select(0, order).transpose(0, 1).contiguous()  # (3, J, N)
    perm = [torch.tensor(p, device=device) for p in _PERM]
    sign = [torch.tensor(s, dtype=dtype, device=device).view(4, 1, 1) for s in _SIGN]
    yzx, zxy = torch.tensor([1, 2, 0], device=device), torch.tensor([2, 0, 1], device=device)
    off_yzx, off_zxy = off.index_select(0, yzx), off.index_select(0, zxy)
    u_yzx, u_zxy = torch.tensor([2, 3, 1], device=device), torch.tensor([3, 1, 2], device=device)

    gq = lq.new_empty((4, nj, n))
    gp = lq.new_empty((3, nj, n))
    gq[:, 0] = lq[:, 0]
    if root is None:
        gp[:, 0] = 0.0
    else:
        gp[:, 0] = root.expand(lead + (3,)).reshape(n, 3).t()
    for start, end, pslots in plan.levels:
        pidx = torch.tensor(pslots, device=device)
        pq = gq.index_select(1, pidx)  # (4, k, N) parents' global rotations
        lq_level = lq[:, start:end]
        nq = pq[0] * lq_level
        for c in range(3):
            nq = nq.addcmul(pq[c + 1], lq_level.index_select(0, perm[c]) * sign[c])
        gq[:, start:end] = nq
        # rotate offsets by the parents: v + w t + u x t, t = 2 u x v
        u_a, u_b = pq.index_select(0, u_yzx), pq.index_select(0, u_zxy)
        t = (u_a * off_zxy[:, start:end]).addcmul(u_b, off_yzx[:, start:end], value=-1.0) * 2.0
        rv = (u_a * t.index_select(0, zxy)).addcmul(u_b, t.index_select(0, yzx), value=-1.0)
        rv = rv.addcmul(pq[0], t) + off[:, start:end]
        gp[:, start:end] = gp.index_select(1, pidx) + rv
    inverse = torch.tensor(plan.inverse, device=device)
    positions = gp.index_select(1, inverse).permute(2, 1, 0).reshape(lead + (nj, 3))
    rots = gq.index_select(1, inverse).permute(2, 1, 0).reshape(lead + (nj, 4))
    if as_numpy:
        return FKResult(positions.numpy(), rots.numpy())
    return FKResult(positions, rots)


def local_positions(rotations: Tensor, offsets: Tensor, parents: Sequence[int]) -> Tensor:
    """Joint positions relative to the root (TDCN's ``p_t = f_FK(q_t, s̄)``, Eq. 1).

    Args:
        rotations: ``(..., J, 4)`` local wxyz.
        offsets: ``(J, 3)`` or ``(..., J, 3)``.
        parents: ``J`` parents.

    Returns:
        ``(..., J, 3)`` root-relative positions (the root's global rotation is applied).
    """
    return cast(
        Tensor, forward_kinematics(rotations, offsets, parents, None).positions
    )  # tensors in, tensors out


def align_local_rotations(rotations: Tensor, align: Tensor, parents: Sequence[int]) -> Tensor:
    """Re-express local rotations with per-joint global alignments: ``q'_j = C_p⁻¹ ⊗ q_j ⊗ C_j``.

    If ``G_j`` are the global rotations of ``rotations``, those of the result are ``G_j C_j``:
    each joint's frame is turned by its own ``C_j``, the rest of the chain untouched. A constant
    ``C`` is a rest-pose alignment between two characters (the synthetic ground truth,
    :func:`retarget_lib.core.transfer.transfer_rotations`); the residual networks predict ``C`` per
    frame, starting at the identity (= copy the rotations).

    Args:
        rotations: ``(..., J, 4)`` local unit quaternions (wxyz).
        align: ``(..., J, 4)`` alignments ``C`` (wxyz). The right factor ``C_j`` is used as given
            (so the result's norm is ``‖C_j‖``, which a norm regulariser can see); the left factor
            ``C_p`` is normalised. ``C`` of the root's parent is the identity.
        parents: ``J`` parents (root first, ``-1``).

    Returns:
        ``(..., J, 4)``.
    """
    unit = quat_normalize(align, eps=1e-8)
    identity = torch.zeros_like(unit[..., :1, :])
    identity[..., 0] = 1.0
    left = torch.cat([identity, unit[..., list(parents[1:]), :]], -2)
    return quat_mul(quat_conjugate(left), quat_mul(rotations, align))
