"""Evaluation of contact-aware retargeting: Tables 1, 3, 5 and 6 of Villegas et al. 2021 (Sec. 4,
App. A and D), with the paper's numbers beside ours.

**Protocol** (our analogue of the paper's, which uses Mixamo's Y-bot as an unseen skinny source and
three skinny + three bulky targets):

* source: ``mannequin-x``, a real skinned body never used in training, performing held-out clips
  (seed >= ``held_out_seed``) of contact-rich families (clap, hands on hips, pray, touch head) and
  contact-free ones;
* targets: :data:`CONTACT_TARGETS`, three skinny and three bulky synthetic characters, none of
  them a training character of the contact model;
* ground truth for the global position error: the same clip (family, seed) authored on the target
  by :func:`~retarget_lib.data.synthetic.motions.make_motion`, hand contacts solved on the target's
  own mesh (as Mixamo gives each character its own version of a motion);
* source contacts are *detected* (Sec. 3.4) and carried to the target by the App. F correspondence.

**Metrics** (Sec. 4), per (clip, target), then averaged:

* ``interpenetration``: Eq. 4 (with the geodesic weights of Eq. 5) on height-normalised vertices,
  averaged over the evaluated frames
  (:func:`~retarget_lib.geometry.penetration.interpenetration_score`); ×1000 in the tables to give
  readable magnitudes;
* ``vertex contact MSE``: for every frame with a (transferred) source contact, the squared distance
  between the two target vertices of each contact pair, in cm², divided by the target height in
  cm (the normalisation of the position error), averaged over pairs and frames;
* ``foot contact accuracy``: foot contacts detected on the output (Sec. 3.4 thresholds at the
  target's scale) against those detected on the source, share of agreeing (frame, joint) labels;
* ``global position MSE``: the NKN/TDCN normalised MSE (cm² / cm) against the ground truth;
* ``penetration rate``: share of the arm and leg vertices inside the rest of the body (mean of
  the four limbs, :func:`~retarget_lib.geometry.penetration_rate.penetration_rate`), a metric of
  later work;
* ``foot height error`` (ours): in the source's foot-contact (frame, joint) labels, the mean
  distance in cm of the output's heel or toe joint from its rest height (the ground of Eq. 6),
  :func:`foot_height_error`. The paper's foot contact accuracy counts a foot 5 cm *below* the
  floor as a contact (its toe test is "height at most 3 cm"); this column sees floating and
  sinking feet alike.

Interpenetration and the penetration rate are evaluated on every ``eval_every``-th frame (profile
``fast``: every 3rd, ``paper``: every frame).
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from functools import cache
from pathlib import Path

import numpy as np
import pandas as pd

from ..core.character import Character
from ..core.measures import estimated_standing_height, foot_rest_heights
from ..core.motion import Motion
from ..core.quantities import FOOT_CONTACT_IDS
from ..data.manifest import (
    CheckpointEntry,
    checkpoint_entries,
    default_checkpoint,
    table_checkpoints,
)
from ..data.sources.mannequin import load_mannequin
from ..data.synthetic.characters import make_character
from ..data.synthetic.motions import body_radii_from_mesh, make_motion
from ..geometry.contacts import SelfContacts, detect_foot_contacts, transfer_contacts
from ..geometry.ik import apply_foot_contact_ik
from ..geometry.penetration import InterpenetrationEnergy, interpenetration_score
from ..geometry.penetration_rate import penetration_rate
from ..losses.contact import TABLE3_ROWS as ENERGY_ROWS
from ..methods.contact import (
    contact_clip,
    load_contact_model,
    retarget_with_eso,
    retarget_with_network,
)
from ..methods.registry import get_method
from .paper import CONTACT_PAPER_METRICS, PAPER_TABLE1, PAPER_TABLE3, PAPER_TABLE5, PAPER_TABLE6
from .results import StoredResult, compare_with_stored, load_result, write_result
from .tdcn import METRES_TO_CM, normalized_mse, write_table

__all__ = [
    "CONTACT_TARGETS",
    "CONTACT_PROFILES",
    "METRICS",
    "ContactCase",
    "stored_contact_results",
    "contact_row_checkpoints",
    "rerun_cases",
    "rerun_tolerance",
    "contact_cases",
    "contact_methods",
    "evaluate_contact_case",
    "evaluate_contact_methods",
    "write_contact_tables",
    "vertex_contact_mse",
    "foot_contact_accuracy",
    "foot_height_error",
    "foot_heights_in_contact",
    "contact_tables",
    "summary_table",
    "TABLE3_STEPS",
    "ablation_steps",
    "run_contact_evaluation",
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


def contact_cases(profile: str = "fast") -> list[ContactCase]:
    """The test cases of ``profile`` (:data:`CONTACT_PROFILES`): every clip × every target."""
    if profile not in CONTACT_PROFILES:
        raise ValueError(f"unknown profile {profile!r}; choose from {list(CONTACT_PROFILES)}")
    p = CONTACT_PROFILES[profile]
    source_char = _character(CONTACT_SOURCE)
    cases = []
    for family in p["families"]:
        for seed in p["seeds"]:
            motion = make_motion(
                family, source_char.skeleton, seed, body_radii=_radii(CONTACT_SOURCE)
            )
            motion = motion.slice(0, p["max_frames"]) if p["max_frames"] else motion
            motion.name = f"{family}_{seed:03d}"
            clip = contact_clip(
                motion,
                source_char,
                cache_key=f"eval_{CONTACT_SOURCE}_{motion.name}_{motion.num_frames}",
            )
            for names in CONTACT_TARGETS.values():
                for name in names:
                    target = _character(name)
                    truth = make_motion(family, target.skeleton, seed, body_radii=_radii(name))
                    truth = truth.slice(0, motion.num_frames)
                    cases.append(
                        ContactCase(
                            motion.name,
                            family,
                            source_char,
                            target,
                            motion,
                            truth,
                            clip.foot_contacts,
                            transfer_contacts(clip.self_contacts, source_char, target),
                            body_type=next(k for k, v in CONTACT_TARGETS.items() if name in v),
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


# ----------------------------------------------------------------------------- methods
#: a contact method: (case, the target's Eint) -> motion on the target
ContactMethod = Callable[[ContactCase, object], Motion]


def _network_method(model) -> ContactMethod:
    return lambda case, eint: retarget_with_network(model, case.source, case.target)


def _ik_method(model) -> ContactMethod:
    return lambda case, eint: apply_foot_contact_ik(
        retarget_with_network(model, case.source, case.target), case.foot_contacts
    )


def _eso_method(model, eso_config: Mapping) -> ContactMethod:
    """A row that runs ESO: compiled (hundreds of frames per table repay the compilation)."""
    return lambda case, eint: retarget_with_eso(
        model,
        eso_config,
        case.source,
        case.target,
        case.contacts,
        eint,
        case.foot_contacts,
        name=f"{case.clip}->{case.target.name}",
        compile=True,
    )


def _skeleton_method(fn) -> ContactMethod:
    return lambda case, eint: fn(case.source, case.target.skeleton)


def contact_methods(
    rows: tuple[str, ...] = TABLE1_ROWS + TABLE3_ROWS,
    device: str | None = None,
    runs: Mapping[str, Path] | None = None,
) -> tuple[dict[str, ContactMethod], list[str]]:
    """The methods of the requested table rows whose checkpoints are shipped, and the rows missing
    one (reported, never faked).

    ``device`` is where the networks and ESO run (a ``--device`` name; default the CPU); ``runs``
    maps a network row to a checkpoint trained for it (e.g. the finished rows of a ``retarget
    sweep``), used instead of the shipped one.

    Table 3's network rows (the energies of :data:`~retarget_lib.losses.contact.TABLE3_ROWS`) load
    the checkpoint the manifest lists for that row (``table: contact``); :data:`EFULL_ROWS` add IK
    or ESO to the Efull network; :data:`REGISTRY_ROWS` are registry methods with their default
    checkpoints.
    """
    shipped = table_checkpoints("contact")
    models = {}

    def model(row: str):
        if row not in models:
            models[row] = load_contact_model((runs or {}).get(row, shipped[row].id), device)
        return models[row]

    methods, missing = {}, []
    for row in dict.fromkeys(rows):
        base = EFULL_ROWS.get(row, row)
        if base in ENERGY_ROWS or base in VARIANT_ROWS:
            if base not in shipped:
                missing.append(row)
                continue
            net, cfg = model(base)
            methods[row] = (
                _eso_method(net, cfg["eso"])
                if row in ESO_ROWS
                else _ik_method(net)
                if row == "Efull + IK"
                else _network_method(net)
            )
        elif row in REGISTRY_ROWS:
            methods[row] = _skeleton_method(get_method(REGISTRY_ROWS[row]).retargeter(None, device))
        else:
            raise ValueError(f"unknown contact table row {row!r}")
    return methods, missing


# ----------------------------------------------------------------------------- tables
def evaluate_contact_methods(
    methods: Mapping[str, ContactMethod],
    cases: list[ContactCase],
    eval_every: int = 1,
    same: Mapping[str, str] | None = None,
) -> pd.DataFrame:
    """Per (method, case) metrics plus the seconds each method took. ``same`` maps a row to one
    whose outputs it shares (e.g. ``"Efull + ESO" -> "Ours"``), which is then not re-run."""
    same = dict(same or {})
    eints = {}
    rows = []
    for case in cases:
        name = case.target.name
        if name not in eints:
            eints[name] = InterpenetrationEnergy(
                case.target.faces, case.target.rest_vertices, geodesic_weights=True
            )
        for row, method in methods.items():
            if row in same and same[row] in methods:
                continue
            began = time.perf_counter()
            output = method(case, eints[name])
            seconds = time.perf_counter() - began
            metrics = evaluate_contact_case(output, case, eints[name], eval_every)
            for r in [row] + [k for k, v in same.items() if v == row and k in methods]:
                rows.append(
                    {
                        "method": r,
                        "clip": case.clip,
                        "family": case.family,
                        "source": case.source_character.name,
                        "target": name,
                        "body": case.body_type,
                        "contact_rich": case.contact_rich,
                        "frames": case.source.num_frames,
                        "seconds": seconds,
                        **metrics,
                    }
                )
    return pd.DataFrame(rows)


def summary_table(
    per_case: pd.DataFrame, rows: tuple[str, ...], paper: Mapping[str, tuple], mask=None
) -> pd.DataFrame:
    """One row per table row: the mean of each of :data:`METRICS` over the cases (``mask``
    selects some), ``"ours <metric>"``, beside the paper's values ``paper`` (row -> the four
    :data:`~retarget_lib.evaluation.paper.CONTACT_PAPER_METRICS`), ``"paper <metric>"``."""
    data = per_case if mask is None else per_case[mask]
    ours = data.groupby("method")[list(METRICS)].mean()
    out = []
    for row in dict.fromkeys(list(rows) + list(paper)):
        r = {f"ours {m}": (ours.loc[row, m] if row in ours.index else np.nan) for m in METRICS}
        r.update(
            {
                f"paper {m}": v
                for m, v in zip(CONTACT_PAPER_METRICS, paper.get(row, (np.nan,) * 4), strict=False)
            }
        )
        out.append(pd.Series(r, name=row))
    cols = [
        c
        for m in METRICS
        for c in (f"ours {m}", f"paper {m}")
        if not (c.startswith("paper") and m not in CONTACT_PAPER_METRICS)
    ]
    return pd.DataFrame(out)[cols]


def contact_tables(per_case: pd.DataFrame) -> dict[str, pd.DataFrame]:
    """Tables 1, 3, 5 (skinny targets), 6 (bulky targets) from per-case metrics."""
    return {
        "table1": summary_table(per_case, TABLE1_ROWS, PAPER_TABLE1),
        "table3": summary_table(per_case, TABLE3_ROWS, PAPER_TABLE3),
        "table5": summary_table(per_case, TABLE1_ROWS, PAPER_TABLE5, per_case["body"] == "skinny"),
        "table6": summary_table(per_case, TABLE1_ROWS, PAPER_TABLE6, per_case["body"] == "bulky"),
    }


#: Table 3's ablation steps: each adds one ingredient to the row before it
TABLE3_STEPS = (
    ("Eskel", "Eskel+Efoot"),
    ("Eskel+Efoot", "Eskel+Efoot+Eint"),
    ("Eskel+Efoot+Eint w/o w", "Eskel+Efoot+Eint"),
    ("Eskel+Efoot+Eint", "Efull"),
    ("Efull", "Efull + ESO"),
)


def ablation_steps(
    table3: pd.DataFrame, steps: tuple[tuple[str, str], ...] = TABLE3_STEPS
) -> pd.DataFrame:
    """What each Table 3 step does to each metric, here and in the paper.

    Args:
        table3: :func:`contact_tables`'s ``"table3"`` (``ours <metric>`` and ``paper <metric>``
            columns).
        steps: ``(before, after)`` row pairs.

    Returns:
        One row per step and metric: ``before``, ``after``, ``ours change`` and ``paper change``
        (``after − before``) and ``same direction`` (both changes have the same sign; ``False`` if
        either is zero or missing).
    """
    out = []
    for before, after in steps:
        for metric in CONTACT_PAPER_METRICS:
            ours = table3.loc[after, f"ours {metric}"] - table3.loc[before, f"ours {metric}"]
            paper = table3.loc[after, f"paper {metric}"] - table3.loc[before, f"paper {metric}"]
            out.append(
                {
                    "step": f"{before} → {after}",
                    "metric": metric,
                    "ours change": ours,
                    "paper change": paper,
                    "same direction": bool(np.sign(ours) * np.sign(paper) > 0),
                }
            )
    return pd.DataFrame(out).set_index(["step", "metric"])


def contact_row_checkpoints(
    rows: tuple[str, ...] = TABLE1_ROWS + TABLE3_ROWS, runs: Mapping[str, Path] | None = None
) -> dict[str, CheckpointEntry | Path]:
    """Row -> the checkpoint that row runs (:func:`contact_methods`): a network row's own (or its
    ``runs`` replacement), the registry rows' defaults (TDCN, NKN); copy rows need none."""
    shipped, entries, runs = table_checkpoints("contact"), checkpoint_entries(), runs or {}
    out: dict[str, CheckpointEntry | Path] = {}
    for row in rows:
        base = EFULL_ROWS.get(row, row)
        if base in runs:
            out[row] = Path(runs[base])
        elif base in shipped:
            out[row] = shipped[base]
        elif row in REGISTRY_ROWS and default_checkpoint(REGISTRY_ROWS[row]) is not None:
            out[row] = entries[default_checkpoint(REGISTRY_ROWS[row])]
    return out


