"""Real characters, no ground truth: how each method does on the real-character set.

``retarget evaluate --table real`` retargets real mocap (CMU, :mod:`~retarget_lib.data.sources.cmu`)
and a labelled synthetic hand-contact clip onto every character of ``data/real_characters``
(:mod:`~retarget_lib.data.sources.real_characters`: real rigs, real skinned meshes, several rig
conventions and rest poses) with every method, and scores what needs no ground truth. Every
result goes through the same ground rule as ``retarget retarget``
(:func:`~retarget_lib.methods.retarget.on_the_ground`).

Measures, per (character, method, clip); lengths as a percentage of the target's height ``H``
(:meth:`~retarget_lib.core.skeleton.Skeleton.height`) so that characters of any size compare:

* ``identity_pct``: the character's own motion (the first clip moved onto it with ``copy-rest``,
  the rest-compensated transfer) retargeted onto the same character: mean joint distance from
  the input. A method that changes a motion on its own skeleton is wrong there.
* ``skate_pct_per_s``: where a foot of the source stands
  (:func:`~retarget_lib.core.ground.standing_feet`), the mean horizontal speed of the same foot
  joint of the result.
* ``under_floor_pct``: the mean depth of the lowest sole below ``y = 0`` (0 when above).
* ``float_pct``: where a source foot stands, the mean height of the result's same sole above ``y =
  0``.
* ``foot_contact_mismatch``: one minus Villegas et al.'s foot contact accuracy (Sec. 4): heel and
  toe contacts detected on the result and on the source (Sec. 3.4 thresholds, each at its own
  :func:`~retarget_lib.core.measures.estimated_standing_height`,
  :func:`~retarget_lib.geometry.contacts.detect_foot_contacts`), the share of
  (frame, foot joint) labels on which they disagree; 0 when every contact is kept.
* ``arm_penetration``: the share of arm vertices inside the rest of the body (mean of both arms,
  :func:`~retarget_lib.geometry.penetration_rate.penetration_rate`, winding numbers on the skinned
  real mesh), every :data:`PENETRATION_EVERY`-th frame; arm vertices already inside the body in
  the character's rest pose are left out (the mesh as modelled: unposed, four of the eleven real
  characters score 0.018-0.047, their mean 0.012), so the rest pose scores 0.
* ``hand_gap_pct``: on a clip with labelled hand-hand contacts (clap), the mean absolute
  difference, over the labelled frames, between the distance of the two hand joints and that
  distance on the source (scaled by the height ratio): how far hands that touch end up from
  touching as the source's do. ``nan`` for clips without labels.
* ``jitter_log_ratio``: ``|ln(a_result / a_source)|``, the mean joint accelerations of the result
  and the source, both over ``H``: 0 when the result is as smooth as the source, and as large for
  a result twice as jittery as for one smoothed to half (smoothing a motion away is no better).

Bone lengths are not scored: every method outputs rotations on the target's skeleton, so they
are kept exactly.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from functools import partial
from pathlib import Path

import numpy as np
import pandas as pd

from ..core.character import Character
from ..core.ground import clip_ground, foot_positions, sole_heights
from ..core.measures import estimated_standing_height
from ..core.motion import Motion
from ..core.skeleton import J
from ..data.manifest import (
    CheckpointEntry,
    checkpoint_entries,
    default_checkpoint,
    table_checkpoints,
)
from ..data.sources.cmu import load_cmu_clip
from ..data.sources.real_characters import load_real_character, real_character_names
from ..data.sources.real_motions import load_real_motion
from ..data.synthetic.dataset import load_synthetic
from ..files import atomic_write
from ..geometry.contacts import authored_contact_frames, detect_foot_contacts
from ..geometry.penetration_rate import DEFAULT_LIMBS, limb_vertices_inside, penetration_rate
from ..methods.registry import get_method
from ..methods.retarget import on_the_ground
from .results import StoredResult, load_result, write_result
from .tdcn import markdown_table

__all__ = [
    "REAL_METHODS",
    "RealClip",
    "WorstCase",
    "jitter_log_ratio",
    "real_clips",
    "real_measures",
    "run_real_evaluation",
    "stored_real_results",
    "welded",
    "worst_cases",
]

#: table row -> (registry method, Table 4 row whose shipped checkpoint it loads, None = the
#: method's default)
REAL_METHODS: dict[str, tuple[str, str | None]] = {
    "copy": ("copy", None),
    "copy-rest": ("copy-rest", None),
    "tdcn": ("tdcn", None),
    "tdcn (paper form)": ("tdcn", "ours"),
    "nkn": ("nkn", "Baseline"),
    "contact": ("contact", None),
    "contact (no ESO)": ("contact", None),
}
#: rows that run the contact network without encoder-space optimisation (``eso=False``)
WITHOUT_ESO = ("contact (no ESO)",)
#: frames per clip (30 fps) retargeted onto each character
CLIP_FRAMES = 60
#: penetration is measured on every n-th frame (winding numbers on a real mesh cost ~0.1 s a frame)
PENETRATION_EVERY = 10
#: the arms of :data:`~retarget_lib.geometry.penetration_rate.DEFAULT_LIMBS`
ARMS = {limb: DEFAULT_LIMBS[limb] for limb in ("left_arm", "right_arm")}


@dataclass
class RealClip:
    """A source clip of the real table.

    Attributes:
        name: e.g. ``"01_01"`` or ``"clap_008"``.
        motion: canonical 22 joints, 30 fps, :data:`CLIP_FRAMES` frames at most.
        character: the source's skinned character when it has one (its rest mesh sets its ground).
        hands_touch: ``(T,)`` bool, labelled hand-hand contact frames, or ``None``.
    """

    name: str
    motion: Motion
    character: Character | None
    hands_touch: np.ndarray | None


#: where the range-of-motion clip is cut (30 fps frames): 3-5 s, the first arm raises after the
#: opening T-pose, both feet on the floor
ROM_START = 90


def real_clips(frames: int = CLIP_FRAMES) -> list[RealClip]:
    """Two real CMU clips (01_01 jumps, 01_03 walk), the synthetic ``clap_008`` (a held-out clap
    with labelled hand contacts, on its performer) and a second real mocap source's clip
    (``motion_capture_rom`` from :data:`ROM_START`, :mod:`~retarget_lib.data.sources.real_motions`),
    each cut to ``frames`` frames."""
    clips = [
        RealClip(name[:-4], _first(load_cmu_clip(name), frames), None, None)
        for name in ("01_01.bvh", "01_03.bvh")
    ]
    ds = load_synthetic()
    clap = ds.clip("clap_008")
    motion = _first(clap.motion, frames)
    hand_hand = [c for c in clap.hand_contacts if c.part in ("LeftHand", "RightHand")]
    touch = authored_contact_frames(hand_hand, clap.motion.num_frames)[: motion.num_frames]
    clips.append(RealClip(clap.name, motion, ds.characters[clap.performer], touch))
    rom = load_real_motion("motion_capture_rom")
    clips.append(
        RealClip(
            rom.name, rom.slice(ROM_START, min(ROM_START + frames, rom.num_frames)), None, None
        )
    )
    return clips


def _first(motion: Motion, frames: int) -> Motion:
    return motion.slice(0, min(frames, motion.num_frames))


def welded(character: Character, tolerance: float = 1e-6) -> Character:
    """The character with coincident vertices merged (within ``tolerance`` metres).

    Real exports split vertices along hard edges and UV seams (a Quaternius body is 1,058
    disconnected pieces that close one surface); the penetration measure cuts the arms out of the
    mesh and caps the holes, which needs the pieces joined. The first vertex of each group keeps
    its skinning weights; faces that collapse are dropped.
    """
    keys = np.round(character.rest_vertices / tolerance).astype(np.int64)
    _, first, inverse = np.unique(keys, axis=0, return_index=True, return_inverse=True)
    faces = inverse.reshape(-1)[character.faces]
    keep = (
        (faces[:, 0] != faces[:, 1]) & (faces[:, 1] != faces[:, 2]) & (faces[:, 0] != faces[:, 2])
    )
    return Character(
        character.name,
        character.skeleton.copy(),
        character.rest_vertices[first],
        faces[keep],
        character.weights[first],
        character.bulk,
        dict(character.style),
    )


def real_measures(result: Motion, clip: RealClip, character: Character) -> dict[str, float]:
    """The module's GT-free measures of one result (already on the ground) on ``character``."""
    h = character.skeleton.height()
    src = clip.motion
    src_pos, out_pos = src.global_positions(), result.global_positions()
    src_mesh = None if clip.character is None else clip.character.rest_vertices
    standing = clip_ground(src_pos, src.skeleton, src.fps, src_mesh).standing
    feet = foot_positions(out_pos, result.skeleton)
    speed = np.linalg.norm(np.diff(feet[..., [0, 2]], axis=0), axis=-1) * result.fps  # (T-1, 4) m/s
    stand_steps = standing[1:] & standing[:-1]
    soles = sole_heights(out_pos, result.skeleton, character.rest_vertices)
    out = {
        "skate_pct_per_s": 100 * float(speed[stand_steps].mean() / h)
        if stand_steps.any()
        else float("nan"),
        "under_floor_pct": 100 * float(np.maximum(0.0, -soles.min(axis=1)).mean() / h),
        "float_pct": 100 * float(np.maximum(0.0, soles[standing]).mean() / h)
        if standing.any()
        else float("nan"),
        "foot_contact_mismatch": float(
            (
                detect_foot_contacts(
                    out_pos, result.skeleton, estimated_standing_height(result.skeleton)
                )
                != detect_foot_contacts(
                    src_pos, src.skeleton, estimated_standing_height(src.skeleton)
                )
            ).mean()
        ),
    }
    frames = np.arange(0, result.num_frames, PENETRATION_EVERY)
    verts = character.skinned(result.rotations[frames], result.root_positions[frames])
    rates = penetration_rate(
        verts, character.faces, character.weights, ARMS, rest_vertices=character.rest_vertices
    )
    out["arm_penetration"] = float(np.nanmean(list(rates.values())))
    if clip.hands_touch is not None and clip.hands_touch.any():
        lh, rh = J["LeftHand"], J["RightHand"]
        gap_out = np.linalg.norm(out_pos[:, lh] - out_pos[:, rh], axis=-1)[clip.hands_touch]
        gap_src = (
            np.linalg.norm(src_pos[:, lh] - src_pos[:, rh], axis=-1)[clip.hands_touch]
            * h
            / src.skeleton.height()
        )
        out["hand_gap_pct"] = 100 * float(np.abs(gap_out - gap_src).mean() / h)
    else:
        out["hand_gap_pct"] = float("nan")
    out["jitter_log_ratio"] = jitter_log_ratio(result, src)
    return out


