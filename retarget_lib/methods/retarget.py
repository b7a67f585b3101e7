"""Retarget a file to a target skeleton or character with a method of the registry (the
``retarget retarget`` command).

A target BVH contributes its rest offsets (the character), its joint names, channel layout and
length unit: the result is written on the target's *full* joint set
(:func:`~retarget_lib.core.canonical.from_canonical22`), so it loads next to the target's own clips.
"""

from __future__ import annotations

import os
from pathlib import Path

from ..core.canonical import from_canonical22, to_canonical22
from ..core.character import Character
from ..core.motion import Motion
from ..core.skeleton import Skeleton
from ..data.sources.mannequin import load_mannequin
from ..data.synthetic.characters import CHARACTER_NAMES, make_character
from ..io.bvh import load_bvh, load_canonical_bvh, save_bvh
from ..io.shape import load_shape_npz
from .registry import get_method

__all__ = ["resolve_target", "resolve_character", "retarget_file"]


def resolve_target(target: str) -> tuple[Skeleton, Motion | None]:
    """``(canonical-22 skeleton, full target motion or None)`` for a BVH path or a character name."""
    if target.lower().endswith(".bvh"):
        full = load_bvh(target)
        return to_canonical22(full.slice(0, 1)).skeleton, full
    if target not in CHARACTER_NAMES:
        raise ValueError(f"target {target!r} is neither a .bvh file nor a character; characters: "
                         f"{', '.join(CHARACTER_NAMES)}")
    return make_character(target).skeleton, None


def resolve_character(target: str, target_mesh: str | os.PathLike | None) -> Character:
    """The target :class:`~retarget_lib.core.character.Character` of a method that needs the
    target's mesh: the shape file ``target_mesh`` if given, else the character named ``target``
    (a synthetic character or ``mannequin-x``)."""
    if target_mesh is not None:
        return load_shape_npz(target_mesh)
    if target == "mannequin-x":
        return load_mannequin()
    if target in CHARACTER_NAMES:
        return make_character(target)
    raise ValueError(f"--method contact needs the target's mesh: give --target-mesh SHAPE.npz or a character "
                     f"name as --target ({', '.join(CHARACTER_NAMES)}, mannequin-x); got {target!r}")


def retarget_file(source: str | os.PathLike, target: str, method: str, out: str | os.PathLike,
                  checkpoint: str | os.PathLike | None = None, target_mesh: str | os.PathLike | None = None,
                  source_mesh: str | os.PathLike | None = None) -> Path:
    """Load ``source``, retarget it to ``target`` with the registry's ``method`` and write ``out``
    (BVH).

    Args:
        source: source BVH (any joint set :func:`~retarget_lib.core.canonical.to_canonical22` folds).
        target: a target BVH (its skeleton, names and units) or a character name.
        method: a name of :data:`~retarget_lib.methods.registry.REGISTRY`.
        out: output BVH.
        checkpoint: manifest id or path for a learned method (default: the method's default in the
            manifest).
        target_mesh: target shape ``.npz``, for a method that needs the target's mesh.
        source_mesh: source shape ``.npz``: its hand self-contacts are preserved by ``contact``.

    Returns:
        the output path.
    """
    chosen = get_method(method)
    if chosen.needs_mesh:
        character = resolve_character(str(target), target_mesh)
        target_full = load_bvh(target) if str(target).lower().endswith(".bvh") else None
        retarget = chosen.retargeter(checkpoint)
        result = retarget(load_canonical_bvh(source), character,
                          source_character=load_shape_npz(source_mesh) if source_mesh is not None else None)
    else:
        target_skeleton, target_full = resolve_target(str(target))
        result = chosen.retargeter(checkpoint)(load_canonical_bvh(source), target_skeleton)
    if target_full is not None:
        result = from_canonical22(result, target_full.skeleton)
        result.meta.update({k: target_full.meta[k] for k in ("unit_scale", "unit", "channels",
                                                              "file_joint_names") if k in target_full.meta})
    save_bvh(result, out)
    return Path(out)
