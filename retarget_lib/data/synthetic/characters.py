"""Synthetic skinned characters on the canonical 22 joints (the embedded ``synthetic`` source).

Each named character is built deterministically from a :class:`CharacterSpec`:

1. **Skeleton.** A reference skeleton (about 1.75 m tall standing, NKN height ``H`` = 1.56 m) is
   stretched segment by segment (length factors 0.6-1.5: torso, neck, legs, arms, hips and
   shoulder widths, feet), posed in its *rest* pose (T-pose or A-pose arms, arms swept forward,
   spine curved forward or back, knees bent, feet turned out; all encoded in the offsets'
   directions, rest local rotations being identity) and scaled to the target ``H``
   (:meth:`~retarget_lib.core.skeleton.Skeleton.height`).
2. **Body.** An implicit surface, the smooth union of one or more primitives per joint (a loft
   of elliptic cross-sections through the spine for the torso, tapered capsules for limbs and
   neck, ellipsoids for belly and head, rounded boxes for palms, fingers, feet and toes, a
   capsule thumb), widened by the ``bulk``, ``belly``, ``chest`` and ``limbs`` parameters. Its
   zero level set is extracted with marching cubes on a fine grid (about 1 cm) and decimated
   (quadric edge collapse, :func:`~retarget_lib.core.skinning.subsample_mesh`) to about 3000
   vertices: a single closed, watertight mesh with feet resting on ``y = 0``. Building one
   character takes about 0.25 s.
3. **Skinning weights.** Each primitive belongs to the joint whose rotation moves it (the thigh
   capsule to ``LeftUpLeg``, the palm to ``LeftHand`` ...). A vertex's weight for joint ``j``
   falls off with its signed distance to ``j``'s primitives, ``w_j ∝ exp(-d_j / tau)``, keeping
   the 4 largest (rows sum to 1). Vertices on a limb are dominated by that limb's joint and blend
   over about one limb radius around each joint, so the ``w >= 0.5`` vertex groups used for
   self-contacts (Villegas et al. 2021, Sec. 3.2) are the body parts one expects.

Conventions: metres, +Y up, facing +Z, the character's left at +X, rest pose = identity local
rotations.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache
from typing import Protocol

import numpy as np
import trimesh
from skimage.measure import marching_cubes

from ...core.character import Character
from ...core.measures import mesh_ground
from ...core.skeleton import J, canonical22_skeleton
from ...core.skinning import subsample_mesh

__all__ = [
    "CHARACTER_NAMES",
    "CHARACTER_SPECS",
    "CharacterSpec",
    "REFERENCE_OFFSETS",
    "all_characters",
    "build_character",
    "make_character",
    "random_character",
]



# ----------------------------------------------------------------------------- specifications
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
    bulk: float = 1.0
    belly: float = 0.0
    chest: float = 1.0
    limbs: float = 1.0

    #: the fields that are segment length / size factors
    FACTORS = ("torso", "neck", "head", "thigh", "shin", "foot", "hips", "shoulders", "upper_arm",
               "forearm", "hand")


CHARACTER_SPECS: tuple[CharacterSpec, ...] = (
    CharacterSpec("ada", 1.55),
    CharacterSpec("bram", 1.82, shoulders=1.3, upper_arm=1.1, bulk=1.4, chest=1.25, limbs=1.1,
                  arm_angle=35.0),
    CharacterSpec("cleo", 1.62, thigh=1.3, shin=1.3, shoulders=0.75, hips=0.85, bulk=0.75,
                  arm_angle=45.0, limbs=0.9),
    CharacterSpec("dex", 1.25, thigh=0.65, shin=0.65, torso=1.2, head=1.3, shoulders=1.2,
                  bulk=1.45, chest=1.15, hand=1.2, foot=1.15),
    CharacterSpec("echo", 1.21, head=1.45, neck=0.7, upper_arm=0.85, forearm=0.85, thigh=0.85,
                  shin=0.85, bulk=0.95, hand=1.1, arm_angle=20.0),
    CharacterSpec("fern", 1.78, upper_arm=1.35, forearm=1.35, spine_curve=22.0, bulk=0.72,
                  limbs=0.9, shoulders=0.9),
    CharacterSpec("gus", 1.5, neck=0.75, bulk=1.5, belly=1.0, feet_out=20.0, chest=1.1,
                  arm_angle=30.0, hips=1.2),
    CharacterSpec("hana", 1.52, arm_angle=30.0, knee_bend=10.0, spine_curve=-10.0, bulk=0.9,
                  hips=1.1),
    CharacterSpec("ivo", 2.05, upper_arm=1.25, forearm=1.2, bulk=1.35, shoulders=1.2, hand=1.25,
                  arm_angle=40.0, chest=1.2, foot=1.1),
    CharacterSpec("juno", 1.48, torso=1.35, thigh=0.75, shin=0.75, bulk=0.78, arm_angle=10.0),
    CharacterSpec("kato", 1.7, shoulders=1.45, bulk=1.15, limbs=1.25, chest=1.3, hips=0.9),
    CharacterSpec("lumi", 1.35, head=1.5, thigh=0.7, shin=0.7, upper_arm=1.3, forearm=1.25,
                  hand=1.3, arm_angle=25.0, arm_forward=10.0),
    CharacterSpec("milo", 1.38, knee_bend=18.0, spine_curve=15.0, bulk=0.8, neck=1.2,
                  arm_forward=15.0),
    CharacterSpec("nova", 1.7, thigh=1.35, shin=1.4, torso=0.78, arm_angle=50.0, bulk=0.92,
                  shoulders=0.85, foot=0.9),
    CharacterSpec("otto", 1.58, upper_arm=0.72, forearm=0.7, hips=1.4, bulk=1.3, belly=0.6,
                  feet_out=15.0, arm_angle=20.0, foot=1.2),
    CharacterSpec("pia", 1.6, neck=1.5, shoulders=0.7, spine_curve=-8.0, bulk=0.88,
                  arm_angle=40.0, arm_forward=8.0, head=0.9),
)
CHARACTER_NAMES: tuple[str, ...] = tuple(s.name for s in CHARACTER_SPECS)
_SPECS = {s.name: s for s in CHARACTER_SPECS}


# ----------------------------------------------------------------------------- skeleton
#: reference segment lengths (metres, before scaling), giving NKN H = 1.559 m
_REF = dict(spine=0.10, spine1=0.12, spine2=0.12, neck_base=0.16, neck=0.10, thigh=0.42,
            shin=0.40, toe_drop=0.05, toe_fwd=0.13, hip_x=0.09, hip_drop=0.07, clavicle_x=0.045,
            arm=0.11, upper_arm=0.27, forearm=0.25, ankle_height=0.08)


def _rot_x(v: np.ndarray, deg: float) -> np.ndarray:
    """Rotate ``v`` about +X by ``deg`` (positive tips +Y towards +Z)."""
    a = math.radians(deg)
    return np.array([v[0], v[1] * math.cos(a) - v[2] * math.sin(a),
                     v[1] * math.sin(a) + v[2] * math.cos(a)])


def _mirror(v: np.ndarray) -> np.ndarray:
    return v * np.array([-1.0, 1.0, 1.0])


def _unscaled_offsets(spec: CharacterSpec) -> np.ndarray:
    """``(22, 3)`` rest offsets before scaling (root row zero), pose encoded in directions."""
    r = _REF
    off = np.zeros((22, 3))
    up = np.array([0.0, 1.0, 0.0])
    chain = (("Spine", r["spine"] * spec.torso), ("Spine1", r["spine1"] * spec.torso),
             ("Spine2", r["spine2"] * spec.torso), ("Neck", r["neck_base"] * spec.torso),
             ("Head", r["neck"] * spec.neck))
    for k, (name, length) in enumerate(chain, start=1):  # uniform bend along the chain
        off[J[name]] = _rot_x(up * length, spec.spine_curve * k / len(chain))
    knee = math.radians(spec.knee_bend)
    thigh = r["thigh"] * spec.thigh * np.array([0.0, -math.cos(knee), math.sin(knee)])
    shin = r["shin"] * spec.shin * np.array([0.0, -math.cos(knee), -math.sin(knee)])
    out = math.radians(spec.feet_out)
    toe = spec.foot * np.array([r["toe_fwd"] * math.sin(out), -r["toe_drop"],
                                r["toe_fwd"] * math.cos(out)])
    a, f = math.radians(spec.arm_angle), math.radians(spec.arm_forward)
    arm_dir = np.array([math.cos(a) * math.cos(f), -math.sin(a), math.cos(a) * math.sin(f)])
    a_clav = 0.25 * a  # the clavicle follows the arm a little
    clav_dir = np.array([math.cos(a_clav), -math.sin(a_clav), 0.0])
    shoulder = 0.7 * off[J["Neck"]] + np.array([r["clavicle_x"] * spec.shoulders, 0.0, 0.0])
    left = {
        "UpLeg": np.array([r["hip_x"] * spec.hips, -r["hip_drop"], 0.0]),
        "Leg": thigh, "Foot": shin, "ToeBase": toe,
        "Shoulder": shoulder, "Arm": clav_dir * r["arm"] * spec.shoulders,
        "ForeArm": arm_dir * r["upper_arm"] * spec.upper_arm,
        "Hand": arm_dir * r["forearm"] * spec.forearm,
    }
    for part, v in left.items():
        off[J["Left" + part]] = v
        off[J["Right" + part]] = _mirror(v)
    return off


#: ``(22, 3)`` offsets of the reference skeleton (all factors 1, T-pose) before scaling; root row 0
REFERENCE_OFFSETS: np.ndarray = _unscaled_offsets(CharacterSpec("reference", height=1.0))


def _scale(spec: CharacterSpec) -> float:
    """Factor taking the unscaled skeleton to NKN height ``spec.height``."""
    return spec.height / canonical22_skeleton(_unscaled_offsets(spec)).height()


# ----------------------------------------------------------------------------- implicit body
class _Primitive(Protocol):
    """A solid with an approximate signed distance (exact zero set); ``owner`` is the joint that
    moves it."""

    owner: int

    def sdf(self, p: np.ndarray) -> np.ndarray:
        """``(N,)`` signed distance (metres, negative inside) of points ``p (N, 3)``."""

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """``(lo (3,), hi (3,))`` axis-aligned bounding box."""


@dataclass
class _RoundCone:
    """Capsule from ``a`` to ``b`` whose radius goes linearly from ``ra`` to ``rb``."""

    owner: int
    a: np.ndarray
    b: np.ndarray
    ra: float
    rb: float

    def sdf(self, p):
        ab = self.b - self.a
        t = np.clip((p - self.a) @ ab / max(ab @ ab, 1e-12), 0.0, 1.0)
        return np.linalg.norm(p - self.a - t[:, None] * ab, axis=1) - (self.ra + t * (self.rb - self.ra))

    def bounds(self):
        r = max(self.ra, self.rb)
        return np.minimum(self.a, self.b) - r, np.maximum(self.a, self.b) + r


@dataclass
class _Ellipsoid:
    """Ellipsoid with semi-axes ``radii`` along the rows of ``axes`` (orthonormal)."""

    owner: int
    center: np.ndarray
    axes: np.ndarray
    radii: np.ndarray

    def sdf(self, p):
        q = (p - self.center) @ self.axes.T
        k0 = np.linalg.norm(q / self.radii, axis=1)
        k1 = np.maximum(np.linalg.norm(q / self.radii**2, axis=1), 1e-12)
        return k0 * (k0 - 1.0) / k1  # Quilez's bound, exact on the surface

    def bounds(self):
        half = np.abs(self.axes.T) @ self.radii
        return self.center - half, self.center + half


@dataclass
class _RoundBox:
    """Box with half extents ``half`` along the rows of ``axes``, edges rounded by ``rounding``."""

    owner: int
    center: np.ndarray
    axes: np.ndarray
    half: np.ndarray
    rounding: float

    def sdf(self, p):
        q = np.abs((p - self.center) @ self.axes.T) - (self.half - self.rounding)
        outside = np.linalg.norm(np.maximum(q, 0.0), axis=1)
        return outside + np.minimum(q.max(axis=1), 0.0) - self.rounding

    def bounds(self):
        half = np.abs(self.axes.T) @ self.half
        return self.center - half, self.center + half


@dataclass
class _EllipticCone:
    """Segment ``a -> b`` swept by an ellipse whose (side, front) radii go linearly from ``ra`` to
    ``rb``, closed by half-ellipsoid caps reaching ``caps`` beyond the ends; side = world X made
    orthogonal to the segment."""

    owner: int
    a: np.ndarray
    b: np.ndarray
    ra: np.ndarray
    rb: np.ndarray
    caps: tuple[float, float]

    def sdf(self, p):
        ab = self.b - self.a
        length = np.linalg.norm(ab)
        along = ab / length
        side = _unit(np.array([1.0, 0.0, 0.0]) - along[0] * along)
        front = np.cross(side, along)
        rel = p - self.a
        t = np.clip(rel @ along / length, 0.0, 1.0)
        r = self.ra + t[:, None] * (self.rb - self.ra)  # (N, 2) side, front radii
        q = rel - t[:, None] * ab
        cap = np.where(rel @ along < 0.0, self.caps[0], self.caps[1])
        scaled = np.stack((q @ side / r[:, 0], q @ front / r[:, 1], q @ along / cap), axis=1)
        return (np.linalg.norm(scaled, axis=1) - 1.0) * np.minimum(r.min(axis=1), cap)

    def bounds(self):
        r = max(self.ra.max(), self.rb.max(), *self.caps)
        return np.minimum(self.a, self.b) - r, np.maximum(self.a, self.b) + r


def _frame(forward: np.ndarray, up_hint: np.ndarray) -> np.ndarray:
    """``(3, 3)`` orthonormal rows ``(side, up, forward)`` with ``forward`` exact."""
    fwd = forward / np.linalg.norm(forward)
    side = np.cross(up_hint, fwd)
    side /= np.linalg.norm(side)
    return np.stack((side, np.cross(fwd, side), fwd))


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v)


def _body_parts(spec: CharacterSpec, pos: np.ndarray, s: float) -> list[list[_Primitive]]:
    """The primitives of one character, grouped into body parts.

    Primitives within a part (a chain of limb segments, the torso loft) meet with matching
    cross-sections and are joined by a plain union; parts are joined by a smooth union.

    Args:
        spec: the character's parameters.
        pos: ``(22, 3)`` rest joint positions (metres, world).
        s: the skeleton's scale factor (sizes in the helpers are for ``s = 1``).
    """
    parts = _torso_parts(spec, pos, s) + _head_parts(spec, pos, s)
    for side in ("Left", "Right"):
        parts += _arm_parts(spec, pos, s, side) + _leg_parts(spec, pos, s, side)
    return parts


def _torso_parts(spec: CharacterSpec, pos: np.ndarray, s: float) -> list[list[_Primitive]]:
    """A loft of elliptic (side, front) cross-sections through crotch, Hips, Spine, Spine1,
    Spine2 and Neck, plus an optional belly."""
    b, chest, hip_x = spec.bulk, spec.chest, _REF["hip_x"] * spec.hips
    chain = [("Hips", pos[J["Hips"]] - np.array([0.0, 0.075, 0.0]) * s, (hip_x + 0.05, 0.1)),
             ("Hips", pos[J["Hips"]], (hip_x + 0.06, 0.105)),
             ("Spine", pos[J["Spine"]], (0.135, 0.095)),
             ("Spine1", pos[J["Spine1"]], (0.14 * chest**0.5, 0.1 * chest)),
             ("Spine2", pos[J["Spine2"]], ((0.135 + 0.02 * spec.shoulders) * chest**0.5, 0.105 * chest)),
             ("Neck", pos[J["Neck"]], ((0.075 + 0.025 * spec.shoulders) * chest**0.5, 0.07 * chest))]
    # end caps: crotch and shoulder-line roundness; short inner caps just close the kinks
    caps = [0.09 * b * s] + [0.02 * s] * (2 * len(chain) - 4) + [0.035 * b * s]
    loft = [_EllipticCone(J[owner], p0, p1, np.array(r0) * b * s, np.array(r1) * b * s,
                          (caps[2 * k], caps[2 * k + 1]))
            for k, ((owner, p0, r0), (_, p1, r1)) in enumerate(zip(chain[:-1], chain[1:]))]
    parts = [loft]
    if spec.belly > 0:
        size = (0.08 + 0.04 * spec.belly) * b * s
        center = 0.5 * (pos[J["Spine"]] + pos[J["Spine1"]]) + np.array([0.0, 0.0, 0.04 * b * s])
        parts.append([_Ellipsoid(J["Spine"], center, np.eye(3), np.array([1.25, 1.1, 1.0]) * size)])
    return parts


def _head_parts(spec: CharacterSpec, pos: np.ndarray, s: float) -> list[list[_Primitive]]:
    """Neck (tapered capsule) and head (ellipsoid above the Head joint, facing +Z)."""
    b, h = spec.bulk, spec.head * s
    head_up = _unit(pos[J["Head"]] - pos[J["Neck"]])
    neck = _RoundCone(J["Neck"], pos[J["Neck"]] - 0.02 * s * head_up, pos[J["Head"]],
                      0.065 * b**0.6 * s, 0.047 * b**0.5 * s)
    axes = _frame(np.array([0.0, 0.0, 1.0]), head_up)
    head = _Ellipsoid(J["Head"], pos[J["Head"]] + (0.085 * head_up + 0.015 * axes[2]) * h, axes,
                      np.array([0.082, 0.108, 0.098]) * h)
    return [[neck], [head]]


def _arm_parts(spec: CharacterSpec, pos: np.ndarray, s: float, side: str) -> list[list[_Primitive]]:
    """Clavicle, upper arm and forearm (one chain), then palm, fingers and thumb."""
    j = {n: J[side + n] for n in ("Shoulder", "Arm", "ForeArm", "Hand")}
    r = spec.bulk * spec.limbs * s
    chain = [_RoundCone(j["Shoulder"], pos[j["Shoulder"]], pos[j["Arm"]], 0.05 * spec.bulk * s, 0.056 * r),
             _RoundCone(j["Arm"], pos[j["Arm"]], pos[j["ForeArm"]], 0.05 * r, 0.037 * r),
             _RoundCone(j["ForeArm"], pos[j["ForeArm"]], pos[j["Hand"]], 0.037 * r, 0.028 * r)]
    hand = _hand(j["Hand"], pos[j["Hand"]], _unit(pos[j["Hand"]] - pos[j["ForeArm"]]), spec.hand * s)
    return [chain] + [[p] for p in hand]


def _leg_parts(spec: CharacterSpec, pos: np.ndarray, s: float, side: str) -> list[list[_Primitive]]:
    """Thigh and shin (one chain), then the foot and toe blocks."""
    j = {n: J[side + n] for n in ("UpLeg", "Leg", "Foot", "ToeBase")}
    girth = spec.bulk * spec.limbs
    chain = [_RoundCone(j["UpLeg"], pos[j["UpLeg"]], pos[j["Leg"]], 0.082 * girth * s, 0.052 * girth * s),
             _RoundCone(j["Leg"], pos[j["Leg"]], pos[j["Foot"]], 0.052 * girth * s, 0.036 * girth * s)]
    foot = _foot(j["Foot"], j["ToeBase"], pos[j["Foot"]], pos[j["ToeBase"]], spec.foot * s, girth**0.5)
    return [chain, foot]


def _hand(owner: int, wrist: np.ndarray, direction: np.ndarray, size: float) -> list[_Primitive]:
    """Palm block, thinner finger block and a thumb pointing forward (+Z), palm facing down
    when the arm is horizontal."""
    axes = _frame(direction, np.array([0.0, 1.0, 0.0]))  # rows (side = ±Z, normal, along arm)
    side = axes[0] * np.sign(axes[0][2])  # the thumb side: front (+Z)
    palm = _RoundBox(owner, wrist + direction * 0.05 * size, axes,
                     np.array([0.045, 0.018, 0.055]) * size, 0.014 * size)
    fingers = _RoundBox(owner, wrist + direction * 0.135 * size, axes,
                        np.array([0.041, 0.013, 0.045]) * size, 0.011 * size)
    base = wrist + direction * 0.03 * size + side * 0.03 * size
    thumb = _RoundCone(owner, base, base + (0.04 * direction + 0.045 * side) * size,
                       0.015 * size, 0.012 * size)
    return [palm, fingers, thumb]


def _foot(foot: int, toe: int, ankle: np.ndarray, ball: np.ndarray, size: float,
          girth: float) -> list[_Primitive]:
    """Heel-to-ball block (owned by the ankle joint) and a toe block, flat soles."""
    fwd = ball - ankle
    fwd[1] = 0.0
    fwd = _unit(fwd)
    axes = _frame(fwd, np.array([0.0, 1.0, 0.0]))  # rows (side, up, forward)
    sole = ankle[1] - _REF["ankle_height"] * size
    heel = ankle - fwd * 0.06 * size
    top = ankle[1] + 0.02 * size
    center = 0.5 * (heel + ball)
    center[1] = 0.5 * (sole + top)
    half_len = 0.5 * np.linalg.norm((ball - heel)[[0, 2]]) + 0.01 * size
    foot_box = _RoundBox(foot, center, axes,
                         np.array([0.043 * girth * size, 0.5 * (top - sole), half_len]), 0.02 * size)
    toe_center = ball + fwd * 0.035 * size
    toe_center[1] = sole + 0.02 * size
    toe_box = _RoundBox(toe, toe_center, axes, np.array([0.042 * girth, 0.02, 0.04]) * size,
                        0.015 * size)
    return [foot_box, toe_box]


def _smooth_min(a: np.ndarray, b: np.ndarray, k: float) -> np.ndarray:
    """Quadratic smooth minimum (blend width ``k``); equals ``min(a, b)`` where ``|a-b| >= k``."""
    h = np.maximum(k - np.abs(a - b), 0.0) / k
    return np.minimum(a, b) - 0.25 * k * h * h


def _sample_sdf(parts: list[list[_Primitive]], spacing: float,
                blend: float) -> tuple[np.ndarray, np.ndarray]:
    """The body's signed distance on a regular grid: plain union within each part, smooth union
    (width ``blend``) across parts.

    Each part is evaluated only inside its bounding box (grown by the blend width and two
    cells); elsewhere its distance exceeds that margin and cannot change the surface.

    Returns:
        ``(values (nx, ny, nz), origin (3,))``; grid point ``(i, j, k)`` is at
        ``origin + spacing * (i, j, k)``.
    """
    margin = blend + 2 * spacing
    boxes = [[p.bounds() for p in part] for part in parts]
    boxes = [(np.min([b[0] for b in bx], axis=0), np.max([b[1] for b in bx], axis=0)) for bx in boxes]
    lo = np.min([bx[0] for bx in boxes], axis=0) - margin
    hi = np.max([bx[1] for bx in boxes], axis=0) + margin
    shape = np.ceil((hi - lo) / spacing).astype(int) + 1
    values = np.full(shape, margin, dtype=np.float64)
    for part, (plo, phi) in zip(parts, boxes):
        i0 = np.floor((plo - margin - lo) / spacing).astype(int).clip(0)
        i1 = np.minimum(np.ceil((phi + margin - lo) / spacing).astype(int) + 1, shape)
        axes = [lo[d] + spacing * np.arange(i0[d], i1[d]) for d in range(3)]
        pts = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
        block = (slice(i0[0], i1[0]), slice(i0[1], i1[1]), slice(i0[2], i1[2]))
        d = np.min([prim.sdf(pts) for prim in part], axis=0).reshape(values[block].shape)
        values[block] = _smooth_min(values[block], d, blend)
    return values, lo


#: smallest |signed distance| kept at a grid point, in grid cells (see :func:`_extract_mesh`)
_SURFACE_CLEARANCE = 0.02


def _extract_mesh(parts: list[list[_Primitive]], spacing: float, blend: float,
                  target_vertices: int) -> tuple[np.ndarray, np.ndarray]:
    """Marching cubes of the smooth union, largest component, decimated to ~``target_vertices``.

    Returns:
        ``(vertices (V, 3), faces (F, 3))``, outward-facing triangles.
    """
    values, origin = _sample_sdf(parts, spacing, blend)
    # keep the surface >= 2% of a cell away from grid points (no sliver triangles), *keeping each
    # value's sign*: the former clamp set every |value| < 5% of a cell to +5%, which flipped the
    # grid points just inside the surface to outside, moved the surface in steps of whole grid
    # layers where it runs nearly parallel to them, and left stair-step terraces on the broad,
    # gently curved torsos (bram, ivo, gus) that decimation kept
    near = np.abs(values) < _SURFACE_CLEARANCE * spacing
    values[near] = np.where(values[near] < 0.0, -_SURFACE_CLEARANCE, _SURFACE_CLEARANCE) * spacing
    verts, faces, _, _ = marching_cubes(values, level=0.0, spacing=(spacing,) * 3)
    mesh = trimesh.Trimesh(verts + origin, faces, process=True)
    mesh = max(mesh.split(only_watertight=False), key=lambda m: len(m.vertices))
    dummy = np.ones((len(mesh.vertices), 1))
    v, f, _ = subsample_mesh(mesh.vertices, mesh.faces, dummy, n=target_vertices)
    mesh = trimesh.Trimesh(v, f, process=True)
    if mesh.volume < 0:
        mesh.invert()
    return np.asarray(mesh.vertices), np.asarray(mesh.faces, dtype=np.int64)


def _skin_weights(vertices: np.ndarray, prims: list[_Primitive], tau: float, top: int = 4) -> np.ndarray:
    """Skinning weights from the body's own parts.

    ``w_j ∝ exp(-d_j / tau)`` with ``d_j`` the signed distance of the vertex to joint ``j``'s
    primitives, so the joint whose part forms the surface there dominates and neighbouring parts
    blend where their surfaces meet; only the ``top`` largest weights are kept.

    Args:
        vertices: ``(V, 3)`` surface points.
        prims: all primitives (each with its ``owner`` joint).
        tau: falloff length in metres.
        top: influences kept per vertex.

    Returns:
        ``(V, 22)`` weights, rows summing to 1.
    """
    dist = np.full((len(vertices), 22), np.inf)
    for prim in prims:
        dist[:, prim.owner] = np.minimum(dist[:, prim.owner], prim.sdf(vertices))
    logits = -(dist - dist.min(axis=1, keepdims=True)) / tau
    w = np.exp(logits)
    drop = np.argsort(-w, axis=1)[:, top:]
    np.put_along_axis(w, drop, 0.0, axis=1)
    return w / w.sum(axis=1, keepdims=True)


# ----------------------------------------------------------------------------- building
def build_character(spec: CharacterSpec, target_vertices: int = 3000) -> Character:
    """Build a character from its spec (deterministic; about 0.25 s).

    Args:
        spec: the parameters.
        target_vertices: approximate mesh size (1-5k keeps skinning and contacts cheap).

    Returns:
        The :class:`Character`, feet on ``y = 0``, root above the origin.
    """
    for name in CharacterSpec.FACTORS:
        value = getattr(spec, name)
        if not 0.6 <= value <= 1.5:
            raise ValueError(f"character {spec.name!r}: length factor {name}={value} outside 0.6-1.5")
    s = _scale(spec)
    offsets = _unscaled_offsets(spec) * s
    pos = canonical22_skeleton(offsets).rest_positions()
    parts = _body_parts(spec, pos, s)
    vertices, faces = _extract_mesh(parts, spacing=0.011 * s, blend=0.02 * s,
                                    target_vertices=target_vertices)
    weights = _skin_weights(vertices, [p for part in parts for p in part], tau=0.012 * s)
    floor = mesh_ground(vertices)
    vertices[:, 1] -= floor
    offsets[0, 1] = -floor  # root rest position: feet on the ground
    style = dict(
        rest_pose="T-pose" if spec.arm_angle < 15 else "A-pose",
        arm_angle_deg=spec.arm_angle, arm_forward_deg=spec.arm_forward,
        spine_curve_deg=spec.spine_curve, knee_bend_deg=spec.knee_bend, feet_out_deg=spec.feet_out,
        belly=spec.belly, chest=spec.chest, limbs=spec.limbs, scale=s,
        factors={n: getattr(spec, n) for n in CharacterSpec.FACTORS}, source="synthetic",
    )
    return Character(spec.name, canonical22_skeleton(offsets), vertices, faces, weights,
                     bulk=spec.bulk, style=style)


@lru_cache(maxsize=None)
def _cached(spec: CharacterSpec) -> Character:
    return build_character(spec)


def make_character(name: str) -> Character:
    """One of the named synthetic characters (:data:`CHARACTER_NAMES`); built once per process,
    a fresh copy is returned each call.

    Raises:
        KeyError: for an unknown name (the message lists the known ones).
    """
    if name not in _SPECS:
        raise KeyError(f"unknown character {name!r}; known: {', '.join(CHARACTER_NAMES)}")
    return _cached(_SPECS[name]).copy()


def all_characters() -> list[Character]:
    """All named synthetic characters, in :data:`CHARACTER_NAMES` order."""
    return [make_character(n) for n in CHARACTER_NAMES]


def random_character(seed: int) -> Character:
    """An extra, unseen character with parameters drawn from the named family's ranges.

    Args:
        seed: the random seed (same seed, same character); the name is ``"random-<seed>"``.
    """
    rng = np.random.default_rng(seed)
    factors = {n: float(np.clip(rng.lognormal(0.0, 0.15), 0.65, 1.45)) for n in CharacterSpec.FACTORS}
    bulk = float(rng.uniform(0.72, 1.5))
    spec = CharacterSpec(
        f"random-{seed}", height=float(rng.uniform(1.25, 2.0)), **factors,
        arm_angle=float(rng.uniform(25.0, 50.0)) if rng.random() < 0.5 else 0.0,
        arm_forward=float(rng.uniform(0.0, 12.0)), spine_curve=float(rng.uniform(-10.0, 20.0)),
        knee_bend=float(rng.uniform(0.0, 15.0)), feet_out=float(rng.uniform(0.0, 20.0)), bulk=bulk,
        belly=float(rng.uniform(0.0, 1.0)) if bulk > 1.1 else 0.0, chest=float(rng.uniform(0.9, 1.3)),
        limbs=float(rng.uniform(0.9, 1.2)),
    )
    return _cached(spec).copy()
