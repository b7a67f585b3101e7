"""The papers' splits on a reviewer's ``mixamo-local`` folder (manifest ``test_lists``): which
characters and motions are seen in training, which test pairs belong to which TDCN scenario, and
the TDCN training set of a folder.

TDCN (Kim et al. 2020, Sec. 5, Tables 2-3), the **default rule**: the training (seen) characters
are the manifest's nine; a motion is **unseen** if a source of scenario 3 or 4 (Sporty Granny,
Claire, Mutant) performs it and no source of scenario 1 or 2 does (:func:`unseen_motions`). This
rule is ours: the paper defines its test motions by Mixamo page, which the file names of a folder do
not record; it gives the paper's eight pairs exactly their scenarios (pages 45, 51, 52 unseen; 18,
23, 28, 33 seen). A folder **declares its own split** in an optional ``splits.yaml``
(``seen_motions``/``unseen_motions``, ``seen_characters``/``unseen_characters``; the layout and the
checks are in :mod:`retarget_lib.data.sources.mixamo_local`), which replaces the default for what it
names; :func:`folder_split` gives the split in force. Training (:func:`mixamo_training_set`) uses
the seen characters' clips of every seen motion, so unseen motions and characters are never trained
on.

Contact-aware (Villegas et al. 2021, Sec. 4, App. C): the test source (Y Bot) is never trained on;
the paper trains on the seven characters of NKN's training set [32], which it does not name, so
:func:`mixamo_contact_training_set` uses the seen characters of :func:`folder_split` (by default the
manifest's TDCN training characters: NKN's set plus two, TDCN Sec. 5) that have a mesh, on every
motion except the appendix's 30 test motions.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

from ..core.character import Character
from ..core.motion import Motion
from ..core.skeleton import Skeleton
from .manifest import mixamo_local_dir, source
from .sources.mixamo_local import MixamoFolder, load_mixamo_folder

__all__ = [
    "TRAIN_FPS",
    "tdcn_lists",
    "contact_lists",
    "paper_pairs",
    "unseen_motions",
    "scenario_of",
    "FolderSplit",
    "folder_split",
    "mixamo_training_set",
    "mixamo_contact_training_set",
]

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
    return {
        (p["source"], p["target"]): int(key.split("_")[0])
        for key, pairs in tdcn_lists()["scenarios"].items()
        for p in pairs
    }


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


def scenario_of(
    target: str, motion: str, unseen: set[str], train_characters: Sequence[str] | None = None
) -> int:
    """Scenario 1-4 of a case: seen/unseen motion × training/test target character.

    Args:
        target, motion: the case.
        unseen: the unseen motions.
        train_characters: the seen characters (default: the manifest's TDCN training characters).
    """
    seen_target = target in (
        tdcn_lists()["train_characters"] if train_characters is None else train_characters
    )
    return {(True, True): 1, (True, False): 2, (False, True): 3, (False, False): 4}[
        (motion not in unseen, seen_target)
    ]


@dataclass(frozen=True)
class FolderSplit:
    """The TDCN split in force on a folder (:func:`folder_split`).

    Attributes:
        unseen_motions: the unseen motions of the folder.
        train_characters: the seen (training) characters, in order (may name characters the folder
            lacks).
        motion_rule: where ``unseen_motions`` comes from (the ``splits.yaml`` path or the default
            rule).
        character_rule: where ``train_characters`` comes from.
    """

    unseen_motions: frozenset[str]
    train_characters: tuple[str, ...]
    motion_rule: str
    character_rule: str

    def scenario(self, target: str, motion: str) -> int:
        """Scenario 1-4 of a (target, motion) case (:func:`scenario_of`)."""
        return scenario_of(target, motion, set(self.unseen_motions), self.train_characters)

    def describe(self) -> str:
        """One sentence naming the rules and the unseen motions (for reports)."""
        return (
            f"unseen motions ({self.motion_rule}): "
            f"{', '.join(sorted(self.unseen_motions)) or 'none'}; "
            f"seen characters ({self.character_rule}): {', '.join(self.train_characters) or 'none'}"
        )


#: the default rules, as :class:`FolderSplit` and the reports name them
DEFAULT_MOTION_RULE = "default: performed by a scenario 3/4 source and no scenario 1/2 source"
DEFAULT_CHARACTER_RULE = "default: the manifest's TDCN training characters"


def folder_split(folder: MixamoFolder) -> FolderSplit:
    """The split of a loaded folder: its ``splits.yaml`` where it declares a list, the default
    rules (module docstring) elsewhere."""
    declared = folder.splits
    if declared is not None and declared.unseen_motions is not None:
        unseen, motion_rule = declared.unseen_motions, str(declared.path)
    else:
        unseen, motion_rule = frozenset(unseen_motions(folder.performers())), DEFAULT_MOTION_RULE
    if declared is not None and declared.seen_characters is not None:
        train, character_rule = declared.seen_characters, str(declared.path)
    else:
        train, character_rule = tuple(tdcn_lists()["train_characters"]), DEFAULT_CHARACTER_RULE
    return FolderSplit(frozenset(unseen), tuple(train), motion_rule, character_rule)


def mixamo_training_set(
    root: str | Path | None = None,
) -> tuple[dict[str, Skeleton], list[tuple[Motion, Mapping[str, Motion]]]]:
    """The TDCN training set of a folder, for :func:`~retarget_lib.training.tdcn_data.stack_clips`.

    The split is :func:`folder_split`'s (the folder's ``splits.yaml``, else the default rules).
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
    split = folder_split(folder)
    unseen = split.unseen_motions
    train = [n for n in split.train_characters if any(n in who for who in performers.values())]
    if len(train) < 2:
        raise ValueError(
            f"mixamo-local folder {folder.root}: needs clips of at least two of the training "
            "characters "
            f"{list(split.train_characters)} ({split.character_rule}); found {train}"
        )
    skeletons = {
        n: folder.clips[n, min(m for m, who in performers.items() if n in who)].skeleton
        for n in train
    }
    clips = []
    for motion, who in performers.items():
        own_names = [n for n in train if n in who]
        if motion in unseen or not own_names:
            continue
        own = {
            n: folder.clips[n, motion].resample(TRAIN_FPS).with_skeleton(skeletons[n])
            for n in own_names
        }
        reference = own[own_names[0]]
        reference.name = motion
        clips.append(
            (reference, {n: m for n, m in own.items() if m.num_frames == reference.num_frames})
        )
    if not clips:
        raise ValueError(
            f"mixamo-local folder {folder.root}: no seen motion of the training characters"
        )
    return skeletons, clips


