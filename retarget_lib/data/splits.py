"""The four TDCN test scenarios (Kim et al. 2020, Sec. 5, Tables 2-3) on the synthetic data:
seen / unseen characters and motions, and the source -> target pairs of each scenario."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from .manifest import source
from .synthetic.characters import CHARACTER_NAMES
from .synthetic.motions import MOTION_FAMILIES


class MotionId(NamedTuple):
    """One synthetic clip: ``make_motion(family, skeleton, seed)``."""

    family: str
    seed: int

    def __str__(self) -> str:
        return f"{self.family}/{self.seed}"

    @property
    def clip(self) -> str:
        """The clip's name in the synthetic datasets, e.g. ``"walk_003"``."""
        return f"{self.family}_{self.seed:03d}"


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


def tdcn_splits(
    character_names: Sequence[str],
    families: Sequence[str],
    seed: int = 0,
    n_test_characters: int | None = None,
    n_test_families: int = 2,
    seeds_per_family: int = 4,
    n_test_seeds: int = 1,
    pairs_per_scenario: int = 4,
) -> TDCNSplits:
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
    * The ground truth of a pair is :func:`~retarget_lib.core.transfer.retarget_ground_truth` of the
      source clip.

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
        raise ValueError(
            f"need >= 2 seen and >= 2 unseen characters; got {len(names)} characters, "
            f"{n_test} unseen"
        )
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
    test_motions = tuple(
        [MotionId(f, s) for f in train_fams for s in held_seeds]
        + [MotionId(f, s) for f in test_fams for s in range(seeds_per_family)]
    )

    def draw(motions, sources, targets_a, targets_b):
        picks = rng.choice(
            len(motions), size=pairs_per_scenario, replace=len(motions) < pairs_per_scenario
        )
        rows_a, rows_b = [], []
        for k in picks:
            src = sources[rng.integers(len(sources))]
            rows_a.append(ScenarioPair(src, _other(rng, targets_a, src), motions[k]))
            rows_b.append(ScenarioPair(src, _other(rng, targets_b, src), motions[k]))
        return tuple(rows_a), tuple(rows_b)

    s1, s2 = draw(train_motions, train_chars, train_chars, test_chars)
    s3, s4 = draw(test_motions, test_chars, train_chars, test_chars)
    return TDCNSplits(
        train_chars,
        test_chars,
        train_fams,
        test_fams,
        train_motions,
        test_motions,
        {1: s1, 2: s2, 3: s3, 4: s4},
    )


def _other(rng: np.random.Generator, pool: Sequence[str], exclude: str) -> str:
    """A random member of ``pool`` other than ``exclude``."""
    choices = [c for c in pool if c != exclude]
    return choices[rng.integers(len(choices))]


def tdcn_split():
    """The TDCN four-scenario split of the synthetic data, with the manifest's parameters.

    Returns:
        :class:`TDCNSplits`; ``MotionId(family, k)`` is clip
        ``f"{family}_{k:03d}"``.
    """
    params = dict(source("synthetic")["splits"]["tdcn"]["params"])
    return tdcn_splits(CHARACTER_NAMES, MOTION_FAMILIES, **params)
