"""The papers' splits on a reviewer's ``mixamo-local`` folder (manifest ``test_lists``): which
characters and motions are seen in training, which test pairs belong to which TDCN scenario, and
the TDCN training set of a folder.

TDCN (Kim et al. 2020, Sec. 5, Tables 2-3): the training characters are the manifest's nine; a
motion is **unseen** if a source of scenario 3 or 4 (Sporty Granny, Claire, Mutant) performs it and
no source of scenario 1 or 2 does (:func:`unseen_motions`). The paper defines its test motions by
Mixamo page, which a folder of ``<Character>/<Motion>.bvh`` files does not record; this rule gives
the paper's eight pairs exactly their scenarios (pages 45, 51, 52 unseen; 18, 23, 28, 33 seen).
Training (:func:`mixamo_training_set`) uses the training characters' clips of every motion that is
not unseen, so scenario 3/4 motions and the test characters are never trained on.

Contact-aware (Villegas et al. 2021, Sec. 4, App. C): the test source (Y Bot) is never trained on;
the paper trains on the seven characters of NKN's training set [32], which it does not name, so
:func:`mixamo_contact_training_set` uses the manifest's TDCN training characters (NKN's set plus two,
TDCN Sec. 5) that have a ``shape.npz``, on every motion except the appendix's 30 test motions.
"""

from __future__ import annotations

from pathlib import Path
from typing import Mapping

from ..core.character import Character
from ..core.motion import Motion
from ..core.skeleton import Skeleton
from .manifest import mixamo_local_dir, source
from .sources.mixamo_local import load_mixamo_folder

__all__ = ["TRAIN_FPS", "tdcn_lists", "contact_lists", "paper_pairs", "unseen_motions", "scenario_of",
           "mixamo_training_set", "mixamo_contact_training_set"]

#: frame rate of the training clips (the methods' rate)
TRAIN_FPS = 30.0


def tdcn_lists() -> dict:
    """The manifest's TDCN lists (``mixamo-local`` → ``test_lists.tdcn``)."""
    return source("mixamo-local")["test_lists"]["tdcn"]


def contact_lists() -> dict:
    """The manifest's contact lists (``mixamo-local`` → ``test_lists.contact``)."""
    return source("mixamo-local")["test_lists"]["contact"]


def paper_pairs() -> dict[tuple[str, str], int]:
    """The paper's eight ``(source, target) -> scenario`` pairs (Table 3)."""
    return {(p["source"], p["target"]): int(key.split("_")[0])
            for key, pairs in tdcn_lists()["scenarios"].items() for p in pairs}


def unseen_motions(performers: Mapping[str, set[str]]) -> set[str]:
    """Motions that count as unseen (scenarios 3-4) in a folder.

    Args:
        performers: ``motion -> characters performing it``.

    Returns:
        the motions performed by a scenario 3/4 source and by no scenario 1/2 source.
    """
    pairs = paper_pairs()
    seen_sources = {s for (s, _), k in pairs.items() if k in (1, 2)}
    unseen_sources = {s for (s, _), k in pairs.items() if k in (3, 4)}
    return {m for m, who in performers.items() if who & unseen_sources and not who & seen_sources}


def scenario_of(target: str, motion: str, unseen: set[str]) -> int:
    """Scenario 1-4 of a case: seen/unseen motion × training/test target character."""
    seen_target = target in tdcn_lists()["train_characters"]
    return {(True, True): 1, (True, False): 2, (False, True): 3, (False, False): 4}[(motion not in unseen, seen_target)]


def mixamo_training_set(root: str | Path | None = None,
                        ) -> tuple[dict[str, Skeleton], list[tuple[Motion, Mapping[str, Motion]]]]:
    """The TDCN training set of a folder, for :func:`~retarget_lib.training.tdcn.stack_clips`.

    Each training character's skeleton is that of its first clip (by motion name); its other clips
    are put on it (rest offsets of one character's exports agree up to rounding). Clips are
    resampled to :data:`TRAIN_FPS`. A character's clip whose frame count differs from the
    reference performance (the first training character's) is not used as its own version (it
    then performs the reference's ground-truth transfer, like a character without that clip).

    Args:
        root: the folder (default ``$RETARGET_MIXAMO`` or the manifest's path).

    Returns:
        ``(skeletons, clips)``: training character -> skeleton, and ``(reference, own versions)``
        per seen motion.

    Raises:
        ValueError: fewer than two training characters, or no seen motion, in the folder.
    """
    folder = load_mixamo_folder(root if root is not None else mixamo_local_dir())
    performers = folder.performers()
    unseen = unseen_motions(performers)
    train = [n for n in tdcn_lists()["train_characters"] if any(n in who for who in performers.values())]
    if len(train) < 2:
        raise ValueError(f"mixamo-local folder {folder.root}: needs clips of at least two of the training characters "
                         f"{tdcn_lists()['train_characters']}; found {train}")
    skeletons = {n: folder.clips[n, min(m for m, who in performers.items() if n in who)].skeleton for n in train}
    clips = []
    for motion, who in performers.items():
        own_names = [n for n in train if n in who]
        if motion in unseen or not own_names:
            continue
        own = {n: folder.clips[n, motion].resample(TRAIN_FPS).with_skeleton(skeletons[n]) for n in own_names}
        reference = own[own_names[0]]
        reference.name = motion
        clips.append((reference, {n: m for n, m in own.items() if m.num_frames == reference.num_frames}))
    if not clips:
        raise ValueError(f"mixamo-local folder {folder.root}: no seen motion of the training characters")
    return skeletons, clips


def mixamo_contact_training_set(root: str | Path | None = None,
                                ) -> tuple[dict[str, Character], list[tuple[str, str, Motion]]]:
    """The contact-aware training characters and clips of a folder (module docstring).

    Each clip is resampled to :data:`TRAIN_FPS` and put on its character's mesh skeleton (the
    ``shape.npz`` rest offsets) so that skinning it is consistent.

    Returns:
        ``(characters, clips)``: training character -> :class:`Character` (its mesh), and
        ``(character, cache key, motion)`` per training clip (motion named ``"<character>/<motion>"``).

    Raises:
        ValueError: no training character with a mesh, or no training clip.
    """
    folder = load_mixamo_folder(root if root is not None else mixamo_local_dir())
    lists = contact_lists()
    excluded = {lists["source_character"]}
    characters = {n: c for n in tdcn_lists()["train_characters"] if n not in excluded
                  and (c := folder.character(n)) is not None}
    if not characters:
        raise ValueError(f"mixamo-local folder {folder.root}: no shape.npz of a training character "
                         f"{tdcn_lists()['train_characters']}")
    test_motions = {m["name"] for m in lists["motions"]}
    clips = []
    for (name, motion), clip in sorted(folder.clips.items()):
        if name in characters and motion not in test_motions:
            m = clip.resample(TRAIN_FPS).with_skeleton(characters[name].skeleton)
            m.name = f"{name}/{motion}"
            clips.append((name, f"mixamo_{folder.fingerprint(name, motion)}_{m.num_frames}", m))
    if not clips:
        raise ValueError(f"mixamo-local folder {folder.root}: no clip of {sorted(characters)} outside the "
                         "contact test motions")
    return characters, clips
