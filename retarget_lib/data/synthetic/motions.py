"""Synthetic motion library: keyframed and procedural human motion on any canonical-22 character.

Twelve families (:data:`MOTION_FAMILIES`): ``walk``, ``run``, ``jump``, ``turn``, ``wave``,
``clap``, ``hands_on_hips``, ``pray``, ``touch_head``, ``punch``, ``kick``, ``squat``. Each clip
is deterministic in ``(family, skeleton, seed)``; the seed draws the style (speed, stride,
amplitude, arm swing, stance width, timing, turning direction, small asymmetries and noise) and
the duration (2-40 s depending on the family), at 30 fps.

The clips are authored with :mod:`retarget_lib.data.synthetic.authoring` (canonical rest pose, planted
feet, real hand contacts; see there for how a clip is made).

``Motion.meta`` records what was used: ``family``, ``seed``, ``style``, ``body_radii``,
``foot_contacts`` ``(T, 2)`` bool (left, right foot flat on the ground and still),
``joint_contacts`` ``(T, 4)`` bool in :data:`~retarget_lib.core.skeleton.FOOT_CONTACT_JOINTS` order (a toe
stays planted while its heel lifts), and ``hand_contacts``: a list of :class:`HandContact`.
"""

from __future__ import annotations

from typing import Callable, Sequence

import numpy as np

from ...core.motion import Motion
from ...core.skeleton import J, Skeleton
from ...core.transfer import canonical_rest_skeleton, transfer_rotations
from .authoring import (
    FPS,
    SIDES,
    Feet,
    HandContact,
    HandGoal,
    Plan,
    Plant,
    Pose,
    Rig,
    assemble,
    body_radii_from_mesh,
    contact_runs,
    default_body_radii,
    event_times,
    fk,
    foot_rot,
    hermite,
    keyframes,
    minjerk,
    noise,
    palm_targets,
    plan_feet,
    ramp,
    still_plants,
    window,
    yaw_xz,
)

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


# ----------------------------------------------------------------------------- shared styles
def _standing(rig: Rig, rng: np.random.Generator, t: np.ndarray, width: float | None = None,
              toe_out: float | None = None, knee: float | None = None) -> tuple[Pose, list, dict]:
    """Idle standing: feet planted, breathing, small weight shifts, looking around, arms hanging.

    Returns the pose (root and every joint set), the plants and the style values drawn.
    """
    T, s = len(t), rig.scale
    style = {"width": width or rng.uniform(0.8, 1.4), "toe_out": toe_out or rng.uniform(4, 14),
             "knee": knee or rng.uniform(0.975, 0.99),
             "arm_down": min(rng.uniform(76, 84), rig.arm_down)}
    fade = ramp(t, 0.0, 1.0)  # frame 0 is neutral: root over the origin, facing +Z
    pose = Pose(T)
    pose.root[:, 0] = fade * noise(rng, t, 0.012 * s, 0.25)
    pose.root[:, 2] = fade * noise(rng, t, 0.008 * s, 0.25)
    pose.root[:, 1] = style["knee"] * rig.stand + noise(rng, t, 0.003 * s, 0.3)
    pose.pelvis(fade * noise(rng, t, 3.0, 0.2), 2.0 + noise(rng, t, 1.0),
                fade * noise(rng, t, 1.5, 0.25))
    pose.spine(2.0 + noise(rng, t, 2.0, 0.3), noise(rng, t, 3.0, 0.2), noise(rng, t, 1.5, 0.25))
    pose.head(noise(rng, t, 4.0, 0.3), noise(rng, t, 10.0, 0.15), noise(rng, t, 3.0, 0.2))
    for side, sign in SIDES:
        pose.arm(side, sign, style["arm_down"] + noise(rng, t, 2.0, 0.3),
                 4.0 + noise(rng, t, 4.0, 0.3), 15.0 + noise(rng, t, 5.0, 0.3))
    plants = still_plants(rig, t[-1], style["width"], style["toe_out"])
    return pose, plants, style


def _hold_contacts(weight: np.ndarray, hand: str, part: str) -> list[HandContact]:
    """Contact runs where a hand goal is fully on (``weight`` = 1)."""
    return [HandContact(a, b, hand, part) for a, b in contact_runs(weight > 1 - 1e-9)]


