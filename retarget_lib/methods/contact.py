"""Method ``contact`` — contact-aware retargeting of skinned motion (Villegas et al. 2021): the
geometry-conditioned RNN (:class:`~retarget_lib.models.georet.GeometryConditionedRNN`, Eqs. 12-19)
and, at test time, encoder-space optimisation (:mod:`.eso`, Sec. 3.3) with the source's detected
foot and hand contacts (Sec. 3.4) carried to the target's mesh (App. F).

:func:`contact_clip` prepares a source clip (network input, the quantities Eskel reads, detected
contacts); training (:mod:`retarget_lib.training.contact`) and evaluation read the same clips.
Source contacts are detected once per clip and cached (``.cache/contact_training``).
"""

from __future__ import annotations

import os
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from functools import partial
from typing import Any

import numpy as np
import torch

from ..core.character import Character
from ..core.measures import estimated_standing_height, mesh_standing_height
from ..core.motion import Motion
from ..core.quantities import MotionQuantities, forward_root_velocity, leg_ratio, motion_quantities
from ..core.transfer import transfer_rotations
from ..data.checkpoints import load_state
from ..devices import module_device, resolve_device
from ..files import atomic_write, cache_dir, quantised_sha256
from ..geometry.contacts import (
    SelfContacts,
    detect_foot_contacts,
    detect_self_contacts,
    transfer_contacts,
)
from ..geometry.penetration import InterpenetrationEnergy
from ..losses.contact import ContactEnergyWeights
from ..models.georet import GeometryConditionedRNN, ResidualBase, motion_features, pose_outputs
from .eso import encoder_space_optimization, eso_source, use_compiled

Tensor = torch.Tensor

__all__ = [
    "ContactClip",
    "contact_clip",
    "model_from_config",
    "load_contact_model",
    "eweak_rotations",
    "retarget_with_network",
    "ESO_MAX_VERTICES",
    "retarget_contact_with",
    "retarget_with_eso",
    "load",
]

#: above this many vertices, ESO works on a decimated copy of the target mesh (App. B's 3,000): the
#: output is skeletal, so the full mesh follows it exactly. Full meshes work too (Eint's geodesics
#: are searched on demand, each step skins only the vertices its energy reads): compiled, 0.07 s a
#: frame at 10,000 vertices, 0.08 s at 13,380 (`retarget bench --only eso`)
ESO_MAX_VERTICES = 5000


@dataclass
class ContactClip:
    """A source clip with everything training and evaluation read from it.

    Attributes:
        name: clip name.
        character: the performer (its mesh carries the self-contacts).
        motion: the clip on the performer (canonical 22, metres, 30 fps).
        features: ``(T, 267)`` network input (:func:`~retarget_lib.models.georet.motion_features`).
        quantities: source :class:`~retarget_lib.core.quantities.MotionQuantities`, ``(T, ...)``.
        foot_contacts: ``(T, 4)`` bool detected foot contacts (Sec. 3.4).
        self_contacts: detected hand contacts on the performer's mesh (Sec. 3.4).
    """

    name: str
    character: Character
    motion: Motion
    features: Tensor
    quantities: MotionQuantities
    foot_contacts: np.ndarray
    self_contacts: SelfContacts


def _motion_digest(motion: Motion) -> str:
    """12 hex digits of :func:`~retarget_lib.files.quantised_sha256` over the clip's rotations and
    root path at 1e-5 (float noise across CPUs does not change it)."""
    return quantised_sha256(
        (("rotations", motion.rotations), ("root_positions", motion.root_positions)), 1e5
    )[:12]


def _detected_contacts(
    motion: Motion, character: Character, cache_key: str | None
) -> tuple[np.ndarray, SelfContacts]:
    """Foot and hand contacts of a clip on its performer, cached under ``cache_key`` plus a digest
    of the motion's values (a clip that changes, e.g. after a dataset rebuild, never reads a stale
    entry).

    Sec. 3.4's thresholds are scaled with two heights: the feet with the skeleton's
    :func:`~retarget_lib.core.measures.estimated_standing_height`, the hands with the performer's
    :func:`~retarget_lib.core.measures.mesh_standing_height`."""
    path = (
        cache_dir("contact_training") / f"{cache_key}_{_motion_digest(motion)}.npz"
        if cache_key
        else None
    )
    if path is not None and path.exists():
        z = np.load(path)
        return z["foot"], SelfContacts(int(z["num_frames"]), z["frames"], z["pairs"], z["groups"])
    positions = motion.global_positions()
    foot = detect_foot_contacts(
        positions, motion.skeleton, estimated_standing_height(motion.skeleton)
    )
    vertices = character.skinned(motion.rotations, motion.root_positions)
    hands = detect_self_contacts(
        vertices, character.faces, character.weights, mesh_standing_height(character.rest_vertices)
    )
    if path is not None:
        with atomic_write(path) as f:
            np.savez(
                f,
                foot=foot,
                num_frames=hands.num_frames,
                frames=hands.frames,
                pairs=hands.pairs,
                groups=hands.groups,
            )
    return foot, hands


