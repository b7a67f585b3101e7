"""One frame's ESO problem, fixed before its steps (steps 1-2 of :mod:`.optimise`): the initial
output decoded from the carried state, the reachable contact pairs, the joints the hands touch, the
colliding triangle pairs, and the tensors every step reads (:class:`FrameInputs`), with the
constants shared by every frame (:class:`Problem`, :class:`Constants`)."""

from __future__ import annotations

import os
from typing import Any, NamedTuple

import numpy as np
import torch

from ...core.measures import foot_rest_heights
from ...core.quantities import MotionQuantities
from ...core.skeleton import J
from ...core.skinning import linear_blend_skinning
from ...geometry.penetration import PADDING_PAIR, InterpenetrationEnergy, PairPlan
from ...losses.contact import ContactEnergyWeights
from ...models.georet import (
    DecoderGates,
    DecoderState,
    GeometryConditionedRNN,
    ResidualBase,
    TargetContext,
)

Tensor = torch.Tensor

__all__ = [
    "Constants",
    "DETECTION_WORKERS",
    "Frame",
    "FrameInputs",
    "J_COUNT",
    "Pose",
    "Problem",
    "contact_pairs_at",
    "decode",
    "reachable_pairs",
    "reached_joints",
    "skinned",
]

HAND_JOINTS: tuple[int, ...] = (J["LeftHand"], J["RightHand"])
J_COUNT = len(J)


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


class Pose(NamedTuple):
    rotations: Tensor  # (1, 22, 4)
    state: DecoderState  # after frame t: its root_position is r_t, its root_velocity o_t
    positions: Tensor  # (1, 22, 3) global
    vertices: (
        Tensor | None
    )  # (1, U, 3): the U vertices skinned (FrameInputs.rest_vertices posed), or None


def skinned(pose: Pose) -> Tensor:
    """``(U, 3)`` the skinned vertices of a pose decoded with vertices (the initial output and a
    re-detection decode the whole mesh)."""
    if pose.vertices is None:
        raise ValueError("the pose was decoded without vertices")
    return pose.vertices[0]


class Constants(NamedTuple):
    """The tensors every frame's energy shares (scalars as 0-d tensors, so a compiled energy does
    not specialise on one character's height)."""

    context: TargetContext
    rest_joints: Tensor  # (22, 3)
    ground_heights: Tensor  # (4,)
    height: Tensor  # () h_B
    source_height: Tensor  # () h_A
    leg_ratio: Tensor  # ()


class FrameInputs(NamedTuple):
    """One frame's fixed inputs of ``Efull(t)``, as tensors (:meth:`Frame.inputs`): built once
    per frame (and after each re-detection), read by every step's :func:`frame_terms`."""

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


#: threads detecting colliding triangles (ESO's own steps run on one thread)
DETECTION_WORKERS = min(2, os.cpu_count() or 1)

#: the fewest contact pairs and colliding pairs a compiled step sees (padding with zero weight):
#: ``torch.compile`` specialises sizes 0 and 1, so smaller counts would compile again
_COMPILED_MIN = 2


def decode(
    model: GeometryConditionedRNN,
    constants: Constants,
    state: DecoderState,
    gates: DecoderGates,
    base: ResidualBase | None,
    h_enc: Tensor,
    o_prev: Tensor,
    rest_vertices: Tensor,
    skin_weights: Tensor,
) -> Pose:
    """Decode frame ``t`` from ``h^enc_t`` with ``o_(t−1)`` swapped into ``state`` (``gates``: its
    :meth:`~GeometryConditionedRNN.decoder_gates`), then FK and the LBS of the given ``(U, 3)``
    rest vertices (none when ``U = 0``). A ``lower_body_from_base`` model keeps the carried
    ``o_(t−1)`` (ESO's update of it is then zero: no gradient reaches it)."""
    if model.lower_body_from_base:  # the root path is the base's: o_(t−1) is not a variable
        o_prev = state.root_velocity
    rot, _, new_state = model.decode_step(
        h_enc, state._replace(root_velocity=o_prev), constants.context, base, gates
    )
    pos = new_state.local_positions + new_state.root_position[:, None]  # Eq. 18
    verts = None
    if rest_vertices.shape[0]:
        verts = linear_blend_skinning(
            rest_vertices, skin_weights, constants.rest_joints, new_state.global_rotations, pos
        )
    return Pose(rot, new_state, pos, verts)


