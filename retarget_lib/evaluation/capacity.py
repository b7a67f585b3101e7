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

The contact network (Villegas et al. 2021) gets the same check on its own protocol
(:func:`contact_capacity_check`): trained on ``data.max_clips`` synthetic clips of its
``data.train_characters``, every clip retargeted by the network alone (no ESO) onto every training
character; its Table 1 position error (``global position MSE``, the same normalised squared error
on whole clips) on the pairs of two characters must fall below Table 1's copy row on those pairs,
and its identity below the same bar. The ground truth is each clip authored on the target
(:func:`~retarget_lib.data.synthetic.motions.make_motion` with the clip's family and seed), as in
Table 1. It is trained without ground truth, on an energy, so its check also reads that energy
at the ground truth (:func:`contact_energy_at_truth`, on each clip onto its own performer, where
the truth is the source): when the truth's energy is above the network's, the energy's minimum is
not the truth, and no network trained on it can pass the identity bar.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np
import pandas as pd
import torch

from ..core.character import Character
from ..core.motion import Motion
from ..data.synthetic.dataset import dataset_path, fingerprint_of, load_synthetic
from ..data.synthetic.motions import body_radii_from_mesh, make_motion
from ..methods.contact import contact_clip, retarget_with_network
from ..methods.registry import get_method
from ..training.contact import (
    ContactTraining,
    identity_truth,
    synthetic_clip_key,
    synthetic_training_clips,
)
from ..training.tdcn_data import TrainingClips, config_training_clips
from .contact.cases import foot_contact_accuracy
from .tdcn.cases import EvalCase, Method, evaluate_case, normalized_mse, short_chunks

__all__ = [
    "IDENTITY_BAR_PCT",
    "PROTOCOL_COPY",
    "CapacityResult",
    "capacity_cases",
    "capacity_clips",
    "capacity_check",
    "CONTACT_COPY",
    "contact_capacity_cases",
    "contact_capacity_check",
    "contact_network_method",
    "EnergyAtTruth",
    "contact_energy_at_truth",
]

#: the identity bar of a capacity check, % of the target's height
IDENTITY_BAR_PCT = 2.0
#: the protocol copy row a fitted model must beat (NKN's Table 1 copy, TDCN's Table 4 protocol)
PROTOCOL_COPY = "copy-unscaled"
#: the copy row of the contact paper's Table 1 (the local rotations, the root by the leg ratio)
CONTACT_COPY = "copy"


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
        model_short: the model's mean short score over the pairs of two characters (cm²/cm; the
            contact check: Table 1's global position MSE on whole clips).
        copy_short: the copy row's on the same pairs.
        identity_pct: the model's mean joint position error on a character's own clips (the short
            windows), % of H.
        per_case: one row per case and method.
        measure: what ``model_short`` is, for the summary.
        copy_row: the copy row compared with (:data:`PROTOCOL_COPY`, :data:`CONTACT_COPY`).
    """

    model_short: float
    copy_short: float
    identity_pct: float
    per_case: pd.DataFrame
    measure: str = "train short"
    copy_row: str = PROTOCOL_COPY

    @property
    def passed(self) -> bool:
        """Below the copy row and within the identity bar."""
        return self.model_short < self.copy_short and self.identity_pct <= IDENTITY_BAR_PCT

    def summary(self) -> str:
        """One line: the three figures and the verdict."""
        return (
            f"{self.measure} {self.model_short:.4f} vs {self.copy_row} {self.copy_short:.4f}; "
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
        errors.append(_error_pct(out, truth[a:b], case.target.height()))
    return float(np.mean(errors))


def _error_pct(pred: np.ndarray, truth: np.ndarray, height: float) -> float:
    """Mean joint position error of ``pred`` against ``truth`` (``(T, J, 3)`` metres), % of
    ``height``: the identity measure of a capacity check."""
    return 100.0 * float(np.linalg.norm(pred - truth, axis=-1).mean() / height)


def _summarise(per_case: pd.DataFrame, column: str, **labels: str) -> CapacityResult:
    """The model's and the copy row's mean ``column`` over the pairs of two characters, and the
    model's mean identity over the pairs of a character with itself."""
    pairs = per_case[per_case.pair == 1].groupby("method")[column].mean()
    identity = per_case[(per_case.pair == 0) & (per_case.method == "model")]["identity_pct"]
    copy_row = labels.get("copy_row", PROTOCOL_COPY)
    return CapacityResult(
        float(pairs["model"]), float(pairs[copy_row]), float(identity.mean()), per_case, **labels
    )


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
    return _summarise(pd.DataFrame(rows), "short")


# ----------------------------------------------------------------------------- contact network
@dataclass(frozen=True)
class ContactCapacityCase:
    """One training clip onto one training character, with its ground truth.

    Attributes:
        source_character: the clip's performer.
        target: the character retargeted onto.
        source: the clip on its performer.
        truth: the same clip authored on ``target``.
        foot_contacts: ``(T, 4)`` the source's detected foot contacts (Sec. 3.4).
    """

    source_character: Character
    target: Character
    source: Motion
    truth: Motion
    foot_contacts: np.ndarray

    @property
    def identity(self) -> bool:
        """A clip onto its own performer."""
        return self.source_character.name == self.target.name


def contact_capacity_cases(config: Mapping) -> list[ContactCapacityCase]:
    """Every clip the contact run trained on
    (:func:`~retarget_lib.training.contact.synthetic_training_clips`) onto every training
    character.

    Raises:
        ValueError: the config's data is not the synthetic source or has no ``max_clips``.
    """
    data = config["data"]
    if data.get("source", "synthetic") != "synthetic" or not data.get("max_clips"):
        raise ValueError("a contact capacity check needs data.source: synthetic and data.max_clips")
    ds = load_synthetic()
    key = fingerprint_of(dataset_path())[:12]
    targets = [ds.characters[n] for n in data["train_characters"]]
    radii = {c.name: body_radii_from_mesh(c.skeleton, c.rest_vertices, c.weights) for c in targets}
    cases = []
    for clip in synthetic_training_clips(dict(data), ds):
        performer = ds.characters[clip.performer]
        feet = contact_clip(clip.motion, performer, synthetic_clip_key(key, clip)).foot_contacts
        for target in targets:
            truth = (
                clip.motion
                if target.name == performer.name
                else make_motion(
                    clip.family, target.skeleton, clip.seed, body_radii=radii[target.name]
                )
            )
            truth = truth.slice(0, clip.motion.num_frames)
            cases.append(ContactCapacityCase(performer, target, clip.motion, truth, feet))
    return cases


def contact_capacity_check(
    model: Callable[[Motion, Character], Motion], cases: list[ContactCapacityCase]
) -> CapacityResult:
    """Score the network (``model(source, target character)``, e.g.
    :func:`~retarget_lib.methods.contact.retarget_with_network` bound to a model) and
    :data:`CONTACT_COPY` on ``cases``: global position MSE (Table 1), foot contact accuracy, and
    the identity error (% of ``H``, every frame of a clip onto its performer)."""
    copy = get_method(CONTACT_COPY).retargeter()
    rows = []
    for case in cases:
        for name, out in (
            ("model", model(case.source, case.target)),
            (CONTACT_COPY, copy(case.source, case.target.skeleton)),
        ):
            pred, truth = out.global_positions(), case.truth.global_positions()
            h = case.target.skeleton.height()
            rows.append(
                {
                    "method": name,
                    "pair": int(not case.identity),
                    "source": case.source_character.name,
                    "target": case.target.name,
                    "clip": case.source.name,
                    "global position MSE": normalized_mse(pred, truth, h),
                    "foot contact accuracy": foot_contact_accuracy(out, case.foot_contacts),
                    "identity_pct": _error_pct(pred, truth, h) if case.identity else np.nan,
                }
            )
    return _summarise(
        pd.DataFrame(rows),
        "global position MSE",
        measure="train global position MSE",
        copy_row=CONTACT_COPY,
    )


def contact_network_method(model) -> Callable[[Motion, Character], Motion]:
    """``(source, target character) -> motion`` with the network alone (no ESO)."""
    return lambda source, target: retarget_with_network(model, source, target)


@dataclass(frozen=True)
class EnergyAtTruth:
    """A contact run's training energy (its Table 3 row) on windows of its clips onto their own
    performers, where the ground truth is the source itself.

    Attributes:
        row: the energy (``energy.row``).
        windows: how many (window, sampled frame) draws it is averaged over.
        network: mean of each weighted term (:data:`~retarget_lib.training.contact.LOG_TERMS`) of
            the network's output.
        truth: the same of the ground truth.
    """

    row: str
    windows: int
    network: dict[str, float]
    truth: dict[str, float]

    @property
    def truth_is_minimum(self) -> bool:
        """The truth's energy is at most the network's: the energy does not pull away from it."""
        return self.truth["total"] <= self.network["total"]

    def summary(self) -> str:
        """One line: both totals, their non-zero terms, and what it means."""

        def terms(values: dict[str, float]) -> str:
            parts = [f"{k} {v:.4g}" for k, v in values.items() if k != "total" and v > 0]
            return ", ".join(parts) or "every term 0"

        verdict = (
            "the truth is no higher than the network"
            if self.truth_is_minimum
            else "the energy's minimum is not the truth: minimising it moves off the truth"
        )
        return (
            f"{self.row} on its own clips ({self.windows} windows): network "
            f"{self.network['total']:.4g} ({terms(self.network)}), ground truth "
            f"{self.truth['total']:.4g} ({terms(self.truth)}); {verdict}"
        )


def contact_energy_at_truth(
    config: Mapping, model: torch.nn.Module, starts: int = 2, frames: int = 3
) -> EnergyAtTruth:
    """Read a contact run's training energy at the network's output and at the ground truth.

    Every training clip onto its own performer (the truth is the source: its rotations and root
    velocity, :func:`~retarget_lib.training.contact.identity_truth`), ``starts`` windows of
    ``data.window`` frames spread over the clip, each with ``frames`` sampled frames for Ej2j and
    Eint (the trainer samples one at random), weighted as at the last epoch (Efoot's ramp).

    Args:
        config: the run's merged config (its ``config.yaml``).
        model: the trained network (:func:`~retarget_lib.methods.contact.load_contact_model`).
        starts, frames: windows per clip and sampled frames per window.
    """
    trainer = ContactTraining({**config, "train": {**config["train"], "compile": False}})
    last = trainer.window - 1
    draws = [
        (clip, start, target, frame)
        for clip in trainer.clips
        for target in trainer.targets
        if target.character.name == clip.character.name
        for start in np.unique(
            np.linspace(0, clip.motion.num_frames - trainer.window, starts).astype(int)
        )
        for frame in np.unique(np.linspace(0, last, frames).astype(int))
    ]
    weights = trainer.weights.with_foot_ramp(trainer.epochs - 1, trainer.epochs)
    model.eval()
    with torch.no_grad():
        network = trainer.energies(draws, weights, network=model)
        truth = trainer.energies(draws, weights, network=identity_truth)
    return EnergyAtTruth(
        str(config["energy"]["row"]),
        len(draws),
        {k: float(v.mean()) for k, v in network.items()},
        {k: float(v.mean()) for k, v in truth.items()},
    )
