"""Training the TDCN retargeting network and its Table 4 baselines/ablations (Kim et al. 2020,
Secs. 4-5), on the synthetic data, with the shared loop of :mod:`retarget_lib.training.loop`.

::

    from retarget_lib.config import load_config
    from retarget_lib.methods.tdcn import load_generator
    from retarget_lib.training.loop import fit
    from retarget_lib.training.tdcn import RetargetTraining

    cfg = load_config("configs/tdcn_paper.yaml", ["train.steps=300"], profile="fast")
    run = RetargetTraining(cfg)
    final = fit(run.task(), cfg, "runs/ours", cfg["train"]["steps"])
    generator, cfg = load_generator(final)          # eval mode, ready for inference

(or ``retarget train --config configs/tdcn_paper.yaml``).

Data (:class:`TrainingClips`, :class:`WindowSampler`). Like Mixamo, every training character
performs every training clip: its version is the ground-truth transfer of the clip onto it
(:func:`~retarget_lib.core.transfer.retarget_ground_truth`), computed once per process for the TDCN
split's train characters × train clips (:func:`~retarget_lib.data.splits.tdcn_split`; 11
characters × 80 clips = 25k frames each, 0.1 GB float32, built in ~3 s — cheap enough not to be
cached on disk). A sample is

* a source character ``A`` and a random ``window``-frame window (81, Sec. 5) of one of its clips,
  uniform over all windows that lie inside a clip (clips shorter than a window are not used);
* a target ``B``: ``A`` itself with probability ``same_fraction`` (50 %, Sec. 5), otherwise
  another training character, uniformly;
* a *real* window performed by ``B`` (independent clip and start) for the discriminator (Sec. 5:
  "we sampled the motion clips performed by the character, which was taken as the target");
* the balanced-data scaling (Sec. 5, Table 1: "we scaled p_t and r_t with random factors in
  [0.5, 1.5]"): one factor ``s ~ U(scale_range)`` per sample multiplies the source skeleton's
  offsets and its root trajectory, so ``p = f_FK(q, s·s̄)`` and ``H`` scale with it and the
  motion stays physically consistent (a uniformly larger character doing the same motion). With
  ``scale_targets`` the target gets its own factor (``B``'s offsets and ``B``'s real window scale
  together; when ``A = B`` it is ``A``'s factor): without it the generator would only ever see the
  11 training skeletons as ``s̄B``. ``scale_range: null`` is the unbalanced data of A2 (and of the
  NKN baselines, which the paper trained on Villegas et al.'s data, Sec. 6.1 A2).
* Root normalisation: the paper assumes motions "around or across the origin" (Sec. 4.2, before
  Eq. 15), which its root term ``m_t = ||r_t|| / H`` needs. Each window is translated
  horizontally so that its *centre* frame's root is above the origin (``x = z = 0``); the height
  ``y`` is kept (it carries the leg length). A walk then passes across the origin; a standing
  motion stays around it. :func:`~retarget_lib.methods.tdcn.retarget_motion_with` applies the
  same centring to a clip of any length and adds the offset back, scaled by ``H(s̄B) / H(s̄A)`` —
  in one pass (the paper), or per output frame on its own re-centred receptive field
  (``windowed=True``, our variant for long travelling clips).

All sampling uses the global torch RNG, which :func:`~retarget_lib.training.loop.fit` seeds and
checkpoints, so a resumed run draws exactly the batches of an uninterrupted one.

Step (:meth:`RetargetTraining.step`, Figs. 2a and 4, Eq. 6):

1. ``x̂B = G(xA, s̄B)`` (Eq. 4), FK of the unit ``q̂B`` on ``s̄B`` (Eq. 3); then the cycle
   ``x̂A = G(x̂B, s̄A)`` (Eq. 5) on the unit ``q̂B``, ``p̂B`` and ``r̂B``.
2. Generator loss ``Lc + λt Lt + λh Lh + λa La + λr Lr + λo Lo`` (:mod:`retarget_lib.losses`):
   Lc (Eq. 7) on raw ``q̂A``; Lt (Eq. 8) and Lr (Eq. 22) on raw ``q̂B`` and ``q̂A``; Lh (Eq. 17)
   between ``xA`` and ``x̂B`` — for NKN generators (which predict root *offsets*) on the offsets
   ``r_t − r_{t−1}``, the Baseline-height definition (Sec. 6 (iv)); La (Eq. 21) per sample:
   reconstruction when ``A = B``, else least squares (TDCN) or sigmoid cross-entropy (NKN,
   ``loss.gan``) on the discriminator's scores of ``x̂B`` (D frozen); Lo (Eq. 23) on the roots.
   Every term is computed and logged; a zero weight only drops it from the total.
3. Discriminator step: real windows of ``B`` → real, the detached ``x̂B`` of the ``A ≠ B``
   samples → fake (when ``A = B`` the output should *be* real motion; a batch without any ``A ≠ B``
   sample trains the real half only).
4. Adam (lr 1e-4, betas (0.5, 0.999), Sec. 5) for both.

NKN rows use the same step with their own config: sigmoid-CE GAN, ``λr = λo = 0`` (TDCN's
additions), ``λh = 0`` except Baseline-height, unbalanced data. NKN's own cycle loss compares
positions and root velocities; here every row uses Eq. 7 so that only the listed differences
separate the rows.

Checkpoints (``last.pt`` / ``final.pt`` of :func:`~retarget_lib.training.loop.fit`) hold the merged
config and the ``generator``/``discriminator`` state dicts (with the
:class:`~retarget_lib.models.features.FeatureNormalizer` buffers);
:func:`~retarget_lib.methods.tdcn.load_generator` rebuilds the generator from them, and
:func:`export_generator` writes its slim, float16 inference copy.

Speed (2 cores, 2 threads, one step = G and D updates; ``windows/s`` = batch / step time):

==============================  =====  =====  ===========  ==========
row                             width  batch  s/step       windows/s
==============================  =====  =====  ===========  ==========
ours (A2, A3, A5 alike), fast   256    16     0.28         58
A4 (81-frame D), fast           256    16     0.29         55
A1 (dense), fast                256    16     0.73         22
Baseline / -height (GRU), fast  128    16     0.25         63   (compiled decoder; eager 0.72)
Baseline-dense, fast            128    16     0.44         36
Baseline-dilated, fast          128    16     0.22         72
ours, paper width               1024   16     1.6          10
ours, paper                     1024   128    19.4         6.6
A1, paper                       1024   128    77           1.7
Baseline, paper                 512    128    2.9          43
==============================  =====  =====  ===========  ==========

The fast profile (2000 steps at batch 16 for every row, the second half with a decaying rate) takes
11-30 min of training per row on two cores (each checkpoint's ``trained_seconds`` in
``data_manifest.yaml``); the paper schedule (100k steps at batch 128) would be ~540 h for ours on
this CPU — a GPU job.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from functools import lru_cache
from pathlib import Path
from typing import Mapping, NamedTuple, Sequence

import torch

from ..config_schema import DATA_SOURCES
from ..core.measures import nkn_height
from ..core.motion import Motion
from ..core.rotations import quat_from_axis_angle, quat_mul, quat_rotate
from ..core.skeleton import J, Skeleton
from ..core.transfer import change_rest_pose, random_rest_rotations, retarget_ground_truth
from ..data.checkpoints import save_state
from ..data.manifest import mixamo_local_dir
from ..data.splits import tdcn_split
from ..data.synthetic.dataset import load_synthetic
from ..data.synthetic.mixamo_convention import load_mixamo_convention, mixamo_convention_split
from ..losses import (MotionTensors, PositionScale, TDCNLossWeights, adversarial_loss, adversarial_loss_discriminator,
                      adversarial_loss_generator, bone_direction_loss, check_finite, cycle_loss, height_loss,
                      orientation_loss, regularization_loss, sigmoid_ce_discriminator_loss,
                      sigmoid_ce_generator_loss, total_generator_loss, twist_loss)
from ..methods.tdcn import centre_root, model_config
from ..models import build_model, normalize_quaternions, resolve_config
from ..models.features import (generator_features, nkn_source_features, residual_generator_features,
                               root_velocities, source_local_positions)
from ..devices import autocast
from .distributed import SINGLE, Distributed, prepare_module
from .loop import TrainTask, load_checkpoint, seed_everything

Tensor = torch.Tensor

__all__ = [
    "DATA_SOURCES",
    "TrainingClips",
    "stack_clips",
    "training_clips",
    "TrainingBatch",
    "WindowSampler",
    "RetargetTraining",
    "loss_weights",
]

#: (generator loss on scores, discriminator loss on (real, fake) scores) per ``loss.gan``
_GANS = {"lsgan": (adversarial_loss_generator, adversarial_loss_discriminator),
         "sigmoid_ce": (sigmoid_ce_generator_loss, sigmoid_ce_discriminator_loss)}

#: how many windows the optional input normaliser is fitted on
_NORMALIZER_WINDOWS = 256

#: generator kinds whose exports store float16 weights. Measured on the shipped checkpoints: float16
#: moves the Table 4 numbers of every TDCN row by at most 2.6e-4 relative (and, for "ours", the
#: per-family means and CMU clips of notebook 08 by at most 5.8e-4), but the NKN Baseline-dense
#: Table 4 average by 1.1e-3, so NKN generators stay float32
HALF_PRECISION_KINDS = ("tdcn",)


# ------------------------------------------------------------------------------------- data
@dataclass(frozen=True)
class TrainingClips:
    """Every training character's version of every training clip, concatenated along time.

    All characters perform the same clips with the same frame counts, so one frame index
    addresses the same moment of the same clip for every character.

    Attributes:
        characters: ``C`` character names.
        clip_names: ``K`` clip names (``"walk_003"``).
        clip_bounds: ``(K + 1,)`` long; clip ``k`` is frames ``clip_bounds[k]:clip_bounds[k+1]``.
        offsets: ``(C, J, 3)`` rest offsets (metres).
        rotations: ``(C, F, J, 4)`` local unit quaternions (wxyz), float32.
        root_positions: ``(C, F, 3)`` root positions (metres), float32, as authored.
    """

    characters: tuple[str, ...]
    clip_names: tuple[str, ...]
    clip_bounds: Tensor
    offsets: Tensor
    rotations: Tensor
    root_positions: Tensor

    def window_starts(self, window: int) -> Tensor:
        """``(N,)`` long: first frames of every ``window``-frame window that lies inside one clip.

        Raises:
            ValueError: no clip is long enough.
        """
        starts = [torch.arange(int(a), max(int(a), int(b) - window + 1))  # none in a clip shorter than a window
                  for a, b in zip(self.clip_bounds[:-1], self.clip_bounds[1:])]
        starts = torch.cat(starts)
        if starts.numel() == 0:
            raise ValueError(f"no training clip has {window} frames")
        return starts


def stack_clips(skeletons: Mapping[str, Skeleton], clips: Sequence[tuple[Motion, Mapping[str, Motion]]]) -> TrainingClips:
    """Every character performing every clip, concatenated along time (:class:`TrainingClips`).

    Args:
        skeletons: character name -> canonical-22 skeleton.
        clips: ``(reference, own versions)`` per clip: a character with an own version (same frame
            count as the reference, on its skeleton) performs that; every other character performs
            the ground-truth transfer of the reference
            (:func:`~retarget_lib.core.transfer.retarget_ground_truth`).
    """
    lengths = torch.tensor([0] + [ref.num_frames for ref, _ in clips])
    rotations, roots = [], []
    for name, skeleton in skeletons.items():
        versions = [own[name] if name in own else retarget_ground_truth(ref, skeleton) for ref, own in clips]
        rotations.append(torch.cat([torch.as_tensor(m.rotations, dtype=torch.float32) for m in versions]))
        roots.append(torch.cat([torch.as_tensor(m.root_positions, dtype=torch.float32) for m in versions]))
    offsets = torch.stack([torch.as_tensor(s.offsets, dtype=torch.float32) for s in skeletons.values()])
    return TrainingClips(tuple(skeletons), tuple(ref.name for ref, _ in clips), lengths.cumsum(0),
                         offsets, torch.stack(rotations), torch.stack(roots))


def _synthetic_clips() -> tuple[dict[str, Skeleton], list[tuple[Motion, dict]]]:
    """The TDCN split's train characters and train clips (every version a ground-truth transfer)."""
    ds, split = load_synthetic(), tdcn_split()
    clips = [(ds.clip(f"{m.family}_{m.seed:03d}").motion, {}) for m in split.train_motions]
    return {n: ds.characters[n].skeleton for n in split.train_characters}, clips


