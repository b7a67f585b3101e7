"""The *Mixamo-convention* synthetic profile: the papers' training setting, without Mixamo's data.

Both papers train on Mixamo, where every character is rigged in one T-pose rest with identity rest
rotations, and every motion exists on every character (Mixamo's own retargeting keeps feet planted
and hands where they touch). The default synthetic data
(:mod:`~retarget_lib.data.synthetic.dataset`, the *varied-rest* profile) gives its characters
A-poses, T-poses, bent knees and swept arms, so that copying local rotations is wrong there; this
profile is the easier, paper-like one:

* **Characters** ``tp01 .. tp14``: T-pose rest (arms about horizontal, straight legs, feet
  forward, spine up; all encoded in the offsets' directions, rest rotations identity) with each
  bind's own shape within the retarget pose's tolerance (arms -4 to 8 degrees below the
  horizontal, forearms drooping up to 7 more, the spine bent -8 to 12 degrees, toe bones 12-30
  degrees below the horizontal, feet turned out up to 12), which the ground truth keeps; segment
  length factors, heights and girths drawn at random (deterministic by index), kept only when their
  proportions lie within the ranges measured on the real rigs of ``data/real_characters``
  (:data:`REAL_RIG_RANGES`, from ``proportions.csv``, widened by :data:`RANGE_MARGIN`).
* **Motions**: every clip of the synthetic library (same families, same seeds, so the same
  style, speed and timing) **authored on each character** (:func:`~retarget_lib.data.synthetic.
  motions.make_motion`: its own footsteps planted on its own floor, its own hand contacts solved
  by IK on its own body). A character's own version is the ground truth of any pair onto it, as a
  Mixamo character's download is. It differs from copying the source's rotations by what the
  contacts and the leg geometry require (the IK), not by a rest pose.

Training builds the whole profile on first use into ``<cache>/synthetic/mixamo_convention.npz``
(1,680 versions, about 3.5 minutes on one core; not part of ``retarget data build``, nothing
downloads). An evaluation needs far fewer: :func:`mixamo_convention_versions` authors only the
versions its cases read when the profile is not built (Table 4's 144 in ~15 s), with the values
the built profile would give. Split like the varied-rest profile (:func:`mixamo_convention_split`,
the manifest's TDCN split parameters).
"""

from __future__ import annotations

import hashlib
import json
import sys
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, replace
from functools import lru_cache
from pathlib import Path

import numpy as np

from ...core.character import Character
from ...core.motion import Motion
from ...core.skeleton import canonical22_skeleton
from ...files import DataError, atomic_write, cache_dir
from ..manifest import source
from ..sources.real_characters import skeleton_proportions
from ..splits import ScenarioPair, TDCNSplits, tdcn_splits
from .characters import build_character
from .motions import FPS, MOTION_FAMILIES, body_radii_from_mesh, make_motion
from .proportions import CharacterSpec, height_scale, unscaled_offsets

__all__ = [
    "PROFILES",
    "REAL_RIG_RANGES",
    "MixamoConventionData",
    "load_mixamo_convention",
    "mixamo_convention_names",
    "mixamo_convention_spec",
    "mixamo_convention_split",
    "mixamo_convention_versions",
]

#: the two synthetic profiles: the default data, and this module's
PROFILES = ("varied-rest", "mixamo-convention")
#: number of characters of the profile
N_CHARACTERS = 14
#: the real rigs the ranges were measured on: the first real-character set (the goblin and the
#: cowboy, added later, stay outside the training ranges: a test of generalisation)
RANGE_SOURCES: tuple[str, ...] = (
    "makehuman_game_engine",
    "makehuman_rigify",
    "makehuman_default",
    "makehuman_cmu_mb",
    "bcn_epileptic",
    "mrfixit",
    "cryptovoxels",
    "quaternius_female_dress",
    "quaternius_male_casual",
)
#: fractions of the skeleton height ``H`` measured on :data:`RANGE_SOURCES` (``data/real_characters/
#: proportions.csv``, min and max over their rows; ``tests/test_mixamo_convention.py`` re-reads it)
REAL_RIG_RANGES: dict[str, tuple[float, float]] = {
    "leg": (0.3856, 0.5507),
    "arm": (0.2681, 0.3897),
    "spine": (0.2872, 0.4666),
    "shoulder_width": (0.1915, 0.3199),
    "hip_width": (0.0959, 0.1399),
}
#: the ranges are widened by this fraction of their width on each side (9 files, 6 bodies: the
#: measured extremes are not the population's)
RANGE_MARGIN = 0.1
FORMAT_VERSION = 1
#: the arrays the cache stores per character and per version of a clip
CHARACTER_ARRAYS = ("offsets", "vertices", "faces", "weights")
MOTION_ARRAYS = ("rotations", "root", "foot_contacts")


