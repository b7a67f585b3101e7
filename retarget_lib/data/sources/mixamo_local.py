"""``mixamo-local``: a reviewer's own Mixamo download.

Layout (``$RETARGET_MIXAMO``, default ``data/mixamo``; see ``data_manifest.yaml``)::

    <root>/splits.yaml                     optional: which motions / characters are seen (below)
    <root>/<Character>/<Motion>.bvh        one motion clip per file; the file stem is the motion's
    <root>/<Character>/<Motion>.fbx          name, so one motion has one file (any of the four
    <root>/<Character>/<Motion>.glb          formats, not two); FBX/GLB clips "Without Skin" (an
    <root>/<Character>/<Motion>.gltf         armature and its animation) or "With Skin"
    <root>/<Character>/shape.npz           the character's mesh and skin, or else ...
    <root>/<Character>/<Character>.fbx     ... a character file: FBX/GLB/glTF named after the folder
                                           (or ``character``, ``T-Pose``/``tpose``), e.g. the T-pose
                                           "With Skin" download; not a motion
    <root>/<Character>/<Character>.dae     optional Collada export (listed, not read)

**Clips**: BVH as Blender exports Mixamo (``mixamorig:`` prefix, fingers, ``*_End`` sites, cm);
FBX through the optional ``fbx`` extra (:mod:`retarget_lib.io.fbx`, assimp); GLB/glTF with
:func:`~retarget_lib.io.gltf.load_gltf_animation`, with or without a skin. Every clip is folded onto
the canonical 22 joints. FBX clips are sampled at the file's own frame rate and scaled to metres
by its ``UnitScaleFactor`` (:mod:`retarget_lib.io.fbx`); GLB clips at the rate this library stores
in its GLB files, else at the keys' rate when they are baked on every frame
(:func:`~retarget_lib.io.gltf.key_rate`), else at 30 fps (Mixamo's download default). As a last
guard, an FBX/GLB clip or mesh whose canonical skeleton is still taller than 5 units (NKN height
``H``) is taken to be in centimetres and scaled to metres (the rule :mod:`retarget_lib.io.shape`
applies to ``shape.npz``: no character is 5 m tall), e.g. a GLB exported without its armature's
0.01 scale.

**The character's mesh** (:meth:`MixamoFolder.character`, used by the contact tables and contact
training), first found of: ``shape.npz``; the character file; the first clip (by motion name)
that is an FBX/GLB carrying a skin. A character with none of them has no mesh (the contact
coverage says so); its clips still count for Table 4.

**splits.yaml** (optional; :func:`read_splits_file`, validated before any clip is loaded; the
rules it replaces are in :mod:`retarget_lib.data.mixamo_splits`)::

    unseen_motions: [Praying, Jumping]     # or seen_motions: [...]; the folder's other motions
                                           # are then the other kind
    seen_characters: [Kaya, Warrok W Kurniawan]  # or unseen_characters: [...]; seen = training

Each key is optional; at most one of ``seen_motions``/``unseen_motions`` and of
``seen_characters``/``unseen_characters``; every name must be a motion (file stem) or character
(folder) of the folder. Problems raise :class:`~retarget_lib.errors.MixamoFolderError` naming the
file (the command line prints it on one line and exits with 2).

:mod:`retarget_lib.data.sources.mixamo_fixture` writes synthetic characters in this layout (BVH or
FBX or GLB clips, ``shape.npz`` or an FBX/GLB character file).
"""

from __future__ import annotations

import hashlib
import re
from dataclasses import dataclass, field
from pathlib import Path

import yaml

from ...core.canonical import fold_to_canonical22
from ...core.character import Character
from ...core.motion import Motion
from ...core.skeleton import canonical22_skeleton
from ...errors import MixamoFolderError
from ...files import DataError, sha256_file
from ...io.bvh import load_bvh
from ...io.gltf import NoSkinError, load_gltf_animation, load_gltf_rig
from ...io.joint_maps import to_canonical22
from ...io.shape import load_shape_npz

