"""The idle stance every family starts from (feet planted, breathing, small weight shifts, looking
around, arms hanging), and the hand contacts of a goal held on."""

from __future__ import annotations

import numpy as np

from ..authoring import (
    SIDES,
    HandContact,
    Pose,
    Rig,
    contact_runs,
    noise,
    ramp,
    still_plants,
)

__all__ = ["hold_contacts", "standing"]


def standing(
    rig: Rig,
    rng: np.random.Generator,
    t: np.ndarray,
    width: float | None = None,
    toe_out: float | None = None,
    knee: float | None = None,
) -> tuple[Pose, list, dict]:
    """Idle standing: feet planted, breathing, small weight shifts, looking around, arms hanging.

    Returns the pose (root and every joint set), the plants and the style values drawn.
    """
    T, s = len(t), rig.scale
    style = {
        "width": width or rng.uniform(0.8, 1.4),
        "toe_out": toe_out or rng.uniform(4, 14),
        "knee": knee or rng.uniform(0.975, 0.99),
        "arm_down": min(rng.uniform(76, 84), rig.arm_down),
    }
    fade = ramp(t, 0.0, 1.0)  # frame 0 is neutral: root over the origin, facing +Z
    pose = Pose(T)
    pose.root[:, 0] = fade * noise(rng, t, 0.012 * s, 0.25)
    pose.root[:, 2] = fade * noise(rng, t, 0.008 * s, 0.25)
    pose.root[:, 1] = style["knee"] * rig.stand + noise(rng, t, 0.003 * s, 0.3)
    pose.pelvis(
        fade * noise(rng, t, 3.0, 0.2), 2.0 + noise(rng, t, 1.0), fade * noise(rng, t, 1.5, 0.25)
    )
    pose.spine(2.0 + noise(rng, t, 2.0, 0.3), noise(rng, t, 3.0, 0.2), noise(rng, t, 1.5, 0.25))
    pose.head(noise(rng, t, 4.0, 0.3), noise(rng, t, 10.0, 0.15), noise(rng, t, 3.0, 0.2))
    for side, sign in SIDES:
        pose.arm(
            side,
            sign,
            style["arm_down"] + noise(rng, t, 2.0, 0.3),
            4.0 + noise(rng, t, 4.0, 0.3),
            15.0 + noise(rng, t, 5.0, 0.3),
        )
    plants = still_plants(rig, t[-1], style["width"], style["toe_out"])
    return pose, plants, style


def hold_contacts(weight: np.ndarray, hand: str, part: str) -> list[HandContact]:
    """Contact runs where a hand goal is fully on (``weight`` = 1)."""
    return [HandContact(a, b, hand, part) for a, b in contact_runs(weight > 1 - 1e-9)]
