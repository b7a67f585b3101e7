"""Encoder-space optimisation (ESO) of Villegas et al. 2021 (Sec. 3.3, Eqs. 10-11, App. B.1).

The trained :class:`~retarget_lib.models.georet.GeometryConditionedRNN` gives a good first guess
that does not quite meet contacts and penetration constraints. ESO keeps the network fixed and,
frame by frame, optimises the encoder state ``h^enc_t`` and the previous root velocity
``o_(t−1)`` (the decoder input that places frame ``t``'s root, Eq. 18) on the energy of that
frame, ``Efull(t)`` (Eq. 1):

1. decode frame ``t`` once from the carried decoder state → the *initial output* (pose, joints,
   skinned mesh);
2. from it fix the frame's constraints: the self-contact pairs within ``reach`` (15 cm, App. B.1),
   each contact vertex's relaxed target (``0.7`` initial position + ``0.3`` partner,
   :func:`~retarget_lib.losses.contact.eso_self_contact_energy`), the joints the hands touch (held
   near their initial positions, :func:`~retarget_lib.losses.contact.reach_hold_energy`), and the
   colliding triangle pairs for Eint (BVH detection on the initial mesh; ``redetect_every`` > 0
   re-detects on the current mesh every that many iterations);
3. ``N`` Adam steps (lr 0.01, betas (0.5, 0.999), eps 1e-8) on ``h^enc_t`` and ``o_(t−1)``;
4. decode frame ``t`` with the optimised values, keep it (``o_(t−1)`` thereby becomes the
   previous frame's final root velocity), and carry the decoder state to ``t + 1``.

``Efull(t)`` here holds only the terms that depend on frame ``t`` (Sec. 3.3):

=========  ========================================================================================
``j2j``    ``λ ·`` relaxed self-contact term on frame ``t``'s reachable pairs
``hold``   ``hold ·`` mean drift of the joints the hands touch from their initial positions (App. B.1)
``int``    ``β ·`` Eq. 4 on frame ``t``'s mesh and its detected triangle pairs (Eq. 5 weights)
``foot``   ``γ ·`` Eq. 6 at ``t`` (velocity against the already fixed frame ``t − 1``)
``ee``     ``ω ·`` Eq. 9 at ``t`` (velocities against frame ``t − 1``, source and output)
``weak``   Eq. 8: ``ρ Σ_j ‖θ_t − θ^A_t‖²`` + ``‖o_(t−1) − leg_ratio · o^A_(t−1)‖²`` (the velocity
           being optimised; ``o^A_(−1) = 0``)
=========  ========================================================================================

Lengths are expressed in ``weights.length_unit`` before weighting (centimetres by default, see
:mod:`retarget_lib.losses.contact`). Plus ``j2j_distance``, Eq. 3 on the reachable pairs (metres,
unweighted, not in the total): the quantity the relaxed term is meant to shrink over frames.

The reach threshold is absolute (metres on the target, not rescaled by its height), as the paper
states it for Mixamo characters of 1.4-2 m; pass a scaled ``reach`` for very different sizes.
Which side of a contact is "reached": for each reachable pair with a hand vertex (dominant
skinning joint ``LeftHand``/``RightHand``), the dominant joint of every non-hand vertex of that
pair (:func:`reached_joints`).

Speed (:func:`eso_throughput`, ``retarget bench --only eso``; the shipped network, the mannequin's
synthetic ``pray`` clip (palms together) onto MakeHuman's body decimated to 10,000 vertices, 80 colliding triangle pairs
and 3 contact pairs a frame, 30 steps, idle 2-core machine): one uncompiled step is ~8,000 small
tensor operations (decoder, FK, skinning of the vertices the energy reads, energy, backward, Adam:
~8 ms, almost all per-operation overhead), 0.27 s a frame. Compiled (``compile=True``), one step is
one call of one graph (:func:`_adam_step`: energy, its gradient and Adam's update fused by
``torch.compile``): 73 ms a frame, 13.7 frames/s (was 0.10-0.11 s while the backward ran through
autograd's engine and the update through ``torch.optim``), of which ~20 ms are the frame's collision
detection (two threads) and initial decode. Detection runs once per frame by default
(``redetect_every`` re-detects on the whole mesh). The steps run single-threaded (``num_threads``):
their tensors are one frame each.
"""

from __future__ import annotations

import functools
import os
import shutil
import time
import warnings
from typing import Any, Callable, NamedTuple, cast

import numpy as np
import torch

from ..core.measures import estimated_standing_height, foot_rest_heights
from ..core.motion import Motion
from ..core.transfer import transfer_rotations
from ..core.quantities import MotionQuantities, leg_ratio as skeleton_leg_ratio, motion_quantities
from ..core.skeleton import J
from ..core.skinning import linear_blend_skinning
from ..geometry.contacts import detect_foot_contacts
from ..geometry.penetration import PADDING_PAIR, InterpenetrationEnergy, PairPlan, plan_energy
from ..losses.contact import (ContactEnergyWeights, eso_self_contact_energy, end_effector_energy_per_frame,
                              foot_contact_energy_per_frame, reach_hold_energy, self_contact_energy,
                              weak_energy)
from ..models.compiling import compile_function
from ..models.georet import DecoderGates, DecoderState, GeometryConditionedRNN, ResidualBase, TargetContext, motion_features

