"""Table 4's cases and scores (Kim et al. 2020, Sec. 5): the normalised MSE of global joint
positions, the test pairs of both synthetic profiles and the CMU clips, short and long chunks, and
evaluating a method on them."""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd

from ...core.motion import Motion
from ...core.skeleton import Skeleton
from ...core.transfer import retarget_ground_truth
from ...data.sources.cmu import CMU_CLIPS, load_cmu_clip
from ...data.splits import tdcn_split
from ...data.synthetic.dataset import load_synthetic
from ...data.synthetic.mixamo_convention import (
    mixamo_convention_split,
    mixamo_convention_versions,
)

#: a retargeting method: (source motion, target skeleton) -> motion on the target
Method = Callable[[Motion, Skeleton], Motion]


SHORT_FRAMES = 120


#: the row name of "ours" evaluated with a re-centred 81-frame window per frame
WINDOWED_ROW = "ours (windowed)"


METRES_TO_CM = 100.0


def normalized_mse(
    pred: np.ndarray, truth: np.ndarray, height: float, squared_height: bool = False
) -> float:
    """NKN/TDCN normalised MSE of global joint positions.

    Args:
        pred: ``(T, J, 3)`` predicted global joint positions (metres).
        truth: ``(T, J, 3)`` ground-truth global joint positions (metres).
        height: target height ``H`` (metres, :meth:`Skeleton.height`).
        squared_height: divide by ``H²`` (unit-free) instead of ``H`` (in cm).

    Returns:
        ``mean_{t,j} ||pred - truth||² / H`` in cm, or ``/ H²`` (unit-free).
    """
    pred, truth = np.asarray(pred, dtype=np.float64), np.asarray(truth, dtype=np.float64)
    if pred.shape != truth.shape:
        raise ValueError(f"prediction {pred.shape} and ground truth {truth.shape} differ")
    sq = ((pred - truth) ** 2).sum(-1).mean()
    if squared_height:
        return float(sq / height**2)
    return float(sq * METRES_TO_CM**2 / (height * METRES_TO_CM))


@dataclass
class EvalCase:
    """One test pair: a source motion, the target skeleton and the target's ground truth."""

    scenario: int
    source_name: str
    target_name: str
    clip: str
    source: Motion
    target: Skeleton
    truth: Motion


def tdcn_cases() -> list[EvalCase]:
    """The four TDCN scenarios on the synthetic split (``data_manifest.yaml``), with ground truth
    from :func:`~retarget_lib.core.transfer.retarget_ground_truth` (the source clip performed by the
    source character, and by the target character)."""
    ds, split = load_synthetic(), tdcn_split()
    cases = []
    for scenario, pairs in split.scenarios.items():
        for p in pairs:
            clip = ds.clip(p.motion.clip).motion
            src_skel, tgt_skel = ds.characters[p.source].skeleton, ds.characters[p.target].skeleton
            cases.append(
                EvalCase(
                    int(scenario),
                    p.source,
                    p.target,
                    clip.name,
                    retarget_ground_truth(clip, src_skel),
                    tgt_skel,
                    retarget_ground_truth(clip, tgt_skel),
                )
            )
    return cases


def mixamo_convention_cases() -> list[EvalCase]:
    """The four TDCN scenarios on the Mixamo-convention profile
    (:mod:`~retarget_lib.data.synthetic.mixamo_convention`): the source clip is the source
    character's own version, the ground truth the target character's own version (authored on it,
    contacts solved on its body), as a Mixamo download of the same motion would be."""
    split = mixamo_convention_split()
    data = mixamo_convention_versions(p for pairs in split.scenarios.values() for p in pairs)
    cases = []
    for scenario, pairs in split.scenarios.items():
        for p in pairs:
            versions = data.clips[p.motion.clip]
            cases.append(
                EvalCase(
                    int(scenario),
                    p.source,
                    p.target,
                    versions[p.source].name,
                    versions[p.source],
                    data.characters[p.target].skeleton,
                    versions[p.target],
                )
            )
    return cases