def _mixamo_convention_clips() -> tuple[dict[str, Skeleton], list[tuple[Motion, dict]]]:
    """The Mixamo-convention profile's train characters and train clips, each character's own
    version (:mod:`~retarget_lib.data.synthetic.mixamo_convention`)."""
    data, split = load_mixamo_convention(), mixamo_convention_split()
    skeletons = {n: data.characters[n].skeleton for n in split.train_characters}
    clips = []
    for m in split.train_motions:
        versions = data.clips[f"{m.family}_{m.seed:03d}"]
        own = {n: versions[n] for n in skeletons}
        clips.append((own[split.train_characters[0]], own))
    return skeletons, clips


@lru_cache(maxsize=2)
def training_clips(mirror: bool = False, source: str = "synthetic", mixamo_root: str | None = None) -> TrainingClips:
    """The training characters × training clips of ``source``, built once per process.

    Args:
        mirror: also every clip's left/right mirror image (:meth:`Motion.mirror`), as more clips.
        source: one of :data:`DATA_SOURCES`. ``synthetic``: the TDCN split's train characters ×
            train clips (ground-truth transfers). ``mixamo-convention``: the same of the
            Mixamo-convention profile (each character's own version of each clip).
            ``synthetic+mixamo-convention``: both profiles' characters and clips (a character
            without its own version of a clip performs its ground-truth transfer). ``mixamo-local``: the folder's paper training
            characters and seen motions (:func:`~retarget_lib.data.sources.mixamo_training.mixamo_training_set`),
            each character's own clip where it has one. ``mixamo-local+synthetic``: both
            characters sets, both clip sets; a character without its own version of a clip
            performs the clip's ground-truth transfer.
        mixamo_root: the ``mixamo-local`` folder (default ``$RETARGET_MIXAMO``).

    Returns:
        :class:`TrainingClips` (treat as read-only: it is shared within the process).
    """
    if source not in DATA_SOURCES:
        raise ValueError(f"data.source must be one of {DATA_SOURCES}, got {source!r}")
    skeletons: dict[str, Skeleton] = {}
    clips: list[tuple[Motion, Mapping[str, Motion]]] = []
    parts = source.split("+")
    if "mixamo-local" in parts:
        from ..data.mixamo_splits import mixamo_training_set

        skeletons, clips = mixamo_training_set(mixamo_root)
    for part, load in (("mixamo-convention", _mixamo_convention_clips), ("synthetic", _synthetic_clips)):
        if part in parts:
            more_skeletons, more_clips = load()
            skeletons, clips = {**skeletons, **more_skeletons}, clips + more_clips
    if mirror:
        clips += [(ref.mirror(), {k: v.mirror() for k, v in own.items()}) for ref, own in clips]
    return stack_clips(skeletons, clips)