Tensor = torch.Tensor

__all__ = ["COMPILE_FROM_FRAMES", "EsoResult", "EsoSource", "TERMS", "encoder_space_optimization", "eso_source",
           "eso_throughput", "reachable_pairs", "reached_joints", "use_compiled"]

#: energy terms logged per frame and iteration (``j2j_distance`` is a diagnostic, not in the total)
TERMS: tuple[str, ...] = ("j2j", "hold", "int", "foot", "ee", "weak", "j2j_distance")
HAND_JOINTS: tuple[int, ...] = (J["LeftHand"], J["RightHand"])
J_COUNT = len(J)


class EsoResult(NamedTuple):
    """Output of :func:`encoder_space_optimization` (float32 tensors, no gradient).

    Attributes:
        rotations: ``(T, 22, 4)`` local unit wxyz.
        root_positions: ``(T, 3)`` metres.
        positions: ``(T, 22, 3)`` global joints (metres).
        energies: ``(T, N + 1)`` ``Efull(t)`` before each of the ``N`` steps and after the last.
        terms: ``{name: (T, N + 1)}`` weighted terms (:data:`TERMS`; 0 where unused).
        active_contacts: ``(T,)`` reachable contact pairs per frame.
        colliding_pairs: ``(T,)`` triangle pairs detected on each initial output.
        seconds: wall time of the optimisation.
        iterate_rotations: ``(T, N + 1, 22, 4)`` frame ``t``'s local rotations after ``n`` of its
            steps (``n = N``: the kept pose), or ``None`` unless ``keep_iterates``.
        iterate_roots: ``(T, N + 1, 3)`` the same for the root position, or ``None``.
    """

    rotations: Tensor
    root_positions: Tensor
    positions: Tensor
    energies: Tensor
    terms: dict[str, Tensor]
    active_contacts: Tensor
    colliding_pairs: Tensor
    seconds: float
    iterate_rotations: Tensor | None = None
    iterate_roots: Tensor | None = None

    @property
    def frames_per_second(self) -> float:
        return len(self.rotations) / max(self.seconds, 1e-9)


class EsoSource(NamedTuple):
    """Everything ESO needs from a source motion for one target (:func:`eso_source`).

    Attributes:
        features: ``(1, T, 267)`` network input :func:`~retarget_lib.models.georet.motion_features`.
        quantities: source :class:`~retarget_lib.losses.contact.MotionQuantities` (``(T, ...)``).
        leg_ratio: ``h_legs_B / h_legs_A``.
        foot_contacts: ``(T, 4)`` bool source foot contacts.
    """

    features: Tensor
    quantities: MotionQuantities
    leg_ratio: float
    foot_contacts: np.ndarray


def eso_source(motion: Motion, target: Any, foot_contacts: np.ndarray | None = None,
               rest_aligned: bool = False) -> EsoSource:
    """Prepare a canonical-22 source motion for :func:`encoder_space_optimization` on ``target``.

    Args:
        motion: source motion (metres).
        target: a ``Character``-like object (``.skeleton``).
        foot_contacts: ``(T, 4)`` bool; default :func:`retarget_lib.geometry.contacts.detect_foot_contacts`
            on the source.
        rest_aligned: Eweak's ``θ^A`` (and a residual network's base) are the source rotations
            re-expressed on the target's rest pose
            (:func:`~retarget_lib.core.transfer.transfer_rotations`): pass ``model.residual``
            (see :func:`~retarget_lib.methods.contact.eweak_rotations`).
    """
    rot, root, off = motion.torch(torch.float32)
    height = motion.skeleton.height()
    quantities = motion_quantities(rot, root, off, height, motion.skeleton.parents)
    if rest_aligned:
        aligned = transfer_rotations(motion.rotations, motion.skeleton, target.skeleton)
        quantities = quantities._replace(rotations=torch.as_tensor(aligned, dtype=torch.float32))
    if foot_contacts is None:
        foot_contacts = detect_foot_contacts(quantities.positions.double().numpy(), motion.skeleton,
                                             estimated_standing_height(motion.skeleton))
    features = motion_features(rot[None], root[None], off, motion.skeleton.parents, height)
    return EsoSource(features, quantities, skeleton_leg_ratio(motion.skeleton, target.skeleton),
                     np.asarray(foot_contacts, dtype=bool))


def reachable_pairs(pairs: np.ndarray, vertices: Tensor, reach: float) -> np.ndarray:
    """The contact pairs within ``reach`` metres in ``vertices`` (App. B.1's 15 cm rule).

    Args:
        pairs: ``(n, 2)`` vertex pairs.
        vertices: ``(V, 3)`` the network's initial output.
        reach: metres.

    Returns:
        ``(m, 2)`` int64, ``m <= n``.
    """
    pairs = np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
    if not len(pairs):
        return pairs
    v = vertices.detach()
    dist = (v[pairs[:, 0]] - v[pairs[:, 1]]).norm(dim=-1).numpy()
    return pairs[dist <= reach]


