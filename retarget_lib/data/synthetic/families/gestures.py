"""Hand-gesture families from the idle stance: waving, clapping, praying (palms together), hands on
hips and touching the head, with real hand contacts."""

from __future__ import annotations

import numpy as np

from ..authoring import (
    FPS,
    SIDES,
    HandContact,
    HandGoal,
    Plan,
    Rig,
    contact_runs,
    event_times,
    noise,
    palm_targets,
    plan_feet,
    window,
)
from .standing import hold_contacts, standing

__all__ = ["clap", "hands_on_hips", "pray", "touch_head", "wave"]


def _gesture_weight(t: np.ndarray, events, rise: float) -> np.ndarray:
    """Eased on/off weight that is 1 during each event (minus its ramps) and 0 between them."""
    return np.max([window(t, a, b, rise) for a, b in events], axis=0)


def wave(rig: Rig, rng: np.random.Generator, t: np.ndarray) -> Plan:
    """Waving hello with one raised hand swinging side to side about the elbow."""
    pose, plants, style = standing(rig, rng, t)
    side = int(rng.integers(2))
    name, sign = SIDES[side]
    events = event_times(rng, t[-1], lambda: rng.uniform(1.8, 4.5), (0.8, 2.5))
    weight = _gesture_weight(t, events, 0.55)
    freq, amp = rng.uniform(1.5, 3.0), rng.uniform(0.12, 0.2) * rig.arm_reach
    height, out = rng.uniform(0.45, 0.65) * rig.arm_reach, rng.uniform(0.3, 0.45) * rig.arm_reach
    wagging = _gesture_weight(t, [(a + 0.4, b - 0.3) for a, b in events], 0.3)
    wag = amp * np.sin(2 * np.pi * freq * t) * wagging
    offset = np.stack(
        (sign * out + wag, np.full_like(t, height), np.full_like(t, 0.25 * rig.arm_reach)), -1
    )
    goal = HandGoal(
        side,
        lambda body: body.at(f"{name}Arm", offset, "Spine2"),
        weight,
        np.array([sign * 0.6, -0.75, -0.1]),
    )
    pose.head(noise(rng, t, 3.0), sign * 8.0 * weight + noise(rng, t, 5.0), sign * 4.0 * weight)
    style.update(hand=name, freq=freq, waves=len(events))
    return Plan(pose, plan_feet(rig, t, plants, 0.0), [goal], style=style)


def clap(rig: Rig, rng: np.random.Generator, t: np.ndarray) -> Plan:
    """Rounds of clapping in front of the chest; the palms meet and touch for a few frames."""
    pose, plants, style = standing(rig, rng, t)
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

    def center(body):
        return body.at("Spine2", (0.0, -drop, depth))

    left, right = palm_targets(center, gap)
    hands = [
        HandGoal(0, left, weight, np.array([0.55, -0.75, -0.3]), ((-1, 0, 0), (0, 0.5, 0.85))),
        HandGoal(1, right, weight, np.array([-0.55, -0.75, -0.3]), ((1, 0, 0), (0, 0.5, 0.85))),
    ]
    pose.head(6.0 * weight + noise(rng, t, 3.0), noise(rng, t, 6.0), 0.0)
    contacts = [
        HandContact(a, b, h, p)
        for a, b in contact_runs(contact & (weight > 1 - 1e-9))
        for h, p in (("LeftHand", "RightHand"), ("RightHand", "LeftHand"))
    ]
    style.update(freq=freq, rounds=len(events))
    return Plan(pose, plan_feet(rig, t, plants, 0.0), hands, contacts, style)


def pray(rig: Rig, rng: np.random.Generator, t: np.ndarray) -> Plan:
    """Palms pressed together in front of the sternum, often with a small bow."""
    pose, plants, style = standing(rig, rng, t)
    events = event_times(rng, t[-1], lambda: rng.uniform(2.0, 6.0), (1.0, 2.5))
    weight = _gesture_weight(t, events, rng.uniform(0.5, 0.8))
    r, s = rig.radii, rig.scale
    bow = rng.uniform(0.0, 25.0) * _gesture_weight(t, [(a + 0.5, b - 0.5) for a, b in events], 0.6)
    pose.spine(2.0 + bow + noise(rng, t, 1.0), noise(rng, t, 2.0), 0.0)
    pose.head(0.6 * bow + 8.0 * weight + noise(rng, t, 2.0), noise(rng, t, 3.0), 0.0)
    drop = rng.uniform(-0.02, 0.08) * s
    depth = min(r["torso"] + rng.uniform(0.09, 0.15) * s, rig.front_reach(drop, 2 * r["hand"]))
    left, right = palm_targets(
        lambda body: body.at("Spine2", (0.0, -drop, depth)), np.full_like(t, 2 * r["hand"])
    )
    hands = [
        HandGoal(0, left, weight, np.array([0.6, -0.8, -0.1]), ((-1, 0, 0), (0, 1, 0.35))),
        HandGoal(1, right, weight, np.array([-0.6, -0.8, -0.1]), ((1, 0, 0), (0, 1, 0.35))),
    ]
    contacts = hold_contacts(weight, "LeftHand", "RightHand") + hold_contacts(
        weight, "RightHand", "LeftHand"
    )
    style.update(holds=len(events))
    return Plan(pose, plan_feet(rig, t, plants, 0.0), hands, contacts, style)


def hands_on_hips(rig: Rig, rng: np.random.Generator, t: np.ndarray) -> Plan:
    """Both hands resting on the sides of the pelvis while shifting weight and looking around."""
    pose, plants, style = standing(rig, rng, t, width=rng.uniform(1.0, 1.6))
    events = event_times(rng, t[-1], lambda: rng.uniform(2.0, 7.0), (1.0, 2.5))
    weight = _gesture_weight(t, events, rng.uniform(0.5, 0.8))
    r, s = rig.radii, rig.scale
    crest, front = rng.uniform(0.03, 0.09) * s, rng.uniform(-0.02, 0.03) * s
    hands, contacts = [], []
    for f, (name, sign) in enumerate(SIDES):
        off = (sign * (r["hip"] + r["hand"]), crest, front)
        hands.append(
            HandGoal(
                f,
                lambda body, off=off: body.at("Hips", off),
                weight,
                np.array([sign * 0.9, -0.1, -0.45]),
                ((-sign, 0, 0), (0, -0.4, 1)),
            )
        )
        contacts += hold_contacts(weight, f"{name}Hand", f"{name}Hip")
    pose.head(noise(rng, t, 5.0), noise(rng, t, 20.0, 0.2), noise(rng, t, 4.0))
    style.update(holds=len(events))
    return Plan(pose, plan_feet(rig, t, plants, 0.0), hands, contacts, style)


def touch_head(rig: Rig, rng: np.random.Generator, t: np.ndarray) -> Plan:
    """One or both hands on top of the head (patting/scratching), elbows out to the sides."""
    pose, plants, style = standing(rig, rng, t)
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
        hands.append(
            HandGoal(
                f,
                lambda body, off=off: body.at("Head", off),
                weight,
                np.array([sign * 0.9, 0.2, 0.3]),
                ((0, -1, 0), (-sign * 0.6, 0, 0.8)),
            )
        )
        contacts += hold_contacts(weight, f"{name}Hand", "HeadTop")
    pose.head(10.0 * weight + noise(rng, t, 3.0), noise(rng, t, 5.0), 0.0)
    style.update(hands=str(which), touches=len(events))
    return Plan(pose, plan_feet(rig, t, plants, 0.0), hands, contacts, style)
