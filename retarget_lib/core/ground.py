"""The ground under a character and under a clip, and the rule that keeps feet on it.

Library convention: +Y is up and the floor is ``y = 0``. A character's *rest ground* and its
foot joints' rest heights above it are :func:`~retarget_lib.core.measures.rest_ground` and
:func:`~retarget_lib.core.measures.foot_rest_heights`. The *sole height* of a foot joint (heel
``*Foot`` or toe ``*ToeBase``) in a frame is its height minus its rest height above the rest
ground: a foot flat on the floor reads 0 at heel and toe (the convention of Villegas et al.
2021, Sec. 3.1.1, Efoot's heel and toe heights from the T-pose).

The Sec. 3.4 foot thresholds (3 cm, 1 cm per frame at 30 fps, at 180 cm) are defined here once:
:func:`standing_feet` and :func:`~retarget_lib.geometry.contacts.detect_foot_contacts` read them.

A clip's *floor* is where its feet touch (:func:`clip_floor`): a motion file's floor need not be
``y = 0``. The ground rule (:func:`floor_offset`): at every frame where a source foot joint stands
on the source's floor (near it and still, the thresholds of Sec. 3.4 at the character's scale),
the target's same joint is at the source's sole height times the target/source height ratio
above ``y = 0``; between such frames the vertical correction is interpolated, and before the first /
after the last it is held. A clip in which no foot is ever still (a run, a sprint: each foot
touches the floor only while it rolls) is held by the frames where a foot joint is at its floor
instead, moving or not (:func:`ground_contacts`). ``retarget retarget`` applies it to every
method's result.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .measures import foot_rest_heights
from .skeleton import FOOT_CONTACT_JOINTS, Skeleton

__all__ = [
    "FOOT_JOINTS",
    "STAND_BAND_M",
    "STILL_STEP_M",
    "REFERENCE_HEIGHT_M",
    "REFERENCE_FPS",
    "foot_positions",
    "sole_heights",
    "clip_floor",
    "standing_feet",
    "touching_feet",
    "ground_contacts",
    "floor_offset",
    "ClipGround",
    "clip_ground",
]

#: the foot joints the ground rule reads: heels then toes (left, right)
FOOT_JOINTS: tuple[str, ...] = FOOT_CONTACT_JOINTS
#: the standing height at which the thresholds below hold (Villegas et al. 2021, Sec. 3.4: "180 cm")
REFERENCE_HEIGHT_M = 1.80
#: a foot joint within this height of its sole above the floor may stand (Sec. 3.4's 3 cm toe band)
STAND_BAND_M = 0.03
#: ... and moves at most this far per frame at 30 fps (Sec. 3.4's 1 cm, i.e. 0.3 m/s)
STILL_STEP_M = 0.01
#: the frame rate at which :data:`STILL_STEP_M` holds (Mixamo's clips)
REFERENCE_FPS = 30.0
#: the percentile of the per-frame lowest sole height that is a clip's floor: the lowest few
#: frames (a foot pushed through the floor for a moment, a noisy marker) do not set it
FLOOR_PERCENTILE = 5.0


def foot_positions(positions: np.ndarray, skeleton: Skeleton) -> np.ndarray:
    """``(T, 4, 3)`` the :data:`FOOT_JOINTS` of ``(T, J, 3)`` positions in ``skeleton``'s order."""
    return np.asarray(positions)[:, [skeleton.index(n) for n in FOOT_JOINTS]]


def sole_heights(
    positions: np.ndarray, skeleton: Skeleton, rest_vertices: np.ndarray | None = None
) -> np.ndarray:
    """``(T, 4)`` height of each foot joint's sole above ``y = 0`` (metres, :data:`FOOT_JOINTS`
    order).

    Args:
        positions: ``(T, 22, 3)`` global joint positions (metres, +Y up).
        skeleton: their canonical-22 skeleton.
        rest_vertices: the character's rest mesh, if any
            (:func:`~retarget_lib.core.measures.foot_rest_heights`).
    """
    return foot_positions(positions, skeleton)[..., 1] - foot_rest_heights(skeleton, rest_vertices)


def clip_floor(soles: np.ndarray) -> float:
    """A clip's floor height (metres): the :data:`FLOOR_PERCENTILE` percentile over frames of the
    lowest sole height (:func:`sole_heights`) in each frame.

    Args:
        soles: ``(T, 4)`` sole heights.
    """
    return float(np.percentile(np.asarray(soles).min(axis=1), FLOOR_PERCENTILE))


