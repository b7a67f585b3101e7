"""Synthetic motion library: keyframed and procedural human motion on any canonical-22 character.

Twelve families (:data:`MOTION_FAMILIES`): ``walk``, ``run``, ``jump``, ``turn``, ``wave``,
``clap``, ``hands_on_hips``, ``pray``, ``touch_head``, ``punch``, ``kick``, ``squat``. Each clip
is deterministic in ``(family, skeleton, seed)``; the seed draws the style (speed, stride,
amplitude, arm swing, stance width, timing, turning direction, small asymmetries and noise) and
the duration (2-40 s depending on the family), at 30 fps.

How a clip is made (so that it is physically consistent *for the given character*):

1. **Author on the canonical rest pose.** Joint angles are written for a reference copy of the
   character whose bones point in canonical directions (:func:`canonical_rest_skeleton`: spine up,
   legs down, arms sideways in a T-pose, own feet), so "arm lowered 80 degrees" means the same
   world pose for an A-pose and a T-pose character. The angles are moved onto the real character
   with the ground-truth rest compensation (:func:`~retarget_lib.data.pairs.transfer_rotations`).
   Conventions for the angles (degrees): ``fwd`` swings a limb to the front, ``down`` lowers an
   arm from the T-pose, ``bend`` flexes the spine/head forward, ``twist``/``yaw`` turn towards
   the character's left (+X).
2. **Plant the feet.** Footsteps are planned on the ground (``y = 0`` is the lowest foot joint of
   the rest pose, :meth:`Skeleton.leg_length`): a planted foot is flat, still, and keeps its rest
   height; between plants the ankle follows a minimum-jerk path with a lift, toe-off and
   heel-strike pitch, never letting the toe under the floor. The root is lowered wherever a leg
   could not reach, and both legs are solved with :func:`~retarget_lib.ik.two_bone_ik` (knees
   towards the toes).
3. **Make the hand contacts real.** Targets are computed from *this* character's joints plus a
   body-size hint (:func:`default_body_radii`): palms meeting in front of the chest (clap, pray),
   hands on the side of the pelvis (hands_on_hips), a hand on top of the head (touch_head), fists
   at arm's reach (punch). The arms are solved with two-bone IK, eased in and out.

``Motion.meta`` records what was used: ``family``, ``seed``, ``style``, ``body_radii``,
``foot_contacts`` ``(T, 2)`` bool (left, right foot flat on the ground and still),
``joint_contacts`` ``(T, 4)`` bool in :data:`~retarget_lib.ik.FOOT_CONTACT_JOINTS` order (a toe
stays planted while its heel lifts), and ``hand_contacts``: a list of :class:`HandContact`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, NamedTuple, Sequence

import numpy as np
import torch
from scipy.ndimage import gaussian_filter1d, maximum_filter1d

from ..ik import frame_rotation, limb_chain, two_bone_ik
from ..kinematics import forward_kinematics
from ..motion import Motion
from ..rotations import (
    quat_conjugate,
    quat_from_axis_angle,
    quat_from_euler,
    quat_identity,
    quat_mul,
    quat_rotate,
    quat_slerp,
    quat_to_matrix,
)
from ..skeleton import CANONICAL22, CANONICAL22_PARENTS, J, Skeleton, canonical22_skeleton
from .pairs import ACROSS_PAIR, PRIMARY_CHILD, transfer_rotations

__all__ = [
    "FPS",
    "MOTION_FAMILIES",
    "DURATION_RANGES",
    "HandContact",
    "default_body_radii",
    "body_radii_from_mesh",
    "canonical_rest_skeleton",
    "make_motion",
    "motion_library",
]

FPS = 30.0
MOTION_FAMILIES: tuple[str, ...] = (
    "walk", "run", "jump", "turn", "wave", "clap", "hands_on_hips", "pray", "touch_head",
    "punch", "kick", "squat",
)
#: seconds: the duration of a clip is drawn uniformly from its family's range (all within 2-40 s)
DURATION_RANGES: dict[str, tuple[float, float]] = {
    "walk": (4.0, 20.0), "run": (4.0, 16.0), "jump": (3.0, 14.0), "turn": (3.0, 14.0),
    "wave": (3.0, 12.0), "clap": (2.0, 10.0), "hands_on_hips": (3.0, 14.0), "pray": (3.0, 12.0),
    "touch_head": (3.0, 12.0), "punch": (3.0, 16.0), "kick": (3.0, 16.0), "squat": (4.0, 40.0),
}

_SIDES = (("Left", 1.0), ("Right", -1.0))  # name prefix, sign of the character's left (+X)


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
    Pass measured values (e.g. from the character's mesh) to :func:`make_motion` instead.

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


@dataclass
class _Rig:
    """A character prepared for authoring: its reference skeleton and measurements."""

    skeleton: Skeleton
    radii: dict[str, float]
    ref: Skeleton = field(init=False)
    stand: float = field(init=False)  # root height with straight vertical legs, feet flat
    hip_w: float = field(init=False)  # half distance between the hip joints
    ankle_h: np.ndarray = field(init=False)  # (2,) rest ankle heights above the ground
    toe: np.ndarray = field(init=False)  # (2, 3) toe offsets from the ankles (rest = flat foot)
    leg_reach: np.ndarray = field(init=False)  # (2,) thigh + shin
    arm_reach: float = field(init=False)
    arm_down: float = field(init=False)  # largest arm lowering (deg) that keeps hands off the hips
    shoulder: np.ndarray = field(init=False)  # (3,) left shoulder joint from Spine2, canonical rest
    scale: float = field(init=False)

    def __post_init__(self) -> None:
        sk = self.skeleton
        self.ref = canonical_rest_skeleton(sk)
        rest, ref_rest = sk.rest_positions(), self.ref.rest_positions()
        feet = [J[n] for n in ("LeftFoot", "RightFoot", "LeftToeBase", "RightToeBase")]
        self.ankle_h = rest[feet[:2], 1] - rest[feet, 1].min()  # floor: lowest rest foot joint
        self.toe = sk.offsets[feet[2:]]
        lens = sk.bone_lengths()
        self.leg_reach = np.array([lens[J[f"{s}Leg"]] + lens[J[f"{s}Foot"]] for s, _ in _SIDES])
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
def _minjerk(u: np.ndarray) -> np.ndarray:
    """Minimum-jerk ease ``10u^3 - 15u^4 + 6u^5`` on ``[0, 1]`` (clipped outside)."""
    u = np.clip(u, 0.0, 1.0)
    return u ** 3 * (10 - 15 * u + 6 * u * u)


def _ramp(t: np.ndarray, t0: float, t1: float) -> np.ndarray:
    """0 before ``t0``, eased to 1 at ``t1``."""
    return _minjerk((t - t0) / max(t1 - t0, 1e-6))


def _window(t: np.ndarray, t0: float, t1: float, rise: float,
            fall: float | None = None) -> np.ndarray:
    """Eased to 1 over ``[t0, t0 + rise]``, held, eased back to 0 over ``[t1 - fall, t1]``."""
    fall = rise if fall is None else fall
    return _ramp(t, t0, t0 + rise) * (1.0 - _ramp(t, t1 - fall, t1))


def _keys(t: np.ndarray, times: Sequence[float], values: Sequence) -> np.ndarray:
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
    u = _minjerk((t - times[k]) / np.maximum(times[k + 1] - times[k], 1e-6))
    u = u.reshape(u.shape + (1,) * (vals.ndim - 1))
    return vals[k] + (vals[k + 1] - vals[k]) * u


def _noise(rng: np.random.Generator, t: np.ndarray, amp: float, fmax: float = 0.5) -> np.ndarray:
    """Smooth random signal: three sinusoids below ``fmax`` Hz, peak about ``amp``."""
    f = rng.uniform(0.08, fmax, 3)
    ph = rng.uniform(0, 2 * np.pi, 3)
    w = rng.uniform(0.5, 1.0, 3)
    return amp * (w[:, None] * np.sin(2 * np.pi * f[:, None] * t + ph[:, None])).sum(0) / w.sum()


def _events(rng: np.random.Generator, duration: float, length: Callable[[], float],
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


class _Pose:
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
class _Plant:
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
class _Feet:
    ankle: np.ndarray  # (T, 2, 3) ankle targets
    rot: np.ndarray  # (T, 2, 4) global foot rotations
    contacts: np.ndarray  # (T, 4) bool: left ankle, right ankle, left toe, right toe
    knee: np.ndarray  # (T, 2, 3) knee bend (pole) directions: where the toes point


def _foot_rot(yaw: np.ndarray, pitch_deg: np.ndarray) -> torch.Tensor:
    """``(N, 4)`` global foot rotation: heading ``yaw`` (rad), then ``pitch`` toe-down (deg)."""
    return quat_mul(_axis(1, np.degrees(yaw), len(yaw)), _axis(0, pitch_deg, len(yaw)))


def _bump(u: np.ndarray, center: float, half: float) -> np.ndarray:
    """Smooth bump, 1 at ``center``, 0 outside ``center +- half``."""
    return np.sin(np.pi * np.clip((u - center + half) / (2 * half), 0.0, 1.0)) ** 2


def _plan_feet(rig: _Rig, t: np.ndarray, plants: Sequence[Sequence[_Plant]], lift: float,
               land_pitch: float = 10.0) -> _Feet:
    """Ankle targets, foot rotations and contact labels from footstep plans.

    Args:
        rig: the character.
        t: ``(T,)`` seconds.
        plants: per foot (left, right), time-ordered :class:`_Plant` s covering the clip
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
                pitch[piv, f] = p.pivot_deg * _minjerk((t[piv] - p.t1 + p.pivot) / p.pivot)
                flat_toe = _rotate(_foot_rot(np.array([p.yaw]), np.zeros(1)), toe)[0]
                toe_pos = np.array([p.xz[0], h, p.xz[1]]) + flat_toe
                ankle[piv, f] = toe_pos - _rotate(_foot_rot(yaw[piv, f], pitch[piv, f]), toe)
            if k + 1 < len(plants[f]):
                _swing(rig, t, f, p, plants[f][k + 1], lift, land_pitch, ankle, yaw, pitch)
    rot = _foot_rot(yaw.reshape(-1), pitch.reshape(-1)).reshape(T, 2, 4).numpy()
    fwd = np.stack((np.sin(yaw), np.zeros_like(yaw), np.cos(yaw)), -1)
    return _Feet(ankle, rot, contacts, fwd)


