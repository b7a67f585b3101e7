"""The contact tables' cases and metrics (Villegas et al. 2021, Sec. 4, Table 1): the evaluation
profiles and rows, :class:`ContactCase`, and interpenetration, vertex contact MSE, foot contact
accuracy, global position MSE, penetration rate and foot height error of one case."""

from __future__ import annotations

from collections.abc import Collection
from dataclasses import dataclass
from functools import cache

import numpy as np

from ...core.character import Character
from ...core.measures import estimated_standing_height, foot_rest_heights
from ...core.motion import Motion
from ...core.quantities import FOOT_CONTACT_IDS
from ...data.sources.mannequin import load_mannequin
from ...data.synthetic.characters import make_character
from ...data.synthetic.motions import body_radii_from_mesh, make_motion
from ...geometry.contacts import SelfContacts, detect_foot_contacts, transfer_contacts
from ...geometry.penetration import interpenetration_score
from ...geometry.penetration_rate import penetration_rate
from ...methods.contact import (
    ContactClip,
    contact_clip,
)
from ..paper import CONTACT_PAPER_METRICS
from ..tdcn import METRES_TO_CM, normalized_mse

__all__ = [
    "CONTACT_TARGETS",
    "CONTACT_PROFILES",
    "METRICS",
    "ContactCase",
    "contact_case_names",
    "contact_cases",
    "evaluate_contact_case",
    "vertex_contact_mse",
    "foot_contact_accuracy",
    "foot_height_error",
    "foot_heights_in_contact",
]


CONTACT_SOURCE = "mannequin-x"


CONTACT_TARGETS: dict[str, tuple[str, ...]] = {
    "skinny": ("cleo", "juno", "milo"),
    "bulky": ("bram", "gus", "otto"),
}


CONTACT_RICH = ("clap", "hands_on_hips", "pray", "touch_head")


#: clips and frames of each evaluation profile
CONTACT_PROFILES: dict[str, dict] = {
    "fast": dict(
        families=CONTACT_RICH + ("walk", "punch"), seeds=(8,), max_frames=60, eval_every=3
    ),
    "paper": dict(
        families=CONTACT_RICH + ("walk", "run", "jump", "turn", "wave", "punch", "kick", "squat"),
        seeds=(8, 9),
        max_frames=None,
        eval_every=1,
    ),
}


#: the papers' four metrics, then two of ours: the penetration rate and the foot height error
METRICS = CONTACT_PAPER_METRICS + ("penetration rate", "foot height error")


#: Table 1's rows, then ours that are not the paper's: the residual network (+ ESO) and the
#: rest-compensated copy (the synthetic ground truth's convention, so a strong baseline here)
TABLE1_ROWS = ("Ours", "Efull + IK", "TDCN", "NKN", "copy", "Ours (residual)", "copy-rest")


#: Table 1 rows that are a method of the registry, run with its default checkpoint
REGISTRY_ROWS = {"TDCN": "tdcn", "NKN": "nkn", "copy": "copy", "copy-rest": "copy-rest"}


#: network rows that are not an energy of Table 3 (manifest ``row:``): our residual variant
VARIANT_ROWS = ("Efull-residual",)


#: Table 1/3 rows that are a network followed by a test-time step
EFULL_ROWS = {
    "Ours": "Efull",
    "Efull + IK": "Efull",
    "Efull + ESO": "Efull",
    "Ours (residual)": "Efull-residual",
    "Efull-residual + ESO": "Efull-residual",
}


#: the rows that run ESO after their network
ESO_ROWS = ("Ours", "Efull + ESO", "Ours (residual)", "Efull-residual + ESO")


TABLE3_ROWS = (
    "Eskel",
    "Eskel+Efoot",
    "Eskel+Efoot+Eint w/o w",
    "Eskel+Efoot+Eint",
    "Efull",
    "Efull + ESO",
    "Efull-residual",
    "Efull-residual + ESO",
)