def reached_joints(pairs: np.ndarray, skin_weights: np.ndarray) -> list[int]:
    """Joints the hands touch: for each pair with a hand vertex, the dominant joint of its
    non-hand vertices (sorted, unique).

    Args:
        pairs: ``(n, 2)`` vertex pairs.
        skin_weights: ``(V, 22)`` the target's skinning weights.
    """
    owner = np.asarray(skin_weights).argmax(1)[np.asarray(pairs, dtype=np.int64).reshape(-1, 2)]
    is_hand = np.asarray(np.isin(owner, HAND_JOINTS))
    touched = owner[np.asarray(is_hand.any(axis=1))[:, None] & ~is_hand]
    return sorted(set(int(j) for j in touched))


class _Pose(NamedTuple):
    rotations: Tensor  # (1, 22, 4)
    state: DecoderState  # after frame t: its root_position is r_t, its root_velocity o_t
    positions: Tensor  # (1, 22, 3) global
    vertices: Tensor | None  # (1, U, 3): the U vertices skinned (_FrameInputs.rest_vertices posed), or None


def _skinned(pose: _Pose) -> Tensor:
    """``(U, 3)`` the skinned vertices of a pose decoded with vertices (the initial output and a
    re-detection decode the whole mesh)."""
    if pose.vertices is None:
        raise ValueError("the pose was decoded without vertices")
    return pose.vertices[0]


class _Constants(NamedTuple):
    """The tensors every frame's energy shares (scalars as 0-d tensors, so a compiled energy does
    not specialise on one character's height)."""

    context: TargetContext
    rest_joints: Tensor  # (22, 3)
    ground_heights: Tensor  # (4,)
    height: Tensor  # () h_B
    source_height: Tensor  # () h_A
    leg_ratio: Tensor  # ()


class _FrameInputs(NamedTuple):
    """One frame's fixed inputs of ``Efull(t)``, as tensors (:meth:`_Frame.inputs`): built once
    per frame (and after each re-detection), read by every step's :func:`_frame_terms`."""

    state: DecoderState  # before frame t
    gates: DecoderGates  # the decoder's products that h_enc and o_(t−1) do not change
    base: ResidualBase | None  # frame t's (residual networks)
    rest_vertices: Tensor  # (U, 3) the vertices the energy reads, at rest
    skin_weights: Tensor  # (U, 22)
    pairs: Tensor  # (K, 2) contact pairs as positions in those U vertices
    pair_mask: Tensor  # (K,) 1, or 0 on padding
    initial_vertices: Tensor  # (U, 3) the initial output's
    hold: Tensor  # (22,) 1 on the joints the hands touch
    initial_positions: Tensor  # (22, 3)
    eint: PairPlan | None  # Eq. 4's colliding pairs, vertex ids as positions in the U vertices
    previous: Tensor  # (1, 22, 3) frame t−1's final joints
    src_positions: Tensor  # (1, 2, 22, 3) source joints at t − 1, t
    src_rotations: Tensor  # (1, 22, 4) θ^A_t
    src_prev_velocity: Tensor  # (1, 3) o^A_(t−1)
    foot_contacts: Tensor  # (1, 2, 4) float


def _frame_terms(model: GeometryConditionedRNN, weights: ContactEnergyWeights, blend: float,
                 cone: dict[str, float], constants: _Constants, frame: _FrameInputs, h_enc: Tensor,
                 o_prev: Tensor) -> tuple[Tensor, _Pose]:
    """Decode frame ``t`` from ``h^enc_t`` with ``o_(t−1)`` swapped into the state, pose it (FK,
    LBS of the ``U`` vertices the energy reads) and weigh ``Efull(t)``'s terms.

    Tensor operations only, so :func:`torch.compile` can fuse a whole step (``compile=True`` in
    :func:`encoder_space_optimization`).

    Returns:
        ``((len(TERMS) + 1,)`` the weighted :data:`TERMS` and the total last, the pose).
    """
    w = weights
    pose = _decode(model, constants, frame.state, frame.gates, frame.base, h_enc, o_prev, frame.rest_vertices,
                   frame.skin_weights)
    rot, pos, verts = pose.rotations, pose.positions, pose.vertices
    terms = dict.fromkeys(TERMS, pos.new_zeros(()))
    if verts is not None and w.j2j_weight > 0:
        relaxed = eso_self_contact_energy(verts[0], frame.pairs, frame.initial_vertices, blend, frame.pair_mask)
        terms["j2j"] = w.lambda_j2j * w.in_units("j2j", relaxed)
        terms["j2j_distance"] = self_contact_energy(verts[0], frame.pairs, frame.pair_mask).detach()
    if w.hold > 0:
        drift = reach_hold_energy(pos[0], frame.initial_positions, frame.hold)
        terms["hold"] = w.hold * w.in_units("hold", drift)
    if verts is not None and frame.eint is not None:
        terms["int"] = w.int_weight * w.in_units("int", plan_energy(verts, frame.eint, cone)[0])
    window = torch.stack((frame.previous[0], pos[0]))[None]  # (1, 2, 22, 3)
    if w.foot_weight > 0:
        foot = foot_contact_energy_per_frame(window, frame.foot_contacts, constants.ground_heights,
                                             constants.height)[0, 1]
        terms["foot"] = w.foot_weight * w.in_units("foot", foot)
    if w.omega > 0:
        terms["ee"] = w.omega * end_effector_energy_per_frame(window, frame.src_positions, constants.height,
                                                              constants.source_height)[0, 1]
    unit = w.length_unit
    terms["weak"] = weak_energy(rot, frame.src_rotations, o_prev / unit, frame.src_prev_velocity / unit,
                                constants.leg_ratio, w.rho)[0]
    total = cast(Tensor, sum(v for k, v in terms.items() if k != "j2j_distance"))
    return torch.stack([terms[k] for k in TERMS] + [total]), pose


