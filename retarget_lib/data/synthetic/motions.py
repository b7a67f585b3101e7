"""Synthetic motion library: keyframed and procedural human motion on any canonical-22 character.

Twelve families (:data:`MOTION_FAMILIES`): ``walk``, ``run``, ``jump``, ``turn``, ``wave``,
``clap``, ``hands_on_hips``, ``pray``, ``touch_head``, ``punch``, ``kick``, ``squat``. Each clip
is deterministic in ``(family, skeleton, seed)``; the seed draws the style (speed, stride,
amplitude, arm swing, stance width, timing, turning direction, small asymmetries and noise) and
the duration (2-40 s depending on the family), at 30 fps.

The clips are authored with :mod:`retarget_lib.data.synthetic.authoring` (canonical rest pose,
planted feet, real hand contacts; see there for how a clip is made), one function per family in
:mod:`retarget_lib.data.synthetic.families`.

``Motion.meta`` records what was used: ``family``, ``seed``, ``style``, ``body_radii``,
``foot_contacts`` ``(T, 2)`` bool (left, right foot flat on the ground and still),
``joint_contacts`` ``(T, 4)`` bool in :data:`~retarget_lib.core.skeleton.FOOT_CONTACT_JOINTS` order
(a toe stays planted while its heel lifts), and ``hand_contacts``: a list of :class:`HandContact`.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from ...core.motion import Motion
from ...core.skeleton import Skeleton
from .authoring import (
    FPS,
    HandContact,
    Plan,
    Rig,
    assemble,
    body_radii_from_mesh,
    default_body_radii,
)
from .families.fighting import kick, punch, squat
from .families.gestures import clap, hands_on_hips, pray, touch_head, wave
from .families.locomotion import jump, run, turn, walk

__all__ = [
    "FPS",
    "MOTION_FAMILIES",
    "DURATION_RANGES",
    "HandContact",
    "default_body_radii",
    "body_radii_from_mesh",
    "make_motion",
    "motion_library",
]

MOTION_FAMILIES: tuple[str, ...] = (
    "walk",
    "run",
    "jump",
    "turn",
    "wave",
    "clap",
    "hands_on_hips",
    "pray",
    "touch_head",
    "punch",
    "kick",
    "squat",
)
#: seconds: the duration of a clip is drawn uniformly from its family's range (all within 2-40 s)
DURATION_RANGES: dict[str, tuple[float, float]] = {
    "walk": (4.0, 20.0),
    "run": (4.0, 16.0),
    "jump": (3.0, 14.0),
    "turn": (3.0, 14.0),
    "wave": (3.0, 12.0),
    "clap": (2.0, 10.0),
    "hands_on_hips": (3.0, 14.0),
    "pray": (3.0, 12.0),
    "touch_head": (3.0, 12.0),
    "punch": (3.0, 16.0),
    "kick": (3.0, 16.0),
    "squat": (4.0, 40.0),
}

# ----------------------------------------------------------------------------- public API
_FAMILY_FUNCS: dict[str, Callable[[Rig, np.random.Generator, np.ndarray], Plan]] = {
    "walk": walk,
    "run": run,
    "jump": jump,
    "turn": turn,
    "wave": wave,
    "clap": clap,
    "hands_on_hips": hands_on_hips,
    "pray": pray,
    "touch_head": touch_head,
    "punch": punch,
    "kick": kick,
    "squat": squat,
}


def make_motion(
    family: str,
    skeleton: Skeleton,
    seed: int,
    duration: float | None = None,
    body_radii: dict[str, float] | None = None,
) -> Motion:
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


def motion_library(
    skeleton: Skeleton,
    seeds_per_family: int = 2,
    seed: int = 0,
    families: Sequence[str] = MOTION_FAMILIES,
    body_radii: dict[str, float] | None = None,
) -> list[Motion]:
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
    return [
        make_motion(f, skeleton, seed + k, body_radii=body_radii)
        for f in families
        for k in range(seeds_per_family)
    ]
