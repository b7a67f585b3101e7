"""The identity check: retargeting a motion onto the skeleton that performs it must return it.

When the target is the source's own skeleton the right answer is the input (TDCN trains on 50 %
such pairs, Sec. 5, for exactly this case). :func:`identity_errors` retargets each clip onto its
own skeleton and measures how far every joint moves, root-relative and in centimetres **at a
1.7 m body** (errors are scaled by ``1.7 / H``, ``H`` the NKN/TDCN height, so small and tall
characters count alike). The root's own error is reported apart.

:func:`identity_clips` is the standard set: held-out synthetic test clips on a training and a test
character, two synthetic clips on the unseen mannequin-x body, and the three real CMU clips.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, NamedTuple

import numpy as np
import pandas as pd

from ..core.character import Character
from ..core.motion import Motion
from ..core.skeleton import J
from ..core.transfer import retarget_ground_truth
from ..data.sources.cmu import CMU_CLIPS, load_cmu_clip
from ..data.sources.mannequin import load_mannequin
from ..data.synthetic.dataset import load_synthetic

__all__ = [
    "REFERENCE_HEIGHT",
    "IdentityClip",
    "identity_clips",
    "identity_error",
    "identity_errors",
]

#: errors are reported in cm for a body of this height (metres)
REFERENCE_HEIGHT = 1.7
_HANDS = [J["LeftHand"], J["RightHand"]]
_FEET = [J["LeftFoot"], J["RightFoot"], J["LeftToeBase"], J["RightToeBase"]]


class IdentityClip(NamedTuple):
    """One clip of the identity check: ``group`` (``synthetic``, ``mannequin-x``, ``cmu``),
    a name, the motion (canonical 22 joints) and, where it has one, the skinned character that
    performs it (the CMU clips have none)."""

    group: str
    name: str
    motion: Motion
    character: Character | None = None


def identity_clips(
    synthetic_clips: tuple[str, ...] = (
        "walk_008",
        "punch_009",
        "squat_009",
        "wave_000",
        "clap_008",
    ),
    characters: tuple[str, ...] = ("bram", "ada"),
    mannequin_clips: tuple[str, ...] = ("walk_008", "clap_009"),
) -> list[IdentityClip]:
    """The standard identity set (see the module docstring).

    Args:
        synthetic_clips: synthetic clips (``family_seed``); seeds 8-9 and the families wave/clap
            are never trained on (the TDCN split).
        characters: characters that perform them (``bram`` is a training character, ``ada`` a test
            one).
        mannequin_clips: clips performed by mannequin-x (never trained on).
    """
    ds = load_synthetic()
    out = []
    for ch in characters:
        for name in synthetic_clips:
            character = ds.characters[ch]
            out.append(
                IdentityClip(
                    "synthetic",
                    f"{name}@{ch}",
                    retarget_ground_truth(ds.clip(name).motion, character.skeleton),
                    character,
                )
            )
    body = load_mannequin()
    for name in mannequin_clips:
        out.append(
            IdentityClip(
                "mannequin-x",
                f"{name}@mannequin-x",
                retarget_ground_truth(ds.clip(name).motion, body.skeleton),
                body,
            )
        )
    for name in CMU_CLIPS:
        out.append(IdentityClip("cmu", name, load_cmu_clip(name)))
    return out


def identity_error(
    method: Callable[[Motion, Any], Motion], motion: Motion, target: Any = None
) -> dict[str, float]:
    """Retarget ``motion`` onto its own skeleton with ``method`` and measure the change.

    Args:
        method: ``(source motion, target) -> motion``.
        motion: canonical-22 motion.
        target: what ``method`` is given as the target: the motion's own skeleton (default) or
            the character that performs it (methods that need a mesh).

    Returns:
        ``mean``, ``hands``, ``feet``: mean root-relative joint displacement (cm at
        :data:`REFERENCE_HEIGHT`) over all joints / the hands / the feet and toes; ``root``: mean
        root displacement (same unit).
    """
    out = method(motion, motion.skeleton if target is None else target)
    scale = 100.0 * REFERENCE_HEIGHT / motion.skeleton.height()
    p, q = out.global_positions(), motion.global_positions()
    d = np.linalg.norm((p - p[:, :1]) - (q - q[:, :1]), axis=-1) * scale  # (T, J)
    return {
        "mean": float(d.mean()),
        "hands": float(d[:, _HANDS].mean()),
        "feet": float(d[:, _FEET].mean()),
        "root": float(np.linalg.norm(p[:, 0] - q[:, 0], axis=-1).mean() * scale),
    }


def identity_errors(
    method: Callable[[Motion, Any], Motion],
    clips: list[IdentityClip] | None = None,
    characters: bool = False,
) -> pd.DataFrame:
    """:func:`identity_error` on every clip (default :func:`identity_clips`).

    Args:
        method: ``(source motion, target skeleton or character) -> motion``.
        clips: the clips.
        characters: give ``method`` the performing character (skinned; e.g. the contact-aware
            method) instead of the skeleton; clips without one (CMU) are left out.

    Returns:
        One row per clip: ``group``, ``clip``, ``mean``, ``hands``, ``feet``, ``root``.
    """
    clips = identity_clips() if clips is None else clips
    if characters:
        clips = [c for c in clips if c.character is not None]
    return pd.DataFrame(
        [
            {
                "group": c.group,
                "clip": c.name,
                **identity_error(method, c.motion, c.character if characters else None),
            }
            for c in clips
        ]
    )