def stored_contact_results() -> StoredResult:
    """The stored per-case metrics of the contact tables on the shipped checkpoints (``results/
    contact_cases.csv``, written by ``retarget evaluate --table contact --profile fast``; one row
    per method and case), with its provenance and staleness
    (:func:`~retarget_lib.evaluation.results.load_result`).

    ESO makes the full run take ~20 min on 2 cores, so the notebooks read these and re-run a few
    cases live (:func:`rerun_cases`) to show that they reproduce.
    """
    return load_result("contact_cases", rows=contact_row_checkpoints())


#: relative tolerance of a live re-run against the stored table: feed-forward rows (networks, copy,
#: IK) reproduce to float rounding; ESO rows run 30 Adam steps per frame against colliding triangle
#: pairs found anew at every step, so a last-bit change in a matrix product (MKL picks its kernels
#: by CPU) can change which pairs collide and the optimisation takes another path. Measured on
#: hands_on_hips_008 -> otto, Ours (residual): foot height error 0.776-0.796 cm over MKL's code
#: paths (``MKL_CBWR``) on one AMD EPYC, 0.856 cm stored from another CPU; position MSE
#: 0.0900-0.0912. Every other value of that re-run agreed to 0.05 %.
RERUN_RTOL = {"feed-forward": 1e-3, "ESO": 2e-2}
#: the magnitude below which a tolerance is absolute (``rtol * floor``): 1 in every metric's unit,
#: 5 cm (a typical planted-foot distance) for the foot height error
RERUN_FLOOR = {"foot height error": 5.0}