__all__ = [
    "SHAPE_FILE",
    "SPLITS_FILE",
    "CLIP_SUFFIXES",
    "CHARACTER_FILE_STEMS",
    "MixamoCharacterFolder",
    "DeclaredSplit",
    "scan_mixamo_folder",
    "read_splits_file",
    "load_mixamo_motion",
    "load_mixamo_rig",
    "MixamoFolder",
    "load_mixamo_folder",
]

SHAPE_FILE = "shape.npz"
SPLITS_FILE = "splits.yaml"
#: motion clip files (suffixes compared in lower case)
CLIP_SUFFIXES = (".bvh", ".fbx", ".glb", ".gltf")
#: FBX/GLB/glTF file stems (besides the folder's own name) that name the character file, compared
#: in lower case without spaces, dashes or underscores
CHARACTER_FILE_STEMS = ("character", "tpose")
_SKINNED_SUFFIXES = (".fbx", ".glb", ".gltf")
_SPLIT_KEYS = ("seen_motions", "unseen_motions", "seen_characters", "unseen_characters")


#: an FBX/GLB whose canonical skeleton's height exceeds this many file units is in centimetres
_CM_ABOVE_HEIGHT = 5.0


def _motion_in_metres(motion: Motion) -> Motion:
    """A canonical-22 motion read from FBX/GLB, scaled from centimetres when it is taller than
    :data:`_CM_ABOVE_HEIGHT` units."""
    if motion.skeleton.height() <= _CM_ABOVE_HEIGHT:
        return motion
    return motion.copy(
        skeleton=canonical22_skeleton(motion.skeleton.offsets * 0.01),
        root_positions=motion.root_positions * 0.01,
        meta={**motion.meta, "unit": "cm"},
    )


def _character_in_metres(character: Character) -> Character:
    """:func:`_motion_in_metres` for a character (skeleton and mesh)."""
    if character.skeleton.height() <= _CM_ABOVE_HEIGHT:
        return character
    return Character(
        character.name,
        canonical22_skeleton(character.skeleton.offsets * 0.01),
        character.rest_vertices * 0.01,
        character.faces,
        character.weights,
        character.bulk,
        {**character.style, "unit_scale": 0.01},
    )


def _key(stem: str) -> str:
    """A file stem compared for the character file: lower case, only letters and digits."""
    return re.sub(r"[^0-9a-z]", "", stem.lower())


@dataclass
class MixamoCharacterFolder:
    """One character folder found by :func:`scan_mixamo_folder`.

    Attributes:
        name: folder name (the character).
        shape: path of ``shape.npz`` or ``None`` if absent.
        motions: motion name (file stem) -> clip path (``.bvh``, ``.fbx``, ``.glb`` or ``.gltf``).
        collada: path of a ``.dae`` file or ``None``.
        character_file: the FBX/GLB/glTF character file (mesh and skin) or ``None``.
    """

    name: str
    shape: Path | None
    motions: dict[str, Path] = field(default_factory=dict)
    collada: Path | None = None
    character_file: Path | None = None