class TrainingBatch(NamedTuple):
    """One batch of (source window, target skeleton, real target window), Sec. 5.

    Attributes:
        rotations: ``(B, W, J, 4)`` source local quaternions ``q^A``.
        root_positions: ``(B, W, 3)`` source root positions ``r^A`` (scaled, centred).
        offsets_source: ``(B, J, 3)`` source skeleton ``s̄A`` (scaled).
        offsets_target: ``(B, J, 3)`` target skeleton ``s̄B`` (scaled).
        same_character: ``(B,)`` bool, ``A = B``.
        real_rotations: ``(B, W, J, 4)`` a real window performed by ``B``.
        real_root_positions: ``(B, W, 3)`` its root positions (scaled like ``s̄B``, centred).
        source: ``(B,)`` long, index of ``A`` in :attr:`TrainingClips.characters`.
        target: ``(B,)`` long, index of ``B``.
        scale_source: ``(B,)`` balanced-data factor of ``A``.
        scale_target: ``(B,)`` factor of ``B`` (``= scale_source`` where ``A = B``).
    """

    rotations: Tensor
    root_positions: Tensor
    offsets_source: Tensor
    offsets_target: Tensor
    same_character: Tensor
    real_rotations: Tensor
    real_root_positions: Tensor
    source: Tensor
    target: Tensor
    scale_source: Tensor
    scale_target: Tensor