def rerun_tolerance(method: str, metric: str, stored: float) -> float:
    """Largest ``|now - stored|`` accepted when a stored contact result is re-run (see
    :data:`RERUN_RTOL`): ``rtol * max(|stored|, floor)``."""
    rtol = RERUN_RTOL["ESO" if method in ESO_ROWS else "feed-forward"]
    return rtol * max(abs(stored), RERUN_FLOOR.get(metric, 1.0))


def rerun_cases(
    per_case: pd.DataFrame,
    clips: tuple[str, ...],
    targets: tuple[str, ...],
    rows: tuple[str, ...] = TABLE1_ROWS,
    profile: str = "fast",
) -> pd.DataFrame:
    """Re-evaluate some (clip, target) cases live and put the new metrics beside the stored ones.

    Returns:
        One row per (method, clip, target, metric) with ``stored``, ``now``, ``abs diff``,
        ``tolerance`` (:func:`rerun_tolerance`) and ``reproduces`` (within it, or both NaN).
    """
    methods, _ = contact_methods(rows)
    cases = [c for c in contact_cases(profile) if c.clip in clips and c.target.name in targets]
    now = evaluate_contact_methods(methods, cases, CONTACT_PROFILES[profile]["eval_every"])
    return compare_with_stored(
        now, per_case, ("method", "clip", "target"), METRICS, rerun_tolerance
    )