@dataclass
class ContactCase:
    """One source clip retargeted to one target.

    Attributes:
        clip: clip name (``family_seed``).
        family: motion family; ``contact_rich`` tells whether it has hand contacts by design.
        source_character, target: the two characters.
        source: the clip on the source (canonical 22, metres).
        truth: the same clip authored on the target (ground truth).
        foot_contacts: ``(T, 4)`` bool detected on the source.
        contacts: the source's detected hand contacts, on the *target* mesh (App. F transfer).
        body_type: the target's group, ``"skinny"`` or ``"bulky"`` (Tables 5 and 6).
        contact_rich: whether the clip has hand contacts (synthetic: by design of its family).
    """

    clip: str
    family: str
    source_character: Character
    target: Character
    source: Motion
    truth: Motion
    foot_contacts: np.ndarray
    contacts: SelfContacts
    body_type: str
    contact_rich: bool


@cache
def _radii(name: str):
    c = _character(name)
    return body_radii_from_mesh(c.skeleton, c.rest_vertices, c.weights)


@cache
def _character(name: str) -> Character:
    return load_mannequin() if name == CONTACT_SOURCE else make_character(name)


def _case_keys(profile: str) -> list[tuple[str, int, str, str]]:
    """``(family, seed, clip, target)`` of every test case of ``profile``, in order."""
    if profile not in CONTACT_PROFILES:
        raise ValueError(f"unknown profile {profile!r}; choose from {list(CONTACT_PROFILES)}")
    p = CONTACT_PROFILES[profile]
    return [
        (family, seed, f"{family}_{seed:03d}", name)
        for family in p["families"]
        for seed in p["seeds"]
        for names in CONTACT_TARGETS.values()
        for name in names
    ]


def contact_case_names(profile: str = "fast") -> list[tuple[str, str]]:
    """``(clip, target)`` of every test case of ``profile``, in :func:`contact_cases`' order,
    without building any."""
    return [(clip, target) for _, _, clip, target in _case_keys(profile)]


def contact_cases(
    profile: str = "fast", only: Collection[tuple[str, str]] | None = None
) -> list[ContactCase]:
    """The test cases of ``profile`` (:data:`CONTACT_PROFILES`): every clip × every target.

    Args:
        profile: a key of :data:`CONTACT_PROFILES`.
        only: build just these ``(clip, target)`` cases (:func:`contact_case_names`), returned
            in the full order whatever order they are asked in.
    """
    keys = _case_keys(profile)
    every = {(clip, target) for _, _, clip, target in keys}
    wanted = every if only is None else set(only)
    if unknown := wanted - every:
        raise ValueError(f"no such {profile} contact cases: {sorted(unknown)}")
    max_frames = CONTACT_PROFILES[profile]["max_frames"]
    source_char = _character(CONTACT_SOURCE)
    sources: dict[str, tuple[Motion, ContactClip]] = {}  # each clip built once, for its targets
    cases = []
    for family, seed, name, target_name in keys:
        if (name, target_name) not in wanted:
            continue
        if name not in sources:
            motion = make_motion(
                family, source_char.skeleton, seed, body_radii=_radii(CONTACT_SOURCE)
            )
            motion = motion.slice(0, max_frames) if max_frames else motion
            motion.name = name
            sources[name] = (
                motion,
                contact_clip(
                    motion,
                    source_char,
                    cache_key=f"eval_{CONTACT_SOURCE}_{name}_{motion.num_frames}",
                ),
            )
        motion, clip = sources[name]
        target = _character(target_name)
        truth = make_motion(family, target.skeleton, seed, body_radii=_radii(target_name))
        cases.append(
            ContactCase(
                name,
                family,
                source_char,
                target,
                motion,
                truth.slice(0, motion.num_frames),
                clip.foot_contacts,
                transfer_contacts(clip.self_contacts, source_char, target),
                body_type=next(k for k, v in CONTACT_TARGETS.items() if target_name in v),
                contact_rich=family in CONTACT_RICH,
            )
        )
    return cases