def jitter_log_ratio(result: Motion, source: Motion) -> float:
    """``|ln(a_result / a_source)|``: the mean joint acceleration of ``result`` against the
    ``source``'s, each over its skeleton's height (per frame², any frame rate alike for both): 0
    when the result is as smooth as the source, ``ln 2`` for one twice as jittery or smoothed to
    half.

    Args:
        result: ``(T, ...)`` motion on the target.
        source: ``(T, ...)`` the motion it was retargeted from.
    """

    def acceleration(motion: Motion) -> float:
        p = motion.global_positions()  # (T, J, 3)
        return float(
            np.linalg.norm(np.diff(p, 2, axis=0), axis=-1).mean() / motion.skeleton.height()
        )

    ratio = acceleration(result) / max(acceleration(source), 1e-12)
    return float(abs(np.log(max(ratio, 1e-12))))


Retarget = Callable[..., Motion]


def real_checkpoints() -> dict[str, CheckpointEntry]:
    """Row -> the shipped checkpoint a learned row of :data:`REAL_METHODS` loads (rows whose
    checkpoint is not shipped are left out)."""
    shipped, entries = table_checkpoints("tdcn"), checkpoint_entries()
    out = {}
    for row, (name, table_row) in REAL_METHODS.items():
        ident = (
            default_checkpoint(name)
            if table_row is None
            else getattr(shipped.get(table_row), "id", None)
        )
        if ident is not None:
            out[row] = entries[ident]
    return out


