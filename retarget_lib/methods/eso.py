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

Speed (:func:`eso_throughput`: full-size randomly initialised network, the 3,001-vertex bulky
synthetic target ``otto``, a clap clip, 20 frames × 30 iterations, on the shared 2-core CPU at a
load average of about 4): 3.7-5.5 frames/s without Eint or with triangle pairs detected once per
frame; 2.3 frames/s re-detecting every 10 iterations and 2.0 every 5 (poses with 6-12 colliding
pairs per frame). One iteration costs about 10 ms (decoder step, FK and their backward pass) plus
about 5 ms for Eint (vertex normals of the whole mesh); one detection 10-30 ms. Hence the default:
detect once per frame. ESO runs single-threaded (``num_threads``): its tensors are one frame each.
"""

from __future__ import annotations

import time
from typing import Any, NamedTuple, Sequence

import numpy as np
import torch

from ..core.motion import Motion
from ..core.transfer import transfer_rotations
from ..core.quantities import (MotionQuantities, foot_ground_heights, leg_ratio as skeleton_leg_ratio,
                               motion_quantities)
from ..core.skeleton import J
from ..core.skinning import linear_blend_skinning
from ..geometry.contacts import detect_foot_contacts
from ..geometry.penetration import InterpenetrationEnergy
from ..losses.contact import (ContactEnergyWeights, eso_self_contact_energy, end_effector_energy_per_frame,
                              foot_contact_energy_per_frame, reach_hold_energy, self_contact_energy,
                              weak_energy)
from ..models.georet import DecoderState, GeometryConditionedRNN, ResidualBase, TargetContext, motion_features

Tensor = torch.Tensor

__all__ = ["EsoResult", "EsoSource", "TERMS", "encoder_space_optimization", "eso_source", "eso_throughput",
           "reachable_pairs", "reached_joints"]

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
        foot_contacts = detect_foot_contacts(quantities.positions.double().numpy(), motion.skeleton)
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
    is_hand = np.isin(owner, HAND_JOINTS)
    touched = owner[is_hand.any(1)[:, None] & ~is_hand]
    return sorted(set(int(j) for j in touched))


class _Pose(NamedTuple):
    rotations: Tensor  # (1, 22, 4)
    state: DecoderState  # after frame t: its root_position is r_t, its root_velocity o_t
    positions: Tensor  # (1, 22, 3) global
    vertices: Tensor | None  # (1, V, 3)


class _Frame:
    """The fixed data of one frame's ESO problem and its energy ``Efull(t)``."""

    def __init__(self, t: int, initial: _Pose, previous: Tensor, problem: "_Problem"):
        p = problem
        self.problem, self.initial = p, initial
        pairs = p.contacts_at(t) if p.weights.j2j_weight > 0 else np.zeros((0, 2), np.int64)
        self.pairs = reachable_pairs(pairs, initial.vertices[0], p.reach) if len(pairs) else pairs
        self.reached = reached_joints(self.pairs, p.skin_weights) if p.weights.hold > 0 else []
        self.collisions = np.zeros((0, 2), np.int64)
        self.uses_int = p.interpenetration is not None and p.weights.int_weight > 0
        if self.uses_int:
            self.detect(initial.vertices[0])
        self.previous = previous  # (1, 22, 3) frame t−1's final joints (or frame t's initial ones at t = 0)
        src = p.source
        self.src_positions = torch.stack((src.positions[max(t - 1, 0)], src.positions[t]))[None]
        self.src_rotations = src.rotations[t][None]
        self.src_prev_velocity = src.root_velocity[t - 1][None] if t > 0 else src.root_velocity.new_zeros(1, 3)
        contact = torch.as_tensor(p.foot_contacts[t], device=p.offsets.device)
        self.foot_contacts = torch.stack((contact, contact))[None]

    def detect(self, vertices: Tensor) -> None:
        self.collisions = self.problem.interpenetration.pairs(vertices.detach())

    def mesh_vertices(self, redetect_every: int) -> "np.ndarray | bool":
        """Which vertices the energy reads, so each step skins only those: ``False`` (none),
        ``True`` (all: re-detection needs the whole mesh) or the ``(U,)`` sorted vertex ids of the
        contact pairs and of Eint's colliding faces with the faces around their corners (normals).
        On a 13,000-vertex body a colliding frame reads a few hundred."""
        if self.uses_int and redetect_every > 0:
            return True
        if not len(self.pairs) and not len(self.collisions):
            return False
        parts = [self.pairs.reshape(-1)]
        if len(self.collisions):
            parts.append(self.problem.interpenetration.support(self.collisions))
        return np.unique(np.concatenate(parts))

    def energy(self, pose: _Pose, o_prev: Tensor) -> dict[str, Tensor]:
        """Weighted terms of ``Efull(t)`` (:data:`TERMS`) and ``"total"``, each a scalar."""
        p, w = self.problem, self.problem.weights
        zero = pose.positions.new_zeros(())
        terms = dict.fromkeys(TERMS, zero)
        if len(self.pairs):
            relaxed = eso_self_contact_energy(pose.vertices[0], self.pairs, self.initial.vertices[0], p.blend)
            terms["j2j"] = w.lambda_j2j * w.in_units("j2j", relaxed)
            terms["j2j_distance"] = self_contact_energy(pose.vertices[0], self.pairs).detach()
        if self.reached:
            drift = reach_hold_energy(pose.positions[0], self.initial.positions[0], self.reached)
            terms["hold"] = w.hold * w.in_units("hold", drift)
        if len(self.collisions):
            e_int = p.interpenetration.energy_of_pairs(pose.vertices, [self.collisions])[0]
            terms["int"] = w.int_weight * w.in_units("int", e_int)
        window = torch.stack((self.previous[0], pose.positions[0]))[None]  # (1, 2, 22, 3)
        if w.foot_weight > 0:
            foot = foot_contact_energy_per_frame(window, self.foot_contacts, p.ground_heights, p.height)[0, 1]
            terms["foot"] = w.foot_weight * w.in_units("foot", foot)
        if w.omega > 0:
            terms["ee"] = w.omega * end_effector_energy_per_frame(
                window, self.src_positions, p.height, p.source.height)[0, 1]
        unit = w.length_unit
        terms["weak"] = weak_energy(pose.rotations, self.src_rotations, o_prev / unit,
                                    self.src_prev_velocity / unit, p.leg_ratio, w.rho)[0]
        terms["total"] = sum(v for k, v in terms.items() if k != "j2j_distance")
        return terms


