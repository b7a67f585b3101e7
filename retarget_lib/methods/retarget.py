"""Retarget a file to a target skeleton or character with a method of the registry (the
``retarget retarget`` command).

A target BVH contributes its rest offsets (the character), its joint names, channel layout and
length unit: the result is written on the target's *full* joint set
(:func:`~retarget_lib.core.canonical.from_canonical22`), so it loads next to the target's own clips.
A target given by name is written in the source file's length unit. The methods run at
:data:`METHOD_FPS`; the result is resampled back to the source's frame rate (or ``fps``).

Everything the user gives is checked before any work: the output path (:func:`~retarget_lib.files.check_output`:
a ``.bvh``, never an input unless ``force``), options the method would ignore (a mesh for a
skeleton-only method), a target mesh whose skeleton disagrees with the target BVH. A result that
is non-finite or implausibly far away (a corrupt checkpoint) is refused, not written.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from ..core.canonical import from_canonical22, to_canonical22
from ..core.character import Character
from ..core.motion import Motion
from ..core.skeleton import Skeleton
from ..data.sources.mannequin import load_mannequin
from ..data.synthetic.characters import CHARACTER_NAMES, make_character
from ..errors import CheckpointError, RetargetInputError
from ..files import check_output
from ..io.bvh import load_bvh, save_bvh
from ..io.shape import load_shape_npz
from .registry import Method, get_method

__all__ = ["METHOD_FPS", "OUTPUT_SUFFIXES", "MESH_TOLERANCE", "resolve_target", "resolve_character", "retarget_file"]

#: the frame rate every method works at (the models were trained on 30 fps windows)
METHOD_FPS = 30.0
#: what ``out`` can be (glTF/FBX writers do not exist yet)
OUTPUT_SUFFIXES = (".bvh",)
#: a target mesh's rest offsets may differ from the target BVH's by this fraction of the target's
#: height (float32 exports and unit round trips move them by < 0.1 %)
MESH_TOLERANCE = 0.01
#: a result whose root goes further from the origin than this many times the source's range
#: (scaled to the target's size) plus the target's height is refused: no retargeting moves a root
#: that far; a corrupt checkpoint does
ROOT_RANGE_FACTOR = 10.0


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


def _check_options(chosen: Method, target: str, target_mesh, source_mesh, checkpoint) -> None:
    """Refuse options that ``chosen`` would silently ignore."""
    if not chosen.needs_mesh:
        for flag, value in (("--target-mesh", target_mesh), ("--source-mesh", source_mesh)):
            if value is not None:
                raise RetargetInputError(f"{value}: {flag} is only used by methods that need meshes (contact); "
                                         f"--method {chosen.name} would ignore it")
    if not chosen.needs_checkpoint and checkpoint is not None:
        raise RetargetInputError(f"{checkpoint}: --method {chosen.name} has no checkpoint; --checkpoint would be "
                                 "ignored")


def _check_mesh_matches(character: Character, target_skeleton: Skeleton, target_mesh, target) -> None:
    """Refuse a target mesh whose rest skeleton is not the target BVH's (:data:`MESH_TOLERANCE`)."""
    height = target_skeleton.height()
    diff = np.abs(character.skeleton.offsets[1:] - target_skeleton.offsets[1:]).max()
    if diff > MESH_TOLERANCE * height:
        raise RetargetInputError(f"{target_mesh}: its skeleton differs from the target {target} by {diff * 100:.1f} cm "
                                 f"(more than {MESH_TOLERANCE:.0%} of the target's height): a mesh of another "
                                 "character?")


def _check_plausible(result: Motion, source: Motion, target_skeleton: Skeleton, method: str, checkpoint) -> None:
    """Refuse a non-finite result or one whose root leaves :data:`ROOT_RANGE_FACTOR` times the
    source's range."""
    scale = max(1.0, target_skeleton.height() / source.skeleton.height())
    limit = ROOT_RANGE_FACTOR * (np.abs(source.root_positions).max() * scale + target_skeleton.height())
    finite = np.isfinite(result.rotations).all() and np.isfinite(result.root_positions).all()
    reach = float(np.abs(result.root_positions).max()) if finite else float("inf")
    if reach > limit:
        what = "non-finite values" if not finite else f"a root {reach:.3g} m from the origin (limit {limit:.3g} m)"
        if checkpoint is not None or get_method(method).needs_checkpoint:
            raise CheckpointError(f"{checkpoint or method}: --method {method} produced {what}; the checkpoint is "
                                  "corrupt or not trained for this input")
        raise RetargetInputError(f"--method {method} produced {what} for {source.name}")


