"""Motion authoring engine: keyframed, IK-solved poses made physically consistent for one character.

The motion families (:mod:`retarget_lib.data.synthetic.motions`) describe *what* is performed; this module
provides the tools they are written with (timing and easing curves, the canonical pose, footstep
plans, hand goals) and turns a finished :class:`Plan` into a :class:`~retarget_lib.core.motion.Motion`.

How a clip is made (so that it is physically consistent *for the given character*):

1. **Author on the canonical rest pose.** Joint angles are written for a reference copy of the
   character whose bones point in canonical directions (:func:`canonical_rest_skeleton`: spine up,
   legs down, arms sideways in a T-pose, own feet), so "arm lowered 80 degrees" means the same
   world pose for an A-pose and a T-pose character. The angles are moved onto the real character
   with the ground-truth rest compensation (:func:`~retarget_lib.core.transfer.transfer_rotations`).
   Conventions for the angles (degrees): ``fwd`` swings a limb to the front, ``down`` lowers an
   arm from the T-pose, ``bend`` flexes the spine/head forward, ``twist``/``yaw`` turn towards
   the character's left (+X).
2. **Plant the feet.** Footsteps are planned on the ground of the rest pose
   (:func:`~retarget_lib.core.measures.rest_ground`: ``y = 0`` under a character that
   stands on the floor, so its soles, not its toe joints, touch it): a planted foot is flat, still,
   and keeps its rest height above that ground; between plants the ankle follows a minimum-jerk path
   with a lift, toe-off and heel-strike pitch, never letting the toe joint under its rest height. The root is lowered wherever a leg
   could not reach, and both legs are solved with :func:`~retarget_lib.geometry.ik.two_bone_ik` (knees
   towards the toes).
3. **Make the hand contacts real.** Targets are computed from *this* character's joints plus a
   body-size hint (:func:`default_body_radii`): palms meeting in front of the chest (clap, pray),
   hands on the side of the pelvis (hands_on_hips), a hand on top of the head (touch_head), fists
   at arm's reach (punch). The arms are solved with two-bone IK, eased in and out.

:func:`assemble` fills ``Motion.meta`` with the style, body radii and contact labels described in
:mod:`retarget_lib.data.synthetic.motions`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, NamedTuple, Sequence

import numpy as np
import torch
from scipy.ndimage import gaussian_filter1d, maximum_filter1d

from ...core.kinematics import forward_kinematics
from ...core.measures import foot_rest_heights
from ...core.motion import Motion
from ...core.rotations import (
    frame_rotation,
    quat_conjugate,
    quat_from_axis_angle,
    quat_from_euler,
    quat_identity,
    quat_mul,
    quat_rotate,
    quat_slerp,
    quat_to_matrix,
)
from ...core.skeleton import J, Skeleton
from ...core.transfer import canonical_rest_skeleton, transfer_rotations
from ...geometry.ik import limb_chain, two_bone_ik

__all__ = [
    "FPS",
    "SIDES",
    "HandContact",
    "default_body_radii",
    "body_radii_from_mesh",
    "Rig",
    "minjerk",
    "ramp",
    "window",
    "keyframes",
    "noise",
    "event_times",
    "hermite",
    "Pose",
    "Plant",
    "Feet",
    "foot_rot",
    "plan_feet",
    "still_plants",
    "yaw_xz",
    "HandGoal",
    "palm_targets",
    "contact_runs",
    "Plan",
    "fk",
    "assemble",
]

FPS = 30.0

SIDES = (("Left", 1.0), ("Right", -1.0))  # name prefix, sign of the character's left (+X)


class HandContact(NamedTuple):
    """A hand touching a body part over frames ``start:stop``.

    ``hand`` is ``"LeftHand"``/``"RightHand"``; ``part`` is ``"LeftHand"``/``"RightHand"`` (the
    other palm), ``"LeftHip"``/``"RightHip"`` (side of the pelvis) or ``"HeadTop"``.
    """

    start: int
    stop: int
    hand: str
    part: str


# ----------------------------------------------------------------------------- body geometry
def default_body_radii(skeleton: Skeleton) -> dict[str, float]:
    """Body-size hint (metres) for hand contacts, from the skeleton's proportions.

    Keys: ``"hip"`` pelvis half-width at the iliac crest, ``"torso"`` chest half-depth (spine to
    sternum), ``"head"`` head radius, ``"hand"`` half-thickness of the hand (wrist joint to palm).
    Pass measured values (e.g. from the character's mesh) to
    :func:`~retarget_lib.data.synthetic.motions.make_motion` instead.

    Args:
        skeleton: canonical-22 skeleton.
    """
    s = skeleton.height() / 1.75
    rest = skeleton.rest_positions()
    hip_half = 0.5 * abs(rest[J["LeftUpLeg"], 0] - rest[J["RightUpLeg"], 0])
    return {"hip": float(max(1.6 * hip_half, 0.12 * s)), "torso": 0.11 * s, "head": 0.1 * s,
            "hand": 0.008 * s}


def body_radii_from_mesh(skeleton: Skeleton, rest_vertices: np.ndarray,
                         weights: np.ndarray) -> dict[str, float]:
    """Body-size hint measured on a skinned rest mesh (same keys as :func:`default_body_radii`).

    Each part is measured on the vertices whose strongest skinning weight is that part's joints:
    ``hip`` the pelvis half-width just above the hip joints, ``torso`` the sternum's distance in
    front of ``Spine2``, ``head`` such that the top of the head is ``1.9 * head`` above the
    ``Head`` joint (the head-top contact is placed on a sphere of that radius centred
    ``0.9 * head`` above the joint), ``hand`` half the palm thickness.

    Args:
        skeleton: the character's canonical-22 skeleton.
        rest_vertices: ``(V, 3)`` mesh vertices in the rest pose (world, metres).
        weights: ``(V, 22)`` skinning weights.

    Returns:
        ``{"hip", "torso", "head", "hand"}`` in metres.
    """
    rest = skeleton.rest_positions()
    owner = np.asarray(weights).argmax(axis=1)
    v = np.asarray(rest_vertices, dtype=float)
    s = skeleton.height() / 1.75

    def part(*names):
        return v[np.isin(owner, [J[n] for n in names])]

    hips = rest[J["Hips"]]
    pelvis = part("Hips", "Spine", "LeftUpLeg", "RightUpLeg")
    crest = np.abs(pelvis[:, 1] - hips[1] - 0.06 * s) < 0.03 * s
    band = pelvis[crest & (np.abs(pelvis[:, 2] - hips[2]) < 0.06 * s)]  # the sides, not the belly
    chest = part("Spine1", "Spine2")
    chest = chest[np.abs(chest[:, 0] - rest[J["Spine2"], 0]) < 0.06 * s]
    head = part("Head")
    hand = part("LeftHand")
    hand = hand - hand.mean(axis=0)
    thin = np.linalg.svd(hand, full_matrices=False)[2][-1]
    out = default_body_radii(skeleton)
    if len(band):
        out["hip"] = float(np.abs(band[:, 0] - hips[0]).max())
    if len(chest):
        out["torso"] = float(chest[:, 2].max() - rest[J["Spine2"], 2])
    if len(head):
        out["head"] = float(head[:, 1].max() - rest[J["Head"], 1]) / 1.9
    if len(hand) > 3:
        out["hand"] = float(0.5 * np.ptp(hand @ thin))
    return out


@dataclass
class Rig:
    """A character prepared for authoring: its reference skeleton and measurements."""

    skeleton: Skeleton
    radii: dict[str, float]
    ref: Skeleton = field(init=False)
    stand: float = field(init=False)  # root height with straight vertical legs, feet flat
    hip_w: float = field(init=False)  # half distance between the hip joints
    ankle_h: np.ndarray = field(init=False)  # (2,) rest ankle heights above the ground
    toe_h: np.ndarray = field(init=False)  # (2,) rest toe-joint heights above the ground
    toe: np.ndarray = field(init=False)  # (2, 3) toe offsets from the ankles (rest = flat foot)
    leg_reach: np.ndarray = field(init=False)  # (2,) thigh + shin
    arm_reach: float = field(init=False)
    arm_down: float = field(init=False)  # largest arm lowering (deg) that keeps hands off the hips
    shoulder: np.ndarray = field(init=False)  # (3,) left shoulder joint from Spine2, canonical rest
    scale: float = field(init=False)

    def __post_init__(self) -> None:
        sk = self.skeleton
        self.ref = canonical_rest_skeleton(sk)
        ref_rest = self.ref.rest_positions()
        feet = [J[n] for n in ("LeftFoot", "RightFoot", "LeftToeBase", "RightToeBase")]
        self.ankle_h, self.toe_h = np.split(foot_rest_heights(sk), 2)  # Efoot's ḡ (Eq. 6)
        self.toe = sk.offsets[feet[2:]]
        lens = sk.bone_lengths()
        self.leg_reach = np.array([lens[J[f"{s}Leg"]] + lens[J[f"{s}Foot"]] for s, _ in SIDES])
        self.arm_reach = float(lens[J["LeftForeArm"]] + lens[J["LeftHand"]])
        self.stand = float(ref_rest[0, 1] - ref_rest[feet[:2], 1].max() + self.ankle_h.max())
        self.hip_w = 0.5 * float(ref_rest[J["LeftUpLeg"], 0] - ref_rest[J["RightUpLeg"], 0])
        self.scale = sk.height() / 1.75
        self.shoulder = ref_rest[J["LeftArm"]] - ref_rest[J["Spine2"]]
        clear = self.radii["hip"] + self.radii["hand"] + 0.02 * self.scale
        lateral = ref_rest[J["LeftArm"], 0] - ref_rest[0, 0]
        out = np.clip((clear - lateral) / self.arm_reach, -1.0, 1.0)  # cos of the arm's lowering
        self.arm_down = float(np.clip(np.degrees(np.arccos(out)), 60, 84))

    def front_reach(self, drop: float, gap: float) -> float:
        """Farthest distance in front of ``Spine2`` at which both hands still meet comfortably
        (95 % of arm reach) at height ``-drop``, ``gap`` apart."""
        x, y, z = self.shoulder
        room = (0.95 * self.arm_reach) ** 2 - (x - 0.5 * gap) ** 2 - (y + drop) ** 2
        return float(z + np.sqrt(max(room, 0.0)))


# ----------------------------------------------------------------------------- timing helpers
def minjerk(u: np.ndarray) -> np.ndarray:
    """Minimum-jerk ease ``10u^3 - 15u^4 + 6u^5`` on ``[0, 1]`` (clipped outside)."""
    u = np.clip(u, 0.0, 1.0)
    return u ** 3 * (10 - 15 * u + 6 * u * u)


def ramp(t: np.ndarray, t0: float, t1: float) -> np.ndarray:
    """0 before ``t0``, eased to 1 at ``t1``."""
    return minjerk((t - t0) / max(t1 - t0, 1e-6))


def window(t: np.ndarray, t0: float, t1: float, rise: float,
            fall: float | None = None) -> np.ndarray:
    """Eased to 1 over ``[t0, t0 + rise]``, held, eased back to 0 over ``[t1 - fall, t1]``."""
    fall = rise if fall is None else fall
    return ramp(t, t0, t0 + rise) * (1.0 - ramp(t, t1 - fall, t1))


def keyframes(t: np.ndarray, times: Sequence[float], values: Sequence) -> np.ndarray:
    """Minimum-jerk interpolation through keyframes (zero velocity at every key).

    Args:
        t: ``(T,)`` seconds.
        times: ``K`` increasing key times.
        values: ``K`` key values (scalars or equal-shape arrays).

    Returns:
        ``(T, ...)`` values; held constant before the first and after the last key.
    """
    times = np.asarray(times, dtype=float)
    vals = np.asarray(values, dtype=float)
    k = np.clip(np.searchsorted(times, t, side="right") - 1, 0, len(times) - 2)
    u = minjerk((t - times[k]) / np.maximum(times[k + 1] - times[k], 1e-6))
    u = u.reshape(u.shape + (1,) * (vals.ndim - 1))
    return vals[k] + (vals[k + 1] - vals[k]) * u


def noise(rng: np.random.Generator, t: np.ndarray, amp: float, fmax: float = 0.5) -> np.ndarray:
    """Smooth random signal: three sinusoids below ``fmax`` Hz, peak about ``amp``."""
    f = rng.uniform(0.08, fmax, 3)
    ph = rng.uniform(0, 2 * np.pi, 3)
    w = rng.uniform(0.5, 1.0, 3)
    return amp * (w[:, None] * np.sin(2 * np.pi * f[:, None] * t + ph[:, None])).sum(0) / w.sum()


def event_times(rng: np.random.Generator, duration: float, length: Callable[[], float],
            pause: tuple[float, float], start: tuple[float, float] = (0.4, 1.0),
            tail: float = 0.6) -> list[tuple[float, float]]:
    """Random ``(start, end)`` times of repeated actions separated by pauses, all inside the clip.

    At least one event is returned (shortened to fit if needed).
    """
    out = []
    t = rng.uniform(*start)
    while True:
        n = length()
        if t + n > duration - tail:
            break
        out.append((t, t + n))
        t += n + rng.uniform(*pause)
    if not out:
        t0 = min(start[0], 0.25 * duration)
        out.append((t0, max(t0 + 0.5, duration - tail)))
    return out


def hermite(t: np.ndarray, t0: float, t1: float, y0: float, y1: float, v0: float,
             v1: float) -> np.ndarray:
    """Cubic Hermite segment from ``(t0, y0, v0)`` to ``(t1, y1, v1)`` evaluated at ``t``."""
    h = t1 - t0
    u = np.clip((t - t0) / h, 0.0, 1.0)
    return ((2 * u ** 3 - 3 * u ** 2 + 1) * y0 + (u ** 3 - 2 * u ** 2 + u) * h * v0
            + (-2 * u ** 3 + 3 * u ** 2) * y1 + (u ** 3 - u ** 2) * h * v1)


# ----------------------------------------------------------------------------- pose helpers
def _yxz(yaw=0.0, pitch=0.0, roll=0.0, T: int = 1) -> torch.Tensor:
    """``(T, 4)`` rotations ``Ry(yaw) Rx(pitch) Rz(roll)``, degrees (scalars or ``(T,)``)."""
    ang = np.stack(np.broadcast_arrays(*(np.asarray(x, float) for x in (yaw, pitch, roll))), -1)
    ang = np.array(np.broadcast_to(ang, (T, 3)))
    return quat_from_euler(torch.from_numpy(ang), "YXZ", degrees=True)


def _axis(axis: int, deg, T: int) -> torch.Tensor:
    """``(T, 4)`` rotations by ``deg`` (scalar or ``(T,)``) about axis ``axis`` (0=X, 1=Y, 2=Z)."""
    aa = np.zeros((T, 3))
    aa[:, axis] = np.radians(np.broadcast_to(np.asarray(deg, float), (T,)))
    return quat_from_axis_angle(torch.from_numpy(aa))


class Pose:
    """Canonical local rotations ``(T, 22, 4)`` plus the root trajectory being authored."""

    def __init__(self, T: int):
        self.T = T
        self.q = quat_identity((T, 22), dtype=torch.float64)
        self.root = np.zeros((T, 3))

    def set(self, joint: str, q: torch.Tensor) -> None:
        self.q[:, J[joint]] = q

    def pelvis(self, yaw, lean=0.0, roll=0.0) -> None:
        """Root orientation: heading ``yaw``, forward ``lean``, ``roll`` down towards the left."""
        self.set("Hips", _yxz(yaw, lean, roll, T=self.T))

    def spine(self, bend=0.0, twist=0.0, side=0.0) -> None:
        """Spread a forward ``bend``, a ``twist`` and a ``side`` bend (both to the left) over the
        spine."""
        twist, bend, side = (np.asarray(x, float) for x in (twist, bend, side))
        for name, w in (("Spine", 0.3), ("Spine1", 0.35), ("Spine2", 0.35)):
            self.set(name, _yxz(w * twist, w * bend, -w * side, T=self.T))

    def head(self, nod=0.0, yaw=0.0, tilt=0.0) -> None:
        """Neck and head: ``nod`` down, ``yaw`` to the left, ``tilt`` to the left."""
        nod, yaw, tilt = (np.asarray(x, float) for x in (nod, yaw, tilt))
        for name, w in (("Neck", 0.4), ("Head", 0.6)):
            self.set(name, _yxz(w * yaw, w * nod, -w * tilt, T=self.T))

    def arm(self, side: str, sign: float, down=80.0, fwd=0.0, elbow=15.0, twist=0.0,
            shrug=0.0, reach=0.0) -> None:
        """One arm: lowered by ``down`` from the T-pose, swung ``fwd``, ``elbow`` flexion,
        clavicle raised by ``shrug`` and pushed forward by ``reach`` (all degrees)."""
        T = self.T
        shrug, reach = np.asarray(shrug, float), np.asarray(reach, float)
        self.set(f"{side}Shoulder", quat_mul(_axis(2, sign * shrug, T), _axis(1, -sign * reach, T)))
        lower = quat_mul(_axis(2, -sign * np.asarray(down), T), _axis(0, twist, T))
        self.set(f"{side}Arm", quat_mul(_axis(0, -np.asarray(fwd), T), lower))
        self.set(f"{side}ForeArm", _axis(1, -sign * np.asarray(elbow), T))


# ----------------------------------------------------------------------------- feet
@dataclass
class Plant:
    """A foot flat on the ground over ``[t0, t1]`` at ankle ``xz`` with heading ``yaw`` (radians).

    During the last ``pivot`` seconds the heel lifts (pitch up to ``pivot_deg``) about the planted
    toe.
    """

    t0: float
    t1: float
    xz: np.ndarray
    yaw: float
    pivot: float = 0.0
    pivot_deg: float = 0.0


@dataclass
class Feet:
    ankle: np.ndarray  # (T, 2, 3) ankle targets
    rot: np.ndarray  # (T, 2, 4) global foot rotations
    contacts: np.ndarray  # (T, 4) bool: left ankle, right ankle, left toe, right toe
    knee: np.ndarray  # (T, 2, 3) knee bend (pole) directions: where the toes point


def foot_rot(yaw: np.ndarray, pitch_deg: np.ndarray) -> torch.Tensor:
    """``(N, 4)`` global foot rotation: heading ``yaw`` (rad), then ``pitch`` toe-down (deg)."""
    return quat_mul(_axis(1, np.degrees(yaw), len(yaw)), _axis(0, pitch_deg, len(yaw)))


def _bump(u: np.ndarray, center: float, half: float) -> np.ndarray:
    """Smooth bump, 1 at ``center``, 0 outside ``center +- half``."""
    return np.sin(np.pi * np.clip((u - center + half) / (2 * half), 0.0, 1.0)) ** 2


def plan_feet(rig: Rig, t: np.ndarray, plants: Sequence[Sequence[Plant]], lift: float,
               land_pitch: float = 10.0) -> Feet:
    """Ankle targets, foot rotations and contact labels from footstep plans.

    Args:
        rig: the character.
        t: ``(T,)`` seconds.
        plants: per foot (left, right), time-ordered :class:`Plant` s covering the clip
            (the first from ``t = 0``, the last to the end).
        lift: swing foot clearance (metres).
        land_pitch: toe-up pitch just before landing (degrees).
    """
    T = len(t)
    ankle = np.zeros((T, 2, 3))
    yaw = np.zeros((T, 2))
    pitch = np.zeros((T, 2))
    contacts = np.zeros((T, 4), bool)
    for f in (0, 1):
        toe, h = rig.toe[f], rig.ankle_h[f]
        for k, p in enumerate(plants[f]):
            flat = (t >= p.t0) & (t <= p.t1 - p.pivot)
            piv = (t > p.t1 - p.pivot) & (t <= p.t1)
            ankle[flat, f] = (p.xz[0], h, p.xz[1])
            yaw[flat | piv, f] = p.yaw
            contacts[flat, f] = True
            contacts[flat | piv, 2 + f] = True
            if piv.any():
                pitch[piv, f] = p.pivot_deg * minjerk((t[piv] - p.t1 + p.pivot) / p.pivot)
                flat_toe = _rotate(foot_rot(np.array([p.yaw]), np.zeros(1)), toe)[0]
                toe_pos = np.array([p.xz[0], h, p.xz[1]]) + flat_toe
                ankle[piv, f] = toe_pos - _rotate(foot_rot(yaw[piv, f], pitch[piv, f]), toe)
            if k + 1 < len(plants[f]):
                _swing(rig, t, f, p, plants[f][k + 1], lift, land_pitch, ankle, yaw, pitch)
    rot = foot_rot(yaw.reshape(-1), pitch.reshape(-1)).reshape(T, 2, 4).numpy()
    fwd = np.stack((np.sin(yaw), np.zeros_like(yaw), np.cos(yaw)), -1)
    return Feet(ankle, rot, contacts, fwd)


def _rotate(q: torch.Tensor, v: np.ndarray) -> np.ndarray:
    return quat_rotate(q, torch.from_numpy(np.broadcast_to(v, q.shape[:-1] + (3,)).copy())).numpy()


def _swing(rig: Rig, t: np.ndarray, f: int, a: Plant, b: Plant, lift: float, land_pitch: float,
           ankle: np.ndarray, yaw: np.ndarray, pitch: np.ndarray) -> None:
    """Fill the swing of foot ``f`` from plant ``a`` to plant ``b`` in place."""
    m = (t > a.t1) & (t < b.t0)
    if not m.any():
        return
    u = (t[m] - a.t1) / (b.t0 - a.t1)
    s = minjerk(u)
    toe = rig.toe[f]
    start_pitch = a.pivot_deg if a.pivot > 0 else 0.0
    start = np.array([a.xz[0], rig.ankle_h[f], a.xz[1]])
    if a.pivot > 0:  # the swing starts where the heel-raised foot left off
        toe_pos = start + _rotate(foot_rot(np.array([a.yaw]), np.zeros(1)), toe)[0]
        start = toe_pos - _rotate(foot_rot(np.array([a.yaw]), np.array([start_pitch])), toe)[0]
    end = np.array([b.xz[0], rig.ankle_h[f], b.xz[1]])
    dyaw = (b.yaw - a.yaw + np.pi) % (2 * np.pi) - np.pi
    yaw[m, f] = a.yaw + dyaw * s
    pitch[m, f] = start_pitch * (1 - minjerk(u / 0.45)) - land_pitch * _bump(u, 0.8, 0.2)
    pos = start + (end - start) * s[:, None]
    dist = np.linalg.norm(end[[0, 2]] - start[[0, 2]])
    pos[:, 1] += min(lift, 0.5 * lift + dist) * np.sin(np.pi * u ** 0.8) ** 2  # early peak, soft ends
    ankle[m, f] = pos


def still_plants(rig: Rig, duration: float, width: float, toe_out: float) -> list[list[Plant]]:
    """Both feet planted for the whole clip, ``width`` x hip width apart, toes out ``toe_out``
    degrees."""
    return [[Plant(0.0, duration + 1.0, np.array([sign * width * rig.hip_w, 0.0]),
                    sign * np.radians(toe_out))] for _, sign in SIDES]


def yaw_xz(yaw: float, xz: np.ndarray) -> np.ndarray:
    """Rotate a horizontal ``(x, z)`` vector by heading ``yaw`` (radians, towards +X)."""
    c, s = np.cos(yaw), np.sin(yaw)
    return np.array([c * xz[0] + s * xz[1], -s * xz[0] + c * xz[1]])


# ----------------------------------------------------------------------------- hands
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
        return lambda body: center(body) + sign * 0.5 * gap[:, None] * body.axes[:, J["Spine2"], :, 0]
    return make(1.0), make(-1.0)


def contact_runs(mask: np.ndarray) -> list[tuple[int, int]]:
    m = np.concatenate(([False], mask, [False]))
    e = np.flatnonzero(m[1:] != m[:-1])
    return [(int(a), int(b)) for a, b in zip(e[::2], e[1::2])]


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


def _lower_root_to_reach(rig: Rig, q: np.ndarray, root: np.ndarray,
                         ankle: np.ndarray) -> np.ndarray:
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
        toe_y = feet.ankle[:, f, 1] + _rotate(torch.from_numpy(feet.rot[:, f]), rig.toe[f])[:, 1]
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
        ankle, knee, foot = (torch.from_numpy(x[:, f]) for x in (plan.feet.ankle, plan.feet.knee,
                                                                 plan.feet.rot))
        qt = two_bone_ik(qt, off, sk.parents, root_t, limb_chain(sk, limb), ankle, knee, foot)
    if plan.hands:
        ref_offsets = torch.from_numpy(rig.ref.offsets)
        axes = quat_to_matrix(forward_kinematics(plan.pose.q, ref_offsets, sk.parents).rotations)
        pos = fk(rig, qt.numpy(), root)
        body = _Body(pos, axes.numpy())
        for goal in plan.hands:
            qt = _reach(rig, qt, root_t, body, goal)
    meta = dict(meta, style=plan.style, body_radii=dict(rig.radii),
                foot_contacts=plan.feet.contacts[:, :2] & plan.feet.contacts[:, 2:],
                joint_contacts=plan.feet.contacts.copy(), hand_contacts=list(plan.hand_contacts))
    return Motion(sk.copy(), qt.numpy(), root, FPS, name=name, meta=meta)


def _reach(rig: Rig, q: torch.Tensor, root: torch.Tensor, body: _Body,
           goal: HandGoal) -> torch.Tensor:
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
    q = two_bone_ik(q, torch.from_numpy(sk.offsets), sk.parents, root, chain,
                    torch.from_numpy(target), torch.from_numpy(pole))
    return q if goal.palm is None else _orient_palm(rig, q, body, goal, chain)


def _orient_palm(rig: Rig, q: torch.Tensor, body: _Body, goal: HandGoal,
                 chain: tuple[int, int, int]) -> torch.Tensor:
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
