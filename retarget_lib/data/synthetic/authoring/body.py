"""The character an author writes for: :class:`Rig` (the character and its canonical-rest copy,
leg length, standing height, body radii), the body-size hints of the hand contacts, and the
:class:`HandContact` labels a clip records."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from ....core.measures import foot_rest_heights
from ....core.retarget_pose import retarget_pose_skeleton
from ....core.skeleton import J, Skeleton

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
    return {
        "hip": float(max(1.6 * hip_half, 0.12 * s)),
        "torso": 0.11 * s,
        "head": 0.1 * s,
        "hand": 0.008 * s,
    }


def body_radii_from_mesh(
    skeleton: Skeleton, rest_vertices: np.ndarray, weights: np.ndarray
) -> dict[str, float]:
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
    stance_w: float = field(init=False)  # half distance between the ankles, retarget pose
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
        self.ref = retarget_pose_skeleton(sk)
        ref_rest = self.ref.rest_positions()
        feet = [J[n] for n in ("LeftFoot", "RightFoot", "LeftToeBase", "RightToeBase")]
        self.ankle_h, self.toe_h = np.split(foot_rest_heights(sk), 2)  # Efoot's ḡ (Eq. 6)
        self.toe = sk.offsets[feet[2:]]
        lens = sk.bone_lengths()
        self.leg_reach = np.array([lens[J[f"{s}Leg"]] + lens[J[f"{s}Foot"]] for s, _ in SIDES])
        self.arm_reach = float(lens[J["LeftForeArm"]] + lens[J["LeftHand"]])
        self.stand = float(ref_rest[0, 1] - ref_rest[feet[:2], 1].max() + self.ankle_h.max())
        self.hip_w = 0.5 * float(ref_rest[J["LeftUpLeg"], 0] - ref_rest[J["RightUpLeg"], 0])
        # the feet are placed relative to the rig's own stance: legs that splay a few degrees at
        # rest are shape (the retarget pose keeps them), so they splay as much when walking
        self.stance_w = 0.5 * float(ref_rest[feet[0], 0] - ref_rest[feet[1], 0])
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
