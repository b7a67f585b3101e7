"""Hand goals (step 3 of :mod:`retarget_lib.data.synthetic.authoring`) and assembling a finished
:class:`Plan` into a :class:`~retarget_lib.core.motion.Motion`: the rest compensation, the legs and
arms solved with two-bone IK, the root lowered where a leg cannot reach, and the contact labels in
``Motion.meta``."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import torch
from scipy.ndimage import gaussian_filter1d, maximum_filter1d

from ....core.kinematics import forward_kinematics
from ....core.motion import Motion
from ....core.rotations import (
    frame_rotation,
    quat_conjugate,
    quat_mul,
    quat_slerp,
    quat_to_matrix,
)
from ....core.skeleton import J
from ....core.transfer import transfer_rotations
from ....geometry.ik import limb_chain, two_bone_ik
from .body import FPS, SIDES, HandContact, Rig
from .feet import Feet, rotate_vector
from .pose import Pose


class _Body:
    """World joint positions and canonical joint frames of the character being authored."""

    def __init__(self, pos: np.ndarray, axes: np.ndarray):
        self.pos, self.axes = pos, axes  # (T, 22, 3); (T, 22, 3, 3) columns: canonical x, y, z

    def at(self, joint: str, offset, frame: str | None = None) -> np.ndarray:
        """``(T, 3)`` point ``offset`` (``(3,)`` or ``(T, 3)``, metres) from ``joint``, expressed
        in the canonical axes (x left, y up, z forward) of joint ``frame`` (default ``joint``)."""
        off = np.broadcast_to(np.asarray(offset, float), (len(self.pos), 3))
        axes = self.axes[:, J[frame or joint]]
        return self.pos[:, J[joint]] + np.einsum("tij,tj->ti", axes, off)


@dataclass
class HandGoal:
    """Drive one hand (``side`` 0 left, 1 right) to ``target(body)`` with ``weight`` ``(T,)``.

    ``pole`` is the elbow direction and ``palm`` an optional ``(palm normal, finger direction)``
    for the hand, all in the chest's canonical frame.
    """

    side: int
    target: Callable[[_Body], np.ndarray]
    weight: np.ndarray
    pole: np.ndarray
    palm: tuple[tuple[float, float, float], tuple[float, float, float]] | None = None


def palm_targets(center: Callable[[_Body], np.ndarray], gap: np.ndarray):
    """Targets for the two hands ``gap/2`` either side of ``center`` along the chest's left axis."""

    def make(sign):
        return lambda body: (
            center(body) + sign * 0.5 * gap[:, None] * body.axes[:, J["Spine2"], :, 0]
        )

    return make(1.0), make(-1.0)


def contact_runs(mask: np.ndarray) -> list[tuple[int, int]]:
    m = np.concatenate(([False], mask, [False]))
    e = np.flatnonzero(m[1:] != m[:-1])
    return [(int(a), int(b)) for a, b in zip(e[::2], e[1::2], strict=False)]


# ----------------------------------------------------------------------------- assembling
@dataclass
class Plan:
    pose: Pose
    feet: Feet
    hands: list[HandGoal] = field(default_factory=list)
    hand_contacts: list[HandContact] = field(default_factory=list)
    style: dict = field(default_factory=dict)


def fk(rig: Rig, q: np.ndarray, root: np.ndarray) -> np.ndarray:
    return forward_kinematics(q, rig.skeleton.offsets, rig.skeleton.parents, root).positions


def _lower_root_to_reach(
    rig: Rig, q: np.ndarray, root: np.ndarray, ankle: np.ndarray
) -> np.ndarray:
    """Root trajectory lowered (smoothly) wherever a hip cannot reach its ankle target."""
    root = root.copy()
    for _ in range(3):
        pos = fk(rig, q, root)
        need = np.zeros(len(root))
        for f, (side, _) in enumerate(SIDES):
            v = pos[:, J[f"{side}UpLeg"]] - ankle[:, f]
            r = 0.985 * rig.leg_reach[f]
            horiz = np.minimum(v[:, 0] ** 2 + v[:, 2] ** 2, r * r)
            need = np.maximum(need, v[:, 1] - np.sqrt(r * r - horiz))
        if need.max() <= 1e-4:
            break
        root[:, 1] -= gaussian_filter1d(maximum_filter1d(np.maximum(need, 0.0), 13), 2.0)
    return root