def _specs_key() -> str:
    """A digest of everything the built profile depends on here: the character specs and the clip
    list (a change rebuilds the cache instead of loading characters that no longer exist)."""
    text = repr([mixamo_convention_spec(i) for i in range(N_CHARACTERS)]) + repr(_clip_ids())
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def mixamo_convention_names() -> tuple[str, ...]:
    """``("tp01", ..., "tp14")``."""
    return tuple(f"tp{i + 1:02d}" for i in range(N_CHARACTERS))


def _within_real_ranges(spec: CharacterSpec) -> bool:
    skeleton = canonical22_skeleton(unscaled_offsets(spec) * height_scale(spec))
    measured = skeleton_proportions(skeleton)
    for key, (lo, hi) in REAL_RIG_RANGES.items():
        pad = RANGE_MARGIN * (hi - lo)
        if not lo - pad <= float(measured[key]) <= hi + pad:
            return False
    return True


def _bind_shape(index: int) -> dict[str, float]:
    """The rest bones' own shape of T-pose bind ``index``, each within the retarget pose's
    tolerance (:data:`~retarget_lib.core.retarget_pose.TOLERANCE_DEG`), so that it is shape and
    not convention: real T-pose binds differ so (Mixamo's: forearms 6 degrees below the
    horizontal, spines tilted 7 degrees, steep toes), and their ground truth keeps it. Drawn from
    its own stream, so the proportions are those of the profile before these were added."""
    rng = np.random.default_rng([index, 20_21, 7])
    return dict(
        arm_angle=float(rng.uniform(-4.0, 8.0)),
        forearm_droop=float(rng.uniform(0.0, 7.0)),
        spine_curve=float(rng.uniform(-8.0, 12.0)),
        toe_slope=float(rng.uniform(12.0, 30.0)),
        feet_out=float(rng.uniform(0.0, 12.0)),
        arm_forward=float(rng.uniform(-4.0, 6.0)),
    )


def mixamo_convention_spec(index: int) -> CharacterSpec:
    """Character ``index`` (0-based) of the profile: a T-pose :class:`CharacterSpec` whose
    proportions lie within :data:`REAL_RIG_RANGES` (rejection sampling, deterministic by index)
    and whose bones carry a bind's own shape (:func:`_bind_shape`).

    Args:
        index: ``0 .. N_CHARACTERS - 1`` (any non-negative integer gives a character).
    """
    rng = np.random.default_rng([index, 20_21])
    for _ in range(10_000):
        factors = {
            n: float(np.clip(rng.lognormal(0.0, 0.13), 0.65, 1.45)) for n in CharacterSpec.FACTORS
        }
        bulk = float(rng.uniform(0.75, 1.45))
        spec = CharacterSpec(
            f"tp{index + 1:02d}",
            height=float(rng.uniform(1.3, 1.95)),
            **factors,
            bulk=bulk,
            belly=float(rng.uniform(0.0, 0.8)) if bulk > 1.15 else 0.0,
            chest=float(rng.uniform(0.9, 1.3)),
            limbs=float(rng.uniform(0.9, 1.2)),
        )
        if _within_real_ranges(spec):
            return replace(spec, **_bind_shape(index))
    raise RuntimeError(
        f"no character within the real rigs' ranges after 10000 draws (index {index})"
    )


@dataclass
class MixamoConventionData:
    """The profile's characters and every clip on every character.

    Attributes:
        characters: name -> :class:`Character` (T-pose rest, feet on ``y = 0``).
        clips: clip name (``"walk_003"``) -> character name -> that character's own version.
    """

    characters: dict[str, Character]
    clips: dict[str, dict[str, Motion]]


