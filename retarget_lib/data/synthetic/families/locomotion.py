"""Locomotion families: walking and running along straight, curved or turning paths, turning on
the spot, and jumping, each starting and ending at rest."""

from __future__ import annotations

import numpy as np

from ..authoring import (
    FPS,
    SIDES,
    Feet,
    Plan,
    Plant,
    Pose,
    Rig,
    event_times,
    hermite,
    keyframes,
    minjerk,
    noise,
    plan_feet,
    ramp,
    window,
    yaw_xz,
)
from .standing import standing

__all__ = ["jump", "run", "turn", "walk"]


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
    style = {
        "speed": speed,
        "cycle": cycle,
        "step": step,
        "duty": duty,
        "path": str(kind),
        "lead": "left" if lead > 0 else "right",
        "width": rng.uniform(0.35, 0.8),
        "toe_out": rng.uniform(3, 12),
        "arm_swing": rng.uniform(15, 32) * (1.5 if run else 1.0),
    }
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
    pose.spine(
        lean * 0.5 + noise(rng, t, 1.5), -1.4 * pelvis_yaw + noise(rng, t, 2.0), noise(rng, t, 1.0)
    )
    pose.head(-0.4 * lean + noise(rng, t, 4.0, 0.3), 0.4 * pelvis_yaw + noise(rng, t, 8.0, 0.15))
    swing = style["arm_swing"] * go
    for side, sign in SIDES:
        fwd = sign * lead * swing * np.sin(phase) + (10 * go if run else 3)
        elbow = (rng.uniform(75, 95) * go + 15 * (1 - go)) if run else 12 + 0.5 * np.maximum(fwd, 0)
        down = min(rng.uniform(76, 82), rig.arm_down)
        pose.arm(side, sign, down, fwd, elbow + noise(rng, t, 4.0))
    return Plan(pose, feet, style=style)


def _gait_feet(
    rig: Rig,
    rng: np.random.Generator,
    t: np.ndarray,
    path: np.ndarray,
    heading: np.ndarray,
    go: np.ndarray,
    style: dict,
    run: bool,
    lead: float,
) -> tuple[Feet, float]:
    """Footsteps at a fixed cadence, each placed under the root path at its mid-stance time.

    The feet start side by side; the stance share (duty) blends from walking (0.62) to the style's
    value as the speed ramps up; the heel lifts over the last 30 % of each stance.

    Returns:
        the feet and the lead foot's first mid-stance time (the gait phase origin).
    """
    cycle, dur = style["cycle"], t[-1]
    toe_out = np.radians(style["toe_out"])
    plants = [
        [Plant(0.0, 0.0, np.array([sign * 0.9 * rig.stance_w, 0.0]), sign * toe_out)]
        for _, sign in SIDES
    ]
    tau0 = t[np.argmax(go > 1e-3)] + 0.69 * cycle
    f = 0 if lead > 0 else 1
    for tau in np.arange(tau0, dur - 0.2, 0.5 * cycle):
        g = float(np.interp(tau, t, go))
        yaw = float(np.interp(tau, t, heading))
        sign = SIDES[f][1]
        xz = np.array([np.interp(tau, t, path[:, 0]), np.interp(tau, t, path[:, 1])])
        xz = xz + yaw_xz(yaw, np.array([sign * style["width"] * rig.stance_w, 0.0]))
        if g < 0.05 and np.linalg.norm(xz - plants[f][-1].xz) < 0.02 * rig.stand:
            break
        stance = (0.62 + (style["duty"] - 0.62) * g) * cycle
        if len(plants[f]) == 1:
            plants[f][0].t1 = max(tau - 0.5 * stance - (cycle - stance), 0.2)
        heel = (rng.uniform(25, 35) if run else rng.uniform(12, 22)) * g
        plants[f].append(
            Plant(
                tau - 0.5 * stance, tau + 0.5 * stance, xz, yaw + sign * toe_out, 0.3 * stance, heel
            )
        )
        f = 1 - f
    for foot in plants:
        foot[-1].t1, foot[-1].pivot = dur + 1.0, 0.0
    lift = (rng.uniform(0.22, 0.32) if run else rng.uniform(0.08, 0.12)) * rig.stand
    return plan_feet(rig, t, plants, lift, land_pitch=5.0 if run else 12.0), tau0


def walk(rig, rng, t):
    return _locomotion(rig, rng, t, run=False)


def run(rig, rng, t):
    return _locomotion(rig, rng, t, run=True)


