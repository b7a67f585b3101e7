"""The embedded ``synthetic`` dataset: every named character and a motion library, built once into
the cache (``<cache>/synthetic/dataset.npz``) and loaded from there.

Each clip is authored (keyframes + IK, :mod:`retarget_lib.data.synthetic.motions`) on one
*performer* character, so its contacts are exact on that body; performers rotate over all
characters. Any other character's version of a clip is its ground truth
(:func:`retarget_lib.core.transfer. retarget_ground_truth`) — like Mixamo, where every motion exists
on every character.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from ...core.character import Character
from ...core.motion import Motion
from ...core.skeleton import canonical22_skeleton
from ...files import DataError, atomic_write, cache_dir, quantised_sha256
from ..manifest import source
from .characters import CHARACTER_NAMES, make_character
from .motions import FPS, MOTION_FAMILIES, HandContact, body_radii_from_mesh, make_motion

FORMAT_VERSION = 1


def dataset_path() -> Path:
    """Where the built dataset lives."""
    return cache_dir("synthetic") / "dataset.npz"


@dataclass
class SyntheticClip:
    """One clip of the motion library.

    Attributes:
        motion: the clip on its performer (canonical 22 joints, 30 fps, metres).
        family: motion family (one of :data:`~retarget_lib.data.synthetic.motions.MOTION_FAMILIES`).
        seed: style seed within the family.
        performer: name of the character the clip was authored on.
        foot_contacts: ``(T, 2)`` bool, left/right foot flat and still (as authored).
        joint_contacts: ``(T, 4)`` bool per :data:`~retarget_lib.core.skeleton.FOOT_CONTACT_JOINTS`
            (a toe can stay planted while its heel lifts).
        hand_contacts: hand-contact intervals (as authored).
    """

    motion: Motion
    family: str
    seed: int
    performer: str
    foot_contacts: np.ndarray
    joint_contacts: np.ndarray
    hand_contacts: list[HandContact]

    @property
    def name(self) -> str:
        return self.motion.name


@dataclass
class SyntheticDataset:
    """Characters by name and the clip list."""

    characters: dict[str, Character]
    clips: list[SyntheticClip]

    def clip(self, name: str) -> SyntheticClip:
        """The clip called ``name`` (e.g. ``"walk_003"``)."""
        for c in self.clips:
            if c.name == name:
                return c
        raise KeyError(f"no clip {name!r}; e.g. {[c.name for c in self.clips[:3]]}")

    def family(self, family: str) -> list[SyntheticClip]:
        """All clips of one family."""
        if family not in MOTION_FAMILIES:
            raise KeyError(f"unknown family {family!r}; choose from {MOTION_FAMILIES}")
        return [c for c in self.clips if c.family == family]


def build_config() -> dict:
    """The ``build`` section of the manifest's ``synthetic`` entry."""
    return dict(source("synthetic")["build"])


def generate(
    seed: int, clips_per_family: int, characters: list[Character] | None = None
) -> SyntheticDataset:
    """Build the dataset in memory (deterministic in ``seed``).

    Args:
        seed: base seed; clip ``k`` of a family gets seed ``seed * 1000 + k``.
        clips_per_family: clips per family.
        characters: the characters (default: every named character).
    """
    characters = characters or [make_character(n) for n in CHARACTER_NAMES]
    radii = {
        c.name: body_radii_from_mesh(c.skeleton, c.rest_vertices, c.weights) for c in characters
    }
    clips = []
    for fi, family in enumerate(MOTION_FAMILIES):
        for k in range(clips_per_family):
            performer = characters[(fi * clips_per_family + k) % len(characters)]
            clip_seed = seed * 1000 + k
            m = make_motion(family, performer.skeleton, clip_seed, body_radii=radii[performer.name])
            m.name = f"{family}_{k:03d}"
            clips.append(
                SyntheticClip(
                    m,
                    family,
                    clip_seed,
                    performer.name,
                    np.asarray(m.meta["foot_contacts"], dtype=bool),
                    np.asarray(m.meta["joint_contacts"], dtype=bool),
                    [HandContact(*h) for h in m.meta.get("hand_contacts", [])],
                )
            )
    return SyntheticDataset({c.name: c for c in characters}, clips)