def _methods(only: Sequence[str] | None, device: str | None) -> dict[str, tuple[Retarget, bool]]:
    """row -> (retarget function, needs the mesh); a learned row without a shipped checkpoint is
    left out."""
    checkpoints = real_checkpoints()
    methods = {}
    for row, (name, _) in REAL_METHODS.items():
        method = get_method(name)
        if (only is not None and row not in only) or (
            method.needs_checkpoint and row not in checkpoints
        ):
            continue
        entry = checkpoints.get(row)
        fn = method.retargeter(None if entry is None else entry.id, device)
        methods[row] = (partial(fn, eso=False) if row in WITHOUT_ESO else fn, method.needs_mesh)
    return methods


def _run(
    fn: Retarget, needs_mesh: bool, motion: Motion, character: Character, source: Character | None
) -> Motion:
    if needs_mesh:  # the contact method: its ESO compiled (every case of the table repays it)
        return fn(motion, character, source_character=source, compile=True)
    return fn(motion, character.skeleton)


def evaluate_real(
    methods: Mapping[str, tuple[Retarget, bool]],
    clips: Sequence[RealClip],
    characters: Sequence[str],
) -> pd.DataFrame:
    """One row per (character, method, clip) with :func:`real_measures` and ``identity_pct``."""
    copy_rest = get_method("copy-rest").retargeter()
    rows = []
    for name in characters:
        character = welded(load_real_character(name).character())
        h = character.skeleton.height()
        for k, clip in enumerate(clips):
            own = copy_rest(
                clip.motion, character.skeleton
            )  # the character's own version of the clip
            for row, (fn, needs_mesh) in methods.items():
                result = on_the_ground(
                    _run(fn, needs_mesh, clip.motion, character, clip.character),
                    clip.motion,
                    character,
                    clip.character,
                )
                identity = float("nan")
                if (
                    k == 0
                ):  # identity on the first clip only (contact: ~0.5 s a frame on a real mesh)
                    again = _run(fn, needs_mesh, own, character, character)
                    identity = 100 * float(
                        np.linalg.norm(
                            again.global_positions() - own.global_positions(), axis=-1
                        ).mean()
                        / h
                    )
                rows.append(
                    {
                        "character": name,
                        "method": row,
                        "clip": clip.name,
                        "identity_pct": identity,
                        **real_measures(result, clip, character),
                    }
                )
    return pd.DataFrame(rows)