def run_contact_evaluation(
    out_dir: str | Path,
    profile: str = "fast",
    rows: tuple[str, ...] | None = None,
    device: str | None = None,
    runs: Mapping[str, Path] | None = None,
    command: str = "retarget evaluate --table contact --profile fast --out DIR",
) -> tuple[dict[str, pd.DataFrame], list[str]]:
    """Evaluate every Table 1/3 row with a shipped checkpoint on :func:`contact_cases`; write
    ``contact_table{1,3,5,6}.csv/.md`` and ``contact_cases.csv`` into ``out_dir``.

    Args:
        out_dir: output folder.
        profile: :data:`CONTACT_PROFILES` key.
        rows: evaluate only these rows and merge them into an existing ``contact_cases.csv`` of
            ``out_dir`` (replacing their old results); default every row, from scratch.
        device, runs: as :func:`contact_methods`.
        command: the command recorded in the provenance of ``contact_cases``.

    Returns:
        ``(tables, missing_rows)``.
    """
    out = Path(out_dir)
    t0 = time.perf_counter()
    methods, missing = contact_methods(rows or TABLE1_ROWS + TABLE3_ROWS, device, runs)
    cases = contact_cases(profile)
    per_case = evaluate_contact_methods(
        methods,
        cases,
        CONTACT_PROFILES[profile]["eval_every"],
        same={"Efull + ESO": "Ours", "Efull-residual + ESO": "Ours (residual)"},
    )
    if rows and (out / "contact_cases.csv").exists():
        old = pd.read_csv(out / "contact_cases.csv")
        per_case = pd.concat(
            [old[~old["method"].isin(per_case["method"].unique())], per_case], ignore_index=True
        )
        previous = out / "contact_cases.provenance.json"
        if previous.exists():  # say which rows are new and where the others come from
            before = json.loads(previous.read_text())
            command += (
                f" [rows {', '.join(sorted(set(methods)))} recomputed; the others kept from commit "
                f"{before['commit'][:12]}, {before['date']}]"
            )
    note = (
        f"Contact-aware retargeting, profile {profile}: source {CONTACT_SOURCE} (unseen), "
        f"{len(cases)} cases "
        f"(targets {CONTACT_TARGETS}); interpenetration x1000, vertex contact MSE and global "
        "position MSE "
        "in cm^2/cm; 'paper' columns: Villegas et al. 2021 (Mixamo). "
        + (f"Rows without a shipped checkpoint: {', '.join(missing)}." if missing else "")
    )
    tables = write_contact_tables(per_case, out, note)
    write_result(
        per_case,
        out,
        "contact_cases",
        command=command,
        profile=profile,
        checkpoints=contact_row_checkpoints(tuple(per_case["method"].unique()), runs),
        seconds=time.perf_counter() - t0,
    )
    return tables, missing


def write_contact_tables(
    per_case: pd.DataFrame, out_dir: str | Path, note: str
) -> dict[str, pd.DataFrame]:
    """:func:`contact_tables` of ``per_case`` written as ``contact_table{1,3,5,6}.csv/.md`` (each
    with ``note``) into ``out_dir`` (atomically); the per-case file with its provenance is written
    by :func:`run_contact_evaluation`.

    Returns:
        the tables.
    """
    out = Path(out_dir)
    tables = contact_tables(per_case)
    titles = {
        "table1": "Table 1",
        "table3": "Table 3 (ablation)",
        "table5": "Table 5 (skinny targets)",
        "table6": "Table 6 (bulky targets)",
    }
    for name, table in tables.items():
        write_table(table, out, f"contact_{name}", f"{titles[name]}. {note}")
    return tables