class WindowSampler:
    """Random training batches (see the module docstring, "Data").

    Args:
        clips: :class:`TrainingClips` (at least two characters).
        window: frames per window (paper: 81).
        same_fraction: probability that the target is the source (paper: 0.5).
        scale_range: ``(low, high)`` of the balanced-data factor (paper: ``(0.5, 1.5)``), or
            ``None`` for unbalanced data (factor 1).
        scale_targets: scale the target skeleton (and its real windows) by its own factor too.
        random_yaw: turn every window about the vertical axis through its centre frame's root by
            a uniform random angle (our augmentation, not the paper's: the synthetic clips all
            start facing +Z, real clips face anywhere).
        rest_jitter_deg: our augmentation, not the paper's (0 = off): half the source skeletons
            and, independently, half the target skeletons get a random rest pose
            (:func:`~retarget_lib.core.transfer.random_rest_rotations`, swings up to this angle)
            with their windows re-expressed on it (:func:`~retarget_lib.core.transfer.change_rest_pose`:
            every joint stays where it was). The synthetic characters mostly share straight-leg
            rest poses, real files do not (CMU's legs are splayed by 20°), and a network that
            must compensate rest poses has to see them vary. ``A = B`` pairs share one rest pose.
        rest_arm_drop_deg: our augmentation (0 = off): a skeleton that gets a random rest pose
            also has both upper arms lowered from their rest by an angle uniform in
            ``[0, rest_arm_drop_deg]`` (about the forward axis). Real rigs rest with their arms
            anywhere from a T-pose to hanging 70-83° below the horizontal
            (``data/real_characters/proportions.csv``), the synthetic characters at most 50°.
    """

    def __init__(self, clips: TrainingClips, window: int = 81, same_fraction: float = 0.5,
                 scale_range: tuple[float, float] | None = (0.5, 1.5), scale_targets: bool = True,
                 random_yaw: bool = False, rest_jitter_deg: float = 0.0, rest_arm_drop_deg: float = 0.0):
        if len(clips.characters) < 2:
            raise ValueError("need at least two training characters")
        if not 0.0 <= same_fraction <= 1.0:
            raise ValueError(f"same_fraction must be in [0, 1], got {same_fraction}")
        low, high = (1.0, 1.0) if scale_range is None else map(float, scale_range)
        if not 0.0 < low <= high:
            raise ValueError(f"scale_range must be null or [low, high] with 0 < low <= high, got {scale_range}")
        self.clips, self.window, self.same_fraction = clips, int(window), float(same_fraction)
        self.scale_low, self.scale_high, self.scale_targets = low, high, bool(scale_targets)
        self.random_yaw = bool(random_yaw)
        if not 0.0 <= float(rest_jitter_deg) <= 180.0:
            raise ValueError(f"rest_jitter_deg must be in [0, 180], got {rest_jitter_deg}")
        self.rest_jitter_deg = float(rest_jitter_deg)
        if not 0.0 <= float(rest_arm_drop_deg) <= 180.0:
            raise ValueError(f"rest_arm_drop_deg must be in [0, 180], got {rest_arm_drop_deg}")
        self.rest_arm_drop_deg = float(rest_arm_drop_deg)
        self.starts = clips.window_starts(self.window)

    def _scales(self, batch: int, generator: torch.Generator | None) -> Tensor:
        return self.scale_low + (self.scale_high - self.scale_low) * torch.rand(batch, generator=generator)

    def _windows(self, character: Tensor, scale: Tensor, generator: torch.Generator | None) -> tuple[Tensor, Tensor]:
        """Random windows of ``character``'s clips: ``(q (B,W,J,4), centred scaled r (B,W,3))``."""
        start = self.starts[torch.randint(len(self.starts), (len(character),), generator=generator)]
        frames = start[:, None] + torch.arange(self.window)
        rows = character[:, None]
        root = centre_root(self.clips.root_positions[rows, frames] * scale[:, None, None])[0]
        rotations = self.clips.rotations[rows, frames]
        if self.random_yaw:
            angle = (2 * torch.rand(len(character), generator=generator) - 1) * torch.pi
            axis_angle = torch.zeros(len(character), 3)
            axis_angle[:, 1] = angle
            yaw = quat_from_axis_angle(axis_angle)[:, None]
            rotations = rotations.clone()
            rotations[:, :, 0] = quat_mul(yaw, rotations[:, :, 0])
            root = quat_rotate(yaw, root)
        return rotations, root

    def sample(self, batch: int, generator: torch.Generator | None = None) -> TrainingBatch:
        """Draw ``batch`` samples (global torch RNG unless ``generator`` is given)."""
        n = len(self.clips.characters)
        source = torch.randint(n, (batch,), generator=generator)
        same = torch.rand(batch, generator=generator) < self.same_fraction
        target = torch.where(same, source, (source + torch.randint(1, n, (batch,), generator=generator)) % n)
        scale_a = self._scales(batch, generator)
        other = self._scales(batch, generator) if self.scale_targets else torch.ones(batch)
        scale_b = torch.where(same, scale_a, other)
        q_a, r_a = self._windows(source, scale_a, generator)
        q_real, r_real = self._windows(target, scale_b, generator)
        off = self.clips.offsets
        off_a, off_b = off[source] * scale_a[:, None, None], off[target] * scale_b[:, None, None]
        if self.rest_jitter_deg > 0 or self.rest_arm_drop_deg > 0:
            turn_a, turn_b = (self._rest_turns(o, generator) for o in (off_a, off_b))
            turn_b = torch.where(same[:, None, None], turn_a, turn_b)
            (q_a, off_a), (q_real, off_b) = change_rest_pose(q_a, off_a, turn_a), change_rest_pose(q_real, off_b, turn_b)
        return TrainingBatch(q_a, r_a, off_a, off_b, same, q_real, r_real, source, target, scale_a, scale_b)

    def _rest_turns(self, offsets: Tensor, generator: torch.Generator | None) -> Tensor:
        """``(B, J, 4)``: random rest-pose turns for half the samples, identity for the others."""
        turns = random_rest_rotations(offsets, self.rest_jitter_deg, generator)
        if self.rest_arm_drop_deg > 0:
            drop = torch.rand(len(offsets), generator=generator) * math.radians(self.rest_arm_drop_deg)
            for arm, side in ((J["LeftArm"], -1.0), (J["RightArm"], 1.0)):  # the left arm points +X: about -Z
                lower = quat_from_axis_angle(torch.stack([torch.zeros_like(drop), torch.zeros_like(drop),
                                                          side * drop], dim=-1))
                turns[:, arm] = quat_mul(lower, turns[:, arm])
        keep = torch.rand(len(offsets), generator=generator) < 0.5
        return torch.where(keep[:, None, None], torch.tensor([1.0, 0.0, 0.0, 0.0]), turns)