# ----------------------------------------------------------------------------- locomotion
def _locomotion(rig: Rig, rng: np.random.Generator, t: np.ndarray, run: bool) -> Plan:
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
    go = window(t, t_lift, t_stop + ramp_len, ramp_len)
    kind = rng.choice(["straight", "curve", "turn"])
    rate = np.zeros(T)
    if kind == "curve":
        rate[:] = rng.choice([-1, 1]) * rng.uniform(8, 25)
    elif kind == "turn":
        a = rng.uniform(t_lift + ramp_len, max(t_lift + ramp_len + 0.1, t_stop - 2.0))
        span = rng.uniform(1.5, 3.0)
        peak = rng.choice([-1, 1]) * rng.uniform(45, 120)  # degrees turned in total
        rate = peak * window(t, a, a + span, 0.5 * span) / (0.5 * span)
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
    pose = Pose(T)
    sway = lead * rng.uniform(0.01, 0.025) * rig.scale * np.cos(phase) * go * (0.4 if run else 1.0)
    side_axis = np.stack((np.cos(heading), -np.sin(heading)), -1)
    pose.root[:, [0, 2]] = path + sway[:, None] * side_axis
    # pelvis lowest at mid-stance when running, highest when walking (inverted pendulum)
    bob = (-0.035 if run else 0.012) * L * np.cos(2 * phase) * go
    pose.root[:, 1] = L * (0.985 - (0.06 if run else 0.01) * go) + bob
    lean = (rng.uniform(6, 12) if run else rng.uniform(1, 5)) * go + 2 * (1 - go)
    pelvis_yaw = lead * rng.uniform(3, 7) * np.sin(phase) * go
    pose.pelvis(np.degrees(heading) + pelvis_yaw, lean * 0.5, -lead * 3.0 * np.cos(phase) * go)
    pose.spine(lean * 0.5 + noise(rng, t, 1.5), -1.4 * pelvis_yaw + noise(rng, t, 2.0),
               noise(rng, t, 1.0))
    pose.head(-0.4 * lean + noise(rng, t, 4.0, 0.3), 0.4 * pelvis_yaw + noise(rng, t, 8.0, 0.15))
    swing = style["arm_swing"] * go
    for side, sign in SIDES:
        fwd = sign * lead * swing * np.sin(phase) + (10 * go if run else 3)
        elbow = (rng.uniform(75, 95) * go + 15 * (1 - go)) if run else 12 + 0.5 * np.maximum(fwd, 0)
        down = min(rng.uniform(76, 82), rig.arm_down)
        pose.arm(side, sign, down, fwd, elbow + noise(rng, t, 4.0))
    return Plan(pose, feet, style=style)


def _gait_feet(rig: Rig, rng: np.random.Generator, t: np.ndarray, path: np.ndarray,
               heading: np.ndarray, go: np.ndarray, style: dict, run: bool,
               lead: float) -> tuple[Feet, float]:
    """Footsteps at a fixed cadence, each placed under the root path at its mid-stance time.

    The feet start side by side; the stance share (duty) blends from walking (0.62) to the style's
    value as the speed ramps up; the heel lifts over the last 30 % of each stance.

    Returns:
        the feet and the lead foot's first mid-stance time (the gait phase origin).
    """
    cycle, dur = style["cycle"], t[-1]
    toe_out = np.radians(style["toe_out"])
    plants = [[Plant(0.0, 0.0, np.array([sign * 0.9 * rig.hip_w, 0.0]), sign * toe_out)]
              for _, sign in SIDES]
    tau0 = t[np.argmax(go > 1e-3)] + 0.69 * cycle
    f = 0 if lead > 0 else 1
    for tau in np.arange(tau0, dur - 0.2, 0.5 * cycle):
        g = float(np.interp(tau, t, go))
        yaw = float(np.interp(tau, t, heading))
        sign = SIDES[f][1]
        xz = np.array([np.interp(tau, t, path[:, 0]), np.interp(tau, t, path[:, 1])])
        xz = xz + yaw_xz(yaw, np.array([sign * style["width"] * rig.hip_w, 0.0]))
        if g < 0.05 and np.linalg.norm(xz - plants[f][-1].xz) < 0.02 * rig.stand:
            break
        stance = (0.62 + (style["duty"] - 0.62) * g) * cycle
        if len(plants[f]) == 1:
            plants[f][0].t1 = max(tau - 0.5 * stance - (cycle - stance), 0.2)
        heel = (rng.uniform(25, 35) if run else rng.uniform(12, 22)) * g
        plants[f].append(Plant(tau - 0.5 * stance, tau + 0.5 * stance, xz, yaw + sign * toe_out,
                                0.3 * stance, heel))
        f = 1 - f
    for foot in plants:
        foot[-1].t1, foot[-1].pivot = dur + 1.0, 0.0
    lift = (rng.uniform(0.22, 0.32) if run else rng.uniform(0.08, 0.12)) * rig.stand
    return plan_feet(rig, t, plants, lift, land_pitch=5.0 if run else 12.0), tau0