def mixamo_contact_training_set(
    root: str | Path | None = None,
) -> tuple[dict[str, Character], list[tuple[str, str, Motion]]]:
    """The contact-aware training characters and clips of a folder (module docstring).

    Each clip is resampled to :data:`TRAIN_FPS` and put on its character's mesh skeleton (the rest
    offsets of ``shape.npz`` or of the character's FBX/GLB) so that skinning it is consistent.

    Returns:
        ``(characters, clips)``: training character -> :class:`Character` (its mesh), and
        ``(character, cache key, motion)`` per training clip (motion named
        ``"<character>/<motion>"``).

    Raises:
        ValueError: no training character with a mesh, or no training clip.
    """
    folder = load_mixamo_folder(root if root is not None else mixamo_local_dir())
    lists = contact_lists()
    excluded = {lists["source_character"]}
    train = folder_split(folder).train_characters
    characters = {
        n: c for n in train if n not in excluded and (c := folder.character(n)) is not None
    }
    if not characters:
        raise ValueError(
            f"mixamo-local folder {folder.root}: no mesh (shape.npz or a skinned FBX/GLB) of a "
            "training "
            f"character {list(train)}"
        )
    test_motions = {m["name"] for m in lists["motions"]}
    clips = []
    for (name, motion), clip in sorted(folder.clips.items()):
        if name in characters and motion not in test_motions:
            m = clip.resample(TRAIN_FPS).with_skeleton(characters[name].skeleton)
            m.name = f"{name}/{motion}"
            clips.append((name, f"mixamo_{folder.fingerprint(name, motion)}_{m.num_frames}", m))
    if not clips:
        raise ValueError(
            f"mixamo-local folder {folder.root}: no clip of {sorted(characters)} outside the "
            "contact test motions"
        )
    return characters, clips