def scan_mixamo_folder(root: str | Path) -> list[MixamoCharacterFolder]:
    """List the characters, their motion clips and mesh files in a ``mixamo-local`` folder
    (module docstring); folders with neither a clip nor a mesh file are skipped.

    Raises:
        DataError: if ``root`` is missing or holds no character folder with a clip.
        MixamoFolderError: two files of one motion (``Walk.bvh`` and ``Walk.fbx``), or two
            character files, in one folder (naming them).
    """
    root = Path(root)
    if not root.is_dir():
        raise DataError(
            f"mixamo-local folder {root} does not exist; set RETARGET_MIXAMO "
            "(layout: <Character>/<Motion>.bvh|.fbx|.glb + <Character>/shape.npz or "
            "<Character>.fbx|.glb)"
        )
    found = []
    for folder in sorted(p for p in root.iterdir() if p.is_dir()):
        files = sorted(
            p
            for p in folder.iterdir()
            if p.is_file() and not p.name.startswith(".") and p.suffix.lower() in CLIP_SUFFIXES
        )
        names = {_key(folder.name), *CHARACTER_FILE_STEMS}
        character_files = [
            p for p in files if p.suffix.lower() in _SKINNED_SUFFIXES and _key(p.stem) in names
        ]
        if len(character_files) > 1:
            raise MixamoFolderError(
                f"{folder}: {len(character_files)} character files "
                f"({', '.join(p.name for p in character_files)}); keep one"
            )
        motions: dict[str, Path] = {}
        for p in files:
            if p in character_files:
                continue
            if p.stem in motions:
                raise MixamoFolderError(
                    f"{p}: motion {p.stem!r} is also in {motions[p.stem].name}; keep one file "
                    "per motion"
                )
            motions[p.stem] = p
        shape = folder / SHAPE_FILE
        if not motions and not character_files and not shape.exists():
            continue
        dae = sorted(folder.glob("*.dae"))
        found.append(
            MixamoCharacterFolder(
                folder.name,
                shape if shape.exists() else None,
                motions,
                dae[0] if dae else None,
                character_files[0] if character_files else None,
            )
        )
    if not any(c.motions for c in found):
        raise DataError(f"no <Character>/<Motion>.bvh|.fbx|.glb|.gltf found under {root}")
    return found


@dataclass(frozen=True)
class DeclaredSplit:
    """What a folder's ``splits.yaml`` declares (``None``: not declared, the default rule applies).

    Attributes:
        path: the file.
        unseen_motions: the unseen motions (from ``unseen_motions``, or every motion of the folder
            not in ``seen_motions``), or ``None``.
        seen_characters: the seen (training) characters in the file's order (from
            ``seen_characters``, or every character not in ``unseen_characters``, by name), or
            ``None``.
    """

    path: Path
    unseen_motions: frozenset[str] | None
    seen_characters: tuple[str, ...] | None


def read_splits_file(
    root: str | Path, characters: list[MixamoCharacterFolder]
) -> DeclaredSplit | None:
    """Read and validate ``<root>/splits.yaml`` against the scanned folder (module docstring).

    Args:
        root: the folder.
        characters: its :func:`scan_mixamo_folder` entries (the names the file may use).

    Returns:
        the :class:`DeclaredSplit`, or ``None`` when the folder has no ``splits.yaml``.

    Raises:
        MixamoFolderError: not YAML, not a mapping, an unknown key, both keys of a pair, a value
            that is not a list of distinct names, or a name that is not a motion / character of
            the folder (the message names the file, the key and the names).
    """
    path = Path(root) / SPLITS_FILE
    if not path.exists():
        return None
    try:
        data = yaml.safe_load(path.read_text(encoding="utf-8"))
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None)
        where = f" (line {mark.line + 1})" if mark is not None else ""
        raise MixamoFolderError(
            f"{path}: not valid YAML{where}: {getattr(e, 'problem', None) or e}"
        ) from None
    except (OSError, UnicodeDecodeError) as e:
        raise MixamoFolderError(f"{path}: cannot be read: {e}") from None
    data = {} if data is None else data
    if not isinstance(data, dict):
        raise MixamoFolderError(
            f"{path}: must be a mapping with keys among {', '.join(_SPLIT_KEYS)}; "
            f"got a {type(data).__name__}"
        )
    unknown = [str(k) for k in data if k not in _SPLIT_KEYS]
    if unknown:
        raise MixamoFolderError(
            f"{path}: unknown keys {unknown}; allowed: {', '.join(_SPLIT_KEYS)}"
        )
    motions = sorted({m for c in characters for m in c.motions})
    names = sorted(c.name for c in characters)
    lists = {}
    for key, value in data.items():
        if not isinstance(value, list) or not all(isinstance(v, str) and v for v in value):
            raise MixamoFolderError(f"{path}: {key} must be a list of names, got {value!r}")
        twice = sorted({v for v in value if value.count(v) > 1})
        if twice:
            raise MixamoFolderError(f"{path}: {key} lists {twice} more than once")
        known, what = (
            (motions, "motions (file stems)")
            if key.endswith("motions")
            else (names, "characters (folders)")
        )
        strangers = [v for v in value if v not in known]
        if strangers:
            raise MixamoFolderError(
                f"{path}: {key} names {strangers}, which are not {what} of {Path(root)}; "
                f"it has {known}"
            )
        lists[key] = value
    for kind in ("motions", "characters"):
        if f"seen_{kind}" in lists and f"unseen_{kind}" in lists:
            raise MixamoFolderError(
                f"{path}: give seen_{kind} or unseen_{kind}, not both (the other is the rest "
                f"of the folder's {kind})"
            )
    unseen = (
        frozenset(lists["unseen_motions"])
        if "unseen_motions" in lists
        else frozenset(motions) - set(lists["seen_motions"])
        if "seen_motions" in lists
        else None
    )
    seen = (
        tuple(lists["seen_characters"])
        if "seen_characters" in lists
        else tuple(n for n in names if n not in lists["unseen_characters"])
        if "unseen_characters" in lists
        else None
    )
    return DeclaredSplit(path, unseen, seen)