# ------------------------------------------------------------------------------- configs


def loss_weights(config: dict) -> TDCNLossWeights:
    """:class:`~retarget_lib.losses.TDCNLossWeights` from the ``loss`` section (``lambda_*`` keys)."""
    loss = config["loss"]
    return TDCNLossWeights(**{f.name: float(loss[f.name]) for f in fields(TDCNLossWeights) if f.name in loss})


def _check_row(resolved: dict, config: dict, weights: TDCNLossWeights) -> None:
    """Refuse configs whose data/loss contradict the Table 4 row named in ``model.row``."""
    row = resolved.get("row", resolved["kind"])
    problems = []
    if resolved.get("data") == "unbalanced" and config["data"]["scale_range"] is not None:
        problems.append("data.scale_range must be null (unbalanced data)")
    if resolved.get("loss") == "no_height" and weights.lambda_h != 0:
        problems.append("loss.lambda_h must be 0 (no height loss)")
    if resolved["kind"] == "nkn" and bool(resolved.get("height_loss", False)) != (weights.lambda_h != 0):
        problems.append(f"loss.lambda_h must be {'> 0' if resolved.get('height_loss') else '0'} "
                        "for this NKN variant")
    if config["loss"]["gan"] not in _GANS:
        problems.append(f"loss.gan must be one of {list(_GANS)}")
    if problems:
        raise ValueError(f"config {config.get('name', '?')!r} (row {row}): " + "; ".join(problems))