def _walk(rig, rng, t):
    return _locomotion(rig, rng, t, run=False)


def _run(rig, rng, t):
    return _locomotion(rig, rng, t, run=True)


# ----------------------------------------------------------------------------- turning and jumping
def _turn(rig: Rig, rng: np.random.Generator, t: np.ndarray) -> Plan:
    """Turns on the spot by 60-180 degrees, stepping round with alternating feet."""
    pose, _, style = _standing(rig, rng, t)
    T, dur = len(t), t[-1]
    rate = rng.uniform(90, 150)
    angles: list[float] = []

    def length():
        angles.append(float(rng.choice([-1, 1]) * rng.uniform(60, 180)))
        return abs(angles[-1]) / rate + 0.6

    events = event_times(rng, dur, length, (0.6, 2.0), start=(0.3, 0.8))
    angles = angles[:len(events)]
    heading = np.zeros(T)
    toe_out = np.radians(style["toe_out"])
    plants = [[Plant(0.0, 0.0, np.array([sign * style["width"] * rig.hip_w, 0.0]), sign * toe_out)]
              for _, sign in SIDES]
    total = 0.0
    for (a, b), ang in zip(events, angles):
        heading += ang * ramp(t, a, b - 0.2)
        n_steps = int(np.ceil(abs(ang) / 50.0)) + 1
        first = 0 if ang > 0 else 1  # step first with the foot on the turning side
        swing = min(0.42, 0.85 * (b - a) / (n_steps - 0.15))  # one foot down before the next lifts
        for k in range(n_steps):
            f = first if k % 2 == 0 else 1 - first
            lift_off = a + k * (b - a - swing) / max(n_steps - 1, 1)
            progress = float(minjerk(np.array((lift_off + swing - a) / (b - a - 0.2))))
            yaw = np.radians(total + ang * progress)
            sign = SIDES[f][1]
            xz = yaw_xz(yaw, np.array([sign * style["width"] * rig.hip_w, 0.0]))
            plants[f][-1].t1 = lift_off
            plants[f].append(Plant(lift_off + swing, dur + 1.0, xz, yaw + sign * toe_out))
        total += ang
    for foot in plants:
        if len(foot) == 1:
            foot[0].t1 = dur + 1.0
    yaw_deg = heading + noise(rng, t, 2.0) * ramp(t, 0, 1)
    lead = np.interp(t + 0.25, t, heading) - heading  # the upper body leads the turn
    pose.pelvis(yaw_deg, 3.0, 0.0)
    pose.spine(3.0 + noise(rng, t, 1.5), 0.6 * lead, 0.0)
    pose.head(noise(rng, t, 3.0), 0.8 * lead, 0.0)
    style.update(angles=[round(x, 1) for x in angles], rate=rate)
    return Plan(pose, plan_feet(rig, t, plants, 0.06 * rig.stand), style=style)


