"""Source/target pairs: the ground-truth retargeting of synthetic motion, copy baselines, and the
four TDCN test scenarios.

Ground truth (DESIGN.md, "Data"): the target performs the source's motion with the same *global*
bone directions and twists, rest-pose differences compensated, and the root trajectory scaled by
the leg-length ratio -- what Mixamo produces when one animation is applied to many characters.

Why copying local rotations is a baseline and not the answer: a local rotation is relative to the
rest pose, and rest poses differ (A-pose vs T-pose arms, a curved vs straight spine, splayed
feet). Copying ``q_j`` from an A-pose character onto a T-pose character raises every arm by the
A/T angle difference. Rest-compensation fixes exactly that: per joint a constant rotation ``C_j``
maps the target's rest bone direction onto the source's, and ``G^B_j = G^A_j C_j`` for every
global rotation ``G``; in local terms ``q^B_j = C_p^-1 q^A_j C_j`` (``p`` = parent). Both
characters then point every bone the same way in the world (TDCN's and NKN's evaluation compare
against this kind of target).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple, Sequence

import numpy as np
import torch

from ..ik import frame_rotation
from ..motion import Motion
from ..rotations import quat_between, quat_canonical, quat_conjugate, quat_identity, quat_mul
from ..skeleton import CANONICAL22, CANONICAL22_PARENTS, J, JointSetError, Skeleton

__all__ = [
    "PRIMARY_CHILD",
    "ACROSS_PAIR",
    "rest_alignment",
    "transfer_rotations",
    "retarget_ground_truth",
    "copy_rotations",
    "copy_rotations_rest_compensated",
    "MotionId",
    "ScenarioPair",
    "TDCNSplits",
    "tdcn_splits",
]

#: the child whose bone defines each canonical joint's rest direction (-1: leaf, uses its parent's)
PRIMARY_CHILD: tuple[int, ...] = tuple(
    {"Hips": J["Spine"], "Spine": J["Spine1"], "Spine1": J["Spine2"], "Spine2": J["Neck"],
     "Neck": J["Head"], "LeftUpLeg": J["LeftLeg"], "LeftLeg": J["LeftFoot"],
     "LeftFoot": J["LeftToeBase"], "RightUpLeg": J["RightLeg"], "RightLeg": J["RightFoot"],
     "RightFoot": J["RightToeBase"], "LeftShoulder": J["LeftArm"], "LeftArm": J["LeftForeArm"],
     "LeftForeArm": J["LeftHand"], "RightShoulder": J["RightArm"], "RightArm": J["RightForeArm"],
     "RightForeArm": J["RightHand"]}.get(name, -1) for name in CANONICAL22)

#: joints with several children: their rest frame also uses the left-minus-right child offset
ACROSS_PAIR: dict[int, tuple[int, int]] = {
    J["Hips"]: (J["LeftUpLeg"], J["RightUpLeg"]),
    J["Spine2"]: (J["LeftShoulder"], J["RightShoulder"]),
}


def _check(skeleton: Skeleton) -> None:
    if not skeleton.is_canonical22():
        raise JointSetError("rest alignment needs the canonical 22 joints; fold the motion first "
                            "with retarget_lib.skeleton.to_canonical22")


def rest_alignment(source: Skeleton, target: Skeleton) -> np.ndarray:
    """Per-joint constant rotations that compensate rest-pose differences.

    ``C_j`` maps the target's rest bone direction of joint ``j`` (towards
    :data:`PRIMARY_CHILD`) onto the source's, by the shortest arc; for the hips and the chest
    (:data:`ACROSS_PAIR`) it maps the whole rest frame (bone + left-right axis). A leaf (head,
    hands, toes) has no bone of its own and uses its parent's ``C``. Then ``G^B_j = G^A_j C_j``
    gives both characters the same global bone directions.

    Args:
        source: canonical-22 skeleton ``A``.
        target: canonical-22 skeleton ``B``.

    Returns:
        ``(22, 4)`` wxyz; identity rows where the rest poses agree (e.g. uniform scaling).
    """
    _check(source)
    _check(target)
    off_a, off_b = torch.from_numpy(source.offsets), torch.from_numpy(target.offsets)
    out = quat_identity((22,), dtype=torch.float64)
    for j, child in enumerate(PRIMARY_CHILD):
        if child < 0:
            out[j] = out[CANONICAL22_PARENTS[j]]
        elif j in ACROSS_PAIR:
            left, right = ACROSS_PAIR[j]
            out[j] = frame_rotation(off_b[child], off_b[left] - off_b[right],
                                   off_a[child], off_a[left] - off_a[right])
        else:
            out[j] = quat_between(off_b[child], off_a[child])
    return quat_canonical(out).numpy()


def transfer_rotations(rotations: np.ndarray, source: Skeleton, target: Skeleton) -> np.ndarray:
    """Local rotations of ``source`` -> local rotations of ``target`` with the same global bone
    directions and twists: ``q^B_j = C_p^-1 q^A_j C_j`` (:func:`rest_alignment`).

    Args:
        rotations: ``(..., 22, 4)`` local rotations on ``source``, wxyz.
        source: the skeleton ``rotations`` belong to.
        target: the skeleton to express them on.

    Returns:
        ``(..., 22, 4)`` local rotations on ``target``, float64.
    """
    c = torch.from_numpy(rest_alignment(source, target))
    root = quat_identity((1,), dtype=torch.float64)
    c_parent = torch.cat((root, c[list(CANONICAL22_PARENTS[1:])]))
    q = torch.from_numpy(np.asarray(rotations, dtype=np.float64))
    return quat_canonical(quat_mul(quat_conjugate(c_parent), quat_mul(q, c))).numpy()


def _root_scale(source: Skeleton, target: Skeleton) -> float:
    return target.leg_length() / source.leg_length()


def retarget_ground_truth(motion: Motion, target_skeleton: Skeleton) -> Motion:
    """The ground-truth retargeting of a synthetic motion onto another character (DESIGN.md).

    Every global bone direction and twist of the source is reproduced (:func:`transfer_rotations`;
    an A-pose source and a T-pose target end up with the same world-space arms), and the root
    trajectory is multiplied by ``target.leg_length() / source.leg_length()`` (like Mixamo, and
    like TDCN's root-velocity normalisation by leg length, Sec. 4.1). Nothing else is adjusted:
    when limb *proportions* differ the target's feet may slide or float a little -- exactly the
    contact errors that the contact-aware method (Villegas et al. 2021) is designed to remove.

    Args:
        motion: source motion on the canonical 22 joints.
        target_skeleton: canonical-22 target character.

    Returns:
        the target's :class:`Motion` (same frames and fps).
    """
    rot = transfer_rotations(motion.rotations, motion.skeleton, target_skeleton)
    root = motion.root_positions * _root_scale(motion.skeleton, target_skeleton)
    return motion.copy(skeleton=target_skeleton.copy(), rotations=rot, root_positions=root,
                       meta=dict(motion.meta, retargeted="ground_truth"))


def copy_rotations(motion: Motion, target_skeleton: Skeleton) -> Motion:
    """Baseline: copy the local rotations unchanged, scale the root by the leg-length ratio.

    Correct only when both characters share the same rest pose (bone *directions*); otherwise
    every rest-pose difference shows up as a pose error (NKN/TDCN "Copy" baseline).

    Args:
        motion: source motion on the canonical 22 joints.
        target_skeleton: canonical-22 target character.
    """
    root = motion.root_positions * _root_scale(motion.skeleton, target_skeleton)
    return motion.copy(skeleton=target_skeleton.copy(), root_positions=root,
                       meta=dict(motion.meta, retargeted="copy"))


def copy_rotations_rest_compensated(motion: Motion, target_skeleton: Skeleton) -> Motion:
    """Baseline "copy with rest-pose compensation".

    This is the same mathematics as :func:`retarget_ground_truth` (which is implemented as a
    rest-compensated copy), so on synthetic pairs it scores zero error by construction; it is
    listed separately so that evaluation tables can name it. On real Mixamo data the ground
    truth comes from Mixamo's own retargeter and the two differ.
    """
    out = retarget_ground_truth(motion, target_skeleton)
    out.meta["retargeted"] = "copy_rest_compensated"
    return out


# ----------------------------------------------------------------------------- TDCN scenarios
class MotionId(NamedTuple):
    """One synthetic clip: ``make_motion(family, skeleton, seed)``."""

    family: str
    seed: int

    def __str__(self) -> str:
        return f"{self.family}/{self.seed}"


class ScenarioPair(NamedTuple):
    """One test case ``source -> target`` on motion ``motion`` (TDCN Table 3's rows)."""

    source: str
    target: str
    motion: MotionId


@dataclass(frozen=True)
class TDCNSplits:
    """Training data and the four TDCN test scenarios (Kim et al. 2020, Sec. 5, Table 3).

    Attributes:
        train_characters: the seen characters (all training clips are performed by them).
        test_characters: the unseen characters.
        train_families, test_families: motion families used / held out in training.
        train_motions: the seen clips: every train character performs every one of them.
        test_motions: the unseen clips: held-out seeds of the train families, and every seed of
            the held-out families.
        scenarios: ``{1: [...], 2: [...], 3: [...], 4: [...]}`` lists of :class:`ScenarioPair`:
            (1) seen motion -> seen character, (2) seen motion -> unseen character,
            (3) unseen motion -> seen character, (4) unseen motion -> unseen character.
    """

    train_characters: tuple[str, ...]
    test_characters: tuple[str, ...]
    train_families: tuple[str, ...]
    test_families: tuple[str, ...]
    train_motions: tuple[MotionId, ...]
    test_motions: tuple[MotionId, ...]
    scenarios: dict[int, tuple[ScenarioPair, ...]]


def tdcn_splits(character_names: Sequence[str], families: Sequence[str], seed: int = 0,
                n_test_characters: int | None = None, n_test_families: int = 2,
                seeds_per_family: int = 4, n_test_seeds: int = 1,
                pairs_per_scenario: int = 4) -> TDCNSplits:
    """Split characters and clips like TDCN's test protocol (Sec. 5, Tables 2-3).

    Decisions, and why:

    * **Characters** are split at random (by ``seed``) into seen and unseen, about a third unseen
      (TDCN: 9 training characters, test characters such as Mutant and Sporty Granny never seen).
    * **An unseen motion** is a clip no training character ever performed. Two kinds are held
      out so that both "new style" and "new action" generalisation are measured: the last
      ``n_test_seeds`` seeds of every training family (same action, new speed/stride/timing --
      like a different Mixamo take of a similar action) and all seeds of ``n_test_families``
      whole families (a new action, like an unseen Mixamo page).
    * **Sources**, as in Table 3: a seen motion is performed by a seen character (it is in the
      training data); an unseen motion is performed by an unseen character (TDCN's scenario 3/4
      sources -- Sporty Granny, Claire, Mutant -- are test characters).
    * Scenarios 1/2 share their motions and sources and differ only in the target, as do 3/4
      (Table 3 uses page 52 for both Claire->Warrok and Claire->Mutant), so the effect of an
      unseen target is measured on the same inputs. Source and target always differ.
    * The ground truth of a pair is :func:`retarget_ground_truth` of the source clip.

    Args:
        character_names: all character names (e.g. ``characters.CHARACTER_NAMES``).
        families: all motion families (e.g. ``motions.MOTION_FAMILIES``).
        seed: random seed of the split.
        n_test_characters: unseen characters (default ``max(2, round(len / 3))``).
        n_test_families: families held out entirely.
        seeds_per_family: clip seeds ``0 .. seeds_per_family - 1`` per family.
        n_test_seeds: seeds per training family held out of training.
        pairs_per_scenario: pairs in each scenario list.

    Returns:
        :class:`TDCNSplits`.
    """
    names = sorted(character_names)
    n_test = max(2, round(len(names) / 3)) if n_test_characters is None else n_test_characters
    if not 2 <= n_test <= len(names) - 2:
        raise ValueError(f"need >= 2 seen and >= 2 unseen characters; got {len(names)} characters, "
                         f"{n_test} unseen")
    if not 0 < n_test_families < len(families) or not 0 < n_test_seeds < seeds_per_family:
        raise ValueError("need at least one held-out and one training family and seed")
    rng = np.random.default_rng(seed)
    perm = [names[i] for i in rng.permutation(len(names))]
    test_chars, train_chars = tuple(sorted(perm[:n_test])), tuple(sorted(perm[n_test:]))
    fam = list(families)
    held = set(fam[i] for i in rng.permutation(len(fam))[:n_test_families])
    train_fams = tuple(f for f in fam if f not in held)
    test_fams = tuple(f for f in fam if f in held)
    n_train_seeds = seeds_per_family - n_test_seeds
    train_motions = tuple(MotionId(f, s) for f in train_fams for s in range(n_train_seeds))
    held_seeds = range(n_train_seeds, seeds_per_family)
    test_motions = tuple([MotionId(f, s) for f in train_fams for s in held_seeds]
                         + [MotionId(f, s) for f in test_fams for s in range(seeds_per_family)])

    def draw(motions, sources, targets_a, targets_b):
        picks = rng.choice(len(motions), size=pairs_per_scenario,
                           replace=len(motions) < pairs_per_scenario)
        rows_a, rows_b = [], []
        for k in picks:
            src = sources[rng.integers(len(sources))]
            rows_a.append(ScenarioPair(src, _other(rng, targets_a, src), motions[k]))
            rows_b.append(ScenarioPair(src, _other(rng, targets_b, src), motions[k]))
        return tuple(rows_a), tuple(rows_b)

    s1, s2 = draw(train_motions, train_chars, train_chars, test_chars)
    s3, s4 = draw(test_motions, test_chars, train_chars, test_chars)
    return TDCNSplits(train_chars, test_chars, train_fams, test_fams, train_motions, test_motions,
                      {1: s1, 2: s2, 3: s3, 4: s4})


def _other(rng: np.random.Generator, pool: Sequence[str], exclude: str) -> str:
    """A random member of ``pool`` other than ``exclude``."""
    choices = [c for c in pool if c != exclude]
    return choices[rng.integers(len(choices))]