#: threads detecting colliding triangles (ESO's own steps run on one thread)
DETECTION_WORKERS = min(2, os.cpu_count() or 1)

#: the fewest contact pairs and colliding pairs a compiled step sees (padding with zero weight):
#: ``torch.compile`` specialises sizes 0 and 1, so smaller counts would compile again
_COMPILED_MIN = 2


def _decode(model: GeometryConditionedRNN, constants: _Constants, state: DecoderState, gates: DecoderGates,
            base: ResidualBase | None, h_enc: Tensor, o_prev: Tensor, rest_vertices: Tensor,
            skin_weights: Tensor) -> _Pose:
    """Decode frame ``t`` from ``h^enc_t`` with ``o_(t−1)`` swapped into ``state`` (``gates``: its
    :meth:`~GeometryConditionedRNN.decoder_gates`), then FK and the LBS of the given ``(U, 3)``
    rest vertices (none when ``U = 0``)."""
    rot, _, new_state = model.decode_step(h_enc, state._replace(root_velocity=o_prev), constants.context, base,
                                          gates)
    pos = new_state.local_positions + new_state.root_position[:, None]  # Eq. 18
    verts = None
    if rest_vertices.shape[0]:
        verts = linear_blend_skinning(rest_vertices, skin_weights, constants.rest_joints,
                                      new_state.global_rotations, pos)
    return _Pose(rot, new_state, pos, verts)


class _Frame:
    """The fixed data of one frame's ESO problem: its state, contacts, held joints, colliding pairs."""

    def __init__(self, t: int, problem: "_Problem", constants: _Constants, state: DecoderState,
                 h_enc: Tensor, previous: "_Pose | None", redetect_every: int, padded: bool):
        p = problem
        self.t, self.problem = t, p
        self.state = state
        self.base = p.base.frame(t)
        self.redetect_every, self.padded = redetect_every, padded
        with torch.no_grad():
            self.gates = p.model.decoder_gates(state, constants.context)
            self.initial = _decode(p.model, constants, state, self.gates, self.base, h_enc, state.root_velocity,
                                   p.rest_vertices, p.skin_weights_t)
        self.previous = (previous or self.initial).positions  # (1, 22, 3); frame t's own at t = 0
        pairs = p.contacts_at(t) if p.weights.j2j_weight > 0 else np.zeros((0, 2), np.int64)
        self.pairs = reachable_pairs(pairs, _skinned(self.initial), p.reach) if len(pairs) else pairs
        self.reached = reached_joints(self.pairs, p.skin_weights) if p.weights.hold > 0 else []
        self.collisions = np.zeros((0, 2), np.int64)
        self.uses_int = p.interpenetration is not None and p.weights.int_weight > 0
        if self.uses_int:
            self.detect(_skinned(self.initial))

    def detect(self, vertices: Tensor) -> None:
        """Colliding triangle pairs of ``(V, 3)`` vertices (the whole mesh), kept for Eint; on two
        threads when there are two cores (the optimisation itself runs on one)."""
        self.collisions = self.problem.eint().pairs(vertices.detach(), DETECTION_WORKERS)

    def mesh_vertices(self, pairs: np.ndarray, collisions: np.ndarray) -> np.ndarray:
        """The ``(U,)`` sorted vertex ids the energy reads, so each step skins only those: all of
        them when re-detecting (detection needs the whole mesh), else the contact pairs' and Eint's
        colliding faces with the faces around their corners (normals). On a 13,000-vertex body a
        colliding frame reads a few hundred."""
        if self.uses_int and self.redetect_every > 0:
            return np.arange(len(self.problem.rest_vertices))
        parts = [pairs.reshape(-1)]
        if len(collisions):
            parts.append(self.problem.eint().support(collisions))
        return np.unique(np.concatenate(parts)).astype(np.int64)

    def inputs(self) -> _FrameInputs:
        """This frame's :class:`_FrameInputs` for the current pairs. When ``padded`` (a compiled
        step) there are at least :data:`_COMPILED_MIN` contact and colliding pairs, the extra
        ones with zero weight, so every frame runs the same compiled code."""
        p, device, dtype = self.problem, self.problem.offsets.device, self.problem.offsets.dtype
        nv = len(p.rest_vertices)
        pairs, collisions = self.pairs.reshape(-1, 2), self.collisions
        mask = np.ones(len(pairs))
        uses_int = self.uses_int and bool(self.padded or len(collisions))
        if self.padded:
            extra = max(_COMPILED_MIN - len(pairs), 0)
            pairs = np.concatenate([pairs, np.tile([[0, min(1, nv - 1)]], (extra, 1))])
            mask = np.concatenate([mask, np.zeros(extra)])
            if uses_int:  # the plan's padding faces: their vertices must be among the U read
                collisions = np.concatenate([collisions, np.tile([PADDING_PAIR], (_COMPILED_MIN, 1))])
        ids = self.mesh_vertices(pairs, collisions if uses_int else collisions[:0])
        where = np.full(nv, -1, np.int64)
        where[ids] = np.arange(len(ids))
        index = torch.as_tensor(ids, device=device)
        hold = torch.zeros(J_COUNT, dtype=dtype, device=device)
        hold[list(self.reached)] = 1.0
        eint = None
        if uses_int:
            eint = p.eint().plan([self.collisions], vertex_index=where,
                                           min_pairs=_COMPILED_MIN if self.padded else 0, device=device)
        src, t = p.source, self.t
        contact = torch.as_tensor(p.foot_contacts[t], device=device).to(dtype)
        return _fresh(_FrameInputs(
            self.state, self.gates, self.base, p.rest_vertices[index], p.skin_weights_t[index],
            torch.as_tensor(where[pairs], device=device), torch.as_tensor(mask, dtype=dtype, device=device),
            _skinned(self.initial)[index], hold, self.initial.positions[0], eint, self.previous,
            torch.stack((src.positions[max(t - 1, 0)], src.positions[t]))[None], src.rotations[t][None],
            src.root_velocity[t - 1][None] if t > 0 else src.root_velocity.new_zeros(1, 3),
            torch.stack((contact, contact))[None]))