def _clip_ids() -> list[tuple[str, int]]:
    per_family = int(source("synthetic")["build"]["clips_per_family"])
    return [(family, k) for family in MOTION_FAMILIES for k in range(per_family)]


def _characters(count: int = N_CHARACTERS) -> dict[str, Character]:
    """Characters ``tp01 ..`` (the first ``count``), built from their specs."""
    characters = {}
    for i in range(count):
        c = build_character(mixamo_convention_spec(i))
        c.style = dict(c.style, source="synthetic-mixamo-convention")
        characters[c.name] = c
    return characters


def _body_radii(characters: dict[str, Character]) -> dict[str, dict[str, float]]:
    """Each character's body-size hint for authoring (from its own mesh)."""
    return {
        n: body_radii_from_mesh(c.skeleton, c.rest_vertices, c.weights)
        for n, c in characters.items()
    }


def _author(clip: str, character: Character, radii: dict[str, float]) -> Motion:
    """``character``'s own version of ``clip`` (``"walk_003"``)."""
    family, k = clip.rsplit("_", 1)
    m = make_motion(family, character.skeleton, int(k), body_radii=radii)
    m.name = clip
    return m


def generate(
    count: int = N_CHARACTERS, clip_ids: list[tuple[str, int]] | None = None
) -> MixamoConventionData:
    """Build the profile in memory (deterministic).

    Args:
        count: characters ``tp01 ..`` to build (the profile has :data:`N_CHARACTERS`).
        clip_ids: ``(family, seed)`` of the clips (default: every clip of the synthetic library).
    """
    characters = _characters(count)
    radii = _body_radii(characters)
    clips: dict[str, dict[str, Motion]] = {}
    for family, k in clip_ids or _clip_ids():
        name = f"{family}_{k:03d}"
        clips[name] = {n: _author(name, c, radii[n]) for n, c in characters.items()}
    return MixamoConventionData(characters, clips)


def data_path() -> Path:
    """Where the built profile lives."""
    return cache_dir("synthetic") / "mixamo_convention.npz"


def _character_arrays(c: Character) -> tuple[dict[str, np.ndarray], dict]:
    """A character as the cache stores it: its arrays and its index entry."""
    arrays = {
        "offsets": c.skeleton.offsets,
        "vertices": c.rest_vertices.astype(np.float32),
        "faces": c.faces.astype(np.int32),
        "weights": c.weights.astype(np.float32),
    }
    entry = {
        "name": c.name,
        "bulk": float(c.bulk),
        "style": json.loads(json.dumps(c.style, default=float)),
    }
    return arrays, entry


def _character_from(arrays: Mapping[str, np.ndarray], entry: dict) -> Character:
    """Inverse of :func:`_character_arrays` (float64 again)."""
    return Character(
        entry["name"],
        canonical22_skeleton(arrays["offsets"]),
        arrays["vertices"].astype(np.float64),
        arrays["faces"].astype(np.int64),
        arrays["weights"].astype(np.float64),
        entry["bulk"],
        entry["style"],
    )


def _motion_arrays(m: Motion) -> dict[str, np.ndarray]:
    """A character's version of a clip as the cache stores it (float32)."""
    return {
        "rotations": m.rotations.astype(np.float32),
        "root": m.root_positions.astype(np.float32),
        "foot_contacts": np.asarray(m.meta["foot_contacts"], dtype=bool),
    }


def _motion_from(arrays: Mapping[str, np.ndarray], clip: str, character: Character) -> Motion:
    """Inverse of :func:`_motion_arrays` (float64, unit quaternions again)."""
    q = arrays["rotations"].astype(np.float64)
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    return Motion(
        character.skeleton.copy(),
        q,
        arrays["root"].astype(np.float64),
        FPS,
        name=clip,
        meta={
            "family": clip.rsplit("_", 1)[0],
            "performer": character.name,
            "foot_contacts": arrays["foot_contacts"],
        },
    )