# ---------------------------------------------------------------------------- training
def learning_rate(lr: float, index: int, steps: int, decay_from: float | None) -> float:
    """Adam's learning rate at step ``index`` of ``steps``: constant, or constant up to the fraction
    ``decay_from`` of the run and then linear towards 0 (the GAN schedule of CycleGAN, Zhu et al.
    2017, Sec. 7: same Adam betas (0.5, 0.999) as here). A function of the step alone, so a resumed
    run continues the same schedule.

    Args:
        lr: the base rate (``train.lr``).
        index: 0-based step.
        steps: the run's total steps (``train.steps``).
        decay_from: ``None`` for the paper's constant rate, else a fraction in [0, 1].

    Returns:
        the rate; the last step of a decayed run uses ``lr / (decayed steps)``, never 0.
    """
    if decay_from is None:
        return lr
    start = int(round(float(decay_from) * steps))
    if index < start:
        return lr
    return lr * (steps - index) / max(steps - start, 1)


class RetargetTraining:
    """Generator, discriminator, optimisers, sampler and the training step of one Table 4 row.

    Construction seeds the global RNGs with ``config["seed"]`` so that the initial weights depend
    on the config only (:func:`~retarget_lib.training.loop.fit` then re-seeds for the data).

    Args:
        config: merged experiment config (:func:`~retarget_lib.config.load_config`) with sections
            ``model``, ``data`` (``window``, ``same_fraction``, ``scale_range``, ``scale_targets``,
            optional ``mirror``, ``random_yaw``, ``rest_jitter_deg``),
            ``loss`` (``gan``, ``twist_alpha_deg``, ``lambda_*``) and ``train`` (``batch``, ``lr``,
            ``betas``).
        clips: training data (default :func:`training_clips`).
        device: where the networks and each step's batch live (default CPU). Batches are drawn on
            the CPU either way, so every device sees the same data.
        amp: bfloat16 autocast for the forward passes (CUDA only, :func:`~retarget_lib.devices.autocast`).
        layout: this process's place in a ``torchrun`` job: each step draws the global batch
            ``train.batch`` and keeps this rank's shard (:mod:`~retarget_lib.training.distributed`).

    Attributes:
        generator, discriminator: the :class:`~retarget_lib.models.ModelPair`.
        sampler: the :class:`WindowSampler`.
        weights: the :class:`~retarget_lib.losses.TDCNLossWeights` of Eq. 6.
    """

    def __init__(self, config: dict, clips: TrainingClips | None = None, device: torch.device | None = None,
                 amp: bool = False, layout: Distributed = SINGLE):
        self.config = config
        self.device, self.amp, self.layout = device or torch.device("cpu"), amp, layout
        self.rows = layout.shard(int(config["train"]["batch"]))
        autocast(self.device, amp)  # refuses --amp off CUDA before any work
        seed_everything(int(config["seed"]))
        self.generator, self.discriminator = build_model(model_config(config))
        self.resolved = self.generator.config
        self.weights = loss_weights(config)
        _check_row(self.resolved, config, self.weights)
        loss, data, train = config["loss"], config["data"], config["train"]
        self.gan, self.alpha_deg, self.batch = loss["gan"], float(loss["twist_alpha_deg"]), int(train["batch"])
        self.twist_exclude_root = bool(loss.get("twist_exclude_root", False))
        self.reduction = loss.get("reduction", "mean")
        if clips is None:
            source = data.get("source", "synthetic")
            root = str(mixamo_local_dir()) if "mixamo-local" in source.split("+") else None
            clips = training_clips(bool(data.get("mirror", False)), source, root)
        self.sampler = WindowSampler(clips, data["window"], data["same_fraction"], data["scale_range"],
                                     data["scale_targets"], bool(data.get("random_yaw", False)),
                                     float(data.get("rest_jitter_deg", 0.0)), float(data.get("rest_arm_drop_deg", 0.0)))
        if self.resolved["normalize_inputs"]:
            self._fit_normalizer()
        self.position_scale = self._fit_position_scale() if loss.get("standardize", False) else None
        if bool(train.get("compile", False)) and hasattr(self.generator, "compile_decoder"):
            self.generator.compile_decoder()  # NKN's per-frame GRU decoder; TDCN has no per-frame loop
        for module in (self.generator, self.discriminator):
            prepare_module(module, self.device, layout)
        adam = dict(lr=float(train["lr"]), betas=tuple(float(b) for b in train["betas"]))
        self.opt_g = torch.optim.Adam(self.generator.parameters(), **adam)
        self.opt_d = torch.optim.Adam(self.discriminator.parameters(), **adam)
        self.lr, self.steps = adam["lr"], int(train["steps"])
        self.decay_from = train.get("decay_from")

    def task(self) -> TrainTask:
        """The :class:`~retarget_lib.training.loop.TrainTask` for :func:`~retarget_lib.training.loop.fit`."""
        return TrainTask({"generator": self.generator, "discriminator": self.discriminator},
                         {"generator": self.opt_g, "discriminator": self.opt_d}, self.step)

    @torch.no_grad()
    def _fit_normalizer(self) -> None:
        """Fit the generator's input normaliser on source windows (own RNG: global state untouched)."""
        b = self.sampler.sample(_NORMALIZER_WINDOWS, torch.Generator().manual_seed(int(self.config["seed"])))
        p = source_local_positions(b.rotations, b.offsets_source)
        if self.resolved["kind"] == "tdcn":
            features = residual_generator_features if self.generator.residual else generator_features
            x = features(b.rotations, b.root_positions, b.offsets_source, b.offsets_target, p)
        else:
            h = nkn_height(b.offsets_source) if self.generator.normalize_root else None
            x = nkn_source_features(p, b.root_positions, h)
        self.generator.normalizer.fit(x)

    @torch.no_grad()
    def _fit_position_scale(self) -> PositionScale:
        """The z-scores of ``loss.standardize`` (:class:`~retarget_lib.losses.tdcn.PositionScale`),
        fitted on source windows drawn with their own RNG (global state untouched)."""
        b = self.sampler.sample(_NORMALIZER_WINDOWS, torch.Generator().manual_seed(int(self.config["seed"]) + 1))
        return PositionScale.fit(source_local_positions(b.rotations, b.offsets_source), b.root_positions)

    def _retarget(self, q: Tensor, r: Tensor, p: Tensor, off_src: Tensor, off_tgt: Tensor):
        """``G(x, s̄_tgt)`` (Eqs. 4-5) → (raw output, unit q̂ ``(B,W,J,4)``, ``p̂ = f_FK(q̂, s̄_tgt)``)."""
        out = self.generator.generate(q, r, off_src, off_tgt, positions=p)
        q_unit = normalize_quaternions(out.rotations)
        return out, q_unit, source_local_positions(q_unit, off_tgt)

    def generator_terms(self, batch: TrainingBatch) -> tuple[dict[str, Tensor], MotionTensors]:
        """The six loss terms of Eq. 6 for one batch (D is used but not updated).

        Args:
            batch: a :class:`TrainingBatch`.

        Returns:
            ``(terms, x̂B)``: scalar tensors ``Lc, Lt, Lh, La, Lr, Lo`` (unweighted), and the
            retargeted motion (``p (B,W,J,3)``, raw ``q (B,W,J,4)``, ``r (B,W,3)``).
        """
        q_a, r_a, off_a, off_b = batch.rotations, batch.root_positions, batch.offsets_source, batch.offsets_target
        p_a = source_local_positions(q_a, off_a)
        out_b, q_b_unit, p_b = self._retarget(q_a, r_a, p_a, off_a, off_b)                    # Eq. 4
        out_a, _, p_a_hat = self._retarget(q_b_unit, out_b.root_positions, p_b, off_b, off_a)  # Eq. 5
        x_a = MotionTensors(p_a, q_a, r_a)
        x_b_hat = MotionTensors(p_b, out_b.rotations, out_b.root_positions)
        if out_b.root_velocities is None:
            root_a, root_b = r_a, out_b.root_positions
        else:  # NKN predicts root offsets: Lh on offsets (Baseline-height, Sec. 6 (iv))
            root_a, root_b = root_velocities(r_a), out_b.root_velocities
        x_a_hat = MotionTensors(p_a_hat, out_a.rotations, out_a.root_positions)
        d, red = self.discriminator, self.reduction
        h_fake = d(d.features(p_b, out_b.root_positions, off_b))
        z = self.position_scale.apply if self.position_scale is not None else (lambda x: x)
        terms = {
            "Lc": cycle_loss(z(x_a), z(x_a_hat), red),
            "Lt": twist_loss(out_b.rotations, out_a.rotations, self.alpha_deg, exclude_root=self.twist_exclude_root,
                             reduction=red),
            "Lh": height_loss(p_a, p_b, root_a, root_b, nkn_height(off_a), nkn_height(off_b),
                              self.weights.lambda_g, red),
            "La": adversarial_loss(h_fake, z(x_a), z(x_b_hat), batch.same_character, gan=self.gan, reduction=red),
            "Lr": regularization_loss(out_b.rotations, out_a.rotations, red),
            "Lo": orientation_loss(q_a[:, :, 0], out_b.rotations[:, :, 0], red),
            "Ld": bone_direction_loss(p_a, p_b, self.generator.parents, red),
        }
        return terms, x_b_hat

    def discriminator_loss(self, batch: TrainingBatch, x_b_hat: MotionTensors) -> Tensor:
        """Eq. 21 for D (LSGAN) or NKN's sigmoid CE: real windows of ``B`` vs the ``A ≠ B`` fakes.

        Args:
            batch: the batch the fakes were made from.
            x_b_hat: the generator's output (detached here).

        Returns:
            scalar loss; the real half only if the batch has no ``A ≠ B`` sample.
        """
        d, off_b = self.discriminator, batch.offsets_target
        g_loss, d_loss = _GANS[self.gan]
        p_real = source_local_positions(batch.real_rotations, off_b)
        h_real = d(d.features(p_real, batch.real_root_positions, off_b))
        fake = ~batch.same_character
        if not fake.any():
            return g_loss(h_real)  # = the "real → real" half of the discriminator loss
        h_fake = d(d.features(x_b_hat.p.detach()[fake], x_b_hat.r.detach()[fake], off_b[fake]))
        return d_loss(h_real, h_fake)

    def step(self, index: int) -> dict[str, float]:
        """One generator and one discriminator update (Eq. 6).

        The batch is drawn from the global RNGs on the CPU (in a multi-process run: the global
        batch, of which this rank keeps its shard) and moved to :attr:`device`.

        Args:
            index: step number (seeds this rank's dropout in a multi-process run; a single process
                draws everything from the global RNGs).

        Returns:
            ``{Lc, Lt, Lh, La, Lr, Lo, total, D}`` as floats (terms unweighted; this rank's shard).

        Raises:
            NonFiniteLossError: a weighted term, the total or the D loss is NaN/inf (named).
        """
        lr = learning_rate(self.lr, index, self.steps, self.decay_from)
        for opt in (self.opt_g, self.opt_d):
            for group in opt.param_groups:
                group["lr"] = lr
        batch = TrainingBatch(*(t[self.rows].to(self.device) for t in self.sampler.sample(self.batch)))
        with self.layout.rank_random(int(self.config["seed"]), index, self.device):
            self.discriminator.requires_grad_(False)  # La's gradient reaches G only
            try:
                with autocast(self.device, self.amp):
                    terms, x_b_hat = self.generator_terms(batch)
                    total, log = total_generator_loss(terms, self.weights)
                self.opt_g.zero_grad(set_to_none=True)
                total.backward()
                self.layout.average_gradients(self.generator)
                self.opt_g.step()
            finally:
                self.discriminator.requires_grad_(True)
            with autocast(self.device, self.amp):
                d_loss = check_finite("D", self.discriminator_loss(batch, x_b_hat))
            self.opt_d.zero_grad(set_to_none=True)
            d_loss.backward()
            self.layout.average_gradients(self.discriminator)
            self.opt_d.step()
        log["D"] = float(d_loss.detach())
        return log


# ---------------------------------------------------------------------------- inference


def export_generator(checkpoint: str | Path, out: str | Path) -> Path:
    """Write a slim, inference-only copy of a training checkpoint (atomically): the generator's
    weights (normaliser included), the step and the config — no discriminator, optimiser or RNG
    state. :func:`~retarget_lib.methods.tdcn.load_generator` reads it like a full checkpoint.

    TDCN generators are stored as float16 (:data:`HALF_PRECISION_KINDS`; read back as float32),
    NKN generators as float32.

    Returns:
        ``out``.
    """
    state = load_checkpoint(checkpoint)
    slim = {"step": state["step"], "config": state["config"],
            "modules": {"generator": state["modules"]["generator"]}}
    kind = resolve_config(model_config(state["config"]))["kind"]
    return save_state(slim, out, half=kind in HALF_PRECISION_KINDS)


