"""The data TDCN and its Table 4 rows train on (Kim et al. 2020, Sec. 5): every training character
performing every training clip (:class:`TrainingClips`), and random batches of windows drawn from
them (:class:`WindowSampler`), for :class:`~retarget_lib.training.tdcn.RetargetTraining`.

Like Mixamo, every training character
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
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from functools import lru_cache
from typing import NamedTuple

import torch

from ..config_schema import DATA_SOURCES
from ..core.motion import Motion
from ..core.retarget_pose import pose_offsets
from ..core.rotations import quat_from_axis_angle, quat_mul, quat_rotate
from ..core.skeleton import J, Skeleton, canonical22_skeleton
from ..core.transfer import (
    random_rest_rotations,
    retarget_ground_truth,
    transfer_rotations_tensor,
)
from ..data.manifest import mixamo_local_dir
from ..data.mixamo_splits import mixamo_training_set
from ..data.splits import tdcn_split
from ..data.synthetic.dataset import load_synthetic
from ..data.synthetic.mixamo_convention import load_mixamo_convention, mixamo_convention_split
from ..methods.retarget import METHOD_FPS
from ..methods.tdcn import centre_root

Tensor = torch.Tensor

__all__ = [
    "TrainingBatch",
    "TrainingClips",
    "WindowSampler",
    "config_training_clips",
    "stack_clips",
    "training_clips",
]


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
        starts = [
            torch.arange(
                int(a), max(int(a), int(b) - window + 1)
            )  # none in a clip shorter than a window
            for a, b in zip(self.clip_bounds[:-1], self.clip_bounds[1:], strict=False)
        ]
        starts = torch.cat(starts)
        if starts.numel() == 0:
            raise ValueError(f"no training clip has {window} frames")
        return starts

    def subset(self, clips: int | None = None, characters: int | None = None) -> TrainingClips:
        """The first ``clips`` clips performed by the first ``characters`` characters (``None``:
        all): a capacity check's tiny training set (``data.max_clips``, ``data.max_characters``)."""
        k, c = len(self.clip_names), len(self.characters)
        k = k if clips is None else min(int(clips), k)
        c = c if characters is None else min(int(characters), c)
        end = int(self.clip_bounds[k])
        return TrainingClips(
            self.characters[:c],
            self.clip_names[:k],
            self.clip_bounds[: k + 1],
            self.offsets[:c],
            self.rotations[:c, :end],
            self.root_positions[:c, :end],
        )

    def motion(self, character: int, clip: int, fps: float = METHOD_FPS) -> Motion:
        """Character ``character``'s version of clip ``clip`` as a :class:`Motion` (float64)."""
        a, b = int(self.clip_bounds[clip]), int(self.clip_bounds[clip + 1])
        return Motion(
            canonical22_skeleton(self.offsets[character].double().numpy()),
            self.rotations[character, a:b].double().numpy(),
            self.root_positions[character, a:b].double().numpy(),
            fps,
            name=f"{self.clip_names[clip]}@{self.characters[character]}",
        )


def stack_clips(
    skeletons: Mapping[str, Skeleton], clips: Sequence[tuple[Motion, Mapping[str, Motion]]]
) -> TrainingClips:
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
        versions = [
            own[name] if name in own else retarget_ground_truth(ref, skeleton) for ref, own in clips
        ]
        rotations.append(
            torch.cat([torch.as_tensor(m.rotations, dtype=torch.float32) for m in versions])
        )
        roots.append(
            torch.cat([torch.as_tensor(m.root_positions, dtype=torch.float32) for m in versions])
        )
    offsets = torch.stack(
        [torch.as_tensor(s.offsets, dtype=torch.float32) for s in skeletons.values()]
    )
    return TrainingClips(
        tuple(skeletons),
        tuple(ref.name for ref, _ in clips),
        lengths.cumsum(0),
        offsets,
        torch.stack(rotations),
        torch.stack(roots),
    )


def _synthetic_clips() -> tuple[dict[str, Skeleton], list[tuple[Motion, dict]]]:
    """The TDCN split's train characters and train clips (every version a ground-truth transfer)."""
    ds, split = load_synthetic(), tdcn_split()
    clips = [(ds.clip(m.clip).motion, {}) for m in split.train_motions]
    return {n: ds.characters[n].skeleton for n in split.train_characters}, clips


def _mixamo_convention_clips() -> tuple[dict[str, Skeleton], list[tuple[Motion, dict]]]:
    """The Mixamo-convention profile's train characters and train clips, each character's own
    version (:mod:`~retarget_lib.data.synthetic.mixamo_convention`)."""
    data, split = load_mixamo_convention(), mixamo_convention_split()
    skeletons = {n: data.characters[n].skeleton for n in split.train_characters}
    clips = []
    for m in split.train_motions:
        versions = data.clips[m.clip]
        own = {n: versions[n] for n in skeletons}
        clips.append((own[split.train_characters[0]], own))
    return skeletons, clips