def load_mixamo_motion(path: str | Path, fps: float | None = 30.0) -> Motion:
    """Load a Mixamo clip (BVH with any prefix, fingers, end sites; FBX; GLB/glTF, with or without
    a skin) folded to the canonical 22 joints.

    Args:
        path: the clip file (its suffix chooses the reader).
        fps: resample to this rate (``None``: keep the file's own rate).

    Raises:
        MixamoFolderError: a suffix other than :data:`CLIP_SUFFIXES`; and what the readers raise
            (``BVHError``, ``GLTFError``, ``FBXError``, ``JointSetError``), naming the file.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".bvh":
        motion = to_canonical22(load_bvh(path), "mixamo", what=str(path))
    elif suffix in (".glb", ".gltf"):
        raw, joint_map = load_gltf_animation(path)
        motion = _motion_in_metres(fold_to_canonical22(raw, joint_map))
    elif suffix == ".fbx":
        from ...io.fbx import load_fbx_animation  # noqa: PLC0415 (the optional extra, checked when used)

        raw, joint_map = load_fbx_animation(path)
        motion = _motion_in_metres(fold_to_canonical22(raw, joint_map))
    else:
        raise MixamoFolderError(f"{path}: not a motion clip (a clip is {', '.join(CLIP_SUFFIXES)})")
    motion.name = path.stem
    return motion if fps is None else motion.resample(fps)


def load_mixamo_rig(path: str | Path) -> Character:
    """The canonical-22 character (mesh, weights folded onto the 22 joints) of a skinned FBX,
    GLB or glTF file, or of a ``shape.npz``, named after the file.

    Raises:
        NoSkinError: an FBX/GLB without a skinned mesh; and what the readers raise, naming the file.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".npz":
        return load_shape_npz(path)
    if suffix == ".fbx":
        from ...io.fbx import load_fbx_rig  # noqa: PLC0415 (the optional extra, checked when used)

        return _character_in_metres(load_fbx_rig(path).character())
    if suffix in (".glb", ".gltf"):
        return _character_in_metres(load_gltf_rig(path).character())
    raise MixamoFolderError(f"{path}: not a character mesh file (shape.npz, .fbx, .glb, .gltf)")