def save_dataset(ds: SyntheticDataset, path: Path) -> None:
    """Write the dataset as one ``.npz`` (atomically)."""
    arrays: dict[str, np.ndarray] = {}
    index = {"version": FORMAT_VERSION, "characters": [], "clips": []}
    for name, c in ds.characters.items():
        arrays[f"char/{name}/offsets"] = c.skeleton.offsets
        arrays[f"char/{name}/vertices"] = c.rest_vertices.astype(np.float32)
        arrays[f"char/{name}/faces"] = c.faces.astype(np.int32)
        arrays[f"char/{name}/weights"] = c.weights.astype(np.float32)
        index["characters"].append(
            {"name": name, "bulk": float(c.bulk), "style": _jsonable(c.style)}
        )
    for i, clip in enumerate(ds.clips):
        arrays[f"clip/{i}/rotations"] = clip.motion.rotations.astype(np.float32)
        arrays[f"clip/{i}/root"] = clip.motion.root_positions.astype(np.float32)
        arrays[f"clip/{i}/offsets"] = clip.motion.skeleton.offsets
        arrays[f"clip/{i}/foot_contacts"] = clip.foot_contacts
        arrays[f"clip/{i}/joint_contacts"] = clip.joint_contacts
        index["clips"].append(
            {
                "name": clip.name,
                "family": clip.family,
                "seed": clip.seed,
                "performer": clip.performer,
                "hand_contacts": [list(map(_jsonable, h)) for h in clip.hand_contacts],
            }
        )
    arrays["index"] = np.array(json.dumps(index))
    with atomic_write(path) as f:
        np.savez_compressed(f, **arrays)


def _jsonable(x):
    if isinstance(x, dict):
        return {k: _jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    if isinstance(x, np.generic):
        return x.item()
    if isinstance(x, np.ndarray):
        return x.tolist()
    return x


def read_dataset(path: Path) -> SyntheticDataset:
    """Read a dataset written by :func:`save_dataset`."""
    with np.load(path, allow_pickle=False) as z:
        index = json.loads(str(z["index"]))
        if index.get("version") != FORMAT_VERSION:
            raise DataError(
                f"{path} has format {index.get('version')}, expected {FORMAT_VERSION}; "
                "run `retarget data build --force`"
            )
        chars = {}
        for entry in index["characters"]:
            n = entry["name"]
            chars[n] = Character(
                n,
                canonical22_skeleton(z[f"char/{n}/offsets"]),
                z[f"char/{n}/vertices"].astype(np.float64),
                z[f"char/{n}/faces"].astype(np.int64),
                z[f"char/{n}/weights"].astype(np.float64),
                entry["bulk"],
                entry["style"],
            )
        clips = []
        for i, entry in enumerate(index["clips"]):
            fc, jc = z[f"clip/{i}/foot_contacts"], z[f"clip/{i}/joint_contacts"]
            hc = [HandContact(*h) for h in entry["hand_contacts"]]
            m = Motion(
                canonical22_skeleton(z[f"clip/{i}/offsets"]),
                z[f"clip/{i}/rotations"].astype(np.float64),
                z[f"clip/{i}/root"].astype(np.float64),
                FPS,
                name=entry["name"],
                meta={
                    "family": entry["family"],
                    "performer": entry["performer"],
                    "foot_contacts": fc,
                    "joint_contacts": jc,
                    "hand_contacts": hc,
                },
            )
            m.rotations /= np.linalg.norm(m.rotations, axis=-1, keepdims=True)
            clips.append(
                SyntheticClip(m, entry["family"], entry["seed"], entry["performer"], fc, jc, hc)
            )
    return SyntheticDataset(chars, clips)


def fingerprint_of(path: Path) -> str:
    """SHA-256 over the dataset's arrays rounded to 0.1 mm (lengths) / 1e-4 (rotations, weights)
    (:func:`~retarget_lib.files.quantised_sha256`).

    Robust to last-bit float differences between CPUs, but any real change to a character or clip
    changes it.
    """
    with np.load(path, allow_pickle=False) as z:
        return quantised_sha256(((key, z[key]) for key in sorted(z.files)), 1e4)


def build_synthetic(force: bool = False) -> Path:
    """Build the dataset into the cache unless it is already there (``force`` rebuilds)."""
    path = dataset_path()
    if path.exists() and not force:
        return path
    cfg = build_config()
    save_dataset(generate(int(cfg["seed"]), int(cfg["clips_per_family"])), path)
    load_synthetic.cache_clear()
    return path


@lru_cache(maxsize=1)
def load_synthetic() -> SyntheticDataset:
    """The built dataset (cached in-process). Raises :class:`DataError` if it was not built."""
    path = dataset_path()
    if not path.exists():
        raise DataError(f"synthetic dataset not built ({path}); run `retarget data build`")
    return read_dataset(path)