def _jump(rig: Rig, rng: np.random.Generator, t: np.ndarray) -> Plan:
    """Two-footed jumps (in place or forward, sometimes turning): crouch with the arms back,
    push off onto the toes, ballistic flight with tucked legs, landing absorbed in the knees."""
    pose, _, style = _standing(rig, rng, t, width=rng.uniform(0.9, 1.3))
    T, dur, L, g = len(t), t[-1], rig.stand, 9.81
    toe_out = np.radians(style["toe_out"])
    root_y = pose.root[:, 1].copy()
    stand_y = style["knee"] * L
    heading = np.zeros(T)
    arm_fwd, spine_bend, elbow = np.full(T, 4.0), np.zeros(T), np.full(T, 15.0)
    plants = [[Plant(0.0, 0.0, np.array([sign * style["width"] * rig.hip_w, 0.0]), sign * toe_out)]
              for _, sign in SIDES]
    jumps = []

    def length():
        h = rng.uniform(0.12, 0.35) * L
        jumps.append({"h": h, "dist": rng.choice([0.0, rng.uniform(0.2, 0.8)]) * L,
                      "turn": rng.choice([0.0, 0.0, rng.choice([-1, 1]) * rng.uniform(30, 90)]),
                      "crouch": rng.uniform(0.15, 0.28) * L, "prep": rng.uniform(0.45, 0.7)})
        return jumps[-1]["prep"] + 2 * np.sqrt(2 * h / g) + 0.9

    events = event_times(rng, dur, length, (0.5, 1.8), start=(0.4, 0.9))
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
            root_y[m] += hermite(t[m], *s) - stand_y
        fl = (t > t_off) & (t < t_land)
        root_y[fl] += y_off + v * (t[fl] - t_off) - 0.5 * g * (t[fl] - t_off) ** 2 - stand_y
        move = ramp(t, t_off - 0.1, t_land + 0.1)
        yaw1 = yaw0 + np.radians(jp["turn"])
        x1 = x0 + yaw_xz(yaw0, np.array([0.0, jp["dist"]]))
        heading += jp["turn"] * move
        pose.root[:, [0, 2]] += move[:, None] * (x1 - x0)
        for f, (_, sign) in enumerate(SIDES):
            plants[f][-1].t1 = t_off
            plants[f][-1].pivot, plants[f][-1].pivot_deg = 0.35 * jp["prep"], rng.uniform(30, 45)
            xz = x1 + yaw_xz(yaw1, np.array([sign * style["width"] * rig.hip_w, 0.0]))
            plants[f].append(Plant(t_land, dur + 1.0, xz, yaw1 + sign * toe_out))
        arm_fwd += keyframes(t, [a, t_low, t_off, t_land, t_absorb + 0.2, b],
                             [0, -50, 150, 60, 35, 0])
        spine_bend += keyframes(t, [a, t_low, t_off, t_land, t_absorb, b], [0, 30, -4, 8, 25, 0])
        elbow += keyframes(t, [a, t_low, t_off, t_land, b], [0, 10, 0, 20, 0])
        x0, yaw0 = x1, yaw1
        jp.update(t_off=t_off, t_land=t_land, y_off=y_off)
    pose.root[:, 1] = root_y
    pose.pelvis(heading + noise(rng, t, 2.0) * ramp(t, 0, 1), 2.0 + 0.4 * spine_bend, 0.0)
    pose.spine(0.6 * spine_bend + noise(rng, t, 1.5), noise(rng, t, 2.0), 0.0)
    pose.head(-0.5 * spine_bend + noise(rng, t, 3.0), noise(rng, t, 5.0), 0.0)
    for side, sign in SIDES:
        down = style["arm_down"] - 0.1 * np.maximum(arm_fwd, 0)
        pose.arm(side, sign, down, arm_fwd + noise(rng, t, 3.0), elbow)
    feet = plan_feet(rig, t, plants, 0.0, land_pitch=-8.0)
    for jp in jumps[:len(events)]:  # in the air the feet travel with the hips, legs tucked
        fl = (t > jp["t_off"]) & (t < jp["t_land"])
        u = (t[fl] - jp["t_off"]) / (jp["t_land"] - jp["t_off"])
        rise = root_y[fl] - jp["y_off"] + 0.25 * jp["h"] * np.sin(np.pi * u)
        feet.ankle[fl, :, 1] += rise[:, None]
    style.update(jumps=len(events))
    return Plan(pose, feet, style=style)


# ----------------------------------------------------------------------------- hand gestures
def _gesture_weight(t: np.ndarray, events, rise: float) -> np.ndarray:
    """Eased on/off weight that is 1 during each event (minus its ramps) and 0 between them."""
    return np.max([window(t, a, b, rise) for a, b in events], axis=0)