class _Problem:
    """Constants shared by every frame: the model, target, source and settings (on the model's
    device)."""

    def __init__(self, model: GeometryConditionedRNN, target: Any, source: MotionQuantities, leg_ratio: float,
                 foot_contacts: np.ndarray, contacts: Any, interpenetration: InterpenetrationEnergy | None,
                 weights: ContactEnergyWeights, reach: float, blend: float):
        dtype = dict(dtype=model.rotation_head.weight.dtype, device=model.rotation_head.weight.device)
        self.model, self.weights, self.reach, self.blend = model, weights, float(reach), float(blend)
        self.offsets = torch.as_tensor(target.skeleton.offsets, **dtype)
        self.rest_joints = torch.as_tensor(target.skeleton.rest_positions(), **dtype)
        self.rest_vertices = torch.as_tensor(np.asarray(target.rest_vertices), **dtype)
        self.skin_weights = np.asarray(target.weights)
        self.skin_weights_t = torch.as_tensor(self.skin_weights, **dtype)
        self.height = float(target.height)
        self.ground_heights = torch.as_tensor(foot_ground_heights(target.skeleton), **dtype)
        self.source = MotionQuantities(*(torch.as_tensor(x, **dtype) for x in source[:3]), float(source.height))
        self.leg_ratio = float(leg_ratio)
        #: what a residual network corrects (Eweak's targets θ^A, o^(A→B)); ignored by the paper's network
        self.base = ResidualBase(self.source.rotations[None], self.leg_ratio * self.source.root_velocity[None])
        self.foot_contacts = np.asarray(foot_contacts, dtype=bool)
        self.contacts = contacts
        self.interpenetration = interpenetration

    def contacts_at(self, t: int) -> np.ndarray:
        if self.contacts is None:
            return np.zeros((0, 2), np.int64)
        pairs = self.contacts.at(t) if hasattr(self.contacts, "at") else self.contacts[t]
        return np.asarray(pairs, dtype=np.int64).reshape(-1, 2)

    def pose(self, t: int, h_enc: Tensor, o_prev: Tensor, state: DecoderState, context: TargetContext,
             mesh: "bool | np.ndarray") -> _Pose:
        """Decode frame ``t`` from ``h^enc_t`` with ``o_(t−1)`` swapped into the state, then FK (+ LBS).

        ``mesh``: skin no vertex (``False``), all (``True``), or only the ``(U,)`` given ones
        (:meth:`_Frame.mesh_vertices`; the others stay at 0 in the ``(1, V, 3)`` result, read by nothing).
        """
        rot, _, new_state = self.model.decode_step(h_enc, state._replace(root_velocity=o_prev), context,
                                                   self.base.frame(t))
        pos = new_state.local_positions + new_state.root_position[:, None]  # Eq. 18
        verts = None
        if mesh is True:
            verts = linear_blend_skinning(self.rest_vertices, self.skin_weights_t, self.rest_joints,
                                          new_state.global_rotations, pos)
        elif mesh is not False:
            index = torch.as_tensor(mesh, device=pos.device)
            part = linear_blend_skinning(self.rest_vertices[index], self.skin_weights_t[index], self.rest_joints,
                                         new_state.global_rotations, pos)
            verts = part.new_zeros(1, len(self.rest_vertices), 3).index_copy(1, index, part)
        return _Pose(rot, new_state, pos, verts)


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
                               num_threads: int | None = 1, keep_iterates: bool = False) -> EsoResult:
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
        state = model.initial_state(context, start)
        log = _Log(num_frames, iterations, keep_iterates)
        frames: list[_Pose] = []
        for t in range(num_frames):
            pose = _optimise_frame(t, problem, h_enc[t:t + 1], state, context, frames, iterations, lr,
                                   redetect_every, log)
            frames.append(pose)
            state = pose.state
    finally:
        torch.set_num_threads(threads)
        model.train(was_training)
        for p, flag in zip(model.parameters(), grad_flags):
            p.requires_grad_(flag)
    return EsoResult(torch.cat([f.rotations for f in frames]).cpu(),
                     torch.cat([f.state.root_position for f in frames]).cpu(),
                     torch.cat([f.positions for f in frames]).cpu(), log.energies, log.terms,
                     torch.as_tensor(log.active), torch.as_tensor(log.collisions), time.perf_counter() - began,
                     log.rotations, log.roots)


