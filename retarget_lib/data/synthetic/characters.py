"""Synthetic skinned characters on the canonical 22 joints (the embedded ``synthetic`` source).

Each named character is built deterministically from a
:class:`~retarget_lib.data.synthetic.proportions.CharacterSpec`:

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

from functools import cache

import numpy as np

from ...core.character import Character
from ...core.measures import mesh_ground
from ...core.skeleton import canonical22_skeleton
from .implicit_body import body_parts, extract_mesh, skin_weights
from .proportions import CharacterSpec, height_scale, unscaled_offsets

__all__ = [
    "CHARACTER_NAMES",
    "CHARACTER_SPECS",
    "all_characters",
    "build_character",
    "make_character",
    "random_character",
]


# ----------------------------------------------------------------------------- the named characters
CHARACTER_SPECS: tuple[CharacterSpec, ...] = (
    CharacterSpec("ada", 1.55),
    CharacterSpec(
        "bram", 1.82, shoulders=1.3, upper_arm=1.1, bulk=1.4, chest=1.25, limbs=1.1, arm_angle=35.0
    ),
    CharacterSpec(
        "cleo",
        1.62,
        thigh=1.3,
        shin=1.3,
        shoulders=0.75,
        hips=0.85,
        bulk=0.75,
        arm_angle=45.0,
        limbs=0.9,
    ),
    CharacterSpec(
        "dex",
        1.25,
        thigh=0.65,
        shin=0.65,
        torso=1.2,
        head=1.3,
        shoulders=1.2,
        bulk=1.45,
        chest=1.15,
        hand=1.2,
        foot=1.15,
    ),
    CharacterSpec(
        "echo",
        1.21,
        head=1.45,
        neck=0.7,
        upper_arm=0.85,
        forearm=0.85,
        thigh=0.85,
        shin=0.85,
        bulk=0.95,
        hand=1.1,
        arm_angle=20.0,
    ),
    CharacterSpec(
        "fern",
        1.78,
        upper_arm=1.35,
        forearm=1.35,
        spine_curve=22.0,
        bulk=0.72,
        limbs=0.9,
        shoulders=0.9,
    ),
    CharacterSpec(
        "gus",
        1.5,
        neck=0.75,
        bulk=1.5,
        belly=1.0,
        feet_out=20.0,
        chest=1.1,
        arm_angle=30.0,
        hips=1.2,
    ),
    CharacterSpec(
        "hana", 1.52, arm_angle=30.0, knee_bend=10.0, spine_curve=-10.0, bulk=0.9, hips=1.1
    ),
    CharacterSpec(
        "ivo",
        2.05,
        upper_arm=1.25,
        forearm=1.2,
        bulk=1.35,
        shoulders=1.2,
        hand=1.25,
        arm_angle=40.0,
        chest=1.2,
        foot=1.1,
    ),
    CharacterSpec("juno", 1.48, torso=1.35, thigh=0.75, shin=0.75, bulk=0.78, arm_angle=10.0),
    CharacterSpec("kato", 1.7, shoulders=1.45, bulk=1.15, limbs=1.25, chest=1.3, hips=0.9),
    CharacterSpec(
        "lumi",
        1.35,
        head=1.5,
        thigh=0.7,
        shin=0.7,
        upper_arm=1.3,
        forearm=1.25,
        hand=1.3,
        arm_angle=25.0,
        arm_forward=10.0,
    ),
    CharacterSpec(
        "milo", 1.38, knee_bend=18.0, spine_curve=15.0, bulk=0.8, neck=1.2, arm_forward=15.0
    ),
    CharacterSpec(
        "nova",
        1.7,
        thigh=1.35,
        shin=1.4,
        torso=0.78,
        arm_angle=50.0,
        bulk=0.92,
        shoulders=0.85,
        foot=0.9,
    ),
    CharacterSpec(
        "otto",
        1.58,
        upper_arm=0.72,
        forearm=0.7,
        hips=1.4,
        bulk=1.3,
        belly=0.6,
        feet_out=15.0,
        arm_angle=20.0,
        foot=1.2,
    ),
    CharacterSpec(
        "pia",
        1.6,
        neck=1.5,
        shoulders=0.7,
        spine_curve=-8.0,
        bulk=0.88,
        arm_angle=40.0,
        arm_forward=8.0,
        head=0.9,
    ),
)
CHARACTER_NAMES: tuple[str, ...] = tuple(s.name for s in CHARACTER_SPECS)
_SPECS = {s.name: s for s in CHARACTER_SPECS}


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
            raise ValueError(
                f"character {spec.name!r}: length factor {name}={value} outside 0.6-1.5"
            )
    s = height_scale(spec)
    offsets = unscaled_offsets(spec) * s
    pos = canonical22_skeleton(offsets).rest_positions()
    parts = body_parts(spec, pos, s)
    vertices, faces = extract_mesh(
        parts, spacing=0.011 * s, blend=0.02 * s, target_vertices=target_vertices
    )
    weights = skin_weights(vertices, [p for part in parts for p in part], tau=0.012 * s)
    floor = mesh_ground(vertices)
    vertices[:, 1] -= floor
    offsets[0, 1] = -floor  # root rest position: feet on the ground
    style = dict(
        rest_pose="T-pose" if spec.arm_angle < 15 else "A-pose",
        arm_angle_deg=spec.arm_angle,
        arm_forward_deg=spec.arm_forward,
        spine_curve_deg=spec.spine_curve,
        knee_bend_deg=spec.knee_bend,
        feet_out_deg=spec.feet_out,
        belly=spec.belly,
        chest=spec.chest,
        limbs=spec.limbs,
        scale=s,
        factors={n: getattr(spec, n) for n in CharacterSpec.FACTORS},
        source="synthetic",
    )
    return Character(
        spec.name,
        canonical22_skeleton(offsets),
        vertices,
        faces,
        weights,
        bulk=spec.bulk,
        style=style,
    )


@cache
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
    factors = {
        n: float(np.clip(rng.lognormal(0.0, 0.15), 0.65, 1.45)) for n in CharacterSpec.FACTORS
    }
    bulk = float(rng.uniform(0.72, 1.5))
    spec = CharacterSpec(
        f"random-{seed}",
        height=float(rng.uniform(1.25, 2.0)),
        **factors,
        arm_angle=float(rng.uniform(25.0, 50.0)) if rng.random() < 0.5 else 0.0,
        arm_forward=float(rng.uniform(0.0, 12.0)),
        spine_curve=float(rng.uniform(-10.0, 20.0)),
        knee_bend=float(rng.uniform(0.0, 15.0)),
        feet_out=float(rng.uniform(0.0, 20.0)),
        bulk=bulk,
        belly=float(rng.uniform(0.0, 1.0)) if bulk > 1.1 else 0.0,
        chest=float(rng.uniform(0.9, 1.3)),
        limbs=float(rng.uniform(0.9, 1.2)),
    )
    return _cached(spec).copy()