def save(data: MixamoConventionData, path: Path) -> None:
    """Write the profile as one ``.npz`` (atomically)."""
    arrays: dict[str, np.ndarray] = {}
    index: dict = {
        "version": FORMAT_VERSION,
        "specs": _specs_key(),
        "characters": [],
        "clips": list(data.clips),
    }
    for name, c in data.characters.items():
        stored, entry = _character_arrays(c)
        arrays.update({f"char/{name}/{k}": v for k, v in stored.items()})
        index["characters"].append(entry)
    for clip, versions in data.clips.items():
        for name, m in versions.items():
            arrays.update({f"clip/{clip}/{name}/{k}": v for k, v in _motion_arrays(m).items()})
    arrays["index"] = np.array(json.dumps(index))
    with atomic_write(path) as f:
        np.savez_compressed(f, **arrays)


def read(path: Path) -> MixamoConventionData:
    """Read what :func:`save` wrote."""
    with np.load(path, allow_pickle=False) as z:
        index = json.loads(str(z["index"]))
        if index.get("version") != FORMAT_VERSION:
            raise DataError(
                f"{path} has format {index.get('version')}, expected {FORMAT_VERSION}; delete it "
                "to rebuild"
            )
        chars = {
            e["name"]: _character_from({k: z[f"char/{e['name']}/{k}"] for k in CHARACTER_ARRAYS}, e)
            for e in index["characters"]
        }
        clips = {
            clip: {
                n: _motion_from({k: z[f"clip/{clip}/{n}/{k}"] for k in MOTION_ARRAYS}, clip, c)
                for n, c in chars.items()
            }
            for clip in index["clips"]
        }
    return MixamoConventionData(chars, clips)


def _built_key(path: Path) -> str | None:
    with np.load(path, allow_pickle=False) as z:
        return json.loads(str(z["index"])).get("specs")


def build_mixamo_convention(force: bool = False) -> Path:
    """Build the profile into the cache unless it is there and current (``force`` rebuilds)."""
    path = data_path()
    if not force and _is_built():
        return path
    print(
        "building the Mixamo-convention synthetic profile (once, about 3.5 minutes) ...",
        file=sys.stderr,
    )
    save(generate(), path)
    load_mixamo_convention.cache_clear()
    return path


@lru_cache(maxsize=1)
def load_mixamo_convention() -> MixamoConventionData:
    """The built profile (built into the cache on first use; cached in-process)."""
    return read(build_mixamo_convention())


def _is_built() -> bool:
    path = data_path()
    return path.exists() and _built_key(path) == _specs_key()


def mixamo_convention_versions(pairs: Iterable[ScenarioPair]) -> MixamoConventionData:
    """Every character of the profile and at least each pair's clip on its source and on its
    target character (the source clip and the ground truth of an evaluation case).

    From the built profile when the cache holds it (then every version); otherwise only those
    versions are authored, now, and not cached (about 0.1 s each: an evaluation's 144 versions in
    ~15 s against ~3 minutes for the whole profile, which only training needs). Either way the
    values are the same: both pass through the cache's float32 storage.

    Args:
        pairs: evaluation pairs of :func:`mixamo_convention_split` (``ScenarioPair``).
    """
    if _is_built():
        return load_mixamo_convention()
    built = _characters()
    radii = _body_radii(built)
    characters = {n: _character_from(*_character_arrays(c)) for n, c in built.items()}
    wanted = {(p.motion.clip, name) for p in pairs for name in (p.source, p.target)}
    clips: dict[str, dict[str, Motion]] = {}
    for clip, name in sorted(wanted):
        motion = _author(clip, built[name], radii[name])
        clips.setdefault(clip, {})[name] = _motion_from(
            _motion_arrays(motion), clip, characters[name]
        )
    return MixamoConventionData(characters, clips)


def mixamo_convention_split() -> TDCNSplits:
    """The TDCN four-scenario split of this profile's characters and clips (the manifest's TDCN
    split parameters; a ``MotionId``'s clip is ``MotionId.clip``)."""
    params = dict(source("synthetic")["splits"]["tdcn"]["params"])
    return tdcn_splits(mixamo_convention_names(), MOTION_FAMILIES, **params)