def _fresh(inputs: Any) -> Any:
    """Every tensor of a (nested) named tuple as its own contiguous copy: a compiled step guards
    on strides and storage offsets, which views of the clip's tensors would change every frame."""
    if isinstance(inputs, Tensor):
        return inputs.detach().clone(memory_format=torch.contiguous_format)
    if isinstance(inputs, tuple):
        return type(inputs)(*(_fresh(x) for x in inputs))
    return inputs


class _Problem:
    """Constants shared by every frame: the model, target, source and settings (on the model's
    device)."""

    def __init__(self, model: GeometryConditionedRNN, target: Any, source: MotionQuantities, leg_ratio: float,
                 foot_contacts: np.ndarray, contacts: Any, interpenetration: InterpenetrationEnergy | None,
                 weights: ContactEnergyWeights, reach: float, blend: float):
        weight = model.rotation_head.weight
        as_model = lambda a: torch.as_tensor(a, dtype=weight.dtype, device=weight.device)  # noqa: E731
        self.model, self.weights, self.reach, self.blend = model, weights, float(reach), float(blend)
        self.offsets = as_model(target.skeleton.offsets)
        self.rest_joints = as_model(target.skeleton.rest_positions())
        self.rest_vertices = as_model(np.asarray(target.rest_vertices))
        self.skin_weights = np.asarray(target.weights)
        self.skin_weights_t = as_model(self.skin_weights)
        self.height = float(target.height)
        self.ground_heights = as_model(foot_rest_heights(target.skeleton))
        self.source = MotionQuantities(as_model(source.rotations), as_model(source.root_velocity),
                                       as_model(source.positions), float(source.height))
        self.leg_ratio = float(leg_ratio)
        #: what a residual network corrects (Eweak's targets θ^A, o^(A→B)); ignored by the paper's network
        self.base = ResidualBase(self.source.rotations[None], self.leg_ratio * self.source.root_velocity[None])
        self.foot_contacts = np.asarray(foot_contacts, dtype=bool)
        self.contacts = contacts
        self.interpenetration = interpenetration
        self.cone = dict(interpenetration.cone) if interpenetration is not None else {}

    def constants(self, context: TargetContext) -> _Constants:
        scalar = lambda x: torch.tensor(x, dtype=self.offsets.dtype, device=self.offsets.device)  # noqa: E731
        return _Constants(context, self.rest_joints, self.ground_heights, scalar(self.height),
                          scalar(self.source.height), scalar(self.leg_ratio))

    def contacts_at(self, t: int) -> np.ndarray:
        return _contact_pairs_at(self.contacts, t)

    def eint(self) -> InterpenetrationEnergy:
        """The target's Eint (only asked for when it is used)."""
        if self.interpenetration is None:
            raise ValueError("ESO was given no InterpenetrationEnergy")
        return self.interpenetration


def _contact_pairs_at(contacts: Any, t: int) -> np.ndarray:
    """Frame ``t``'s ``(n, 2)`` contact vertex pairs of ``contacts`` (see
    :func:`encoder_space_optimization`: a ``SelfContacts``, a sequence of pair arrays, or ``None``)."""
    if contacts is None:
        return np.zeros((0, 2), np.int64)
    pairs = contacts.at(t) if hasattr(contacts, "at") else contacts[t]
    return np.asarray(pairs, dtype=np.int64).reshape(-1, 2)


def _check_inputs(features: Tensor, source: MotionQuantities, foot_contacts: np.ndarray) -> int:
    t = features.shape[1]
    if features.dim() != 3 or features.shape[0] != 1:
        raise ValueError(f"source_features must be (T, 267) or (1, T, 267), got {tuple(features.shape)}")
    if source.rotations.shape[0] != t or source.positions.shape[0] != t or source.root_velocity.shape[0] != t:
        raise ValueError(f"source quantities must have T = {t} frames, got {tuple(source.rotations.shape)}")
    if np.shape(foot_contacts) != (t, 4):
        raise ValueError(f"foot_contacts must be ({t}, 4), got {np.shape(foot_contacts)}")
    return t