def contact_clip(motion: Motion, character: Character, cache_key: str | None = None) -> ContactClip:
    """Prepare one source clip performed by ``character`` (its skeleton must be the motion's)."""
    rot, root, off = motion.torch(torch.float32)
    height = motion.skeleton.height()
    quantities = motion_quantities(rot, root, off, height, motion.skeleton.parents)
    features = motion_features(rot[None], root[None], off, motion.skeleton.parents, height)[0]
    foot, hands = _detected_contacts(motion, character, cache_key)
    return ContactClip(motion.name, character, motion, features, quantities, foot, hands)


def model_from_config(config: dict) -> GeometryConditionedRNN:
    """The network of ``config["model"]`` (App. B.1: hidden 512, PointNet 256, dropout 0.1)."""
    m = config["model"]
    return GeometryConditionedRNN(
        hidden=int(m["hidden"]),
        layers=int(m["layers"]),
        geometry=int(m["geometry"]),
        dropout=float(m["dropout"]),
        residual=bool(m.get("residual", False)),
        lower_body_from_base=bool(m.get("lower_body_from_base", False)),
        root_residual=bool(m.get("root_residual", False)),
    )


def load_contact_model(
    checkpoint: str | os.PathLike,
    device: str | torch.device | None = None,
) -> tuple[GeometryConditionedRNN, dict]:
    """``(model in eval mode, config)`` from a training or exported checkpoint: a manifest id (the
    shipped file, sha256 verified) or a path
    (:func:`~retarget_lib.data.checkpoints.resolve_checkpoint`), on ``device`` (a ``--device`` name
    or ``torch.device``; default the CPU)."""
    state = load_state(checkpoint)
    model = model_from_config(state["config"])
    model.load_state_dict(state["modules"]["model"])
    return model.eval().to(resolve_device(device or "cpu")), state["config"]


def eweak_rotations(
    model: GeometryConditionedRNN, rotations: np.ndarray, source: Any, target: Any
) -> Tensor:
    """The ``θ^A`` that Eweak (Eq. 8) compares the output with, and a residual network's base.

    The paper's network: the source's local rotations as they are. A residual network (our variant,
    ``model.residual``): the same rotations re-expressed on the target's rest pose
    (:func:`~retarget_lib.core.transfer.transfer_rotations`, the rest-compensated copy: the
    rotation deltas from the retarget pose), so that an untrained residual network is copy-rest.
    Mixamo's characters share one T-pose, so there the two coincide (the alignment is the
    identity); ours do not (A-pose, T-pose, bent knees), and comparing raw local angles would ask
    the network to keep each rest convention's difference as a pose error.

    Args:
        model: the network (only ``model.residual`` is read).
        rotations: ``(..., 22, 4)`` source local rotations (wxyz).
        source, target: the two skeletons.

    Returns:
        ``(..., 22, 4)`` float32.
    """
    if model.residual:
        rotations = transfer_rotations(rotations, source, target)
    return torch.as_tensor(np.asarray(rotations), dtype=torch.float32)


@torch.no_grad()
def retarget_with_network(model: GeometryConditionedRNN, source: Motion, target: Any) -> Motion:
    """Retarget ``source`` onto ``target`` (a ``Character``) with the network alone (no ESO):
    Eqs. 12-19 over the whole clip, root starting at the source's first root times the leg ratio.

    Returns:
        The motion on ``target.skeleton`` (computed on the model's device).
    """
    device = module_device(model)
    rot, root, off = (x.to(device) for x in source.torch(torch.float32))
    feats = motion_features(
        rot[None], root[None], off, source.skeleton.parents, source.skeleton.height()
    )
    as_f32 = lambda a: torch.as_tensor(a, dtype=torch.float32, device=device)  # noqa: E731
    t_off = as_f32(target.skeleton.offsets)
    ratio = leg_ratio(source.skeleton, target.skeleton)
    aligned = eweak_rotations(model, source.rotations, source.skeleton, target.skeleton).to(device)
    base = ResidualBase(aligned[None], forward_root_velocity(root[None]) * ratio)
    out = model(
        feats,
        t_off[None],
        as_f32(target.rest_vertices)[None],
        as_f32(target.weights)[None],
        target.height,
        base,
    )
    start = ratio * root[0]
    posed = pose_outputs(out.rotations, out.root_velocity, t_off, start=start[None])
    return Motion(
        target.skeleton,
        out.rotations[0].double().cpu().numpy(),
        posed.root_positions[0].double().cpu().numpy(),
        source.fps,
        name=f"{source.name}->{getattr(target, 'name', 'target')}",
    )