@dataclass
class WorstCase:
    """The posed mesh of one method's worst real-character case, for a render.

    Attributes:
        method, character, clip, frame: which case and frame (30 fps).
        vertices: ``(V, 3)`` the skinned mesh at that frame; faces: ``(F, 3)``.
        inside: ``(V,)`` bool, arm vertices inside the body
            (:func:`~retarget_lib.geometry.penetration_rate.limb_vertices_inside`).
        penetration: the case's ``arm_penetration``.
    """

    method: str
    character: str
    clip: str
    frame: int
    vertices: np.ndarray
    faces: np.ndarray
    inside: np.ndarray
    penetration: float


def worst_cases(
    per_case: pd.DataFrame, methods: Mapping[str, tuple[Retarget, bool]], clips: Sequence[RealClip]
) -> list[WorstCase]:
    """Per method, the (character, clip) with the largest ``arm_penetration`` in ``per_case``,
    retargeted again, at the measured frame with the most arm vertices inside the body."""
    by_name = {c.name: c for c in clips}
    out = []
    for row, (fn, needs_mesh) in methods.items():
        cases = per_case[per_case["method"] == row]
        if cases.empty:
            continue
        worst = cases.loc[cases["arm_penetration"].idxmax()]
        clip = by_name[worst["clip"]]
        character = welded(load_real_character(worst["character"]).character())
        result = on_the_ground(
            _run(fn, needs_mesh, clip.motion, character, clip.character),
            clip.motion,
            character,
            clip.character,
        )
        frames = np.arange(0, result.num_frames, PENETRATION_EVERY)
        verts = character.skinned(result.rotations[frames], result.root_positions[frames])
        inside = limb_vertices_inside(
            verts, character.faces, character.weights, ARMS, character.rest_vertices
        )
        k = int(np.argmax(inside.sum(1)))
        out.append(
            WorstCase(
                row,
                worst["character"],
                worst["clip"],
                int(frames[k]),
                verts[k],
                character.faces,
                inside[k],
                float(worst["arm_penetration"]),
            )
        )
    return out