def cmu_cases(characters: Sequence[str] | None = None) -> list[EvalCase]:
    """The real CMU clips (never trained on) onto the TDCN test characters, against the ground-truth
    convention (:func:`~retarget_lib.core.transfer.retarget_ground_truth`: the rotation deltas
    from the retarget pose, the root scaled by the leg ratio). Source name ``"CMU"``, scenario 0.

    The CMU skeletons' rest poses differ from every synthetic character's (01_01 and 01_03 stand
    with their legs splayed by 20°), so this is where a learned rest-pose compensation is tested
    outside its training distribution.

    Args:
        characters: target characters (default the TDCN split's test characters).
    """
    chars = load_synthetic().characters
    names = tdcn_split().test_characters if characters is None else characters
    return [
        EvalCase(
            0,
            "CMU",
            t,
            name,
            clip,
            chars[t].skeleton,
            retarget_ground_truth(clip, chars[t].skeleton),
        )
        for name in CMU_CLIPS
        for clip in [load_cmu_clip(name)]
        for t in names
    ]


#: per-comparison scores: ``(pred (N,J,3), truth (N,J,3), H) -> {suffix: value}`` (metres in, any
#: unit out)
Scores = Callable[[np.ndarray, np.ndarray, float], dict[str, float]]


def table4_scores(pred: np.ndarray, truth: np.ndarray, height: float) -> dict[str, float]:
    """Table 4's scores of one comparison: ``""`` (cm²/H in cm) and ``"_h2"`` (/H², unit-free)."""
    return {
        "": normalized_mse(pred, truth, height),
        "_h2": normalized_mse(pred, truth, height, squared_height=True),
    }


def short_chunks(frames: int, short_frames: int = SHORT_FRAMES) -> list[tuple[int, int]]:
    """The "short" protocol's ``[start, stop)`` chunks of a ``frames``-frame clip, as the authors'
    evaluation code cuts them (``evaluate.py`` of medialab-ku/retargetting-tdcn, ``load_testdata``
    of rubenvillegas/cvpr2018nkn): consecutive ``short_frames``-frame chunks, and where a remainder
    is left, one more chunk of the last ``short_frames`` frames (overlapping the one before). A clip
    shorter than one chunk is one chunk (the authors' code skips such clips; the synthetic split
    has clips of 2 s)."""
    if frames <= short_frames:
        return [(0, frames)]
    chunks = [(s, s + short_frames) for s in range(0, frames - short_frames + 1, short_frames)]
    if chunks[-1][1] < frames:
        chunks.append((frames - short_frames, frames))
    return chunks


def truth_frames(
    pred_frames: int, pred_fps: float, start: int, truth_frames_total: int, truth_fps: float
) -> np.ndarray:
    """Indices of the ground-truth frames inside the time span of a prediction.

    The prediction covers source frames ``start .. start + pred_frames - 1`` at ``pred_fps``; the
    ground truth's frame ``k`` is at ``k / truth_fps`` seconds. At equal rates these are frames
    ``start .. start + pred_frames - 1`` (cut at the ground truth's end).

    Returns:
        ``(N,)`` int ground-truth frame indices.
    """
    if abs(pred_fps - truth_fps) < 1e-9:
        return np.arange(start, min(start + pred_frames, truth_frames_total))
    t0, t1 = start / pred_fps, (start + pred_frames - 1) / pred_fps
    k = np.arange(int(np.ceil(t0 * truth_fps - 1e-6)), int(np.floor(t1 * truth_fps + 1e-6)) + 1)
    return k[(k >= 0) & (k < truth_frames_total)]