def retarget_contact_with(
    model: GeometryConditionedRNN,
    config: dict,
    source: Motion,
    target: Character,
    source_character: Character | None = None,
    eso: bool = True,
    compile: bool | None = None,
) -> Motion:
    """Contact-aware retargeting (Villegas et al. 2021): the geometry-conditioned RNN, then
    encoder-space optimisation with the source's detected contacts.

    Args:
        model, config: from :func:`load_contact_model`.
        source: canonical-22 source motion.
        target: target ``Character`` (skeleton, mesh and skinning weights).
        source_character: the source's skinned body (e.g. a shape file of the same character);
            without it no hand self-contacts can be detected, and only foot contacts,
            interpenetration and the skeleton terms guide ESO.
        eso: run ESO (App. B.1 settings from the checkpoint's config); ``False`` = network only.
        compile: run ESO's steps compiled (:func:`~retarget_lib.methods.eso.use_compiled`;
            ``None``: for long clips).

    Face pairs that already intersect in the target's rest pose (clothing layers) are left out of
    Eint (``InterpenetrationEnergy(ignore_rest_intersections=True)``).

    Returns:
        The motion on ``target.skeleton``.
    """
    if not eso:
        return retarget_with_network(model, source, target)
    if target.num_vertices > ESO_MAX_VERTICES:
        target = target.decimated(3000)
    contacts = None
    if source_character is not None:
        clip = contact_clip(source, source_character)
        contacts = transfer_contacts(clip.self_contacts, source_character, target)
    eint = InterpenetrationEnergy(
        target.faces, target.rest_vertices, ignore_rest_intersections=True
    )
    return retarget_with_eso(model, config["eso"], source, target, contacts, eint, compile=compile)


def retarget_with_eso(
    model: GeometryConditionedRNN,
    eso_config: Mapping,
    source: Motion,
    target: Character,
    contacts: SelfContacts | None,
    interpenetration: InterpenetrationEnergy,
    foot_contacts: np.ndarray | None = None,
    name: str | None = None,
    compile: bool | None = None,
) -> Motion:
    """The network's output refined by encoder-space optimisation (Sec. 3.3) with the App. B.1
    settings of a checkpoint's config.

    Args:
        model: the geometry-conditioned RNN (eval mode).
        eso_config: the config's ``eso`` section (``iterations``, ``lr``, ``reach``, ``blend``;
            ``rho`` and ``beta_int`` where the config sets them, else App. B.1's 10 and 1:
            :meth:`~retarget_lib.losses.contact.ContactEnergyWeights.from_eso_config`).
        source: canonical-22 source motion.
        target: target ``Character``.
        contacts: the source's hand contacts on the target's mesh, or ``None``.
        interpenetration: the target's Eint.
        foot_contacts: ``(T, 4)`` the source's foot contacts (default: detected on the source).
        name: the result's name (default the source's).
        compile: run ESO's steps compiled (:func:`~retarget_lib.methods.eso.use_compiled`;
            ``None``: for long clips, or when this process compiled them already).

    Returns:
        The motion on ``target.skeleton``.
    """
    src = eso_source(source, target, foot_contacts, rest_aligned=model.residual)
    res = encoder_space_optimization(
        model,
        src.features,
        target,
        src.quantities,
        src.foot_contacts,
        src.leg_ratio,
        contacts=contacts,
        interpenetration=interpenetration,
        weights=ContactEnergyWeights.from_eso_config(eso_config),
        iterations=int(eso_config["iterations"]),
        lr=float(eso_config["lr"]),
        reach=float(eso_config["reach"]),
        blend=float(eso_config["blend"]),
        compile=use_compiled(source.num_frames, compile),
    )
    return Motion(
        target.skeleton,
        res.rotations.double().numpy(),
        res.root_positions.double().numpy(),
        source.fps,
        name=source.name if name is None else name,
    )


def load(
    checkpoint: str | os.PathLike, device: str | torch.device | None = None
) -> Callable[..., Motion]:
    """The registry's loader: ``retarget(source, target_character, source_character=None,
    eso=True)`` with the contact model of ``checkpoint`` (:func:`retarget_contact_with`) on
    ``device`` (network and ESO; default the CPU)."""
    model, config = load_contact_model(checkpoint, device)
    return partial(retarget_contact_with, model, config)