def _wave(rig: Rig, rng: np.random.Generator, t: np.ndarray) -> Plan:
    """Waving hello with one raised hand swinging side to side about the elbow."""
    pose, plants, style = _standing(rig, rng, t)
    side = int(rng.integers(2))
    name, sign = SIDES[side]
    events = event_times(rng, t[-1], lambda: rng.uniform(1.8, 4.5), (0.8, 2.5))
    weight = _gesture_weight(t, events, 0.55)
    freq, amp = rng.uniform(1.5, 3.0), rng.uniform(0.12, 0.2) * rig.arm_reach
    height, out = rng.uniform(0.45, 0.65) * rig.arm_reach, rng.uniform(0.3, 0.45) * rig.arm_reach
    wagging = _gesture_weight(t, [(a + 0.4, b - 0.3) for a, b in events], 0.3)
    wag = amp * np.sin(2 * np.pi * freq * t) * wagging
    offset = np.stack((sign * out + wag, np.full_like(t, height),
                       np.full_like(t, 0.25 * rig.arm_reach)), -1)
    goal = HandGoal(side, lambda body: body.at(f"{name}Arm", offset, "Spine2"), weight,
                     np.array([sign * 0.6, -0.75, -0.1]))
    pose.head(noise(rng, t, 3.0), sign * 8.0 * weight + noise(rng, t, 5.0), sign * 4.0 * weight)
    style.update(hand=name, freq=freq, waves=len(events))
    return Plan(pose, plan_feet(rig, t, plants, 0.0), [goal], style=style)


def _clap(rig: Rig, rng: np.random.Generator, t: np.ndarray) -> Plan:
    """Rounds of clapping in front of the chest; the palms meet and touch for a few frames."""
    pose, plants, style = _standing(rig, rng, t)
    freq = rng.uniform(1.5, 3.0)
    events = event_times(rng, t[-1], lambda: int(rng.integers(3, 10)) / freq + 1.1, (0.7, 2.0))
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
    left, right = palm_targets(center, gap)
    hands = [HandGoal(0, left, weight, np.array([0.55, -0.75, -0.3]),
                       ((-1, 0, 0), (0, 0.5, 0.85))),
             HandGoal(1, right, weight, np.array([-0.55, -0.75, -0.3]),
                       ((1, 0, 0), (0, 0.5, 0.85)))]
    pose.head(6.0 * weight + noise(rng, t, 3.0), noise(rng, t, 6.0), 0.0)
    contacts = [HandContact(a, b, h, p) for a, b in contact_runs(contact & (weight > 1 - 1e-9))
                for h, p in (("LeftHand", "RightHand"), ("RightHand", "LeftHand"))]
    style.update(freq=freq, rounds=len(events))
    return Plan(pose, plan_feet(rig, t, plants, 0.0), hands, contacts, style)


def _pray(rig: Rig, rng: np.random.Generator, t: np.ndarray) -> Plan:
    """Palms pressed together in front of the sternum, often with a small bow."""
    pose, plants, style = _standing(rig, rng, t)
    events = event_times(rng, t[-1], lambda: rng.uniform(2.0, 6.0), (1.0, 2.5))
    weight = _gesture_weight(t, events, rng.uniform(0.5, 0.8))
    r, s = rig.radii, rig.scale
    bow = rng.uniform(0.0, 25.0) * _gesture_weight(t, [(a + 0.5, b - 0.5) for a, b in events], 0.6)
    pose.spine(2.0 + bow + noise(rng, t, 1.0), noise(rng, t, 2.0), 0.0)
    pose.head(0.6 * bow + 8.0 * weight + noise(rng, t, 2.0), noise(rng, t, 3.0), 0.0)
    drop = rng.uniform(-0.02, 0.08) * s
    depth = min(r["torso"] + rng.uniform(0.09, 0.15) * s, rig.front_reach(drop, 2 * r["hand"]))
    left, right = palm_targets(lambda body: body.at("Spine2", (0.0, -drop, depth)),
                                np.full_like(t, 2 * r["hand"]))
    hands = [HandGoal(0, left, weight, np.array([0.6, -0.8, -0.1]), ((-1, 0, 0), (0, 1, 0.35))),
             HandGoal(1, right, weight, np.array([-0.6, -0.8, -0.1]), ((1, 0, 0), (0, 1, 0.35)))]
    contacts = (_hold_contacts(weight, "LeftHand", "RightHand")
                + _hold_contacts(weight, "RightHand", "LeftHand"))
    style.update(holds=len(events))
    return Plan(pose, plan_feet(rig, t, plants, 0.0), hands, contacts, style)


