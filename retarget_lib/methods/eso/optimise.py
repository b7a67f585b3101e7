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
``hold``   ``hold ·`` mean drift of the joints the hands touch from their initial positions (App.
B.1) ``int``    ``β ·`` Eq. 4 on frame ``t``'s mesh and its detected triangle pairs (Eq. 5 weights)
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
synthetic ``pray`` clip (palms together) onto MakeHuman's body decimated to 10,000 vertices, 80
colliding triangle pairs and 3 contact pairs a frame, 30 steps, idle 2-core machine): one uncompiled
step is ~8,000 small tensor operations (decoder, FK, skinning of the vertices the energy reads,
energy, backward, Adam: ~8 ms, almost all per-operation overhead), 0.27 s a frame. Compiled
(``compile=True``), one step is one call of one graph
(:func:`~retarget_lib.methods.eso.step.adam_step`: energy, its gradient and Adam's update fused by
``torch.compile``): 73 ms a frame, 13.7 frames/s (was 0.10-0.11 s while the backward ran through
autograd's engine and the update through ``torch.optim``), of which ~20 ms are the frame's collision
detection (two threads) and initial decode. Detection runs once per frame by default
(``redetect_every`` re-detects on the whole mesh). The steps run single-threaded (``num_threads``):
their tensors are one frame each.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any, NamedTuple

import numpy as np
import torch

from ...core.motion import Motion
from ...core.quantities import MotionQuantities
from ...geometry.penetration import InterpenetrationEnergy
from ...losses.contact import ContactEnergyWeights
from ...models.georet import GeometryConditionedRNN
from .energy import TERMS
from .frame import J_COUNT, Constants, Frame, Pose, Problem, contact_pairs_at, decode, skinned
from .source import eso_source
from .step import AdamState, adam_step, compiled_step

Tensor = torch.Tensor

__all__ = ["EsoResult", "encoder_space_optimization", "eso_throughput"]


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


def _check_inputs(features: Tensor, source: MotionQuantities, foot_contacts: np.ndarray) -> int:
    t = features.shape[1]
    if features.dim() != 3 or features.shape[0] != 1:
        raise ValueError(
            f"source_features must be (T, 267) or (1, T, 267), got {tuple(features.shape)}"
        )
    if (
        source.rotations.shape[0] != t
        or source.positions.shape[0] != t
        or source.root_velocity.shape[0] != t
    ):
        raise ValueError(
            f"source quantities must have T = {t} frames, got {tuple(source.rotations.shape)}"
        )
    if np.shape(foot_contacts) != (t, 4):
        raise ValueError(f"foot_contacts must be ({t}, 4), got {np.shape(foot_contacts)}")
    return t


def encoder_space_optimization(
    model: GeometryConditionedRNN,
    source_features: Tensor,
    target: Any,
    source: MotionQuantities,
    foot_contacts: np.ndarray,
    leg_ratio: float,
    contacts: Any = None,
    interpenetration: InterpenetrationEnergy | None = None,
    weights: ContactEnergyWeights | None = None,
    iterations: int = 30,
    lr: float = 0.01,
    reach: float = 0.15,
    blend: float = 0.3,
    start: Tensor | None = None,
    redetect_every: int = 0,
    num_threads: int | None = 1,
    keep_iterates: bool = False,
    compile: bool = False,
    step: Callable[..., tuple[tuple[Tensor, Tensor], AdamState, Tensor, Pose]] | None = None,
) -> EsoResult:
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
        start: ``(3,)`` frame 0's root position, on the model's device (default ``leg_ratio ×`` the
            source's first root).
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
        step: the step to take instead of the library's
            (:func:`~retarget_lib.methods.eso.step.adam_step`, or its compiled form): a function
            with ``adam_step``'s arguments and results, e.g. a notebook exercise's own update.
            ``compile`` then only pads the pairs.

    Runs on the model's device (move the model with ``.to(device)``); the per-frame contact and
    collision detection stay on the CPU; the result's tensors are on the CPU.

    Returns:
        :class:`EsoResult`.
    """
    weights = ContactEnergyWeights.eso() if weights is None else weights
    features = source_features[None] if source_features.dim() == 2 else source_features
    num_frames = _check_inputs(features, source, foot_contacts)
    if iterations < 0 or redetect_every < 0:
        raise ValueError(
            f"iterations and redetect_every must be >= 0, got {iterations}, {redetect_every}"
        )
    problem = Problem(
        model,
        target,
        source,
        leg_ratio,
        foot_contacts,
        contacts,
        interpenetration,
        weights,
        reach,
        blend,
    )
    if start is None:
        start = problem.leg_ratio * problem.source.positions[0, 0]
    if step is None:
        step = compiled_step() if compile else adam_step
    # inductor's parallel kernels for these dynamic sizes corrupt memory on 2 threads (torch 2.13)
    if compile:
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
            context = model.target_context(
                problem.offsets,
                problem.rest_vertices[None],
                problem.skin_weights_t[None],
                problem.height,
            )
        constants = problem.constants(context)
        state = model.initial_state(context, start)
        log = _Log(num_frames, iterations, keep_iterates)
        frames: list[Pose] = []
        for t in range(num_frames):
            frame = Frame(
                t,
                problem,
                constants,
                state,
                h_enc[t : t + 1],
                frames[-1] if frames else None,
                redetect_every,
                padded=compile,
            )
            pose = _optimise_frame(frame, constants, h_enc[t : t + 1], iterations, lr, log, step)
            frames.append(pose)
            state = pose.state
    finally:
        torch.set_num_threads(threads)
        model.train(was_training)
        for p, flag in zip(model.parameters(), grad_flags, strict=False):
            p.requires_grad_(flag)
    return EsoResult(
        torch.cat([f.rotations for f in frames]).cpu(),
        torch.cat([f.state.root_position for f in frames]).cpu(),
        torch.cat([f.positions for f in frames]).cpu(),
        log.values[..., -1],
        {k: log.values[..., i] for i, k in enumerate(TERMS)},
        torch.as_tensor(log.active),
        torch.as_tensor(log.collisions),
        time.perf_counter() - began,
        log.rotations,
        log.roots,
    )


class _Log:
    def __init__(self, frames: int, iterations: int, keep_iterates: bool = False):
        self.values = torch.zeros(
            frames, iterations + 1, len(TERMS) + 1
        )  # the terms, then the total
        self.active = [0] * frames
        self.collisions = [0] * frames
        self.rotations = torch.zeros(frames, iterations + 1, J_COUNT, 4) if keep_iterates else None
        self.roots = torch.zeros(frames, iterations + 1, 3) if keep_iterates else None

    def record(self, t: int, n: int, values: Tensor, pose: Pose) -> None:
        self.values[t, n] = values.detach().cpu()
        if self.rotations is not None and self.roots is not None:
            self.rotations[t, n] = pose.rotations[0].detach().cpu()
            self.roots[t, n] = pose.state.root_position[0].detach().cpu()


def _optimise_frame(
    frame: Frame,
    constants: Constants,
    h_enc: Tensor,
    iterations: int,
    lr: float,
    log: _Log,
    step: Callable[..., tuple[tuple[Tensor, Tensor], AdamState, Tensor, Pose]],
) -> Pose:
    """Steps 3-4 of the module docstring for one frame (steps 1-2: :class:`Frame`); returns the
    kept pose (its state carried on). ``step``: :func:`adam_step`, compiled or not."""
    p, t = frame.problem, frame.t
    variables = (h_enc.clone(), frame.state.root_velocity.clone())
    adam, rate = (
        AdamState.start(variables),
        torch.tensor(lr, dtype=h_enc.dtype, device=h_enc.device),
    )
    log.active[t], log.collisions[t] = len(frame.pairs), len(frame.collisions)
    inputs = frame.inputs()
    redetect = frame.redetect_every if frame.uses_int else 0
    for n in range(iterations):
        if redetect and n and n % redetect == 0:
            with torch.no_grad():
                current = decode(
                    p.model,
                    constants,
                    frame.state,
                    frame.gates,
                    frame.base,
                    *variables,
                    p.rest_vertices,
                    p.skin_weights_t,
                )
            frame.detect(skinned(current))
            inputs = frame.inputs()
        variables, adam, values, pose = step(
            p.model, p.weights, p.blend, p.cone, constants, inputs, variables, adam, rate
        )
        log.record(t, n, values, pose)
    # the same step again for the terms at the final values (its update unused): one compiled graph
    _, _, values, final = step(
        p.model, p.weights, p.blend, p.cone, constants, inputs, variables, adam, rate
    )
    log.record(t, iterations, values, final)
    return Pose(final.rotations, final.state, final.positions, None)


def eso_throughput(
    model: GeometryConditionedRNN,
    motion: Motion,
    target: Any,
    frames: int = 10,
    iterations: int = 30,
    interpenetration: InterpenetrationEnergy | None = None,
    contacts: Any = None,
    redetect_every: int = 0,
    compile: bool = False,
) -> dict[str, float]:
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
    clip = motion.copy(
        rotations=motion.rotations[:frames], root_positions=motion.root_positions[:frames]
    )
    src = eso_source(clip, target, rest_aligned=model.residual)  # as the contact method prepares it
    warm_up = src.quantities._replace(
        **{k: v[:1] for k, v in src.quantities._asdict().items() if k != "height"}
    )
    # first-call costs (lazy imports in torch.optim; the compilation) not timed
    encoder_space_optimization(
        model,
        src.features[:, :1],
        target,
        warm_up,
        src.foot_contacts[:1],
        src.leg_ratio,
        contacts=[contact_pairs_at(contacts, 0)],
        interpenetration=interpenetration,
        iterations=2,
        compile=compile,
    )
    result = encoder_space_optimization(
        model,
        src.features,
        target,
        src.quantities,
        src.foot_contacts,
        src.leg_ratio,
        contacts=contacts,
        interpenetration=interpenetration,
        iterations=iterations,
        redetect_every=redetect_every,
        compile=compile,
    )
    return {
        "frames": float(frames),
        "iterations": float(iterations),
        "vertices": float(len(target.rest_vertices)),
        "seconds": result.seconds,
        "frames_per_second": result.frames_per_second,
        "colliding_pairs": float(result.colliding_pairs.float().mean()),
    }
