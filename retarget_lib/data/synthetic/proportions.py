"""The parameters of a synthetic character (:class:`CharacterSpec`) and the skeleton they give: a
reference skeleton stretched segment by segment, posed in its rest pose through the offsets'
directions, and the factor that scales it to the spec's height (step 1 of
:mod:`retarget_lib.data.synthetic.characters`).

Conventions: metres, +Y up, facing +Z, the character's left at +X.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ...core.skeleton import J, canonical22_skeleton

__all__ = [
    "REFERENCE_LENGTHS",
    "REFERENCE_OFFSETS",
    "CharacterSpec",
    "height_scale",
    "unscaled_offsets",
]


@dataclass(frozen=True)
class CharacterSpec:
    """Parameters of one synthetic character. Length factors multiply the reference skeleton's
    segments (before the whole skeleton is scaled to ``height``) and must lie in 0.6-1.5.

    Attributes:
        name: identifier.
        height: target NKN height ``H`` in metres (1.2-2.1).
        torso: Hips->Spine->Spine1->Spine2->Neck lengths.
        neck: Neck->Head length.
        head: head size (geometry only).
        thigh: UpLeg->Leg length.
        shin: Leg->Foot length.
        foot: foot size (Foot->ToeBase offset and foot geometry).
        hips: hip joint spacing.
        shoulders: clavicle lengths (shoulder width).
        upper_arm: Arm->ForeArm length.
        forearm: ForeArm->Hand length.
        hand: hand size (geometry only).
        arm_angle: arms below horizontal in degrees (0 = T-pose, 30-50 = A-pose).
        arm_forward: arms swept forward (towards +Z) in degrees.
        spine_curve: total forward bend of the spine-neck-head chain in degrees (negative = back).
        knee_bend: rest knee flexion in degrees.
        feet_out: toes turned outwards in degrees.
        forearm_droop: forearm below the upper arm's direction in degrees (a T-pose bind's shape:
            Mixamo's forearms droop about 6 degrees).
        toe_slope: the ankle -> toe bone below the horizontal in degrees, its length kept
            (``None``: the reference foot's 21 degrees); at most 30 keeps the toe joint above the
            sole.
        bulk: overall girth (0.7 skinny - 1.6 bulky).
        belly: belly size (0 = none, 1 = large).
        chest: chest breadth and depth factor.
        limbs: limb thickness factor on top of ``bulk``.
    """

    name: str
    height: float
    torso: float = 1.0
    neck: float = 1.0
    head: float = 1.0
    thigh: float = 1.0
    shin: float = 1.0
    foot: float = 1.0
    hips: float = 1.0
    shoulders: float = 1.0
    upper_arm: float = 1.0
    forearm: float = 1.0
    hand: float = 1.0
    arm_angle: float = 0.0
    arm_forward: float = 0.0
    spine_curve: float = 0.0
    knee_bend: float = 0.0
    feet_out: float = 0.0
    forearm_droop: float = 0.0
    toe_slope: float | None = None
    bulk: float = 1.0
    belly: float = 0.0
    chest: float = 1.0
    limbs: float = 1.0

    #: the fields that are segment length / size factors
    FACTORS = (
        "torso",
        "neck",
        "head",
        "thigh",
        "shin",
        "foot",
        "hips",
        "shoulders",
        "upper_arm",
        "forearm",
        "hand",
    )


#: reference segment lengths (metres, before scaling), giving NKN H = 1.559 m
REFERENCE_LENGTHS = dict(
    spine=0.10,
    spine1=0.12,
    spine2=0.12,
    neck_base=0.16,
    neck=0.10,
    thigh=0.42,
    shin=0.40,
    toe_drop=0.05,
    toe_fwd=0.13,
    hip_x=0.09,
    hip_drop=0.07,
    clavicle_x=0.045,
    arm=0.11,
    upper_arm=0.27,
    forearm=0.25,
    ankle_height=0.08,
)


def _rot_x(v: np.ndarray, deg: float) -> np.ndarray:
    """Rotate ``v`` about +X by ``deg`` (positive tips +Y towards +Z)."""
    a = math.radians(deg)
    return np.array(
        [v[0], v[1] * math.cos(a) - v[2] * math.sin(a), v[1] * math.sin(a) + v[2] * math.cos(a)]
    )


def _mirror(v: np.ndarray) -> np.ndarray:
    return v * np.array([-1.0, 1.0, 1.0])


def unscaled_offsets(spec: CharacterSpec) -> np.ndarray:
    """``(22, 3)`` rest offsets before scaling (root row zero), pose encoded in directions."""
    r = REFERENCE_LENGTHS
    off = np.zeros((22, 3))
    up = np.array([0.0, 1.0, 0.0])
    chain = (
        ("Spine", r["spine"] * spec.torso),
        ("Spine1", r["spine1"] * spec.torso),
        ("Spine2", r["spine2"] * spec.torso),
        ("Neck", r["neck_base"] * spec.torso),
        ("Head", r["neck"] * spec.neck),
    )
    for k, (name, length) in enumerate(chain, start=1):  # uniform bend along the chain
        off[J[name]] = _rot_x(up * length, spec.spine_curve * k / len(chain))
    knee = math.radians(spec.knee_bend)
    thigh = r["thigh"] * spec.thigh * np.array([0.0, -math.cos(knee), math.sin(knee)])
    shin = r["shin"] * spec.shin * np.array([0.0, -math.cos(knee), -math.sin(knee)])
    out = math.radians(spec.feet_out)
    toe_fwd, toe_drop = r["toe_fwd"], r["toe_drop"]
    if spec.toe_slope is not None:
        slope, length = math.radians(spec.toe_slope), math.hypot(toe_fwd, toe_drop)
        toe_fwd, toe_drop = length * math.cos(slope), length * math.sin(slope)
    toe = spec.foot * np.array([toe_fwd * math.sin(out), -toe_drop, toe_fwd * math.cos(out)])

    def arm_direction(down_deg: float) -> np.ndarray:
        a, f = math.radians(down_deg), math.radians(spec.arm_forward)
        return np.array([math.cos(a) * math.cos(f), -math.sin(a), math.cos(a) * math.sin(f)])

    a = math.radians(spec.arm_angle)
    arm_dir = arm_direction(spec.arm_angle)
    a_clav = 0.25 * a  # the clavicle follows the arm a little
    clav_dir = np.array([math.cos(a_clav), -math.sin(a_clav), 0.0])
    shoulder = 0.7 * off[J["Neck"]] + np.array([r["clavicle_x"] * spec.shoulders, 0.0, 0.0])
    left = {
        "UpLeg": np.array([r["hip_x"] * spec.hips, -r["hip_drop"], 0.0]),
        "Leg": thigh,
        "Foot": shin,
        "ToeBase": toe,
        "Shoulder": shoulder,
        "Arm": clav_dir * r["arm"] * spec.shoulders,
        "ForeArm": arm_dir * r["upper_arm"] * spec.upper_arm,
        "Hand": arm_direction(spec.arm_angle + spec.forearm_droop) * r["forearm"] * spec.forearm,
    }
    for part, v in left.items():
        off[J["Left" + part]] = v
        off[J["Right" + part]] = _mirror(v)
    return off


#: ``(22, 3)`` offsets of the reference skeleton (all factors 1, T-pose) before scaling; root row 0
REFERENCE_OFFSETS: np.ndarray = unscaled_offsets(CharacterSpec("reference", height=1.0))


def height_scale(spec: CharacterSpec) -> float:
    """Factor taking the unscaled skeleton to NKN height ``spec.height``."""
    return spec.height / canonical22_skeleton(unscaled_offsets(spec)).height()