class Frame:
    """The fixed data of one frame's ESO problem: its state, contacts, held joints, colliding
    pairs."""

    def __init__(
        self,
        t: int,
        problem: Problem,
        constants: Constants,
        state: DecoderState,
        h_enc: Tensor,
        previous: Pose | None,
        redetect_every: int,
        padded: bool,
    ):
        p = problem
        self.t, self.problem = t, p
        self.state = state
        self.base = p.base.frame(t)
        self.redetect_every, self.padded = redetect_every, padded
        with torch.no_grad():
            self.gates = p.model.decoder_gates(state, constants.context)
            self.initial = decode(
                p.model,
                constants,
                state,
                self.gates,
                self.base,
                h_enc,
                state.root_velocity,
                p.rest_vertices,
                p.skin_weights_t,
            )
        self.previous = (previous or self.initial).positions  # (1, 22, 3); frame t's own at t = 0
        pairs = p.contacts_at(t) if p.weights.j2j_weight > 0 else np.zeros((0, 2), np.int64)
        self.pairs = reachable_pairs(pairs, skinned(self.initial), p.reach) if len(pairs) else pairs
        self.reached = reached_joints(self.pairs, p.skin_weights) if p.weights.hold > 0 else []
        self.collisions = np.zeros((0, 2), np.int64)
        self.uses_int = p.interpenetration is not None and p.weights.int_weight > 0
        if self.uses_int:
            self.detect(skinned(self.initial))

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

    def inputs(self) -> FrameInputs:
        """This frame's :class:`FrameInputs` for the current pairs. When ``padded`` (a compiled
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
                collisions = np.concatenate(
                    [collisions, np.tile([PADDING_PAIR], (_COMPILED_MIN, 1))]
                )
        ids = self.mesh_vertices(pairs, collisions if uses_int else collisions[:0])
        where = np.full(nv, -1, np.int64)
        where[ids] = np.arange(len(ids))
        index = torch.as_tensor(ids, device=device)
        hold = torch.zeros(J_COUNT, dtype=dtype, device=device)
        hold[list(self.reached)] = 1.0
        eint = None
        if uses_int:
            eint = p.eint().plan(
                [self.collisions],
                vertex_index=where,
                min_pairs=_COMPILED_MIN if self.padded else 0,
                device=device,
            )
        src, t = p.source, self.t
        contact = torch.as_tensor(p.foot_contacts[t], device=device).to(dtype)
        return _fresh(
            FrameInputs(
                self.state,
                self.gates,
                self.base,
                p.rest_vertices[index],
                p.skin_weights_t[index],
                torch.as_tensor(where[pairs], device=device),
                torch.as_tensor(mask, dtype=dtype, device=device),
                skinned(self.initial)[index],
                hold,
                self.initial.positions[0],
                eint,
                self.previous,
                torch.stack((src.positions[max(t - 1, 0)], src.positions[t]))[None],
                src.rotations[t][None],
                src.root_velocity[t - 1][None] if t > 0 else src.root_velocity.new_zeros(1, 3),
                torch.stack((contact, contact))[None],
            )
        )


def _fresh(inputs: Any) -> Any:
    """Every tensor of a (nested) named tuple as its own contiguous copy: a compiled step guards
    on strides and storage offsets, which views of the clip's tensors would change every frame."""
    if isinstance(inputs, Tensor):
        return inputs.detach().clone(memory_format=torch.contiguous_format)
    if isinstance(inputs, tuple):
        return type(inputs)(*(_fresh(x) for x in inputs))
    return inputs


class Problem:
    """Constants shared by every frame: the model, target, source and settings (on the model's
    device)."""

    def __init__(
        self,
        model: GeometryConditionedRNN,
        target: Any,
        source: MotionQuantities,
        leg_ratio: float,
        foot_contacts: np.ndarray,
        contacts: Any,
        interpenetration: InterpenetrationEnergy | None,
        weights: ContactEnergyWeights,
        reach: float,
        blend: float,
    ):
        weight = model.rotation_head.weight
        as_model = lambda a: torch.as_tensor(a, dtype=weight.dtype, device=weight.device)  # noqa: E731
        self.model, self.weights, self.reach, self.blend = (
            model,
            weights,
            float(reach),
            float(blend),
        )
        self.offsets = as_model(target.skeleton.offsets)
        self.rest_joints = as_model(target.skeleton.rest_positions())
        self.rest_vertices = as_model(np.asarray(target.rest_vertices))
        self.skin_weights = np.asarray(target.weights)
        self.skin_weights_t = as_model(self.skin_weights)
        self.height = float(target.height)
        self.ground_heights = as_model(foot_rest_heights(target.skeleton))
        self.source = MotionQuantities(
            as_model(source.rotations),
            as_model(source.root_velocity),
            as_model(source.positions),
            float(source.height),
        )
        self.leg_ratio = float(leg_ratio)
        #: what a residual network corrects (Eweak's targets θ^A, o^(A→B)); ignored by the paper's
        #: network
        self.base = ResidualBase(
            self.source.rotations[None], self.leg_ratio * self.source.root_velocity[None]
        )
        self.foot_contacts = np.asarray(foot_contacts, dtype=bool)
        self.contacts = contacts
        self.interpenetration = interpenetration
        self.cone = dict(interpenetration.cone) if interpenetration is not None else {}

    def constants(self, context: TargetContext) -> Constants:
        scalar = lambda x: torch.tensor(x, dtype=self.offsets.dtype, device=self.offsets.device)  # noqa: E731
        return Constants(
            context,
            self.rest_joints,
            self.ground_heights,
            scalar(self.height),
            scalar(self.source.height),
            scalar(self.leg_ratio),
        )

    def contacts_at(self, t: int) -> np.ndarray:
        return contact_pairs_at(self.contacts, t)

    def eint(self) -> InterpenetrationEnergy:
        """The target's Eint (only asked for when it is used)."""
        if self.interpenetration is None:
            raise ValueError("ESO was given no InterpenetrationEnergy")
        return self.interpenetration


def contact_pairs_at(contacts: Any, t: int) -> np.ndarray:
    """Frame ``t``'s ``(n, 2)`` contact vertex pairs of ``contacts`` (see
    :func:`encoder_space_optimization`: a ``SelfContacts``, a sequence of pair arrays, or
    ``None``)."""
    if contacts is None:
        return np.zeros((0, 2), np.int64)
    pairs = contacts.at(t) if hasattr(contacts, "at") else contacts[t]
    return np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