@dataclass
class MixamoFolder:
    """Every clip of a ``mixamo-local`` folder, loaded at the files' own frame rates.

    Attributes:
        root: the folder.
        characters: the :class:`MixamoCharacterFolder` entries (sorted by name).
        clips: ``(character, motion) -> Motion`` on the canonical 22 joints, metres, native fps.
        splits: the folder's ``splits.yaml`` (:class:`DeclaredSplit`), or ``None``.
    """

    root: Path
    characters: list[MixamoCharacterFolder]
    clips: dict[tuple[str, str], Motion]
    splits: DeclaredSplit | None = None
    _meshes: dict[str, tuple[Path | None, Character | None]] = field(
        default_factory=dict, repr=False, compare=False
    )

    def performers(self) -> dict[str, set[str]]:
        """``motion -> {characters that perform it}``, motions sorted by name."""
        out: dict[str, set[str]] = {}
        for character, motion in sorted(self.clips, key=lambda k: k[1]):
            out.setdefault(motion, set()).add(character)
        return out

    def clip_path(self, character: str, motion: str) -> Path:
        """The file of a character's clip of a motion (``.bvh``, ``.fbx``, ``.glb`` or ``.gltf``).

        Raises:
            KeyError: the folder has no such clip.
        """
        entry = next((c for c in self.characters if c.name == character), None)
        if entry is None or motion not in entry.motions:
            raise KeyError(f"{self.root}: no clip of {motion!r} by {character!r}")
        return entry.motions[motion]

    def _mesh(self, name: str) -> tuple[Path | None, Character | None]:
        """``(file, character)`` of a character's mesh (module docstring's order), loaded once."""
        if name not in self._meshes:
            entry = next((c for c in self.characters if c.name == name), None)
            found: tuple[Path | None, Character | None] = (None, None)
            if entry is not None:
                explicit = entry.shape or entry.character_file
                if explicit is not None:
                    found = (explicit, load_mixamo_rig(explicit))
                else:
                    for motion in sorted(entry.motions):
                        path = entry.motions[motion]
                        if path.suffix.lower() not in _SKINNED_SUFFIXES:
                            continue
                        try:
                            found = (path, load_mixamo_rig(path))
                            break
                        except NoSkinError:  # a clip downloaded "Without Skin"
                            continue
            if found[1] is not None:
                found[1].name = name
            self._meshes[name] = found
        return self._meshes[name]

    def mesh_file(self, name: str) -> Path | None:
        """The file a character's mesh comes from (``shape.npz``, the character file or a skinned
        clip), or ``None``."""
        return self._mesh(name)[0]

    def fingerprint(self, character: str, motion: str) -> str:
        """16 hex digits of the sha256 of a clip's file and its character's mesh file (cache
        keys)."""
        mesh = self.mesh_file(character)
        parts = [sha256_file(self.clip_path(character, motion))] + (
            [sha256_file(mesh)] if mesh is not None else []
        )
        return hashlib.sha256("".join(parts).encode()).hexdigest()[:16]

    def character(self, name: str) -> Character | None:
        """The character's mesh as a :class:`Character` named ``name`` (``None`` without one).

        Raises:
            ShapeError, GLTFError, FBXError, JointSetError: a malformed ``shape.npz`` or character
                file, naming it.
        """
        character = self._mesh(name)[1]
        return None if character is None else character.copy()


def load_mixamo_folder(root: str | Path) -> MixamoFolder:
    """Scan (:func:`scan_mixamo_folder`), validate ``splits.yaml`` (:func:`read_splits_file`),
    then load every clip of a ``mixamo-local`` folder.

    Raises:
        DataError: no such folder or no clip in it.
        MixamoFolderError: an ambiguous layout or an invalid ``splits.yaml``.
        BVHError, GLTFError, FBXError: a malformed clip (names the file).
        JointSetError: a clip whose joints do not fold onto the canonical 22 (names the file's
            joints).
    """
    characters = scan_mixamo_folder(root)
    splits = read_splits_file(root, characters)
    clips = {
        (c.name, motion): load_mixamo_motion(path, fps=None)
        for c in characters
        for motion, path in c.motions.items()
    }
    return MixamoFolder(Path(root), characters, clips, splits)