def _rotate(q: torch.Tensor, v: np.ndarray) -> np.ndarray:
    return quat_rotate(q, torch.from_numpy(np.broadcast_to(v, q.shape[:-1] + (3,)).copy())).numpy()


def _swing(rig: _Rig, t: np.ndarray, f: int, a: _Plant, b: _Plant, lift: float, land_pitch: float,
           ankle: np.ndarray, yaw: np.ndarray, pitch: np.ndarray) -> None:
    """Fill the swing of foot ``f`` from plant ``a`` to plant ``b`` in place."""
    m = (t > a.t1) & (t < b.t0)
    if not m.any():
        return
    u = (t[m] - a.t1) / (b.t0 - a.t1)
    s = _minjerk(u)
    toe = rig.toe[f]
    start_pitch = a.pivot_deg if a.pivot > 0 else 0.0
    start = np.array([a.xz[0], rig.ankle_h[f], a.xz[1]])
    if a.pivot > 0:  # the swing starts where the heel-raised foot left off
        toe_pos = start + _rotate(_foot_rot(np.array([a.yaw]), np.zeros(1)), toe)[0]
        start = toe_pos - _rotate(_foot_rot(np.array([a.yaw]), np.array([start_pitch])), toe)[0]
    end = np.array([b.xz[0], rig.ankle_h[f], b.xz[1]])
    dyaw = (b.yaw - a.yaw + np.pi) % (2 * np.pi) - np.pi
    yaw[m, f] = a.yaw + dyaw * s
    pitch[m, f] = start_pitch * (1 - _minjerk(u / 0.45)) - land_pitch * _bump(u, 0.8, 0.2)
    pos = start + (end - start) * s[:, None]
    dist = np.linalg.norm(end[[0, 2]] - start[[0, 2]])
    pos[:, 1] += min(lift, 0.5 * lift + dist) * np.sin(np.pi * u ** 0.8) ** 2  # early peak, soft ends
    ankle[m, f] = pos


def _still_plants(rig: _Rig, duration: float, width: float, toe_out: float) -> list[list[_Plant]]:
    """Both feet planted for the whole clip, ``width`` x hip width apart, toes out ``toe_out``
    degrees."""
    return [[_Plant(0.0, duration + 1.0, np.array([sign * width * rig.hip_w, 0.0]),
                    sign * np.radians(toe_out))] for _, sign in _SIDES]


def _yaw_xz(yaw: float, xz: np.ndarray) -> np.ndarray:
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
class _HandGoal:
    """Drive one hand (``side`` 0 left, 1 right) to ``target(body)`` with ``weight`` ``(T,)``.

    ``pole`` is the elbow direction and ``palm`` an optional ``(palm normal, finger direction)``
    for the hand, all in the chest's canonical frame.
    """

    side: int
    target: Callable[[_Body], np.ndarray]
    weight: np.ndarray
    pole: np.ndarray
    palm: tuple[tuple[float, float, float], tuple[float, float, float]] | None = None


def _palm_targets(center: Callable[[_Body], np.ndarray], gap: np.ndarray):
    """Targets for the two hands ``gap/2`` either side of ``center`` along the chest's left axis."""
    def make(sign):
        return lambda body: center(body) + sign * 0.5 * gap[:, None] * body.axes[:, J["Spine2"], :, 0]
    return make(1.0), make(-1.0)


def _contact_runs(mask: np.ndarray) -> list[tuple[int, int]]:
    m = np.concatenate(([False], mask, [False]))
    e = np.flatnonzero(m[1:] != m[:-1])
    return [(int(a), int(b)) for a, b in zip(e[::2], e[1::2])]


# ----------------------------------------------------------------------------- assembling
@dataclass
class _Plan:
    pose: _Pose
    feet: _Feet
    hands: list[_HandGoal] = field(default_factory=list)
    hand_contacts: list[HandContact] = field(default_factory=list)
    style: dict = field(default_factory=dict)