def _load_retargeter(chosen: Method, checkpoint, device):
    """``chosen.retargeter(checkpoint, device)``, with a checkpoint that does not fit its model (missing
    keys, wrong shapes or config) reported as :class:`~retarget_lib.errors.CheckpointError`."""
    try:
        return chosen.retargeter(checkpoint, device)
    except (KeyError, TypeError, AttributeError, RuntimeError) as e:
        problem = str(e).strip().splitlines()[0][:200] if str(e).strip() else type(e).__name__
        raise CheckpointError(f"{checkpoint or chosen.default_checkpoint()}: not a valid {chosen.name} checkpoint: "
                              f"{type(e).__name__}: {problem}") from None


def retarget_file(source: str | os.PathLike, target: str, method: str, out: str | os.PathLike,
                  checkpoint: str | os.PathLike | None = None, target_mesh: str | os.PathLike | None = None,
                  source_mesh: str | os.PathLike | None = None, fps: float | None = None,
                  force: bool = False, device: str | None = None) -> Path:
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
        fps: output frame rate (default: the source's).
        force: allow ``out`` to be one of the inputs.
        device: where a learned method's network (and ESO) runs: ``auto``, ``cpu``, ``cuda``,
            ``mps`` (default the CPU).

    Returns:
        the output path.

    Raises:
        RetargetInputError: any bad input (its subclasses name the file and the problem):
            :class:`~retarget_lib.errors.OutputPathError`, :class:`~retarget_lib.io.bvh.BVHError`,
            :class:`~retarget_lib.io.shape.ShapeError`, :class:`~retarget_lib.errors.CheckpointError`,
            :class:`~retarget_lib.errors.LimitError`, :class:`~retarget_lib.errors.InputFileError`,
            :class:`~retarget_lib.errors.DeviceError`.
    """
    chosen = get_method(method)
    _check_options(chosen, str(target), target_mesh, source_mesh, checkpoint)
    check_output(out, [source, target, target_mesh, source_mesh, checkpoint], OUTPUT_SUFFIXES, force)
    raw = load_bvh(source)
    motion = to_canonical22(raw).resample(METHOD_FPS)
    out_fps = float(fps) if fps is not None else raw.fps
    if not (np.isfinite(out_fps) and 1.0 <= out_fps <= 1000.0):
        raise RetargetInputError(f"--fps {fps}: the output frame rate must be within 1-1000")
    if chosen.needs_mesh:
        character = resolve_character(str(target), target_mesh)
        target_full = None
        if str(target).lower().endswith(".bvh"):
            target_skeleton, target_full = resolve_target(str(target))
            _check_mesh_matches(character, target_skeleton, target_mesh, target)
        source_character = load_shape_npz(source_mesh) if source_mesh is not None else None
        result = _load_retargeter(chosen, checkpoint, device)(motion, character, source_character=source_character)
        target_skeleton = character.skeleton
    else:
        target_skeleton, target_full = resolve_target(str(target))
        result = _load_retargeter(chosen, checkpoint, device)(motion, target_skeleton)
    _check_plausible(result, motion, target_skeleton, method, checkpoint)
    result = result.resample(out_fps)
    if target_full is not None:  # the target's joints, names, channels and unit
        result = from_canonical22(result, target_full.skeleton)
        keys, layout = ("unit_scale", "unit", "channels", "file_joint_names"), target_full.meta
    else:  # a named character: the source file's unit, whatever the method
        keys, layout = ("unit_scale", "unit"), raw.meta
    result.meta.update({k: layout[k] for k in keys if k in layout})
    save_bvh(result, out)
    return Path(out)