def _hands_on_hips(rig: Rig, rng: np.random.Generator, t: np.ndarray) -> Plan:
    """Both hands resting on the sides of the pelvis while shifting weight and looking around."""
    pose, plants, style = _standing(rig, rng, t, width=rng.uniform(1.0, 1.6))
    events = event_times(rng, t[-1], lambda: rng.uniform(2.0, 7.0), (1.0, 2.5))
    weight = _gesture_weight(t, events, rng.uniform(0.5, 0.8))
    r, s = rig.radii, rig.scale
    crest, front = rng.uniform(0.03, 0.09) * s, rng.uniform(-0.02, 0.03) * s
    hands, contacts = [], []
    for f, (name, sign) in enumerate(SIDES):
        off = (sign * (r["hip"] + r["hand"]), crest, front)
        hands.append(HandGoal(f, lambda body, off=off: body.at("Hips", off), weight,
                               np.array([sign * 0.9, -0.1, -0.45]), ((-sign, 0, 0), (0, -0.4, 1))))
        contacts += _hold_contacts(weight, f"{name}Hand", f"{name}Hip")
    pose.head(noise(rng, t, 5.0), noise(rng, t, 20.0, 0.2), noise(rng, t, 4.0))
    style.update(holds=len(events))
    return Plan(pose, plan_feet(rig, t, plants, 0.0), hands, contacts, style)


def _touch_head(rig: Rig, rng: np.random.Generator, t: np.ndarray) -> Plan:
    """One or both hands on top of the head (patting/scratching), elbows out to the sides."""
    pose, plants, style = _standing(rig, rng, t)
    which = rng.choice(["left", "right", "both"])
    events = event_times(rng, t[-1], lambda: rng.uniform(1.5, 4.5), (1.0, 2.5))
    weight = _gesture_weight(t, events, rng.uniform(0.55, 0.8))
    r = rig.radii
    rub = np.radians(8.0) * np.sin(2 * np.pi * rng.uniform(1.0, 2.5) * t) * (which != "both")
    hands, contacts = [], []
    for f, (name, sign) in enumerate(SIDES):
        if which not in (name.lower(), "both"):
            continue
        lean = np.radians(25.0 if which == "both" else 5.0) * sign + rub
        direction = np.stack((np.sin(lean), np.cos(lean), np.full_like(t, 0.1)), -1)
        direction /= np.linalg.norm(direction, axis=-1, keepdims=True)
        center = np.array([0.0, 0.9 * r["head"], 0.15 * r["head"]])
        off = center + (r["head"] + r["hand"]) * direction
        hands.append(HandGoal(f, lambda body, off=off: body.at("Head", off), weight,
                               np.array([sign * 0.9, 0.2, 0.3]), ((0, -1, 0), (-sign * 0.6, 0, 0.8))))
        contacts += _hold_contacts(weight, f"{name}Hand", "HeadTop")
    pose.head(10.0 * weight + noise(rng, t, 3.0), noise(rng, t, 5.0), 0.0)
    style.update(hands=str(which), touches=len(events))
    return Plan(pose, plan_feet(rig, t, plants, 0.0), hands, contacts, style)