def standing_feet(
    feet: np.ndarray, soles: np.ndarray, floor: float, height: float, fps: float
) -> np.ndarray:
    """``(T, 4)`` bool: where each foot joint stands on the floor.

    Sec. 3.4's toe rule for every foot joint: at most :data:`STAND_BAND_M` above the floor and at
    most :data:`STILL_STEP_M` of 3-D movement since the previous frame, both at 180 cm scale
    (times ``height / 1.80``) and at 30 fps (the step times ``30 / fps``); frame 0 takes its step
    to frame 1.

    Args:
        feet: ``(T, 4, 3)`` global positions of the :data:`FOOT_JOINTS` (metres).
        soles: ``(T, 4)`` their sole heights (:func:`sole_heights`), metres.
        floor: the clip's floor (:func:`clip_floor`), metres.
        height: the character's height (metres), the scale of the thresholds; the ground rule
            (:func:`retarget_lib.methods.retarget.on_the_ground`) and the real table pass the
            NKN height ``H`` (:meth:`~retarget_lib.core.skeleton.Skeleton.height`), not the
            standing height of :func:`~retarget_lib.geometry.contacts.detect_foot_contacts`.
        fps: the clip's frame rate.
    """
    scale = height / REFERENCE_HEIGHT_M
    low = touching_feet(soles, floor, height)
    if len(low) < 2:
        return low
    step = np.linalg.norm(np.diff(np.asarray(feet, dtype=np.float64), axis=0), axis=-1)
    step = np.concatenate([step[:1], step])
    return low & (step <= STILL_STEP_M * scale * REFERENCE_FPS / fps)


def touching_feet(soles: np.ndarray, floor: float, height: float) -> np.ndarray:
    """``(T, 4)`` bool: where each foot joint is at the floor, still or not: the height half of
    :func:`standing_feet` (at most :data:`STAND_BAND_M` above ``floor`` at 180 cm scale).

    Args:
        soles: ``(T, 4)`` sole heights (:func:`sole_heights`), metres.
        floor: the clip's floor (:func:`clip_floor`), metres.
        height: the character's height (metres), the scale of the band.
    """
    return np.asarray(soles, dtype=np.float64) - floor <= STAND_BAND_M * height / REFERENCE_HEIGHT_M


def ground_contacts(
    feet: np.ndarray, soles: np.ndarray, floor: float, height: float, fps: float
) -> np.ndarray:
    """``(T, 4)`` bool: the foot joints the ground rule holds on the floor.

    The standing ones (:func:`standing_feet`); in a clip where no foot joint ever stands (a run:
    every foot on the floor still rolls faster than Sec. 3.4's 1 cm a frame), the touching ones
    (:func:`touching_feet`), so that a run's feet meet the target's floor as they meet the
    source's. Arguments as :func:`standing_feet`.
    """
    standing = standing_feet(feet, soles, floor, height, fps)
    return standing if standing.any() else touching_feet(soles, floor, height)


@dataclass(frozen=True)
class ClipGround:
    """Where a clip's feet meet its floor (:func:`clip_ground`).

    Attributes:
        soles: ``(T, 4)`` sole heights (:func:`sole_heights`), metres.
        floor: the clip's floor (:func:`clip_floor`), metres.
        standing: ``(T, 4)`` bool, the foot joints standing on it (:func:`standing_feet`).
        contacts: ``(T, 4)`` bool, the ones the ground rule holds (:func:`ground_contacts`).
    """

    soles: np.ndarray
    floor: float
    standing: np.ndarray
    contacts: np.ndarray


def clip_ground(
    positions: np.ndarray,
    skeleton: Skeleton,
    fps: float,
    rest_vertices: np.ndarray | None = None,
) -> ClipGround:
    """A clip's soles, floor, standing and held foot joints, its thresholds at the skeleton's
    height ``H``: what the ground rule, the posture check and the real table read of a source.

    Args:
        positions: ``(T, 22, 3)`` global joint positions (metres, +Y up).
        skeleton: their canonical-22 skeleton.
        fps: the clip's frame rate.
        rest_vertices: the performer's rest mesh, if any (its soles).
    """
    soles = sole_heights(positions, skeleton, rest_vertices)
    floor = clip_floor(soles)
    feet = foot_positions(positions, skeleton)
    height = skeleton.height()
    return ClipGround(
        soles,
        floor,
        standing_feet(feet, soles, floor, height, fps),
        ground_contacts(feet, soles, floor, height, fps),
    )


def floor_offset(
    target_soles: np.ndarray,
    source_soles: np.ndarray,
    source_floor: float,
    standing: np.ndarray,
    ratio: float,
) -> np.ndarray:
    """``(T,)`` vertical shift of the target's root that keeps its feet on ``y = 0`` where the
    source's stand (the module's ground rule).

    At a frame where source joints stand, the shift lifts or lowers the target so that none of
    those joints is below the source's sole height above its floor times ``ratio`` and the lowest
    is exactly there; between such frames it is interpolated linearly, before the first and after
    the last it is held. A clip whose feet never stand gets no shift.

    Args:
        target_soles: ``(T, 4)`` the result's sole heights above ``y = 0`` (metres).
        source_soles: ``(T, 4)`` the source's sole heights (metres, in the source's frame).
        source_floor: the source clip's floor (:func:`clip_floor`), metres.
        standing: ``(T, 4)`` bool, :func:`ground_contacts` of the source.
        ratio: target height / source height (a source sole 1 cm above its floor is ``ratio`` cm
            above the target's).
    """
    standing = np.asarray(standing, dtype=bool)
    wanted = (np.asarray(source_soles) - source_floor) * ratio
    need = np.where(standing, wanted - np.asarray(target_soles), -np.inf).max(axis=1)  # (T,)
    frames = np.flatnonzero(standing.any(axis=1))
    if len(frames) == 0:
        return np.zeros(len(standing))
    return np.interp(np.arange(len(standing)), frames, need[frames])