def _fk(rig: _Rig, q: np.ndarray, root: np.ndarray) -> np.ndarray:
    return forward_kinematics(q, rig.skeleton.offsets, rig.skeleton.parents, root).positions


def _lower_root_to_reach(rig: _Rig, q: np.ndarray, root: np.ndarray,
                         ankle: np.ndarray) -> np.ndarray:
    """Root trajectory lowered (smoothly) wherever a hip cannot reach its ankle target."""
    root = root.copy()
    for _ in range(3):
        pos = _fk(rig, q, root)
        need = np.zeros(len(root))
        for f, (side, _) in enumerate(_SIDES):
            v = pos[:, J[f"{side}UpLeg"]] - ankle[:, f]
            r = 0.985 * rig.leg_reach[f]
            horiz = np.minimum(v[:, 0] ** 2 + v[:, 2] ** 2, r * r)
            need = np.maximum(need, v[:, 1] - np.sqrt(r * r - horiz))
        if need.max() <= 1e-4:
            break
        root[:, 1] -= gaussian_filter1d(maximum_filter1d(np.maximum(need, 0.0), 13), 2.0)
    return root


def _lift_toes_above_floor(rig: _Rig, feet: _Feet) -> None:
    """Raise swinging feet (in place) wherever a pitched toe would dip under ``y = 0``."""
    for f in (0, 1):
        toe_y = feet.ankle[:, f, 1] + _rotate(torch.from_numpy(feet.rot[:, f]), rig.toe[f])[:, 1]
        feet.ankle[:, f, 1] -= np.minimum(toe_y, 0.0)


def _assemble(rig: _Rig, plan: _Plan, name: str, meta: dict) -> Motion:
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
        pos = _fk(rig, qt.numpy(), root)
        body = _Body(pos, axes.numpy())
        for goal in plan.hands:
            qt = _reach(rig, qt, root_t, body, goal)
    meta = dict(meta, style=plan.style, body_radii=dict(rig.radii),
                foot_contacts=plan.feet.contacts[:, :2] & plan.feet.contacts[:, 2:],
                joint_contacts=plan.feet.contacts.copy(), hand_contacts=list(plan.hand_contacts))
    return Motion(sk.copy(), qt.numpy(), root, FPS, name=name, meta=meta)


def _reach(rig: _Rig, q: torch.Tensor, root: torch.Tensor, body: _Body,
           goal: _HandGoal) -> torch.Tensor:
    """Solve one arm towards its goal, blended by the goal's weight (elbow plane blended too)."""
    sk = rig.skeleton
    chain = limb_chain(sk, ("left_arm", "right_arm")[goal.side])
    pos = _fk(rig, q.numpy(), root.numpy())
    hand, upper, elbow = pos[:, chain[2]], pos[:, chain[0]], pos[:, chain[1]]
    w = goal.weight[:, None]
    target = hand + w * (goal.target(body) - hand)
    pole_world = np.einsum("tij,j->ti", body.axes[:, J["Spine2"]], goal.pole)
    bend = elbow - upper
    pole = (1 - w) * bend / np.linalg.norm(bend, axis=-1, keepdims=True) + w * pole_world
    q = two_bone_ik(q, torch.from_numpy(sk.offsets), sk.parents, root, chain,
                    torch.from_numpy(target), torch.from_numpy(pole))
    return q if goal.palm is None else _orient_palm(rig, q, body, goal, chain)