class _Log:
    def __init__(self, frames: int, iterations: int, keep_iterates: bool = False):
        self.energies = torch.zeros(frames, iterations + 1)
        self.terms = {k: torch.zeros(frames, iterations + 1) for k in TERMS}
        self.active = [0] * frames
        self.collisions = [0] * frames
        self.rotations = torch.zeros(frames, iterations + 1, J_COUNT, 4) if keep_iterates else None
        self.roots = torch.zeros(frames, iterations + 1, 3) if keep_iterates else None

    def record(self, t: int, n: int, terms: dict[str, Tensor], pose: "_Pose | None" = None) -> None:
        self.energies[t, n] = float(terms["total"].detach())
        for k in TERMS:
            self.terms[k][t, n] = float(terms[k].detach())
        if self.rotations is not None and pose is not None:
            self.rotations[t, n] = pose.rotations[0].detach().cpu()
            self.roots[t, n] = pose.state.root_position[0].detach().cpu()


def _optimise_frame(t: int, problem: _Problem, h_enc: Tensor, state: DecoderState, context: TargetContext,
                    frames: Sequence[_Pose], iterations: int, lr: float, redetect_every: int, log: _Log) -> _Pose:
    """Steps 1-4 of the module docstring for frame ``t``; returns the kept pose (its state carried on)."""
    h = h_enc.clone().requires_grad_(True)
    o_prev = state.root_velocity.clone().requires_grad_(True)
    with torch.no_grad():
        initial = problem.pose(t, h, o_prev, state, context, mesh=True)
    previous = frames[-1].positions if frames else initial.positions
    frame = _Frame(t, initial, previous, problem)
    log.active[t], log.collisions[t] = len(frame.pairs), len(frame.collisions)
    optimiser = torch.optim.Adam([h, o_prev], lr=lr, betas=(0.5, 0.999), eps=1e-8)
    mesh = frame.mesh_vertices(redetect_every)
    for n in range(iterations):
        optimiser.zero_grad(set_to_none=True)
        pose = problem.pose(t, h, o_prev, state, context, mesh)
        if frame.uses_int and redetect_every and n and n % redetect_every == 0:
            frame.detect(pose.vertices[0])
        terms = frame.energy(pose, o_prev)
        terms["total"].backward()
        optimiser.step()
        log.record(t, n, terms, pose)
    with torch.no_grad():
        final = problem.pose(t, h, o_prev, state, context, mesh)
        log.record(t, iterations, frame.energy(final, o_prev), final)
    return final._replace(vertices=None)


def eso_throughput(model: GeometryConditionedRNN, motion: Motion, target: Any, frames: int = 10,
                   iterations: int = 30, interpenetration: InterpenetrationEnergy | None = None,
                   contacts: Any = None, redetect_every: int = 0) -> dict[str, float]:
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

    Returns:
        ``{"frames", "iterations", "vertices", "seconds", "frames_per_second", "colliding_pairs"}``
        (mean colliding triangle pairs per frame).
    """
    if motion.num_frames < frames:
        raise ValueError(f"the motion has {motion.num_frames} frames, fewer than {frames}")
    clip = motion.copy(rotations=motion.rotations[:frames], root_positions=motion.root_positions[:frames])
    src = eso_source(clip, target)
    warm_up = src.quantities._replace(**{k: v[:1] for k, v in src.quantities._asdict().items() if k != "height"})
    encoder_space_optimization(model, src.features[:, :1], target, warm_up, src.foot_contacts[:1], src.leg_ratio,
                               iterations=1)  # first-call costs (lazy imports in torch.optim) not timed
    result = encoder_space_optimization(model, src.features, target, src.quantities, src.foot_contacts,
                                        src.leg_ratio, contacts=contacts, interpenetration=interpenetration,
                                        iterations=iterations, redetect_every=redetect_every)
    return {"frames": float(frames), "iterations": float(iterations), "vertices": float(len(target.rest_vertices)),
            "seconds": result.seconds, "frames_per_second": result.frames_per_second,
            "colliding_pairs": float(result.colliding_pairs.float().mean())}