def aligned_positions(
    pred: Motion, start: int, truth: np.ndarray, truth_fps: float
) -> tuple[np.ndarray, np.ndarray]:
    """A prediction's and the ground truth's global joint positions at the ground truth's frame
    times.

    Args:
        pred: the method's output for source frames ``start ..`` (at ``pred.fps``).
        start: first source frame of ``pred``.
        truth: ``(T, J, 3)`` ground-truth global positions (metres).
        truth_fps: the ground truth's frame rate.

    Returns:
        ``(pred (N,J,3), truth (N,J,3))``; at equal frame rates the prediction's own frames,
        otherwise the prediction interpolated (:meth:`Motion.at_times`) at the ground-truth frames
        of its time span (:func:`truth_frames`).
    """
    k = truth_frames(pred.num_frames, pred.fps, start, len(truth), truth_fps)
    if abs(pred.fps - truth_fps) < 1e-9:
        return pred.global_positions()[: len(k)], truth[k]
    return pred.at_times(k / truth_fps - start / pred.fps).global_positions(), truth[k]


def evaluate_case(
    method: Method, case: EvalCase, short_frames: int = SHORT_FRAMES, scores: Scores = table4_scores
) -> dict[str, float]:
    """Long (whole clip) and short (mean over :func:`short_chunks`) scores of one method on one
    case.

    Each chunk is retargeted on its own and compared at the ground truth's frame times
    (:func:`aligned_positions`).

    Returns:
        ``{"long" + suffix, "short" + suffix}`` for every suffix of ``scores`` (default
        :func:`table4_scores`: ``long, long_h2, short, short_h2``).
    """
    h = case.target.height()
    truth = case.truth.global_positions()
    out = {}
    frames = case.source.num_frames
    for length, chunks in (("long", [(0, frames)]), ("short", short_chunks(frames, short_frames))):
        per_chunk = [
            scores(
                *aligned_positions(
                    method(case.source.slice(a, b), case.target), a, truth, case.truth.fps
                ),
                h,
            )
            for a, b in chunks
        ]
        out.update(
            {f"{length}{k}": float(np.mean([c[k] for c in per_chunk])) for k in per_chunk[0]}
        )
    return out


def error_breakdown(method: Method, case: EvalCase, frames: int = SHORT_FRAMES) -> dict[str, float]:
    """Where one method's error on one case comes from: the root's path or the pose.

    The first ``frames`` frames are retargeted as one short chunk and scored like Table 4
    (:func:`normalized_mse`); ``root`` is the same measure on the root joint alone, and ``pose``
    on the root-relative joints (the root subtracted from prediction and ground truth).

    Returns:
        ``{"total", "root", "pose"}``, cm²/cm.
    """
    pred = method(case.source.slice(0, frames), case.target).global_positions()
    truth = case.truth.slice(0, frames).global_positions()
    h = case.target.height()
    return {
        "total": normalized_mse(pred, truth, h),
        "root": normalized_mse(pred[:, :1], truth[:, :1], h),
        "pose": normalized_mse(pred - pred[:, :1], truth - truth[:, :1], h),
    }


def evaluate_method(
    method: Method, cases: list[EvalCase], scores: Scores = table4_scores
) -> pd.DataFrame:
    """Per-case results: one row per case with scenario, names and the scores of
    :func:`evaluate_case`."""
    return pd.DataFrame(
        [
            {
                "scenario": c.scenario,
                "source": c.source_name,
                "target": c.target_name,
                "clip": c.clip,
                **evaluate_case(method, c, scores=scores),
            }
            for c in cases
        ]
    )


def evaluate_methods(
    methods: Mapping[str, Method], cases: list[EvalCase], scores: Scores = table4_scores
) -> pd.DataFrame:
    """:func:`evaluate_method` of every method, stacked, with a leading ``method`` column."""
    per_case = []
    for name, method in methods.items():
        res = evaluate_method(method, cases, scores)
        res.insert(0, "method", name)
        per_case.append(res)
    return pd.concat(per_case, ignore_index=True)