def _orient_palm(rig: _Rig, q: torch.Tensor, body: _Body, goal: _HandGoal,
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


# ----------------------------------------------------------------------------- shared styles
def _standing(rig: _Rig, rng: np.random.Generator, t: np.ndarray, width: float | None = None,
              toe_out: float | None = None, knee: float | None = None) -> tuple[_Pose, list, dict]:
    """Idle standing: feet planted, breathing, small weight shifts, looking around, arms hanging.

    Returns the pose (root and every joint set), the plants and the style values drawn.
    """
    T, s = len(t), rig.scale
    style = {"width": width or rng.uniform(0.8, 1.4), "toe_out": toe_out or rng.uniform(4, 14),
             "knee": knee or rng.uniform(0.975, 0.99),
             "arm_down": min(rng.uniform(76, 84), rig.arm_down)}
    fade = _ramp(t, 0.0, 1.0)  # frame 0 is neutral: root over the origin, facing +Z
    pose = _Pose(T)
    pose.root[:, 0] = fade * _noise(rng, t, 0.012 * s, 0.25)
    pose.root[:, 2] = fade * _noise(rng, t, 0.008 * s, 0.25)
    pose.root[:, 1] = style["knee"] * rig.stand + _noise(rng, t, 0.003 * s, 0.3)
    pose.pelvis(fade * _noise(rng, t, 3.0, 0.2), 2.0 + _noise(rng, t, 1.0),
                fade * _noise(rng, t, 1.5, 0.25))
    pose.spine(2.0 + _noise(rng, t, 2.0, 0.3), _noise(rng, t, 3.0, 0.2), _noise(rng, t, 1.5, 0.25))
    pose.head(_noise(rng, t, 4.0, 0.3), _noise(rng, t, 10.0, 0.15), _noise(rng, t, 3.0, 0.2))
    for side, sign in _SIDES:
        pose.arm(side, sign, style["arm_down"] + _noise(rng, t, 2.0, 0.3),
                 4.0 + _noise(rng, t, 4.0, 0.3), 15.0 + _noise(rng, t, 5.0, 0.3))
    plants = _still_plants(rig, t[-1], style["width"], style["toe_out"])
    return pose, plants, style


def _hold_contacts(weight: np.ndarray, hand: str, part: str) -> list[HandContact]:
    """Contact runs where a hand goal is fully on (``weight`` = 1)."""
    return [HandContact(a, b, hand, part) for a, b in _contact_runs(weight > 1 - 1e-9)]


# ----------------------------------------------------------------------------- locomotion
def _locomotion(rig: _Rig, rng: np.random.Generator, t: np.ndarray, run: bool) -> _Plan:
    """Walk or run along a straight, curved or turning path, starting and ending at rest."""
    T, L, dur = len(t), rig.stand, t[-1]
    lead = rng.choice([1.0, -1.0])
    if run:
        cycle, step = rng.uniform(0.62, 0.78), rng.uniform(0.8, 1.2) * L
        duty = rng.uniform(0.3, 0.4)
        ramp_len = rng.uniform(1.4, 2.0)
    else:
        cycle, step = rng.uniform(0.95, 1.25), rng.uniform(0.5, 0.72) * L
        duty = rng.uniform(0.58, 0.63)
        ramp_len = rng.uniform(0.8, 1.3)
    speed = 2 * step / cycle
    t_lift = rng.uniform(0.3, 0.6)
    t_stop = dur - rng.uniform(0.6, 1.0) - ramp_len
    go = _window(t, t_lift, t_stop + ramp_len, ramp_len)
    kind = rng.choice(["straight", "curve", "turn"])
    rate = np.zeros(T)
    if kind == "curve":
        rate[:] = rng.choice([-1, 1]) * rng.uniform(8, 25)
    elif kind == "turn":
        a = rng.uniform(t_lift + ramp_len, max(t_lift + ramp_len + 0.1, t_stop - 2.0))
        span = rng.uniform(1.5, 3.0)
        peak = rng.choice([-1, 1]) * rng.uniform(45, 120)  # degrees turned in total
        rate = peak * _window(t, a, a + span, 0.5 * span) / (0.5 * span)
    heading = np.radians(np.cumsum(rate * go) / FPS)
    heading -= heading[0]
    vel = speed * go[:, None] * np.stack((np.sin(heading), np.cos(heading)), -1)
    path = np.concatenate((np.zeros((1, 2)), np.cumsum(vel[:-1], 0) / FPS))  # (T, 2) x, z
    style = {"speed": speed, "cycle": cycle, "step": step, "duty": duty, "path": str(kind),
             "lead": "left" if lead > 0 else "right", "width": rng.uniform(0.35, 0.8),
             "toe_out": rng.uniform(3, 12),
             "arm_swing": rng.uniform(15, 32) * (1.5 if run else 1.0)}
    feet, tau0 = _gait_feet(rig, rng, t, path, heading, go, style, run, lead)
    phase = 2 * np.pi * (t - tau0) / cycle  # 0 at the lead foot's mid-stance
    pose = _Pose(T)
    sway = lead * rng.uniform(0.01, 0.025) * rig.scale * np.cos(phase) * go * (0.4 if run else 1.0)
    side_axis = np.stack((np.cos(heading), -np.sin(heading)), -1)
    pose.root[:, [0, 2]] = path + sway[:, None] * side_axis
    # pelvis lowest at mid-stance when running, highest when walking (inverted pendulum)
    bob = (-0.035 if run else 0.012) * L * np.cos(2 * phase) * go
    pose.root[:, 1] = L * (0.985 - (0.06 if run else 0.01) * go) + bob
    lean = (rng.uniform(6, 12) if run else rng.uniform(1, 5)) * go + 2 * (1 - go)
    pelvis_yaw = lead * rng.uniform(3, 7) * np.sin(phase) * go
    pose.pelvis(np.degrees(heading) + pelvis_yaw, lean * 0.5, -lead * 3.0 * np.cos(phase) * go)
    pose.spine(lean * 0.5 + _noise(rng, t, 1.5), -1.4 * pelvis_yaw + _noise(rng, t, 2.0),
               _noise(rng, t, 1.0))
    pose.head(-0.4 * lean + _noise(rng, t, 4.0, 0.3), 0.4 * pelvis_yaw + _noise(rng, t, 8.0, 0.15))
    swing = style["arm_swing"] * go
    for side, sign in _SIDES:
        fwd = sign * lead * swing * np.sin(phase) + (10 * go if run else 3)
        elbow = (rng.uniform(75, 95) * go + 15 * (1 - go)) if run else 12 + 0.5 * np.maximum(fwd, 0)
        down = min(rng.uniform(76, 82), rig.arm_down)
        pose.arm(side, sign, down, fwd, elbow + _noise(rng, t, 4.0))
    return _Plan(pose, feet, style=style)


def _gait_feet(rig: _Rig, rng: np.random.Generator, t: np.ndarray, path: np.ndarray,
               heading: np.ndarray, go: np.ndarray, style: dict, run: bool,
               lead: float) -> tuple[_Feet, float]:
    """Footsteps at a fixed cadence, each placed under the root path at its mid-stance time.

    The feet start side by side; the stance share (duty) blends from walking (0.62) to the style's
    value as the speed ramps up; the heel lifts over the last 30 % of each stance.

    Returns:
        the feet and the lead foot's first mid-stance time (the gait phase origin).
    """
    cycle, dur = style["cycle"], t[-1]
    toe_out = np.radians(style["toe_out"])
    plants = [[_Plant(0.0, 0.0, np.array([sign * 0.9 * rig.hip_w, 0.0]), sign * toe_out)]
              for _, sign in _SIDES]
    tau0 = t[np.argmax(go > 1e-3)] + 0.69 * cycle
    f = 0 if lead > 0 else 1
    for tau in np.arange(tau0, dur - 0.2, 0.5 * cycle):
        g = float(np.interp(tau, t, go))
        yaw = float(np.interp(tau, t, heading))
        sign = _SIDES[f][1]
        xz = np.array([np.interp(tau, t, path[:, 0]), np.interp(tau, t, path[:, 1])])
        xz = xz + _yaw_xz(yaw, np.array([sign * style["width"] * rig.hip_w, 0.0]))
        if g < 0.05 and np.linalg.norm(xz - plants[f][-1].xz) < 0.02 * rig.stand:
            break
        stance = (0.62 + (style["duty"] - 0.62) * g) * cycle
        if len(plants[f]) == 1:
            plants[f][0].t1 = max(tau - 0.5 * stance - (cycle - stance), 0.2)
        heel = (rng.uniform(25, 35) if run else rng.uniform(12, 22)) * g
        plants[f].append(_Plant(tau - 0.5 * stance, tau + 0.5 * stance, xz, yaw + sign * toe_out,
                                0.3 * stance, heel))
        f = 1 - f
    for foot in plants:
        foot[-1].t1, foot[-1].pivot = dur + 1.0, 0.0
    lift = (rng.uniform(0.22, 0.32) if run else rng.uniform(0.08, 0.12)) * rig.stand
    return _plan_feet(rig, t, plants, lift, land_pitch=5.0 if run else 12.0), tau0


def _walk(rig, rng, t):
    return _locomotion(rig, rng, t, run=False)


def _run(rig, rng, t):
    return _locomotion(rig, rng, t, run=True)


# ----------------------------------------------------------------------------- turning and jumping
def _turn(rig: _Rig, rng: np.random.Generator, t: np.ndarray) -> _Plan:
    """Turns on the spot by 60-180 degrees, stepping round with alternating feet."""
    pose, _, style = _standing(rig, rng, t)
    T, dur = len(t), t[-1]
    rate = rng.uniform(90, 150)
    angles: list[float] = []

    def length():
        angles.append(float(rng.choice([-1, 1]) * rng.uniform(60, 180)))
        return abs(angles[-1]) / rate + 0.6

    events = _events(rng, dur, length, (0.6, 2.0), start=(0.3, 0.8))
    angles = angles[:len(events)]
    heading = np.zeros(T)
    toe_out = np.radians(style["toe_out"])
    plants = [[_Plant(0.0, 0.0, np.array([sign * style["width"] * rig.hip_w, 0.0]), sign * toe_out)]
              for _, sign in _SIDES]
    total = 0.0
    for (a, b), ang in zip(events, angles):
        heading += ang * _ramp(t, a, b - 0.2)
        n_steps = int(np.ceil(abs(ang) / 50.0)) + 1
        first = 0 if ang > 0 else 1  # step first with the foot on the turning side
        swing = min(0.42, 0.85 * (b - a) / (n_steps - 0.15))  # one foot down before the next lifts
        for k in range(n_steps):
            f = first if k % 2 == 0 else 1 - first
            lift_off = a + k * (b - a - swing) / max(n_steps - 1, 1)
            progress = float(_minjerk(np.array((lift_off + swing - a) / (b - a - 0.2))))
            yaw = np.radians(total + ang * progress)
            sign = _SIDES[f][1]
            xz = _yaw_xz(yaw, np.array([sign * style["width"] * rig.hip_w, 0.0]))
            plants[f][-1].t1 = lift_off
            plants[f].append(_Plant(lift_off + swing, dur + 1.0, xz, yaw + sign * toe_out))
        total += ang
    for foot in plants:
        if len(foot) == 1:
            foot[0].t1 = dur + 1.0
    yaw_deg = heading + _noise(rng, t, 2.0) * _ramp(t, 0, 1)
    lead = np.interp(t + 0.25, t, heading) - heading  # the upper body leads the turn
    pose.pelvis(yaw_deg, 3.0, 0.0)
    pose.spine(3.0 + _noise(rng, t, 1.5), 0.6 * lead, 0.0)
    pose.head(_noise(rng, t, 3.0), 0.8 * lead, 0.0)
    style.update(angles=[round(x, 1) for x in angles], rate=rate)
    return _Plan(pose, _plan_feet(rig, t, plants, 0.06 * rig.stand), style=style)


def _hermite(t: np.ndarray, t0: float, t1: float, y0: float, y1: float, v0: float,
             v1: float) -> np.ndarray:
    """Cubic Hermite segment from ``(t0, y0, v0)`` to ``(t1, y1, v1)`` evaluated at ``t``."""
    h = t1 - t0
    u = np.clip((t - t0) / h, 0.0, 1.0)
    return ((2 * u ** 3 - 3 * u ** 2 + 1) * y0 + (u ** 3 - 2 * u ** 2 + u) * h * v0
            + (-2 * u ** 3 + 3 * u ** 2) * y1 + (u ** 3 - u ** 2) * h * v1)


def _jump(rig: _Rig, rng: np.random.Generator, t: np.ndarray) -> _Plan:
    """Two-footed jumps (in place or forward, sometimes turning): crouch with the arms back,
    push off onto the toes, ballistic flight with tucked legs, landing absorbed in the knees."""
    pose, _, style = _standing(rig, rng, t, width=rng.uniform(0.9, 1.3))
    T, dur, L, g = len(t), t[-1], rig.stand, 9.81
    toe_out = np.radians(style["toe_out"])
    root_y = pose.root[:, 1].copy()
    stand_y = style["knee"] * L
    heading = np.zeros(T)
    arm_fwd, spine_bend, elbow = np.full(T, 4.0), np.zeros(T), np.full(T, 15.0)
    plants = [[_Plant(0.0, 0.0, np.array([sign * style["width"] * rig.hip_w, 0.0]), sign * toe_out)]
              for _, sign in _SIDES]
    jumps = []

    def length():
        h = rng.uniform(0.12, 0.35) * L
        jumps.append({"h": h, "dist": rng.choice([0.0, rng.uniform(0.2, 0.8)]) * L,
                      "turn": rng.choice([0.0, 0.0, rng.choice([-1, 1]) * rng.uniform(30, 90)]),
                      "crouch": rng.uniform(0.15, 0.28) * L, "prep": rng.uniform(0.45, 0.7)})
        return jumps[-1]["prep"] + 2 * np.sqrt(2 * h / g) + 0.9

    events = _events(rng, dur, length, (0.5, 1.8), start=(0.4, 0.9))
    x0, yaw0 = np.zeros(2), 0.0
    for (a, b), jp in zip(events, jumps):
        v = np.sqrt(2 * jp["h"] / g) * g
        t_low, t_off = a + 0.6 * jp["prep"], a + jp["prep"]
        t_land = t_off + 2 * v / g
        t_absorb, t_up = t_land + 0.25, b
        y_off = stand_y + 0.03 * L
        seg = [(a, t_low, stand_y, stand_y - jp["crouch"], 0.0, 0.0),
               (t_low, t_off, stand_y - jp["crouch"], y_off, 0.0, v),
               (t_land, t_absorb, y_off, stand_y - 0.8 * jp["crouch"], -v, 0.0),
               (t_absorb, t_up, stand_y - 0.8 * jp["crouch"], stand_y, 0.0, 0.0)]
        for s in seg:  # offsets from the idle height, zero at both ends of the jump
            m = (t >= s[0]) & (t < s[1])
            root_y[m] += _hermite(t[m], *s) - stand_y
        fl = (t > t_off) & (t < t_land)
        root_y[fl] += y_off + v * (t[fl] - t_off) - 0.5 * g * (t[fl] - t_off) ** 2 - stand_y
        move = _ramp(t, t_off - 0.1, t_land + 0.1)
        yaw1 = yaw0 + np.radians(jp["turn"])
        x1 = x0 + _yaw_xz(yaw0, np.array([0.0, jp["dist"]]))
        heading += jp["turn"] * move
        pose.root[:, [0, 2]] += move[:, None] * (x1 - x0)
        for f, (_, sign) in enumerate(_SIDES):
            plants[f][-1].t1 = t_off
            plants[f][-1].pivot, plants[f][-1].pivot_deg = 0.35 * jp["prep"], rng.uniform(30, 45)
            xz = x1 + _yaw_xz(yaw1, np.array([sign * style["width"] * rig.hip_w, 0.0]))
            plants[f].append(_Plant(t_land, dur + 1.0, xz, yaw1 + sign * toe_out))
        arm_fwd += _keys(t, [a, t_low, t_off, t_land, t_absorb + 0.2, b], [0, -50, 150, 60, 35, 0])
        spine_bend += _keys(t, [a, t_low, t_off, t_land, t_absorb, b], [0, 30, -4, 8, 25, 0])
        elbow += _keys(t, [a, t_low, t_off, t_land, b], [0, 10, 0, 20, 0])
        x0, yaw0 = x1, yaw1
        jp.update(t_off=t_off, t_land=t_land, y_off=y_off)
    pose.root[:, 1] = root_y
    pose.pelvis(heading + _noise(rng, t, 2.0) * _ramp(t, 0, 1), 2.0 + 0.4 * spine_bend, 0.0)
    pose.spine(0.6 * spine_bend + _noise(rng, t, 1.5), _noise(rng, t, 2.0), 0.0)
    pose.head(-0.5 * spine_bend + _noise(rng, t, 3.0), _noise(rng, t, 5.0), 0.0)
    for side, sign in _SIDES:
        down = style["arm_down"] - 0.1 * np.maximum(arm_fwd, 0)
        pose.arm(side, sign, down, arm_fwd + _noise(rng, t, 3.0), elbow)
    feet = _plan_feet(rig, t, plants, 0.0, land_pitch=-8.0)
    for jp in jumps[:len(events)]:  # in the air the feet travel with the hips, legs tucked
        fl = (t > jp["t_off"]) & (t < jp["t_land"])
        u = (t[fl] - jp["t_off"]) / (jp["t_land"] - jp["t_off"])
        rise = root_y[fl] - jp["y_off"] + 0.25 * jp["h"] * np.sin(np.pi * u)
        feet.ankle[fl, :, 1] += rise[:, None]
    style.update(jumps=len(events))
    return _Plan(pose, feet, style=style)


# ----------------------------------------------------------------------------- hand gestures
def _gesture_weight(t: np.ndarray, events, rise: float) -> np.ndarray:
    """Eased on/off weight that is 1 during each event (minus its ramps) and 0 between them."""
    return np.max([_window(t, a, b, rise) for a, b in events], axis=0)


def _wave(rig: _Rig, rng: np.random.Generator, t: np.ndarray) -> _Plan:
    """Waving hello with one raised hand swinging side to side about the elbow."""
    pose, plants, style = _standing(rig, rng, t)
    side = int(rng.integers(2))
    name, sign = _SIDES[side]
    events = _events(rng, t[-1], lambda: rng.uniform(1.8, 4.5), (0.8, 2.5))
    weight = _gesture_weight(t, events, 0.55)
    freq, amp = rng.uniform(1.5, 3.0), rng.uniform(0.12, 0.2) * rig.arm_reach
    height, out = rng.uniform(0.45, 0.65) * rig.arm_reach, rng.uniform(0.3, 0.45) * rig.arm_reach
    wagging = _gesture_weight(t, [(a + 0.4, b - 0.3) for a, b in events], 0.3)
    wag = amp * np.sin(2 * np.pi * freq * t) * wagging
    offset = np.stack((sign * out + wag, np.full_like(t, height),
                       np.full_like(t, 0.25 * rig.arm_reach)), -1)
    goal = _HandGoal(side, lambda body: body.at(f"{name}Arm", offset, "Spine2"), weight,
                     np.array([sign * 0.6, -0.75, -0.1]))
    pose.head(_noise(rng, t, 3.0), sign * 8.0 * weight + _noise(rng, t, 5.0), sign * 4.0 * weight)
    style.update(hand=name, freq=freq, waves=len(events))
    return _Plan(pose, _plan_feet(rig, t, plants, 0.0), [goal], style=style)


def _clap(rig: _Rig, rng: np.random.Generator, t: np.ndarray) -> _Plan:
    """Rounds of clapping in front of the chest; the palms meet and touch for a few frames."""
    pose, plants, style = _standing(rig, rng, t)
    freq = rng.uniform(1.5, 3.0)
    events = _events(rng, t[-1], lambda: int(rng.integers(3, 10)) / freq + 1.1, (0.7, 2.0))
    weight = _gesture_weight(t, events, 0.5)
    r, s = rig.radii, rig.scale
    closed, opened = 2 * r["hand"], rng.uniform(0.22, 0.38) * s
    touch = max(0.15, 2.2 * freq / FPS)  # share of a clap cycle with the palms together
    gap = np.full_like(t, opened)
    contact = np.zeros(len(t), bool)
    for a, b in events:
        m = (t >= a + 0.55) & (t <= b - 0.55)
        phase = ((t[m] - a - 0.55) * freq + touch + 0.5 * (1 - touch)) % 1.0
        opening = 0.5 * (1 - np.cos(2 * np.pi * (phase - touch) / (1 - touch)))
        open_ = np.where(phase < touch, 0.0, opening)
        gap[m] = closed + (opened - closed) * open_
        contact[np.flatnonzero(m)[phase < touch]] = True
    drop = rng.uniform(-0.05, 0.1) * s
    depth = min(r["torso"] + rng.uniform(0.15, 0.25) * s, rig.front_reach(drop, closed))
    center = lambda body: body.at("Spine2", (0.0, -drop, depth))
    left, right = _palm_targets(center, gap)
    hands = [_HandGoal(0, left, weight, np.array([0.55, -0.75, -0.3]),
                       ((-1, 0, 0), (0, 0.5, 0.85))),
             _HandGoal(1, right, weight, np.array([-0.55, -0.75, -0.3]),
                       ((1, 0, 0), (0, 0.5, 0.85)))]
    pose.head(6.0 * weight + _noise(rng, t, 3.0), _noise(rng, t, 6.0), 0.0)
    contacts = [HandContact(a, b, h, p) for a, b in _contact_runs(contact & (weight > 1 - 1e-9))
                for h, p in (("LeftHand", "RightHand"), ("RightHand", "LeftHand"))]
    style.update(freq=freq, rounds=len(events))
    return _Plan(pose, _plan_feet(rig, t, plants, 0.0), hands, contacts, style)


def _pray(rig: _Rig, rng: np.random.Generator, t: np.ndarray) -> _Plan:
    """Palms pressed together in front of the sternum, often with a small bow."""
    pose, plants, style = _standing(rig, rng, t)
    events = _events(rng, t[-1], lambda: rng.uniform(2.0, 6.0), (1.0, 2.5))
    weight = _gesture_weight(t, events, rng.uniform(0.5, 0.8))
    r, s = rig.radii, rig.scale
    bow = rng.uniform(0.0, 25.0) * _gesture_weight(t, [(a + 0.5, b - 0.5) for a, b in events], 0.6)
    pose.spine(2.0 + bow + _noise(rng, t, 1.0), _noise(rng, t, 2.0), 0.0)
    pose.head(0.6 * bow + 8.0 * weight + _noise(rng, t, 2.0), _noise(rng, t, 3.0), 0.0)
    drop = rng.uniform(-0.02, 0.08) * s
    depth = min(r["torso"] + rng.uniform(0.09, 0.15) * s, rig.front_reach(drop, 2 * r["hand"]))
    left, right = _palm_targets(lambda body: body.at("Spine2", (0.0, -drop, depth)),
                                np.full_like(t, 2 * r["hand"]))
    hands = [_HandGoal(0, left, weight, np.array([0.6, -0.8, -0.1]), ((-1, 0, 0), (0, 1, 0.35))),
             _HandGoal(1, right, weight, np.array([-0.6, -0.8, -0.1]), ((1, 0, 0), (0, 1, 0.35)))]
    contacts = (_hold_contacts(weight, "LeftHand", "RightHand")
                + _hold_contacts(weight, "RightHand", "LeftHand"))
    style.update(holds=len(events))
    return _Plan(pose, _plan_feet(rig, t, plants, 0.0), hands, contacts, style)


def _hands_on_hips(rig: _Rig, rng: np.random.Generator, t: np.ndarray) -> _Plan:
    """Both hands resting on the sides of the pelvis while shifting weight and looking around."""
    pose, plants, style = _standing(rig, rng, t, width=rng.uniform(1.0, 1.6))
    events = _events(rng, t[-1], lambda: rng.uniform(2.0, 7.0), (1.0, 2.5))
    weight = _gesture_weight(t, events, rng.uniform(0.5, 0.8))
    r, s = rig.radii, rig.scale
    crest, front = rng.uniform(0.03, 0.09) * s, rng.uniform(-0.02, 0.03) * s
    hands, contacts = [], []
    for f, (name, sign) in enumerate(_SIDES):
        off = (sign * (r["hip"] + r["hand"]), crest, front)
        hands.append(_HandGoal(f, lambda body, off=off: body.at("Hips", off), weight,
                               np.array([sign * 0.9, -0.1, -0.45]), ((-sign, 0, 0), (0, -0.4, 1))))
        contacts += _hold_contacts(weight, f"{name}Hand", f"{name}Hip")
    pose.head(_noise(rng, t, 5.0), _noise(rng, t, 20.0, 0.2), _noise(rng, t, 4.0))
    style.update(holds=len(events))
    return _Plan(pose, _plan_feet(rig, t, plants, 0.0), hands, contacts, style)


def _touch_head(rig: _Rig, rng: np.random.Generator, t: np.ndarray) -> _Plan:
    """One or both hands on top of the head (patting/scratching), elbows out to the sides."""
    pose, plants, style = _standing(rig, rng, t)
    which = rng.choice(["left", "right", "both"])
    events = _events(rng, t[-1], lambda: rng.uniform(1.5, 4.5), (1.0, 2.5))
    weight = _gesture_weight(t, events, rng.uniform(0.55, 0.8))
    r = rig.radii
    rub = np.radians(8.0) * np.sin(2 * np.pi * rng.uniform(1.0, 2.5) * t) * (which != "both")
    hands, contacts = [], []
    for f, (name, sign) in enumerate(_SIDES):
        if which not in (name.lower(), "both"):
            continue
        lean = np.radians(25.0 if which == "both" else 5.0) * sign + rub
        direction = np.stack((np.sin(lean), np.cos(lean), np.full_like(t, 0.1)), -1)
        direction /= np.linalg.norm(direction, axis=-1, keepdims=True)
        center = np.array([0.0, 0.9 * r["head"], 0.15 * r["head"]])
        off = center + (r["head"] + r["hand"]) * direction
        hands.append(_HandGoal(f, lambda body, off=off: body.at("Head", off), weight,
                               np.array([sign * 0.9, 0.2, 0.3]), ((0, -1, 0), (-sign * 0.6, 0, 0.8))))
        contacts += _hold_contacts(weight, f"{name}Hand", "HeadTop")
    pose.head(10.0 * weight + _noise(rng, t, 3.0), _noise(rng, t, 5.0), 0.0)
    style.update(hands=str(which), touches=len(events))
    return _Plan(pose, _plan_feet(rig, t, plants, 0.0), hands, contacts, style)


# ----------------------------------------------------------------------------- fighting, squats
def _fighting_stance(rig: _Rig, rng: np.random.Generator, t: np.ndarray, lead: int):
    """Step from neutral into a staggered guard stance (``lead`` foot forward) in the first second.

    Returns ``(pose, plants, style, ready)`` where ``ready`` eases from 0 to 1 into the stance.
    """
    pose, plants, style = _standing(rig, rng, t, width=rng.uniform(1.1, 1.5),
                                    knee=rng.uniform(0.93, 0.96))
    rear = 1 - lead
    t_go = rng.uniform(0.3, 0.6)
    ready = _ramp(t, t_go, t_go + 0.7)
    stagger = rng.uniform(0.3, 0.45) * rig.stand
    sign = _SIDES[rear][1]
    old = plants[rear][0]
    back = old.xz + np.array([sign * 0.2 * rig.hip_w, -stagger])
    plants[rear] = [_Plant(0.0, t_go, old.xz, old.yaw),
                    _Plant(t_go + 0.4, t[-1] + 1.0, back, old.yaw + sign * np.radians(30))]
    turn = -_SIDES[lead][1] * rng.uniform(15, 30)  # body turned towards the rear side
    pose.root[:, 2] -= 0.45 * stagger * ready
    bounce = 0.012 * rig.stand * np.sin(2 * np.pi * rng.uniform(1.5, 2.5) * t) * ready
    pose.root[:, 1] = (1 - ready * (1 - style["knee"] / 0.985)) * pose.root[:, 1] + bounce
    style.update(lead=_SIDES[lead][0], stagger=stagger, turn=turn)
    return pose, plants, style, ready


def _punch(rig: _Rig, rng: np.random.Generator, t: np.ndarray) -> _Plan:
    """Boxing: guard at the chin, jab (lead hand) and cross (rear hand) combinations."""
    lead = int(rng.integers(2))
    pose, plants, style, ready = _fighting_stance(rig, rng, t, lead)
    events = _events(rng, t[-1], lambda: rng.uniform(0.8, 2.0), (0.6, 1.8), start=(1.3, 1.8))
    extend = [np.zeros_like(t), np.zeros_like(t)]
    twist = np.zeros_like(t)
    for a, b in events:
        k, tp = int(rng.integers(2)), a
        while tp + 0.45 < b:
            hand = lead if k % 2 == 0 else 1 - lead
            out = rng.uniform(0.12, 0.18)
            shape = _window(t, tp, tp + out + 0.27, out, 0.22)  # out, hold 0.05 s, back
            extend[hand] = np.maximum(extend[hand], shape)
            twist -= _SIDES[hand][1] * rng.uniform(10, 22) * shape
            tp += out + 0.27 + rng.uniform(0.0, 0.15)
            k += 1
    base_turn = style["turn"] * ready
    pose.pelvis(base_turn + _noise(rng, t, 2.0) * ready, 4.0 * ready, 0.0)
    pose.spine(6.0 * ready + _noise(rng, t, 1.5), -0.6 * base_turn + twist, 0.0)
    pose.head(8.0 * ready, -0.4 * base_turn - 0.5 * twist, 0.0)
    hands = []
    reach = rng.uniform(0.9, 0.96) * rig.arm_reach
    for f, (name, sign) in enumerate(_SIDES):
        guard = np.array([sign * 0.09, -0.04, 0.16]) * rig.scale
        aim = np.array([-sign * 0.12, 0.0, 1.0]) / np.linalg.norm([0.12, 0.0, 1.0])
        ext = extend[f][:, None]

        def target(body, guard=guard, aim=aim, ext=ext, name=name):
            g = body.at("Neck", guard, "Spine2")
            return g + ext * (body.at(f"{name}Arm", reach * aim, "Spine2") - g)

        hands.append(_HandGoal(f, target, ready, np.array([sign * 0.45, -0.85, -0.2])))
    style.update(combos=len(events))
    return _Plan(pose, _plan_feet(rig, t, plants, 0.05 * rig.stand), hands, style=style)


def _kick(rig: _Rig, rng: np.random.Generator, t: np.ndarray) -> _Plan:
    """Front kicks: knee up (chamber), snap the foot out at hip height, re-chamber, step down."""
    lead = int(rng.integers(2))
    pose, plants, style, ready = _fighting_stance(rig, rng, t, lead)
    kicks = []
    events = _events(rng, t[-1], lambda: rng.uniform(1.1, 1.6), (0.8, 2.0), start=(1.3, 1.8))
    lean = np.zeros_like(t)
    for a, b in events:
        f = 1 - lead if rng.uniform() < 0.7 else lead  # mostly the rear leg
        kicks.append((a, b, f, rng.uniform(-5, 30)))
        old = plants[f][-1]
        old.t1 = a
        plants[f].append(_Plant(b, t[-1] + 1.0, old.xz, old.yaw))
        lean -= rng.uniform(8, 18) * _keys(t, a + (b - a) * np.array([0, 0.35, 0.5, 1]), [0, 0.3, 1, 0])
    pose.pelvis(style["turn"] * ready, 3.0 * ready + 0.5 * lean, 0.0)
    pose.spine(5.0 * ready + 0.5 * lean, -0.6 * style["turn"] * ready, 0.0)
    pose.head(6.0 * ready - 0.6 * lean, -0.4 * style["turn"] * ready, 0.0)
    for side, sign in _SIDES:
        down = 60.0 * ready + style["arm_down"] * (1 - ready)
        pose.arm(side, sign, down, 55.0 * ready, 15 + 95.0 * ready)
    feet = _plan_feet(rig, t, plants, 0.06 * rig.stand)
    q = transfer_rotations(pose.q.numpy(), rig.ref, rig.skeleton)
    hips = _fk(rig, q, pose.root)
    for a, b, f, elev in kicks:
        name = _SIDES[f][0]
        m = (t >= a) & (t <= b)
        hip = hips[m, J[f"{name}UpLeg"]]
        fwd, up = np.array([0.0, 0.0, 1.0]), np.array([0.0, 1.0, 0.0])  # kick straight ahead (+Z)
        l1 = np.linalg.norm(rig.skeleton.offsets[J[f"{name}Leg"]])
        l2 = np.linalg.norm(rig.skeleton.offsets[J[f"{name}Foot"]])
        e = np.radians(elev)
        start = feet.ankle[np.flatnonzero(m)[0], f] - hips[np.flatnonzero(m)[0], J[f"{name}UpLeg"]]
        keys = [start, 0.75 * l1 * fwd - 0.6 * l2 * up + 0.3 * l1 * up,
                0.96 * (l1 + l2) * (np.cos(e) * fwd + np.sin(e) * up),
                0.75 * l1 * fwd - 0.6 * l2 * up + 0.3 * l1 * up, start]
        rel = _keys(t[m], a + (b - a) * np.array([0.0, 0.35, 0.5, 0.68, 1.0]), keys)
        feet.ankle[m, f] = hip + rel
        feet.ankle[m, f, 1] = np.maximum(feet.ankle[m, f, 1], rig.ankle_h[f])
        pitch = _keys(t[m], a + (b - a) * np.array([0.0, 0.35, 0.5, 0.68, 1.0]), [0, 20, 40, 20, 0])
        yaw = plants[f][-1].yaw * (1 - np.sin(np.pi * (t[m] - a) / (b - a)))  # toes to the target
        feet.rot[m, f] = _foot_rot(yaw, pitch).numpy()
        feet.knee[m, f] = (fwd + up) / np.sqrt(2.0)  # knee up and forward
    style.update(kicks=len(kicks))
    return _Plan(pose, feet, style=style)


def _squat(rig: _Rig, rng: np.random.Generator, t: np.ndarray) -> _Plan:
    """Repeated squats, feet wide and turned out, hips back, arms forward for balance."""
    pose, plants, style = _standing(rig, rng, t, width=rng.uniform(1.3, 1.9),
                                    toe_out=rng.uniform(12, 28))
    depth = np.zeros_like(t)
    events = _events(rng, t[-1], lambda: rng.uniform(2.2, 4.0), (0.4, 1.8))
    for a, b in events:
        d = rng.uniform(0.25, 0.45)
        down, hold = rng.uniform(0.4, 0.5) * (b - a), rng.uniform(0.0, 0.15) * (b - a)
        depth = np.maximum(depth, d * _keys(t, [a, a + down, a + down + hold, b], [0, 1, 1, 0]))
    L = rig.stand
    pose.root[:, 1] -= depth * L
    pose.root[:, 2] -= 0.4 * depth * L
    lean = 100.0 * depth
    pose.pelvis(_noise(rng, t, 2.0) * _ramp(t, 0, 1), 2.0 + 0.45 * lean, 0.0)
    pose.spine(2.0 + 0.55 * lean + _noise(rng, t, 1.0), _noise(rng, t, 2.0), 0.0)
    pose.head(-0.6 * lean + _noise(rng, t, 3.0), _noise(rng, t, 5.0), 0.0)
    raise_arms = rng.uniform(0.6, 1.0)
    for side, sign in _SIDES:
        fwd = 4.0 + raise_arms * 220.0 * depth  # arms forward as the hips go back
        pose.arm(side, sign, style["arm_down"], fwd, 15.0 + 20.0 * depth)
    style.update(reps=len(events))
    return _Plan(pose, _plan_feet(rig, t, plants, 0.0), style=style)


# ----------------------------------------------------------------------------- public API
_FAMILY_FUNCS: dict[str, Callable[[_Rig, np.random.Generator, np.ndarray], _Plan]] = {
    "walk": _walk, "run": _run, "jump": _jump, "turn": _turn, "wave": _wave, "clap": _clap,
    "hands_on_hips": _hands_on_hips, "pray": _pray, "touch_head": _touch_head, "punch": _punch,
    "kick": _kick, "squat": _squat,
}


def make_motion(family: str, skeleton: Skeleton, seed: int, duration: float | None = None,
                body_radii: dict[str, float] | None = None) -> Motion:
    """One synthetic clip of ``family`` performed by ``skeleton``.

    Args:
        family: one of :data:`MOTION_FAMILIES`.
        skeleton: any canonical-22 skeleton (metres, +Y up, facing +Z).
        seed: style seed; the same ``(family, skeleton, seed, duration)`` gives the same clip.
        duration: seconds; default drawn from :data:`DURATION_RANGES`.
        body_radii: body-size hint (see :func:`default_body_radii`, whose values fill any
            missing key).

    Returns:
        a :class:`Motion` at 30 fps, starting at the origin facing +Z with its feet on ``y = 0``;
        ``meta`` holds the contact labels (module docstring).
    """
    if family not in _FAMILY_FUNCS:
        raise ValueError(f"unknown motion family {family!r}; choose from {MOTION_FAMILIES}")
    if not skeleton.is_canonical22():
        raise ValueError("make_motion needs a canonical-22 skeleton")
    rng = np.random.default_rng([int(seed), MOTION_FAMILIES.index(family)])
    duration = float(rng.uniform(*DURATION_RANGES[family])) if duration is None else float(duration)
    t = np.arange(max(int(round(duration * FPS)), 2)) / FPS
    rig = _Rig(skeleton, {**default_body_radii(skeleton), **(body_radii or {})})
    plan = _FAMILY_FUNCS[family](rig, rng, t)
    return _assemble(rig, plan, f"{family}_{seed:03d}", {"family": family, "seed": int(seed)})


def motion_library(skeleton: Skeleton, seeds_per_family: int = 2, seed: int = 0,
                   families: Sequence[str] = MOTION_FAMILIES,
                   body_radii: dict[str, float] | None = None) -> list[Motion]:
    """Clips ``seed, seed + 1, ..., seed + seeds_per_family - 1`` of every family.

    Args:
        skeleton: canonical-22 character.
        seeds_per_family: clips per family.
        seed: first clip seed.
        families: which families (default all).
        body_radii: passed to :func:`make_motion`.

    Returns:
        ``len(families) * seeds_per_family`` motions, family-major.
    """
    return [make_motion(f, skeleton, seed + k, body_radii=body_radii)
            for f in families for k in range(seeds_per_family)]