def encoder_space_optimization(model: GeometryConditionedRNN, source_features: Tensor, target: Any,
                               source: MotionQuantities, foot_contacts: np.ndarray, leg_ratio: float,
                               contacts: Any = None, interpenetration: InterpenetrationEnergy | None = None,
                               weights: ContactEnergyWeights | None = None, iterations: int = 30,
                               lr: float = 0.01, reach: float = 0.15, blend: float = 0.3,
                               start: Tensor | None = None, redetect_every: int = 0,
                               num_threads: int | None = 1, keep_iterates: bool = False,
                               compile: bool = False) -> EsoResult:
    """Retarget with the RNN and refine every frame by ESO (Sec. 3.3, Eqs. 10-11, App. B.1).

    Args:
        model: a (trained) :class:`~retarget_lib.models.georet.GeometryConditionedRNN`; used in
            eval mode, its parameters are not changed.
        source_features: ``(T, 267)`` or ``(1, T, 267)``
            :func:`~retarget_lib.models.georet.motion_features` of the source.
        target: ``Character``-like: ``.skeleton`` (canonical 22), ``.rest_vertices (V, 3)``,
            ``.faces``, ``.weights (V, 22)``, ``.height`` (metres).
        source: source :class:`~retarget_lib.losses.contact.MotionQuantities` with ``(T, ...)``
            arrays (rotations, root velocity, global joints) and the source height.
        foot_contacts: ``(T, 4)`` bool source foot contacts (``ik.FOOT_CONTACT_JOINTS`` order).
        leg_ratio: ``h_legs_B / h_legs_A`` (:func:`~retarget_lib.core.quantities.leg_ratio`).
        contacts: target-mesh self-contacts: a ``contacts.SelfContacts`` (``.at(t)``), a sequence
            of ``(n_t, 2)`` vertex-pair arrays, or ``None``.
        interpenetration: the target's ``penetration.InterpenetrationEnergy`` (its geodesic
            weights setting is used), or ``None`` to leave Eint out.
        weights: energy weights; default :meth:`ContactEnergyWeights.eso` (App. B.1).
        iterations: ``N`` Adam steps per frame (30).
        lr: Adam learning rate ``α`` (0.01).
        reach: optimise a contact only if the initial output has it within this distance (metres).
        blend: fraction of a contact gap targeted per frame (0.3).
        start: ``(3,)`` frame 0's root position, on the model's device (default ``leg_ratio ×`` the source's first root).
        redetect_every: re-detect colliding triangles every this many iterations (0 = once per
            frame, on the initial output).
        num_threads: torch intra-op threads while optimising (restored afterwards); ``None``
            keeps the current setting. ESO's tensors are one frame each, so threads only add
            overhead: on the 2-core workshop machine, under load, 2 threads ran 10x slower than 1.
        keep_iterates: also return every frame's pose after each of its steps
            (``EsoResult.iterate_rotations`` / ``iterate_roots``; e.g. to show ESO's progress).
        compile: run each step (decoder, FK, skinning, energy and their backward) compiled by
            ``torch.compile`` (inductor: needs a C++ compiler): the same energy, several times
            faster per step, after a one-off compilation (about half a minute, then cached on
            disk); contact and colliding pairs are padded to at least two with zero weight.
            Always on one thread (``num_threads`` is ignored): the compiled kernels crashed on two.

    Runs on the model's device (move the model with ``.to(device)``); the per-frame contact and
    collision detection stay on the CPU; the result's tensors are on the CPU.

    Returns:
        :class:`EsoResult`.
    """
    weights = ContactEnergyWeights.eso() if weights is None else weights
    features = source_features[None] if source_features.dim() == 2 else source_features
    num_frames = _check_inputs(features, source, foot_contacts)
    if iterations < 0 or redetect_every < 0:
        raise ValueError(f"iterations and redetect_every must be >= 0, got {iterations}, {redetect_every}")
    problem = _Problem(model, target, source, leg_ratio, foot_contacts, contacts, interpenetration, weights,
                       reach, blend)
    if start is None:
        start = problem.leg_ratio * problem.source.positions[0, 0]
    step = _compiled_step() if compile else _adam_step
    if compile:  # inductor's parallel kernels for these dynamic sizes corrupt memory on 2 threads (torch 2.13)
        num_threads = 1
    was_training, threads = model.training, torch.get_num_threads()
    grad_flags = [p.requires_grad for p in model.parameters()]
    model.eval().requires_grad_(False)
    if num_threads is not None:
        torch.set_num_threads(num_threads)
    began = time.perf_counter()
    try:
        with torch.no_grad():
            h_enc = model.encode(features.to(problem.offsets.device, problem.offsets.dtype))[0]
            context = model.target_context(problem.offsets, problem.rest_vertices[None],
                                           problem.skin_weights_t[None], problem.height)
        constants = problem.constants(context)
        state = model.initial_state(context, start)
        log = _Log(num_frames, iterations, keep_iterates)
        frames: list[_Pose] = []
        for t in range(num_frames):
            frame = _Frame(t, problem, constants, state, h_enc[t:t + 1], frames[-1] if frames else None,
                           redetect_every, padded=compile)
            pose = _optimise_frame(frame, constants, h_enc[t:t + 1], iterations, lr, log, step)
            frames.append(pose)
            state = pose.state
    finally:
        torch.set_num_threads(threads)
        model.train(was_training)
        for p, flag in zip(model.parameters(), grad_flags):
            p.requires_grad_(flag)
    return EsoResult(torch.cat([f.rotations for f in frames]).cpu(),
                     torch.cat([f.state.root_position for f in frames]).cpu(),
                     torch.cat([f.positions for f in frames]).cpu(), log.values[..., -1],
                     {k: log.values[..., i] for i, k in enumerate(TERMS)},
                     torch.as_tensor(log.active), torch.as_tensor(log.collisions), time.perf_counter() - began,
                     log.rotations, log.roots)