#: the table's columns, in order
MEASURES = (
    "identity_pct",
    "skate_pct_per_s",
    "under_floor_pct",
    "float_pct",
    "foot_contact_mismatch",
    "arm_penetration",
    "hand_gap_pct",
    "jitter_log_ratio",
)


def real_table(per_case: pd.DataFrame) -> pd.DataFrame:
    """Mean over characters and clips of each measure, one row per method (:data:`REAL_METHODS`
    order, then any other method in the order it first appears)."""
    present = list(dict.fromkeys(per_case["method"]))
    order = [m for m in REAL_METHODS if m in present] + [
        m for m in present if m not in REAL_METHODS
    ]
    return per_case.groupby("method")[list(MEASURES)].mean().loc[order]


def run_real_evaluation(
    out_dir: str | Path,
    device: str | None = None,
    only: Sequence[str] | None = None,
    characters: Sequence[str] | None = None,
    command: str = "retarget evaluate --table real --out DIR",
) -> tuple[pd.DataFrame, list[WorstCase]]:
    """Evaluate, write ``real_cases`` (with provenance), ``real.csv`` and ``real.md``; return the
    table and each method's :func:`worst_cases` (for a render)."""
    methods = _methods(only, device)
    checkpoints = {row: entry for row, entry in real_checkpoints().items() if row in methods}
    t0 = time.perf_counter()
    clips = real_clips()
    per_case = evaluate_real(methods, clips, characters or real_character_names())
    write_result(
        per_case,
        out_dir,
        "real_cases",
        command=command,
        checkpoints=checkpoints,
        profile="fast",
        seconds=time.perf_counter() - t0,
    )
    table = real_table(per_case)
    out = Path(out_dir)
    with atomic_write(out / "real.csv", "w") as f:
        table.to_csv(f)
    with atomic_write(out / "real.md", "w") as f:
        f.write(
            "Real characters (data/real_characters), no ground truth: mean over characters and "
            "clips "
            f"(CMU 01_01, 01_03, synthetic clap_008, assimp's motion capture ROM; {CLIP_FRAMES} "
            "frames each). Lengths in % of the target's "
            "height; lower is better in every column (identity: 0 is exact; foot contact mismatch: "
            "1 - the foot contact "
            "accuracy of Villegas et al.; arm penetration: the share of arm vertices inside the "
            "body that are outside it in the character's rest pose; jitter: 0 is as smooth as "
            "the source).\n\n" + markdown_table(table, 3) + "\n"
        )
    return table, worst_cases(per_case, methods, clips)


#: relative tolerance of a re-run of the stored real table: the methods are feed-forward (float32
#: networks) but for ``contact``, whose 30 Adam steps of ESO amplify float order between CPUs
#: (measured: up to 2 % on single contact cases, see the contact tables); the GT-free measures are
#: means of thresholded quantities, so a last-bit change may flip one frame of one foot
RERUN_RTOL = 0.05
#: below this magnitude the tolerance is absolute
RERUN_FLOOR = 0.05


def rerun_tolerance(method: str, metric: str, stored: float) -> float:
    """Largest ``|now - stored|`` accepted for one stored value."""
    return RERUN_RTOL * max(abs(stored), RERUN_FLOOR)


def stored_real_results() -> StoredResult:
    """The stored ``real_cases`` (``results/``) with its staleness against the shipped
    checkpoints."""
    return load_result("real_cases", rows=real_checkpoints())
