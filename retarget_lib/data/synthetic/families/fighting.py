"""Fighting and squatting families: punches and kicks from a staggered guard stance, and repeated
squats."""

from __future__ import annotations

import numpy as np

from ....core.skeleton import J
from ....core.transfer import transfer_rotations
from ..authoring import (
    SIDES,
    HandGoal,
    Plan,
    Plant,
    Rig,
    event_times,
    fk,
    foot_rot,
    keyframes,
    noise,
    plan_feet,
    ramp,
    window,
)
from .standing import standing

__all__ = ["kick", "punch", "squat"]


def _fighting_stance(rig: Rig, rng: np.random.Generator, t: np.ndarray, lead: int):
    """Step from neutral into a staggered guard stance (``lead`` foot forward) in the first second.

    Returns ``(pose, plants, style, ready)`` where ``ready`` eases from 0 to 1 into the stance.
    """
    pose, plants, style = standing(
        rig, rng, t, width=rng.uniform(1.1, 1.5), knee=rng.uniform(0.93, 0.96)
    )
    rear = 1 - lead
    t_go = rng.uniform(0.3, 0.6)
    ready = ramp(t, t_go, t_go + 0.7)
    stagger = rng.uniform(0.3, 0.45) * rig.stand
    sign = SIDES[rear][1]
    old = plants[rear][0]
    back = old.xz + np.array([sign * 0.2 * rig.hip_w, -stagger])
    plants[rear] = [
        Plant(0.0, t_go, old.xz, old.yaw),
        Plant(t_go + 0.4, t[-1] + 1.0, back, old.yaw + sign * np.radians(30)),
    ]
    turn = -SIDES[lead][1] * rng.uniform(15, 30)  # body turned towards the rear side
    pose.root[:, 2] -= 0.45 * stagger * ready
    bounce = 0.012 * rig.stand * np.sin(2 * np.pi * rng.uniform(1.5, 2.5) * t) * ready
    pose.root[:, 1] = (1 - ready * (1 - style["knee"] / 0.985)) * pose.root[:, 1] + bounce
    style.update(lead=SIDES[lead][0], stagger=stagger, turn=turn)
    return pose, plants, style, ready


def punch(rig: Rig, rng: np.random.Generator, t: np.ndarray) -> Plan:
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


def kick(rig: Rig, rng: np.random.Generator, t: np.ndarray) -> Plan:
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
        lean -= rng.uniform(8, 18) * keyframes(
            t, a + (b - a) * np.array([0, 0.35, 0.5, 1]), [0, 0.3, 1, 0]
        )
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
        keys = [
            start,
            0.75 * l1 * fwd - 0.6 * l2 * up + 0.3 * l1 * up,
            0.96 * (l1 + l2) * (np.cos(e) * fwd + np.sin(e) * up),
            0.75 * l1 * fwd - 0.6 * l2 * up + 0.3 * l1 * up,
            start,
        ]
        rel = keyframes(t[m], a + (b - a) * np.array([0.0, 0.35, 0.5, 0.68, 1.0]), keys)
        feet.ankle[m, f] = hip + rel
        feet.ankle[m, f, 1] = np.maximum(feet.ankle[m, f, 1], rig.ankle_h[f])
        pitch = keyframes(
            t[m], a + (b - a) * np.array([0.0, 0.35, 0.5, 0.68, 1.0]), [0, 20, 40, 20, 0]
        )
        yaw = plants[f][-1].yaw * (1 - np.sin(np.pi * (t[m] - a) / (b - a)))  # toes to the target
        feet.rot[m, f] = foot_rot(yaw, pitch).numpy()
        feet.knee[m, f] = (fwd + up) / np.sqrt(2.0)  # knee up and forward
    style.update(kicks=len(kicks))
    return Plan(pose, feet, style=style)


def squat(rig: Rig, rng: np.random.Generator, t: np.ndarray) -> Plan:
    """Repeated squats, feet wide and turned out, hips back, arms forward for balance."""
    pose, plants, style = standing(
        rig, rng, t, width=rng.uniform(1.3, 1.9), toe_out=rng.uniform(12, 28)
    )
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