# ----------------------------------------------------------------------------- turning and jumping
def turn(rig: Rig, rng: np.random.Generator, t: np.ndarray) -> Plan:
    """Turns on the spot by 60-180 degrees, stepping round with alternating feet."""
    pose, _, style = standing(rig, rng, t)
    T, dur = len(t), t[-1]
    rate = rng.uniform(90, 150)
    angles: list[float] = []

    def length():
        angles.append(float(rng.choice([-1, 1]) * rng.uniform(60, 180)))
        return abs(angles[-1]) / rate + 0.6

    events = event_times(rng, dur, length, (0.6, 2.0), start=(0.3, 0.8))
    angles = angles[: len(events)]
    heading = np.zeros(T)
    toe_out = np.radians(style["toe_out"])
    plants = [
        [Plant(0.0, 0.0, np.array([sign * style["width"] * rig.stance_w, 0.0]), sign * toe_out)]
        for _, sign in SIDES
    ]
    total = 0.0
    for (a, b), ang in zip(events, angles, strict=False):
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
            xz = yaw_xz(yaw, np.array([sign * style["width"] * rig.stance_w, 0.0]))
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


def jump(rig: Rig, rng: np.random.Generator, t: np.ndarray) -> Plan:
    """Two-footed jumps (in place or forward, sometimes turning): crouch with the arms back,
    push off onto the toes, ballistic flight with tucked legs, landing absorbed in the knees."""
    pose, _, style = standing(rig, rng, t, width=rng.uniform(0.9, 1.3))
    T, dur, L, g = len(t), t[-1], rig.stand, 9.81
    toe_out = np.radians(style["toe_out"])
    root_y = pose.root[:, 1].copy()
    stand_y = style["knee"] * L
    heading = np.zeros(T)
    arm_fwd, spine_bend, elbow = np.full(T, 4.0), np.zeros(T), np.full(T, 15.0)
    plants = [
        [Plant(0.0, 0.0, np.array([sign * style["width"] * rig.stance_w, 0.0]), sign * toe_out)]
        for _, sign in SIDES
    ]
    jumps = []

    def length():
        h = rng.uniform(0.12, 0.35) * L
        jumps.append(
            {
                "h": h,
                "dist": rng.choice([0.0, rng.uniform(0.2, 0.8)]) * L,
                "turn": rng.choice([0.0, 0.0, rng.choice([-1, 1]) * rng.uniform(30, 90)]),
                "crouch": rng.uniform(0.15, 0.28) * L,
                "prep": rng.uniform(0.45, 0.7),
            }
        )
        return jumps[-1]["prep"] + 2 * np.sqrt(2 * h / g) + 0.9

    events = event_times(rng, dur, length, (0.5, 1.8), start=(0.4, 0.9))
    x0, yaw0 = np.zeros(2), 0.0
    for (a, b), jp in zip(events, jumps, strict=False):
        v = np.sqrt(2 * jp["h"] / g) * g
        t_low, t_off = a + 0.6 * jp["prep"], a + jp["prep"]
        t_land = t_off + 2 * v / g
        t_absorb, t_up = t_land + 0.25, b
        y_off = stand_y + 0.03 * L
        seg = [
            (a, t_low, stand_y, stand_y - jp["crouch"], 0.0, 0.0),
            (t_low, t_off, stand_y - jp["crouch"], y_off, 0.0, v),
            (t_land, t_absorb, y_off, stand_y - 0.8 * jp["crouch"], -v, 0.0),
            (t_absorb, t_up, stand_y - 0.8 * jp["crouch"], stand_y, 0.0, 0.0),
        ]
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
            xz = x1 + yaw_xz(yaw1, np.array([sign * style["width"] * rig.stance_w, 0.0]))
            plants[f].append(Plant(t_land, dur + 1.0, xz, yaw1 + sign * toe_out))
        arm_fwd += keyframes(
            t, [a, t_low, t_off, t_land, t_absorb + 0.2, b], [0, -50, 150, 60, 35, 0]
        )
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
    for jp in jumps[: len(events)]:  # in the air the feet travel with the hips, legs tucked
        fl = (t > jp["t_off"]) & (t < jp["t_land"])
        u = (t[fl] - jp["t_off"]) / (jp["t_land"] - jp["t_off"])
        rise = root_y[fl] - jp["y_off"] + 0.25 * jp["h"] * np.sin(np.pi * u)
        feet.ankle[fl, :, 1] += rise[:, None]
    style.update(jumps=len(events))
    return Plan(pose, feet, style=style)
