"""Capacity checks: can a paper-form model learn its own training set?

A model trained on a tiny set (``data.max_clips`` clips performed by ``data.max_characters``
characters, no augmentation) for as long as it takes must fit it: its Table 4 error on the pairs it
was trained on falls below the protocol copy row (``copy-unscaled``: the source's local rotations
and root positions copied, NKN's "copy input quaternions and velocities") and its identity (a clip
retargeted onto its own performer, window by window) below :data:`IDENTITY_BAR_PCT` % of the
height. A model that
cannot overfit four clips has a defect, not a budget problem.

The cases are built from the very :class:`~retarget_lib.training.tdcn_data.TrainingClips` the run
trained on (the config's source, cut by its ``max_clips`` / ``max_characters``): every ordered
pair of its characters on every clip, the pairs of a character with itself being the identity.
Scores follow the protocol of Table 4 (:func:`~retarget_lib.evaluation.tdcn.cases.evaluate_case`,
short: 120-frame windows, ``||x - x̂||²`` summed over x, y, z, averaged over joints and frames,
divided by the target's height).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
import pandas as pd

from ..methods.registry import get_method
from ..training.tdcn_data import TrainingClips, config_training_clips
from .tdcn.cases import EvalCase, Method, evaluate_case, short_chunks

__all__ = [
    "IDENTITY_BAR_PCT",
    "PROTOCOL_COPY",
    "CapacityResult",
    "capacity_cases",
    "capacity_clips",
    "capacity_check",
]

#: the identity bar of a capacity check, % of the target's height
IDENTITY_BAR_PCT = 2.0
#: the protocol copy row a fitted model must beat (NKN's Table 1 copy, TDCN's Table 4 protocol)
PROTOCOL_COPY = "copy-unscaled"


def capacity_clips(config: Mapping) -> TrainingClips:
    """The training set of a capacity config: its ``data.source`` cut to ``data.max_clips`` clips
    of ``data.max_characters`` characters, exactly what
    :class:`~retarget_lib.training.tdcn.RetargetTraining` trains on
    (:func:`~retarget_lib.training.tdcn_data.config_training_clips`)."""
    return config_training_clips(config["data"])


def capacity_cases(clips: TrainingClips) -> list[EvalCase]:
    """Every ordered pair of the set's characters on every clip (scenario 1: a pair of two
    characters, 0: a character with itself)."""
    cases = []
    for k, clip in enumerate(clips.clip_names):
        for a, source in enumerate(clips.characters):
            for b, target in enumerate(clips.characters):
                truth = clips.motion(b, k)
                cases.append(
                    EvalCase(
                        int(a != b),
                        source,
                        target,
                        clip,
                        clips.motion(a, k),
                        truth.skeleton,
                        truth,
                    )
                )
    return cases


@dataclass(frozen=True)
class CapacityResult:
    """A capacity check's figures.

    Attributes:
        model_short: the model's mean short score over the pairs of two characters (cm²/cm).
        copy_short: :data:`PROTOCOL_COPY`'s on the same pairs.
        identity_pct: the model's mean joint position error on a character's own clips (the short
            windows), % of H.
        per_case: one row per case and method.
    """

    model_short: float
    copy_short: float
    identity_pct: float
    per_case: pd.DataFrame

    @property
    def passed(self) -> bool:
        """Below the copy row and within the identity bar."""
        return self.model_short < self.copy_short and self.identity_pct <= IDENTITY_BAR_PCT

    def summary(self) -> str:
        """One line: the three figures and the verdict."""
        return (
            f"train short {self.model_short:.4f} vs {PROTOCOL_COPY} {self.copy_short:.4f}; "
            f"identity {self.identity_pct:.2f} % of height (bar {IDENTITY_BAR_PCT}); "
            + ("PASS" if self.passed else "FAIL")
        )


def _identity_pct(method: Method, case: EvalCase) -> float:
    """Mean joint position error of a clip onto its own performer, % of its height, over the short
    protocol's windows (each retargeted on its own, as the short score; the real-character table's
    identity uses 60-frame clips)."""
    truth = case.truth.global_positions()
    errors = []
    for a, b in short_chunks(case.source.num_frames):
        out = method(case.source.slice(a, b), case.target).global_positions()
        errors.append(np.linalg.norm(out - truth[a:b], axis=-1).mean())
    return 100.0 * float(np.mean(errors) / case.target.height())


def capacity_check(model: Method, cases: list[EvalCase]) -> CapacityResult:
    """Score ``model`` and the protocol copy row on ``cases`` (:func:`capacity_cases`)."""
    copy = get_method(PROTOCOL_COPY).retargeter()
    rows = []
    for case in cases:
        for name, method in (("model", model), (PROTOCOL_COPY, copy)):
            scores = evaluate_case(method, case)
            rows.append(
                {
                    "method": name,
                    "pair": case.scenario,
                    "source": case.source_name,
                    "target": case.target_name,
                    "clip": case.clip,
                    "short": scores["short"],
                    "identity_pct": _identity_pct(method, case) if not case.scenario else np.nan,
                }
            )
    per_case = pd.DataFrame(rows)
    pairs = per_case[per_case.pair == 1]
    short = pairs.groupby("method")["short"].mean()
    identity = per_case[(per_case.pair == 0) & (per_case.method == "model")]["identity_pct"]
    return CapacityResult(
        float(short["model"]), float(short[PROTOCOL_COPY]), float(identity.mean()), per_case
    )
