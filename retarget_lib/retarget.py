"""Retarget a file to a target skeleton or character (the ``retarget retarget`` command).

A target BVH contributes its rest offsets (the character), its joint names, channel layout and
length unit: the result is written on the target's *full* joint set
(:func:`~retarget_lib.skeleton.from_canonical22`), so it loads next to the target's own clips.
"""

from __future__ import annotations

from pathlib import Path

from .io.bvh import load_bvh, load_canonical_bvh, save_bvh
from .motion import Motion
from .skeleton import Skeleton, from_canonical22, to_canonical22

METHODS = ("copy", "copy-rest", "tdcn", "nkn")
#: checkpoint used for a learned method when none is given (``checkpoints:`` in the manifest)
DEFAULT_CHECKPOINTS = {"tdcn": "tdcn-ours-fast", "nkn": "nkn-baseline-fast"}


def resolve_target(target: str) -> tuple[Skeleton, Motion | None]:
    """``(canonical-22 skeleton, full target motion or None)`` for a BVH path or a character name."""
    if target.lower().endswith(".bvh"):
        full = load_bvh(target)
        return to_canonical22(full.slice(0, 1)).skeleton, full
    from .data.characters import CHARACTER_NAMES, make_character

    if target not in CHARACTER_NAMES:
        raise ValueError(f"target {target!r} is neither a .bvh file nor a character; characters: "
                         f"{', '.join(CHARACTER_NAMES)}")
    return make_character(target).skeleton, None


def retarget_motion(source: Motion, target: Skeleton, method: str, checkpoint: str | Path | None = None) -> Motion:
    """Retarget a canonical-22 motion onto a canonical-22 target skeleton with ``method``.

    Args:
        source: canonical-22 source motion.
        target: canonical-22 target skeleton.
        method: one of :data:`METHODS`.
        checkpoint: for ``tdcn``/``nkn``: a checkpoint path (``retarget train`` output) or a
            manifest checkpoint id; default :data:`DEFAULT_CHECKPOINTS`.
    """
    from .data.pairs import copy_rotations, copy_rotations_rest_compensated

    if method == "copy":
        return copy_rotations(source, target)
    if method == "copy-rest":
        return copy_rotations_rest_compensated(source, target)
    if method in ("tdcn", "nkn"):
        from .tdcn_training import load_generator, retarget_motion_with

        generator, config = load_generator(resolve_checkpoint(method, checkpoint))
        if config["model"]["row"].startswith("Baseline") != (method == "nkn"):
            raise ValueError(f"checkpoint holds the {config['model']['row']!r} model, not a {method} one")
        return retarget_motion_with(generator, source, target)
    raise ValueError(f"unknown method {method!r}; choose from {METHODS}")


def resolve_checkpoint(method: str, checkpoint: str | Path | None) -> Path:
    """A checkpoint path from a path, a manifest id, or the method's default (manifest id)."""
    from .data.manifest import checkpoint as manifest_checkpoint

    if checkpoint is not None and Path(checkpoint).exists():
        return Path(checkpoint)
    cid = str(checkpoint) if checkpoint is not None else DEFAULT_CHECKPOINTS.get(method)
    if cid is None:
        raise ValueError(f"--method {method} needs --checkpoint (a `retarget train` output): no {method} "
                         "checkpoint is shipped yet")
    return manifest_checkpoint(cid).path


def retarget_file(source: str | Path, target: str, method: str, out: str | Path,
                  checkpoint: str | Path | None = None) -> Path:
    """Load ``source``, retarget it to ``target`` with ``method`` and write ``out`` (BVH).

    Returns:
        the output path.
    """
    target_skeleton, target_full = resolve_target(str(target))
    result = retarget_motion(load_canonical_bvh(source), target_skeleton, method, checkpoint)
    if target_full is not None:
        result = from_canonical22(result, target_full.skeleton)
        result.meta.update({k: target_full.meta[k] for k in ("unit_scale", "unit", "channels",
                                                              "file_joint_names") if k in target_full.meta})
    save_bvh(result, out)
    return Path(out)