# ----------------------------------------------------------------------------- fighting, squats
def _fighting_stance(rig: Rig, rng: np.random.Generator, t: np.ndarray, lead: int):
    """Step from neutral into a staggered guard stance (``lead`` foot forward) in the first second.

    Returns ``(pose, plants, style, ready)`` where ``ready`` eases from 0 to 1 into the stance.
    """
    pose, plants, style = _standing(rig, rng, t, width=rng.uniform(1.1, 1.5),
                                    knee=rng.uniform(0.93, 0.96))
    rear = 1 - lead
    t_go = rng.uniform(0.3, 0.6)
    ready = ramp(t, t_go, t_go + 0.7)
    stagger = rng.uniform(0.3, 0.45) * rig.stand
    sign = SIDES[rear][1]
    old = plants[rear][0]
    back = old.xz + np.array([sign * 0.2 * rig.hip_w, -stagger])
    plants[rear] = [Plant(0.0, t_go, old.xz, old.yaw),
                    Plant(t_go + 0.4, t[-1] + 1.0, back, old.yaw + sign * np.radians(30))]
    turn = -SIDES[lead][1] * rng.uniform(15, 30)  # body turned towards the rear side
    pose.root[:, 2] -= 0.45 * stagger * ready
    bounce = 0.012 * rig.stand * np.sin(2 * np.pi * rng.uniform(1.5, 2.5) * t) * ready
    pose.root[:, 1] = (1 - ready * (1 - style["knee"] / 0.985)) * pose.root[:, 1] + bounce
    style.update(lead=SIDES[lead][0], stagger=stagger, turn=turn)
    return pose, plants, style, ready


def _punch(rig: Rig, rng: np.random.Generator, t: np.ndarray) -> Plan:
    """Boxing: guard at the chin, jab (lead hand) and cross (rear hand) combinations."""
    lead = int(rng.integers(2))
    pose, plants, style, ready = _fighting_stance(rig, rng, t, lead)
    events = event_times(rng, t[-1], lambda: rng.uniform(0.8, 2.0), (0.6, 1.8), start=(1.3, 1.8))
    extend = [np.zeros_like(t), np.zeros_like(t)]
    twist = np.zeros_like(t)
    for a, b in events:
        k, tp = int(rng.integers(2)), a
        while tp + 0.45 < b:
            hand = lead if k % 2 == 0 else 1 - lead
            out = rng.uniform(0.12, 0.18)
            shape = window(t, tp, tp + out + 0.27, out, 0.22)  # out, hold 0.05 s, back
            extend[hand] = np.maximum(extend[hand], shape)
            twist -= SIDES[hand][1] * rng.uniform(10, 22) * shape
            tp += out + 0.27 + rng.uniform(0.0, 0.15)
            k += 1
    base_turn = style["turn"] * ready
    pose.pelvis(base_turn + noise(rng, t, 2.0) * ready, 4.0 * ready, 0.0)
    pose.spine(6.0 * ready + noise(rng, t, 1.5), -0.6 * base_turn + twist, 0.0)
    pose.head(8.0 * ready, -0.4 * base_turn - 0.5 * twist, 0.0)
    hands = []
    reach = rng.uniform(0.9, 0.96) * rig.arm_reach
    for f, (name, sign) in enumerate(SIDES):
        guard = np.array([sign * 0.09, -0.04, 0.16]) * rig.scale
        aim = np.array([-sign * 0.12, 0.0, 1.0]) / np.linalg.norm([0.12, 0.0, 1.0])
        ext = extend[f][:, None]

        def target(body, guard=guard, aim=aim, ext=ext, name=name):
            g = body.at("Neck", guard, "Spine2")
            return g + ext * (body.at(f"{name}Arm", reach * aim, "Spine2") - g)

        hands.append(HandGoal(f, target, ready, np.array([sign * 0.45, -0.85, -0.2])))
    style.update(combos=len(events))
    return Plan(pose, plan_feet(rig, t, plants, 0.05 * rig.stand), hands, style=style)