# ----------------------------------------------------------------------------- metrics
def vertex_contact_mse(vertices: np.ndarray, contacts: SelfContacts, height: float) -> float:
    """Mean squared distance (cm²) between the vertices of every contact pair, divided by the
    height in cm, over all constrained frames; ``nan`` without contacts.

    Args:
        vertices: ``(T, V, 3)`` output mesh (metres).
        contacts: constraints on this mesh.
        height: target height (metres).
    """
    if not len(contacts):
        return float("nan")
    d = (
        vertices[contacts.frames, contacts.pairs[:, 0]]
        - vertices[contacts.frames, contacts.pairs[:, 1]]
    )
    return float((d * METRES_TO_CM).__pow__(2).sum(-1).mean() / (height * METRES_TO_CM))


def foot_contact_accuracy(output: Motion, source_contacts: np.ndarray) -> float:
    """Share of (frame, foot joint) labels on which the output's detected contacts (Sec. 3.4 at
    the output's scale, :func:`~retarget_lib.core.measures.estimated_standing_height`) agree with
    the source's."""
    detected = detect_foot_contacts(
        output.global_positions(), output.skeleton, estimated_standing_height(output.skeleton)
    )
    return float((detected == np.asarray(source_contacts, dtype=bool)).mean())


def foot_heights_in_contact(output: Motion, source_contacts: np.ndarray) -> np.ndarray:
    """Signed heights in cm of the output's heels and toes above Efoot's ground (their rest
    heights, Eq. 6; :func:`~retarget_lib.core.measures.foot_rest_heights`), at every
    (frame, foot joint) label in contact: negative = sunk into the floor.

    Args:
        output: ``(T, ...)`` motion on a canonical 22-joint skeleton (ground ``y = 0``).
        source_contacts: ``(T, 4)`` bool in :data:`~retarget_lib.core.skeleton.FOOT_CONTACT_JOINTS`
            order.

    Returns:
        ``(N,)`` cm, one per contact label (frame-major).
    """
    labels = np.asarray(source_contacts, dtype=bool)
    feet_y = output.global_positions()[:, list(FOOT_CONTACT_IDS), 1]
    return (feet_y - foot_rest_heights(output.skeleton))[labels] * METRES_TO_CM


def foot_height_error(output: Motion, source_contacts: np.ndarray) -> float:
    """Mean ``|y_j − ȳ_j|`` in cm of :func:`foot_heights_in_contact`: how far the output's heels
    and toes are from the floor where the source touches it; ``nan`` without a contact."""
    heights = foot_heights_in_contact(output, source_contacts)
    return float(np.abs(heights).mean()) if heights.size else float("nan")


def evaluate_contact_case(
    output: Motion, case: ContactCase, eint, eval_every: int = 1
) -> dict[str, float]:
    """The :data:`METRICS` of one retargeted motion.

    Args:
        output: the method's motion on ``case.target.skeleton``.
        case: the :class:`ContactCase`.
        eint: the target's ``penetration.InterpenetrationEnergy`` (geodesic weights).
        eval_every: evaluate interpenetration / penetration rate on every this many frames.
    """
    target = case.target
    vertices = target.skinned(output.rotations, output.root_positions)
    sampled = vertices[::eval_every]
    h = target.height
    rate = penetration_rate(sampled, target.faces, target.weights)
    return {
        "interpenetration": 1000.0 * interpenetration_score(eint, sampled, h),
        "vertex contact MSE": vertex_contact_mse(vertices, case.contacts, h),
        "foot contact accuracy": foot_contact_accuracy(output, case.foot_contacts),
        "global position MSE": normalized_mse(
            output.global_positions(), case.truth.global_positions(), h
        ),
        "penetration rate": float(np.nanmean(list(rate.values()))),
        "foot height error": foot_height_error(output, case.foot_contacts),
    }
