"""Retarget a file to a target skeleton or character (the ``retarget retarget`` command).

A target BVH contributes its rest offsets (the character), its joint names, channel layout and
length unit: the result is written on the target's *full* joint set
(:func:`~retarget_lib.core.skeleton.from_canonical22`), so it loads next to the target's own clips.
"""

from __future__ import annotations

from pathlib import Path

from .core.canonical import from_canonical22, to_canonical22
from .core.motion import Motion
from .core.skeleton import Skeleton
from .io.bvh import load_bvh, load_canonical_bvh, save_bvh

METHODS = ("copy", "copy-rest", "tdcn", "nkn", "contact")
#: checkpoint used for a learned method when none is given (``checkpoints:`` in the manifest)
DEFAULT_CHECKPOINTS = {"tdcn": "tdcn-ours-fast", "nkn": "nkn-baseline-fast", "contact": "contact-efull-fast"}
#: above this many vertices, ESO works on a decimated copy of the target mesh (its Eint needs an
#: all-pairs geodesic table: 36 MB at 3k vertices, 2.3 GB at 24k); the output is skeletal, so the
#: full mesh follows it exactly
ESO_MAX_VERTICES = 5000


def resolve_target(target: str) -> tuple[Skeleton, Motion | None]:
    """``(canonical-22 skeleton, full target motion or None)`` for a BVH path or a character name."""
    if target.lower().endswith(".bvh"):
        full = load_bvh(target)
        return to_canonical22(full.slice(0, 1)).skeleton, full
    from .data.synthetic.characters import CHARACTER_NAMES, make_character

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
    from .core.transfer import copy_rotations, copy_rotations_rest_compensated

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
    if method == "contact":
        raise ValueError("--method contact needs the target's mesh: use retarget_contact (or on the command "
                         "line --target-mesh SHAPE.npz or a character name as --target)")
    raise ValueError(f"unknown method {method!r}; choose from {METHODS}")


def resolve_character(target: str, target_mesh: str | Path | None):
    """The target :class:`~retarget_lib.core.character.Character` of ``--method contact``: the
    shape file ``target_mesh`` if given, else the character named ``target`` (a synthetic
    character or ``mannequin-x``)."""
    from .data.synthetic.characters import CHARACTER_NAMES, make_character

    if target_mesh is not None:
        from .io.shape import load_shape_npz

        return load_shape_npz(target_mesh)
    if target == "mannequin-x":
        from .data.sources.mannequin import load_mannequin

        return load_mannequin()
    if target in CHARACTER_NAMES:
        return make_character(target)
    raise ValueError(f"--method contact needs the target's mesh: give --target-mesh SHAPE.npz or a character "
                     f"name as --target ({', '.join(CHARACTER_NAMES)}, mannequin-x); got {target!r}")


def retarget_contact(source: Motion, target, checkpoint: str | Path | None = None, source_character=None,
                     eso: bool = True) -> Motion:
    """Contact-aware retargeting (Villegas et al. 2021): the geometry-conditioned RNN, then
    encoder-space optimisation with the source's detected contacts.

    Args:
        source: canonical-22 source motion.
        target: target ``Character`` (skeleton, mesh and skinning weights).
        checkpoint: contact-model checkpoint path or manifest id (default the shipped ``Efull``).
        source_character: the source's skinned body (e.g. a shape file of the same character);
            without it no hand self-contacts can be detected, and only foot contacts,
            interpenetration and the skeleton terms guide ESO.
        eso: run ESO (App. B.1 settings from the checkpoint's config); ``False`` = network only.

    Returns:
        The motion on ``target.skeleton``.
    """
    from .contact_training import contact_clip, load_contact_model, retarget_with_network
    from .core.skinning import subsample_mesh
    from .eso import encoder_space_optimization, eso_source
    from .geometry.contacts import transfer_contacts
    from .geometry.penetration import InterpenetrationEnergy

    model, config = load_contact_model(resolve_checkpoint("contact", checkpoint))
    if not eso:
        return retarget_with_network(model, source, target)
    if target.num_vertices > ESO_MAX_VERTICES:
        v, f, w = subsample_mesh(target.rest_vertices, target.faces, target.weights, 3000)
        target = target.copy()
        target.rest_vertices, target.faces, target.weights = v, f, w
    contacts = None
    if source_character is not None:
        clip = contact_clip(source, source_character)
        contacts = transfer_contacts(clip.self_contacts, source_character, target)
    src = eso_source(source, target)
    e = config["eso"]
    res = encoder_space_optimization(model, src.features, target, src.quantities, src.foot_contacts, src.leg_ratio,
                                     contacts=contacts,
                                     interpenetration=InterpenetrationEnergy(target.faces, target.rest_vertices),
                                     iterations=int(e["iterations"]), lr=float(e["lr"]), reach=float(e["reach"]),
                                     blend=float(e["blend"]))
    return Motion(target.skeleton, res.rotations.double().numpy(), res.root_positions.double().numpy(), source.fps,
                  name=source.name)


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
                  checkpoint: str | Path | None = None, target_mesh: str | Path | None = None,
                  source_mesh: str | Path | None = None) -> Path:
    """Load ``source``, retarget it to ``target`` with ``method`` and write ``out`` (BVH).

    Returns:
        the output path.
    """
    if method == "contact":
        from .io.shape import load_shape_npz

        character = resolve_character(str(target), target_mesh)
        target_full = load_bvh(target) if str(target).lower().endswith(".bvh") else None
        result = retarget_contact(load_canonical_bvh(source), character, checkpoint,
                                  load_shape_npz(source_mesh) if source_mesh is not None else None)
    else:
        target_skeleton, target_full = resolve_target(str(target))
        result = retarget_motion(load_canonical_bvh(source), target_skeleton, method, checkpoint)
    if target_full is not None:
        result = from_canonical22(result, target_full.skeleton)
        result.meta.update({k: target_full.meta[k] for k in ("unit_scale", "unit", "channels",
                                                              "file_joint_names") if k in target_full.meta})
    save_bvh(result, out)
    return Path(out)