def _lift_toes_above_floor(rig: Rig, feet: Feet) -> None:
    """Raise swinging feet (in place) wherever a pitched toe joint would dip under its rest height
    (the sole under the floor)."""
    for f in (0, 1):
        toe_y = (
            feet.ankle[:, f, 1] + rotate_vector(torch.from_numpy(feet.rot[:, f]), rig.toe[f])[:, 1]
        )
        feet.ankle[:, f, 1] -= np.minimum(toe_y - rig.toe_h[f], 0.0)


def assemble(rig: Rig, plan: Plan, name: str, meta: dict) -> Motion:
    """Canonical pose -> character, legs to the footstep plan, arms to the hand goals."""
    sk = rig.skeleton
    _lift_toes_above_floor(rig, plan.feet)
    off = torch.from_numpy(sk.offsets)
    q = transfer_rotations(plan.pose.q.numpy(), rig.ref, sk)
    root = _lower_root_to_reach(rig, q, plan.pose.root, plan.feet.ankle)
    qt = torch.from_numpy(q)
    root_t = torch.from_numpy(root)
    for f, limb in enumerate(("left_leg", "right_leg")):
        ankle, knee, foot = (
            torch.from_numpy(x[:, f]) for x in (plan.feet.ankle, plan.feet.knee, plan.feet.rot)
        )
        qt = two_bone_ik(qt, off, sk.parents, root_t, limb_chain(sk, limb), ankle, knee, foot)
    if plan.hands:
        ref_offsets = torch.from_numpy(rig.ref.offsets)
        axes = quat_to_matrix(forward_kinematics(plan.pose.q, ref_offsets, sk.parents).rotations)
        pos = fk(rig, qt.numpy(), root)
        body = _Body(pos, axes.numpy())
        for goal in plan.hands:
            qt = _reach(rig, qt, root_t, body, goal)
    meta = dict(
        meta,
        style=plan.style,
        body_radii=dict(rig.radii),
        foot_contacts=plan.feet.contacts[:, :2] & plan.feet.contacts[:, 2:],
        joint_contacts=plan.feet.contacts.copy(),
        hand_contacts=list(plan.hand_contacts),
    )
    return Motion(sk.copy(), qt.numpy(), root, FPS, name=name, meta=meta)


def _reach(
    rig: Rig, q: torch.Tensor, root: torch.Tensor, body: _Body, goal: HandGoal
) -> torch.Tensor:
    """Solve one arm towards its goal, blended by the goal's weight (elbow plane blended too)."""
    sk = rig.skeleton
    chain = limb_chain(sk, ("left_arm", "right_arm")[goal.side])
    pos = fk(rig, q.numpy(), root.numpy())
    hand, upper, elbow = pos[:, chain[2]], pos[:, chain[0]], pos[:, chain[1]]
    w = goal.weight[:, None]
    target = hand + w * (goal.target(body) - hand)
    pole_world = np.einsum("tij,j->ti", body.axes[:, J["Spine2"]], goal.pole)
    bend = elbow - upper
    pole = (1 - w) * bend / np.linalg.norm(bend, axis=-1, keepdims=True) + w * pole_world
    q = two_bone_ik(
        q,
        torch.from_numpy(sk.offsets),
        sk.parents,
        root,
        chain,
        torch.from_numpy(target),
        torch.from_numpy(pole),
    )
    return q if goal.palm is None else _orient_palm(rig, q, body, goal, chain)


def _orient_palm(
    rig: Rig, q: torch.Tensor, body: _Body, goal: HandGoal, chain: tuple[int, int, int]
) -> torch.Tensor:
    """Turn the hand so that its palm faces ``goal.palm[0]`` with the fingers along
    ``goal.palm[1]`` (blended by the goal's weight).

    The rest palm normal is taken as world down perpendicular to the forearm (palms down in a
    T-pose, as in Mixamo rigs); the rest finger direction continues the forearm.
    """
    sk = rig.skeleton
    _, fore, hand = chain
    grot = forward_kinematics(q, torch.from_numpy(sk.offsets), sk.parents).rotations
    rest = sk.rest_positions()
    along = torch.from_numpy(rest[hand] - rest[fore])
    down = torch.tensor([0.0, -1.0, 0.0], dtype=torch.float64)
    down = down - (down @ along) / (along @ along) * along
    axes = torch.from_numpy(body.axes[:, J["Spine2"]])
    normal = axes @ torch.tensor(goal.palm[0], dtype=torch.float64)
    fingers = axes @ torch.tensor(goal.palm[1], dtype=torch.float64)
    want = frame_rotation(down.expand_as(normal), along.expand_as(normal), normal, fingers)
    local = quat_mul(quat_conjugate(grot[:, fore]), want)
    q = q.clone()
    q[:, hand] = quat_slerp(q[:, hand], local, torch.from_numpy(goal.weight))
    return q