def _kick(rig: Rig, rng: np.random.Generator, t: np.ndarray) -> Plan:
    """Front kicks: knee up (chamber), snap the foot out at hip height, re-chamber, step down."""
    lead = int(rng.integers(2))
    pose, plants, style, ready = _fighting_stance(rig, rng, t, lead)
    kicks = []
    events = event_times(rng, t[-1], lambda: rng.uniform(1.1, 1.6), (0.8, 2.0), start=(1.3, 1.8))
    lean = np.zeros_like(t)
    for a, b in events:
        f = 1 - lead if rng.uniform() < 0.7 else lead  # mostly the rear leg
        kicks.append((a, b, f, rng.uniform(-5, 30)))
        old = plants[f][-1]
        old.t1 = a
        plants[f].append(Plant(b, t[-1] + 1.0, old.xz, old.yaw))
        lean -= rng.uniform(8, 18) * keyframes(t, a + (b - a) * np.array([0, 0.35, 0.5, 1]),
                                               [0, 0.3, 1, 0])
    pose.pelvis(style["turn"] * ready, 3.0 * ready + 0.5 * lean, 0.0)
    pose.spine(5.0 * ready + 0.5 * lean, -0.6 * style["turn"] * ready, 0.0)
    pose.head(6.0 * ready - 0.6 * lean, -0.4 * style["turn"] * ready, 0.0)
    for side, sign in SIDES:
        down = 60.0 * ready + style["arm_down"] * (1 - ready)
        pose.arm(side, sign, down, 55.0 * ready, 15 + 95.0 * ready)
    feet = plan_feet(rig, t, plants, 0.06 * rig.stand)
    q = transfer_rotations(pose.q.numpy(), rig.ref, rig.skeleton)
    hips = fk(rig, q, pose.root)
    for a, b, f, elev in kicks:
        name = SIDES[f][0]
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
        rel = keyframes(t[m], a + (b - a) * np.array([0.0, 0.35, 0.5, 0.68, 1.0]), keys)
        feet.ankle[m, f] = hip + rel
        feet.ankle[m, f, 1] = np.maximum(feet.ankle[m, f, 1], rig.ankle_h[f])
        pitch = keyframes(t[m], a + (b - a) * np.array([0.0, 0.35, 0.5, 0.68, 1.0]),
                          [0, 20, 40, 20, 0])
        yaw = plants[f][-1].yaw * (1 - np.sin(np.pi * (t[m] - a) / (b - a)))  # toes to the target
        feet.rot[m, f] = foot_rot(yaw, pitch).numpy()
        feet.knee[m, f] = (fwd + up) / np.sqrt(2.0)  # knee up and forward
    style.update(kicks=len(kicks))
    return Plan(pose, feet, style=style)


def _squat(rig: Rig, rng: np.random.Generator, t: np.ndarray) -> Plan:
    """Repeated squats, feet wide and turned out, hips back, arms forward for balance."""
    pose, plants, style = _standing(rig, rng, t, width=rng.uniform(1.3, 1.9),
                                    toe_out=rng.uniform(12, 28))
    depth = np.zeros_like(t)
    events = event_times(rng, t[-1], lambda: rng.uniform(2.2, 4.0), (0.4, 1.8))
    for a, b in events:
        d = rng.uniform(0.25, 0.45)
        down, hold = rng.uniform(0.4, 0.5) * (b - a), rng.uniform(0.0, 0.15) * (b - a)
        depth = np.maximum(depth, d * keyframes(t, [a, a + down, a + down + hold, b], [0, 1, 1, 0]))
    L = rig.stand
    pose.root[:, 1] -= depth * L
    pose.root[:, 2] -= 0.4 * depth * L
    lean = 100.0 * depth
    pose.pelvis(noise(rng, t, 2.0) * ramp(t, 0, 1), 2.0 + 0.45 * lean, 0.0)
    pose.spine(2.0 + 0.55 * lean + noise(rng, t, 1.0), noise(rng, t, 2.0), 0.0)
    pose.head(-0.6 * lean + noise(rng, t, 3.0), noise(rng, t, 5.0), 0.0)
    raise_arms = rng.uniform(0.6, 1.0)
    for side, sign in SIDES:
        fwd = 4.0 + raise_arms * 220.0 * depth  # arms forward as the hips go back
        pose.arm(side, sign, style["arm_down"], fwd, 15.0 + 20.0 * depth)
    style.update(reps=len(events))
    return Plan(pose, plan_feet(rig, t, plants, 0.0), style=style)


# ----------------------------------------------------------------------------- public API
_FAMILY_FUNCS: dict[str, Callable[[Rig, np.random.Generator, np.ndarray], Plan]] = {
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
    rig = Rig(skeleton, {**default_body_radii(skeleton), **(body_radii or {})})
    plan = _FAMILY_FUNCS[family](rig, rng, t)
    return assemble(rig, plan, f"{family}_{seed:03d}", {"family": family, "seed": int(seed)})


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