@lru_cache(maxsize=2)
def training_clips(
    mirror: bool = False, source: str = "synthetic", mixamo_root: str | None = None
) -> TrainingClips:
    """The training characters × training clips of ``source``, built once per process.

    Args:
        mirror: also every clip's left/right mirror image (:meth:`Motion.mirror`), as more clips.
        source: one of :data:`DATA_SOURCES`. ``synthetic``: the TDCN split's train characters ×
            train clips (ground-truth transfers). ``mixamo-convention``: the same of the
            Mixamo-convention profile (each character's own version of each clip).
            ``synthetic+mixamo-convention``: both profiles' characters and clips (a character
            without its own version of a clip performs its ground-truth transfer). ``mixamo-local``:
            the folder's paper training characters and seen motions
            (:func:`~retarget_lib.data.mixamo_splits.mixamo_training_set`), each character's own
            clip where it has one. ``mixamo-local+synthetic``: both characters sets, both clip sets;
            a character without its own version of a clip performs the clip's ground-truth transfer.
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
        skeletons, clips = mixamo_training_set(mixamo_root)
    for part, load in (
        ("mixamo-convention", _mixamo_convention_clips),
        ("synthetic", _synthetic_clips),
    ):
        if part in parts:
            more_skeletons, more_clips = load()
            skeletons, clips = {**skeletons, **more_skeletons}, clips + more_clips
    if mirror:
        clips += [(ref.mirror(), {k: v.mirror() for k, v in own.items()}) for ref, own in clips]
    return stack_clips(skeletons, clips)


def config_training_clips(data: Mapping) -> TrainingClips:
    """The training set a config's ``data`` section names: :func:`training_clips` of its
    ``source`` (a ``mixamo-local`` part read from ``$RETARGET_MIXAMO``) and ``mirror``, cut to its
    ``max_clips`` / ``max_characters`` (:meth:`TrainingClips.subset`; a capacity check's set)."""
    source = data.get("source", "synthetic")
    root = str(mixamo_local_dir()) if "mixamo-local" in source.split("+") else None
    return training_clips(bool(data.get("mirror", False)), source, root).subset(
        data.get("max_clips"), data.get("max_characters")
    )


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
            with their windows performed on it as the ground truth would
            (:func:`~retarget_lib.core.transfer.transfer_rotations_tensor`: the rotation deltas
            from the retarget pose, so a turn beyond the pose's tolerance is a convention and
            compensated, one within it is the character's shape and kept). The synthetic
            characters mostly share straight-leg rest poses, real files do not (CMU's legs are
            splayed by 20°). ``A = B`` pairs share one rest pose.
        rest_arm_drop_deg: our augmentation (0 = off): a skeleton that gets a random rest pose
            also has both upper arms lowered from their rest by an angle uniform in
            ``[0, rest_arm_drop_deg]`` (about the forward axis). Real rigs rest with their arms
            anywhere from a T-pose to hanging 70-83° below the horizontal
            (``data/real_characters/proportions.csv``), the synthetic characters at most 50°.
    """

    def __init__(
        self,
        clips: TrainingClips,
        window: int = 81,
        same_fraction: float = 0.5,
        scale_range: tuple[float, float] | None = (0.5, 1.5),
        scale_targets: bool = True,
        random_yaw: bool = False,
        rest_jitter_deg: float = 0.0,
        rest_arm_drop_deg: float = 0.0,
    ):
        if len(clips.characters) < 2:
            raise ValueError("need at least two training characters")
        if not 0.0 <= same_fraction <= 1.0:
            raise ValueError(f"same_fraction must be in [0, 1], got {same_fraction}")
        low, high = (1.0, 1.0) if scale_range is None else map(float, scale_range)
        if not 0.0 < low <= high:
            raise ValueError(
                f"scale_range must be null or [low, high] with 0 < low <= high, got {scale_range}"
            )
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
        return self.scale_low + (self.scale_high - self.scale_low) * torch.rand(
            batch, generator=generator
        )

    def _windows(
        self, character: Tensor, scale: Tensor, generator: torch.Generator | None
    ) -> tuple[Tensor, Tensor]:
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
        target = torch.where(
            same, source, (source + torch.randint(1, n, (batch,), generator=generator)) % n
        )
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
            (q_a, off_a), (q_real, off_b) = (
                _re_rested(q_a, off_a, turn_a),
                _re_rested(q_real, off_b, turn_b),
            )
        return TrainingBatch(
            q_a, r_a, off_a, off_b, same, q_real, r_real, source, target, scale_a, scale_b
        )

    def _rest_turns(self, offsets: Tensor, generator: torch.Generator | None) -> Tensor:
        """``(B, J, 4)``: random rest-pose turns for half the samples, identity for the others."""
        turns = random_rest_rotations(offsets, self.rest_jitter_deg, generator)
        if self.rest_arm_drop_deg > 0:
            drop = torch.rand(len(offsets), generator=generator) * math.radians(
                self.rest_arm_drop_deg
            )
            for arm, side in (
                (J["LeftArm"], -1.0),
                (J["RightArm"], 1.0),
            ):  # the left arm points +X: about -Z
                lower = quat_from_axis_angle(
                    torch.stack(
                        [torch.zeros_like(drop), torch.zeros_like(drop), side * drop], dim=-1
                    )
                )
                turns[:, arm] = quat_mul(lower, turns[:, arm])
        keep = torch.rand(len(offsets), generator=generator) < 0.5
        return torch.where(keep[:, None, None], torch.tensor([1.0, 0.0, 0.0, 0.0]), turns)


def _re_rested(rotations: Tensor, offsets: Tensor, turns: Tensor) -> tuple[Tensor, Tensor]:
    """Windows of characters given another rest pose (``turns``, :func:`random_rest_rotations`):
    ``(rotations (B, W, J, 4), offsets (B, J, 3))`` of the re-rested characters performing the
    windows by the ground truth's rule (the rotation deltas from the retarget pose)."""
    moved = pose_offsets(offsets, turns)
    return transfer_rotations_tensor(rotations, offsets, moved), moved