#: from this many frames, :func:`use_compiled` compiles ESO's step by default: the one-off
#: compilation (about 2 minutes the first time on a machine, 19 s from inductor's disk cache after)
#: is then repaid by the faster steps (0.27 -> 0.07 s a frame on MakeHuman's body at 10,000
#: vertices, one thread; ``retarget bench --only eso``)
COMPILE_FROM_FRAMES = 240


def use_compiled(frames: int, compile: bool | None = None) -> bool:
    """Whether ESO on a clip of ``frames`` should run compiled: ``compile`` when given, else
    (``None``) when the clip has :data:`COMPILE_FROM_FRAMES` frames or this process has compiled
    it already. Never without a C++ compiler (inductor's requirement; a warning says so once).
    """
    wanted = compile if compile is not None else (
        frames >= COMPILE_FROM_FRAMES or _compiled_in_process())
    if wanted and not _have_compiler():
        warnings.warn("no C++ compiler (g++, c++ or clang++) on PATH: ESO runs uncompiled", stacklevel=2)
        return False
    return wanted


def _compiled_in_process() -> bool:
    return _compiled_step.cache_info().currsize > 0


@functools.lru_cache(maxsize=1)
def _have_compiler() -> bool:
    return any(shutil.which(name) for name in ("g++", "c++", "clang++"))


@functools.lru_cache(maxsize=1)
def _compiled_step() -> Callable[..., tuple[tuple[Tensor, Tensor], _Adam, Tensor, _Pose]]:
    """:func:`_adam_step` compiled once per process (sizes dynamic: one compilation serves every
    frame, character and pair count; inductor caches it on disk for the next process)."""
    return compile_function(_adam_step, dynamic=True)


class _Log:
    def __init__(self, frames: int, iterations: int, keep_iterates: bool = False):
        self.values = torch.zeros(frames, iterations + 1, len(TERMS) + 1)  # the terms, then the total
        self.active = [0] * frames
        self.collisions = [0] * frames
        self.rotations = torch.zeros(frames, iterations + 1, J_COUNT, 4) if keep_iterates else None
        self.roots = torch.zeros(frames, iterations + 1, 3) if keep_iterates else None

    def record(self, t: int, n: int, values: Tensor, pose: _Pose) -> None:
        self.values[t, n] = values.detach().cpu()
        if self.rotations is not None and self.roots is not None:
            self.rotations[t, n] = pose.rotations[0].detach().cpu()
            self.roots[t, n] = pose.state.root_position[0].detach().cpu()


#: Adam's moment decays and epsilon in ESO (App. B.1)
ADAM_BETAS, ADAM_EPS = (0.5, 0.999), 1e-8


class _Adam(NamedTuple):
    """Adam's state for ESO's two variables ``(h^enc_t, o_(t−1))``: first and second moments and
    the steps taken (a 0-d tensor, so a compiled step does not specialise on it)."""

    first: tuple[Tensor, Tensor]
    second: tuple[Tensor, Tensor]
    steps: Tensor

    @classmethod
    def start(cls, variables: tuple[Tensor, Tensor]) -> "_Adam":
        zeros = tuple(torch.zeros_like(v) for v in variables)
        return cls(zeros, zeros, variables[0].new_zeros(()))  # type: ignore[arg-type]


def _adam_step(model: GeometryConditionedRNN, weights: ContactEnergyWeights, blend: float, cone: dict[str, float],
               constants: _Constants, frame: _FrameInputs, variables: tuple[Tensor, Tensor], adam: _Adam,
               lr: Tensor) -> tuple[tuple[Tensor, Tensor], _Adam, Tensor, _Pose]:
    """One ESO step: ``Efull(t)`` at ``variables = (h^enc_t, o_(t−1))`` (:func:`_frame_terms`), its
    gradient (``torch.func.grad``) and Adam's update (Kingma & Ba 2015, the arithmetic of
    ``torch.optim.Adam``: ``m ← β1 m + (1 − β1) g``, ``v ← β2 v + (1 − β2) g²``,
    ``x ← x − lr/(1 − β1^n) · m / (√v / √(1 − β2^n) + ε)``).

    One pure function, so a compiled step is one call of one fused graph (forward, backward and
    update), without autograd's engine or the optimiser's bookkeeping in between.

    Returns:
        ``(the updated variables, Adam's state, the terms and total at the given variables,
        the pose decoded from them)``.
    """
    def energy(h_enc: Tensor, o_prev: Tensor) -> tuple[Tensor, tuple[Tensor, Tensor, DecoderState, Tensor]]:
        values, pose = _frame_terms(model, weights, blend, cone, constants, frame, h_enc, o_prev)
        return values[-1], (values, pose.rotations, pose.state, pose.positions)  # tensors only

    if torch.compiler.is_compiling():  # functorch's transform is what a compiled graph can trace
        grads, (values, rotations, state, positions) = torch.func.grad(energy, argnums=(0, 1),
                                                                       has_aux=True)(*variables)
    else:  # eager, autograd's engine costs less per operation than the transform's wrappers
        with torch.enable_grad():
            leaves = tuple(v.detach().requires_grad_(True) for v in variables)
            total, (values, rotations, state, positions) = energy(*leaves)
            grads = torch.autograd.grad(total, leaves)
        values, rotations, positions = values.detach(), rotations.detach(), positions.detach()
        state = DecoderState(*(x.detach() for x in state))
    pose = _Pose(rotations, state, positions, None)
    (beta1, beta2), count = ADAM_BETAS, adam.steps + 1
    step = lr / (1 - beta1 ** count)
    root_correction = (1 - beta2 ** count).sqrt()
    first = tuple(m + (1 - beta1) * (g - m) for m, g in zip(adam.first, grads))
    second = tuple(beta2 * v + (1 - beta2) * g * g for v, g in zip(adam.second, grads))
    moved = tuple(x - step * m / (v.sqrt() / root_correction + ADAM_EPS)
                  for x, m, v in zip(variables, first, second))
    return moved, _Adam(first, second, count), values, pose  # type: ignore[arg-type]


def _optimise_frame(frame: _Frame, constants: _Constants, h_enc: Tensor, iterations: int, lr: float, log: _Log,
                    step: Callable[..., tuple[tuple[Tensor, Tensor], _Adam, Tensor, _Pose]]) -> _Pose:
    """Steps 3-4 of the module docstring for one frame (steps 1-2: :class:`_Frame`); returns the
    kept pose (its state carried on). ``step``: :func:`_adam_step`, compiled or not."""
    p, t = frame.problem, frame.t
    variables = (h_enc.clone(), frame.state.root_velocity.clone())
    adam, rate = _Adam.start(variables), torch.tensor(lr, dtype=h_enc.dtype, device=h_enc.device)
    log.active[t], log.collisions[t] = len(frame.pairs), len(frame.collisions)
    inputs = frame.inputs()
    redetect = frame.redetect_every if frame.uses_int else 0
    for n in range(iterations):
        if redetect and n and n % redetect == 0:
            with torch.no_grad():
                current = _decode(p.model, constants, frame.state, frame.gates, frame.base, *variables,
                                  p.rest_vertices, p.skin_weights_t)
            frame.detect(_skinned(current))
            inputs = frame.inputs()
        variables, adam, values, pose = step(p.model, p.weights, p.blend, p.cone, constants, inputs, variables,
                                             adam, rate)
        log.record(t, n, values, pose)
    # the same step again for the terms at the final values (its update unused): one compiled graph
    _, _, values, final = step(p.model, p.weights, p.blend, p.cone, constants, inputs, variables, adam, rate)
    log.record(t, iterations, values, final)
    return _Pose(final.rotations, final.state, final.positions, None)


def eso_throughput(model: GeometryConditionedRNN, motion: Motion, target: Any, frames: int = 10,
                   iterations: int = 30, interpenetration: InterpenetrationEnergy | None = None,
                   contacts: Any = None, redetect_every: int = 0, compile: bool = False) -> dict[str, float]:
    """Frames per second of :func:`encoder_space_optimization` on the first ``frames`` of a clip.

    Args:
        model: the network (a randomly initialised one measures the same cost as a trained one).
        motion: canonical-22 source motion with at least ``frames`` frames.
        target: ``Character``-like target.
        frames: frames to optimise.
        iterations: Adam steps per frame.
        interpenetration: the target's ``InterpenetrationEnergy`` (built outside: its geodesic
            table takes 1-2 s and is not part of the per-frame cost), or ``None``.
        contacts: target self-contacts (see :func:`encoder_space_optimization`).
        redetect_every: see :func:`encoder_space_optimization`.
        compile: compiled steps (see :func:`encoder_space_optimization`; the compilation is
            done by the untimed warm-up run).

    Returns:
        ``{"frames", "iterations", "vertices", "seconds", "frames_per_second", "colliding_pairs"}``
        (mean colliding triangle pairs per frame).
    """
    if motion.num_frames < frames:
        raise ValueError(f"the motion has {motion.num_frames} frames, fewer than {frames}")
    clip = motion.copy(rotations=motion.rotations[:frames], root_positions=motion.root_positions[:frames])
    src = eso_source(clip, target, rest_aligned=model.residual)  # as the contact method prepares it
    warm_up = src.quantities._replace(**{k: v[:1] for k, v in src.quantities._asdict().items() if k != "height"})
    # first-call costs (lazy imports in torch.optim; the compilation) not timed
    encoder_space_optimization(model, src.features[:, :1], target, warm_up, src.foot_contacts[:1], src.leg_ratio,
                               contacts=[_contact_pairs_at(contacts, 0)],
                               interpenetration=interpenetration, iterations=2, compile=compile)
    result = encoder_space_optimization(model, src.features, target, src.quantities, src.foot_contacts,
                                        src.leg_ratio, contacts=contacts, interpenetration=interpenetration,
                                        iterations=iterations, redetect_every=redetect_every, compile=compile)
    return {"frames": float(frames), "iterations": float(iterations), "vertices": float(len(target.rest_vertices)),
            "seconds": result.seconds, "frames_per_second": result.frames_per_second,
            "colliding_pairs": float(result.colliding_pairs.float().mean())}
