"""Contact-aware energies (Villegas, Ceylan, Hertzmann, Yang, Saito, ICCV 2021, Sec. 3.1, App. B.1).

Every term is a small differentiable function on plain tensors, batched over leading dims, so
the training code, encoder-space optimisation (:mod:`retarget_lib.methods.eso`) and notebook 07
share them::

    Efull  = Egeo + Eskel                                   (Eq. 1)
    Egeo   = λ Ej2j + β Eint + γ Efoot                      (Eq. 2)
    Ej2j   = 1/|V| Σ_(i,j) ‖v_i − v_j‖₂                     (Eq. 3)  self_contact_energy
    Eint   = Tzionas et al.'s cone penalty                  (Eq. 4)
    retarget_lib.geometry.penetration Efoot  = Σ_(j∈C) (‖ġ_j‖² + (g_j^y − ḡ_j^y)²) / h_B      (Eq.
    6)  foot_contact_energy Eskel  = Eweak + ω Eee                                  (Eq. 7)
    Eweak  = ρ Σ_j ‖θ^B_j − θ^A_j‖² + ‖o^B − o^(A→B)‖²      (Eq. 8)  weak_energy
    Eee    = Σ_(j∈ee) ‖ġ^B_j / h_B − ġ^A_j / h_A‖²          (Eq. 9)  end_effector_energy

Conventions and readings (the paper leaves them open; decided here):

* **Units.** Metres; velocities are per *frame* (``g_t − g_(t−1)``), not per second. Heights
  ``h`` are the NKN/TDCN character height :meth:`~retarget_lib.core.skeleton.Skeleton.height`.
* **Eq. 3** averages the Euclidean *norm* ``‖v_i − v_j‖₂`` (not its square), as printed: two
  vertices 3 cm apart give ``Ej2j = 0.03``.
* **Velocities in Eqs. 6 and 9** are backward differences; the first frame of a clip has zero
  velocity (:func:`~retarget_lib.core.quantities.frame_velocities`), so there only Efoot's height
  term acts. Clip-level energies are the mean of the per-frame energies ``E(t)`` over frames
  (Eq. 1 is per frame); ``*_per_frame`` variants return ``(..., T)``.
* **Efoot's ground.** ``ḡ_j^y`` is the joint's rest (T-pose) height
  (:func:`~retarget_lib.core.measures.foot_rest_heights`): "we get the heel height from
  reference pose ... so that ground height of zero corresponds to contact" (Sec. 3.1.1).
* **Eq. 8.** ``θ`` are 3×3 rotation matrices (the paper's ``R^(9J)`` representation), so
  ``‖θ^B_j − θ^A_j‖²`` is the squared Frobenius norm: a 90° difference gives ``4``. Only the
  rotation sum is weighted by ``ρ``, as printed. ``o`` is the root velocity
  (:func:`~retarget_lib.core.quantities.forward_root_velocity`: the displacement from frame ``t``
  to ``t + 1``, matching the network's Eq. 18), ``o^(A→B) = (h_legs_B / h_legs_A) o^A`` with
  :meth:`~retarget_lib.core.skeleton.Skeleton.leg_length`.
* **End effectors** (Eq. 9, "hands and feet"): ``LeftHand, RightHand, LeftFoot, RightFoot``
  (:data:`END_EFFECTORS`).
* **ESO's relaxed self-contact term** (App. B.1, "aggregating 0.7 of the distance from the
  initial vertex position and 0.3 of the target contact vertex position"): each contact vertex is
  pulled towards the point ``0.7 · (its initial position) + 0.3 · (its partner's initial
  position)`` (:func:`eso_self_contact_energy`). The other reading, a weighted sum of the two
  *distances* ``0.7‖v − v⁰‖ + 0.3‖v − v_partner‖``, has its minimum at ``v = v⁰`` (the heavier
  point of a weighted two-point Fermat problem), i.e. it would never move a hand; with squared
  distances it has the same minimiser as ours. Per frame the gap therefore closes smoothly by a
  fixed fraction, and since ESO carries each optimised frame into the next one's initial output,
  contacts close over a few frames instead of snapping.

:class:`ContactEnergyWeights` holds ``λ, β, γ, ρ, ω`` (App. B.1 training values), the relaxed ESO
values (:meth:`ContactEnergyWeights.eso`) and the switches of the Table 3 ablation rows
(:meth:`ContactEnergyWeights.row`).

**Length unit of the weighted terms.** The single-term functions take and return metres. The
paper does not state the unit its weights assume, but it quotes every length in centimetres (3 cm,
1 cm, 0.2 cm, 15 cm, "138 cm"), as Mixamo data usually are, so we read the weights as tuned on
centimetre-valued terms. That matters because the terms scale differently with the unit:
Ej2j and Efoot like a length, Eint and Eweak's root term like a squared length, Eee and the
rotation term not at all. In metres, ``λ Ej2j`` would be 100 times and ``β Eint`` 10,000 times
weaker against ``ρ Σ‖Δθ‖²`` than the paper intends. So the combining functions
(:func:`skeleton_energy`, :func:`geometry_energy`, :func:`full_energy`, and ESO) express lengths
in ``ContactEnergyWeights.length_unit`` metres (default 0.01: centimetres) before weighting, i.e.
divide each term by ``length_unit`` to the power :data:`LENGTH_POWER`. ``length_unit=1`` weights
the metre values as they are.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
import torch

from ..core.quantities import FOOT_CONTACT_IDS, MotionQuantities, frame_velocities
from ..core.rotations import quat_to_matrix
from ..core.skeleton import J

Tensor = torch.Tensor
Scalar = float | Tensor

__all__ = [
    "END_EFFECTORS",
    "END_EFFECTOR_IDS",
    "LENGTH_POWER",
    "TABLE3_ROWS",
    "ContactEnergyWeights",
    "ESO_FOOT_WEIGHT",
    "self_contact_energy",
    "eso_self_contact_energy",
    "reach_hold_energy",
    "foot_contact_energy",
    "foot_contact_energy_per_frame",
    "weak_energy",
    "end_effector_energy",
    "end_effector_energy_per_frame",
    "skeleton_energy",
    "geometry_energy",
    "full_energy",
]

#: the end effectors of Eq. 9 ("hands and feet")
END_EFFECTORS: tuple[str, ...] = ("LeftHand", "RightHand", "LeftFoot", "RightFoot")
END_EFFECTOR_IDS: tuple[int, ...] = tuple(J[n] for n in END_EFFECTORS)


# ----------------------------------------------------------------------------- weights
#: power of length of each weighted term (``"weak"`` = its root-velocity part; rotations and Eee
#: are unitless): a term in metres is divided by ``length_unit ** power`` before weighting
LENGTH_POWER: dict[str, int] = {"j2j": 1, "hold": 1, "int": 2, "foot": 1, "weak": 2, "ee": 0}

#: ``γ`` in training and, unchanged, in ESO (App. B.1 relaxes ``ρ, β, λ`` and leaves ``γ`` at its
#: training value; :meth:`ContactEnergyWeights.relaxed` keeps the caller's). In
#: centimetres, Eq. 6 charges a standing foot that slips 1 cm in a frame ``1 cm² / h_B`` (about
#: 0.006 on a 1.7 m body), so at 0.1 the term is ~1e5 times weaker than 1 cm of relaxed contact
#: (``λ = 100``) and ESO slides planted feet to meet hand contacts (real table: foot skating 6.4 %
#: of height a second against copy's 4.6). Measured with ``γ = 1000`` (issue 24's notes): skating
#: 1.6, hand gap and jitter lower, foot contact accuracy on Table 1 0.58 -> 0.93 for the paper-form
#: row; but a character's own motion moves 3.5 % of its height instead of 1.1 % (held feet make the
#: root lag, 5 % by the end of a jumping clip; the same at ``γ = 100``), and Table 1's default row
#: penetrates 26 % more. The paper's value stays until a foot term that keeps the source's own
#: foot motion is found.
ESO_FOOT_WEIGHT = 0.1

#: Table 3 (App. A) rows -> switches; "Efull + ESO" is "Efull" trained, then
#: :meth:`ContactEnergyWeights.eso` at test time
TABLE3_ROWS: dict[str, dict[str, bool]] = {
    "Eskel": dict(use_foot=False, use_int=False, use_j2j=False),
    "Eskel+Efoot": dict(use_foot=True, use_int=False, use_j2j=False),
    "Eskel+Efoot+Eint w/o w": dict(
        use_foot=True, use_int=True, use_j2j=False, geodesic_weights=False
    ),
    "Eskel+Efoot+Eint": dict(use_foot=True, use_int=True, use_j2j=False, geodesic_weights=True),
    "Efull": dict(use_foot=True, use_int=True, use_j2j=True, geodesic_weights=True),
}


#: :attr:`ContactEnergyWeights.ee_scale` values: Eq. 9 as printed, or on Eweak's leg-ratio scale.
EE_SCALES = ("height", "legs")


@dataclass(frozen=True)
class ContactEnergyWeights:
    """Weights of Eqs. 1-9 and the Table 3 switches.

    Attributes:
        lambda_j2j: ``λ``, self-contact weight (Eq. 2; training 1000, ESO 100).
        beta_int: ``β``, interpenetration weight (Eq. 2; training 100, ESO 1).
        gamma_foot: ``γ``, foot-contact weight (Eq. 2; 0.1). App. B.1 ramps it in during
            training by ``epoch / epochs``: use :meth:`with_foot_ramp`.
        rho: ``ρ``, rotation weight inside Eweak (Eq. 8; training 1000, ESO 10).
        omega: ``ω``, end-effector weight (Eq. 7; 1000).
        hold: ESO only (App. B.1): weight of "a distance penalty for the joints the hands reach
            during contact to stay close to their original positions" (:func:`reach_hold_energy`).
            The paper gives no value; :meth:`eso` uses ``λ``'s relaxed value (100), so 1 cm of
            drift of a touched joint costs as much as 1 cm of (relaxed) contact error.
        use_foot, use_int, use_j2j: include Efoot, Eint, Ej2j (Table 3 rows).
        geodesic_weights: build Eint with the geodesic pair weights ``w_r,i`` of Eq. 5 (pass it
            to ``penetration.InterpenetrationEnergy(..., geodesic_weights=...)``); ``False`` is
            the "Eint without w_r,i" row.
        length_unit: metres per length unit in which the weighted terms are measured (0.01 =
            centimetres, our reading of the paper's; see the module docstring and
            :meth:`in_units`).
        ee_scale: how Eee scales the source's end-effector velocities to the target (Eq. 9):
            ``"height"`` as printed (``ġ^A / h_A`` against ``ġ^B / h_B``), or ``"legs"``, the
            scale Eweak gives the root (Eq. 8: ``ġ^B`` against ``(h_legs_B / h_legs_A) ġ^A``,
            both divided by ``h_B``), so the two terms ask for one speed
            (:meth:`ee_source_height`).
    """

    lambda_j2j: float = 1000.0
    beta_int: float = 100.0
    gamma_foot: float = ESO_FOOT_WEIGHT
    rho: float = 1000.0
    omega: float = 1000.0
    hold: float = 0.0
    use_foot: bool = True
    use_int: bool = True
    use_j2j: bool = True
    geodesic_weights: bool = True
    length_unit: float = 0.01
    ee_scale: str = "height"

    def __post_init__(self) -> None:
        if self.length_unit <= 0:
            raise ValueError(f"length_unit must be positive, got {self.length_unit}")
        if self.ee_scale not in EE_SCALES:
            raise ValueError(f"ee_scale must be one of {EE_SCALES}, got {self.ee_scale!r}")

    def ee_source_height(self, height_b: Scalar, height_a: Scalar, leg_ratio: Scalar) -> Scalar:
        """The height Eq. 9 divides the source's velocities by: ``h_A`` (``ee_scale="height"``)
        or ``h_B / leg_ratio`` (``"legs"``, so that ``ġ^A / that = leg_ratio · ġ^A / h_B``)."""
        return height_a if self.ee_scale == "height" else height_b / leg_ratio

    def in_units(self, term: str, value: Tensor) -> Tensor:
        """A term computed in metres, expressed in ``length_unit`` (:data:`LENGTH_POWER`)."""
        return value / self.length_unit ** LENGTH_POWER[term]

    @classmethod
    def eso(cls, rho: float | None = None, beta_int: float | None = None) -> ContactEnergyWeights:
        """ESO's weights: App. B.1's relaxed test-time values (:meth:`relaxed`), with ``rho`` and
        ``beta_int`` in place of its ``ρ = 10`` and ``β = 1`` where given."""
        w = cls().relaxed()
        return replace(
            w,
            rho=w.rho if rho is None else float(rho),
            beta_int=w.beta_int if beta_int is None else float(beta_int),
        )

    @classmethod
    def from_eso_config(cls, section: Mapping[str, Any]) -> ContactEnergyWeights:
        """ESO's weights for a checkpoint config's ``eso`` section: its ``rho`` and ``beta_int``
        where it sets them (see ``configs/contact_residual.yaml``), else App. B.1's (:meth:`eso`).
        """
        return cls.eso(rho=section.get("rho"), beta_int=section.get("beta_int"))

    @classmethod
    def row(cls, name: str) -> ContactEnergyWeights:
        """Training weights for a Table 3 row (:data:`TABLE3_ROWS`).

        Raises:
            ValueError: unknown row name (the message lists the rows).
        """
        if name not in TABLE3_ROWS:
            raise ValueError(f"unknown Table 3 row {name!r}; rows: {list(TABLE3_ROWS)}")
        return cls(**TABLE3_ROWS[name])

    def relaxed(self) -> ContactEnergyWeights:
        """These weights with ESO's relaxed ``ρ = 10, β = 1, λ = 100`` and ``hold = 100`` (App.
        B.1); ``γ`` and the switches kept."""
        return replace(self, rho=10.0, beta_int=1.0, lambda_j2j=100.0, hold=100.0)

    def with_foot_ramp(self, epoch: int, epochs: int) -> ContactEnergyWeights:
        """``γ · epoch / epochs`` (App. B.1: "gradually introduce the foot contact loss")."""
        if epochs <= 0 or not 0 <= epoch <= epochs:
            raise ValueError(f"need 0 <= epoch <= epochs and epochs > 0, got {epoch}/{epochs}")
        return replace(self, gamma_foot=self.gamma_foot * epoch / epochs)

    @property
    def j2j_weight(self) -> float:
        """``λ`` if Ej2j is used, else 0."""
        return self.lambda_j2j if self.use_j2j else 0.0

    @property
    def int_weight(self) -> float:
        """``β`` if Eint is used, else 0."""
        return self.beta_int if self.use_int else 0.0

    @property
    def foot_weight(self) -> float:
        """``γ`` if Efoot is used, else 0."""
        return self.gamma_foot if self.use_foot else 0.0


# ----------------------------------------------------------------------------- helpers


def _batch_scalar(value: Scalar, like: Tensor, trailing: int) -> Tensor:
    """A float or ``(...)`` tensor as a tensor broadcasting against ``(..., *trailing ones)``."""
    t = torch.as_tensor(value, dtype=like.dtype, device=like.device)
    return t.reshape(t.shape + (1,) * trailing)


# ----------------------------------------------------------------------------- geometry terms
def _pair_vertices(vertices: Tensor, pairs: Tensor) -> tuple[Tensor, Tensor]:
    """Gather both ends of each pair: ``(..., K, 3)`` twice."""
    pairs = torch.as_tensor(pairs, dtype=torch.long, device=vertices.device)
    if pairs.shape[-1:] != (2,):
        raise ValueError(f"pairs must be (K, 2) or (..., K, 2), got {tuple(pairs.shape)}")
    if pairs.dim() == 2:
        return vertices[..., pairs[:, 0], :], vertices[..., pairs[:, 1], :]
    lead = torch.broadcast_shapes(vertices.shape[:-2], pairs.shape[:-2])
    verts = vertices.expand(lead + vertices.shape[-2:])
    idx = pairs.expand(lead + pairs.shape[-2:])
    take = lambda k: torch.gather(verts, -2, idx[..., k : k + 1].expand(idx.shape[:-1] + (3,)))  # noqa: E731
    return take(0), take(1)


def _masked_mean(values: Tensor, mask: Tensor | None) -> Tensor:
    """Mean over the last axis, counting only ``mask`` entries; 0 where none counts."""
    if mask is None:
        if values.shape[-1] == 0:
            return values.sum(-1)
        return values.mean(-1)
    mask = torch.as_tensor(mask, dtype=values.dtype, device=values.device)
    return (values * mask).sum(-1) / mask.sum(-1).clamp_min(1.0)


def self_contact_energy(
    vertices: Tensor, pairs: Tensor | np.ndarray, mask: Tensor | None = None
) -> Tensor:
    """``Ej2j``: mean distance between vertices that should touch (Eq. 3, the norm as printed).

    Args:
        vertices: ``(..., V, 3)`` posed output vertices (metres).
        pairs: ``(K, 2)`` vertex index pairs shared by every batch element, or ``(..., K, 2)``
            per element (pad with any valid index and set ``mask``).
        mask: optional ``(..., K)`` bool, the pairs that count.

    Returns:
        ``(...)`` metres; 0 when there are no (unmasked) pairs.
    """
    vi, vj = _pair_vertices(vertices, pairs)
    return _masked_mean((vi - vj).norm(dim=-1), mask)


def eso_self_contact_energy(
    vertices: Tensor,
    pairs: Tensor | np.ndarray,
    initial_vertices: Tensor,
    blend: float = 0.3,
    mask: Tensor | None = None,
) -> Tensor:
    """ESO's relaxed self-contact term (App. B.1), our reading explained in the module docstring.

    For a pair ``(i, j)`` with initial (pre-ESO) positions ``v⁰``, vertex ``i`` is pulled towards
    ``(1 − blend) v⁰_i + blend v⁰_j`` and ``j`` towards ``(1 − blend) v⁰_j + blend v⁰_i``::

        E = 1/(2K) Σ_(i,j) ‖v_i − ((1−b) v⁰_i + b v⁰_j)‖ + ‖v_j − ((1−b) v⁰_j + b v⁰_i)‖

    At ``v = v⁰`` this equals ``blend · Ej2j(v⁰)``; with ``blend = 1`` it starts at Eq. 3's value.

    Args:
        vertices: ``(..., V, 3)`` current vertices (metres).
        pairs: ``(K, 2)`` vertex index pairs.
        initial_vertices: ``(..., V, 3)`` the network's initial output (constants).
        blend: the fraction of the gap to close (paper: 0.3).
        mask: optional ``(K,)`` the pairs that count (1) and padding (0).

    Returns:
        ``(...)`` metres; 0 for no (unmasked) pairs.
    """
    if not 0.0 <= blend <= 1.0:
        raise ValueError(f"blend must lie in [0, 1], got {blend}")
    vi, vj = _pair_vertices(vertices, pairs)
    ui, uj = _pair_vertices(initial_vertices.detach(), pairs)
    gi, gj = torch.lerp(ui, uj, blend), torch.lerp(uj, ui, blend)
    dist = torch.cat(((vi - gi).norm(dim=-1), (vj - gj).norm(dim=-1)), dim=-1)
    return _masked_mean(dist, None if mask is None else torch.cat((mask, mask), dim=-1))


def reach_hold_energy(
    positions: Tensor, initial_positions: Tensor, joints: Sequence[int] | Tensor
) -> Tensor:
    """Mean distance of the joints the hands touch from their initial positions (App. B.1).

    Args:
        positions: ``(..., 22, 3)`` current global joint positions (metres).
        initial_positions: ``(..., 22, 3)`` the network's initial output (constants).
        joints: joint ids to hold (empty → 0), or a ``(22,)`` mask tensor (1 = held).

    Returns:
        ``(...)`` metres.
    """
    if isinstance(joints, Tensor):
        drift = (positions - initial_positions.detach()).norm(dim=-1)
        return _masked_mean(drift, joints)
    idx = list(joints)
    drift = (positions[..., idx, :] - initial_positions.detach()[..., idx, :]).norm(dim=-1)
    return _masked_mean(drift, None)


def foot_contact_energy_per_frame(
    positions: Tensor,
    contacts: Tensor | np.ndarray,
    ground_heights: Tensor | np.ndarray,
    height: Scalar,
) -> Tensor:
    """``Efoot(t)`` for every frame (Eq. 6).

    ``Σ_(j in contact at t) (‖g_t − g_(t−1)‖² + (g_t^y − ground_j)²) / h_B``, first-frame velocity
    0.

    Args:
        positions: ``(..., T, 22, 3)`` global joint positions (metres).
        contacts: ``(..., T, 4)`` bool, per :data:`retarget_lib.core.skeleton.FOOT_CONTACT_JOINTS`.
        ground_heights: ``(4,)`` the joints' rest heights
            (:func:`~retarget_lib.core.measures.foot_rest_heights`).
        height: ``h_B`` (metres), float or ``(...)``.

    Returns:
        ``(..., T)`` metres (squared metres over metres).
    """
    contacts = torch.as_tensor(contacts, device=positions.device)
    if contacts.shape[-1:] != (4,) or contacts.shape[-2:-1] != positions.shape[-3:-2]:
        raise ValueError(
            f"contacts must be (..., T, 4) for positions {tuple(positions.shape)}, "
            f"got {tuple(contacts.shape)}"
        )
    feet = positions[..., list(FOOT_CONTACT_IDS), :]  # (..., T, 4, 3)
    ground = torch.as_tensor(ground_heights, dtype=positions.dtype, device=positions.device)
    speed2 = frame_velocities(feet).pow(2).sum(-1)
    lift2 = (feet[..., 1] - ground).pow(2)
    per_joint = (speed2 + lift2) * contacts.to(positions.dtype)
    return per_joint.sum(-1) / _batch_scalar(height, positions, 1)


def foot_contact_energy(
    positions: Tensor,
    contacts: Tensor | np.ndarray,
    ground_heights: Tensor | np.ndarray,
    height: Scalar,
) -> Tensor:
    """``Efoot`` of a clip: mean over frames of :func:`foot_contact_energy_per_frame` (Eq. 6).

    Returns:
        ``(...)``.
    """
    return foot_contact_energy_per_frame(positions, contacts, ground_heights, height).mean(-1)


# ----------------------------------------------------------------------------- skeleton terms
def weak_energy(
    rot_b: Tensor,
    rot_a: Tensor,
    root_vel_b: Tensor,
    root_vel_a: Tensor,
    leg_ratio: Scalar,
    rho: float,
) -> Tensor:
    """``Eweak = ρ Σ_j ‖θ^B_j − θ^A_j‖²_F + ‖o^B − leg_ratio · o^A‖²`` (Eq. 8), per frame.

    Args:
        rot_b: ``(..., 22, 4)`` output local rotations, unit wxyz (compared as 3×3 matrices).
        rot_a: ``(..., 22, 4)`` source local rotations.
        root_vel_b: ``(..., 3)`` output root velocity ``o^B`` (metres per frame).
        root_vel_a: ``(..., 3)`` source root velocity ``o^A``.
        leg_ratio: ``h_legs_B / h_legs_A`` (:func:`~retarget_lib.core.quantities.leg_ratio`), float
            or ``(...)``.
        rho: ``ρ``.

    Returns:
        ``(...)``.
    """
    if rot_b.shape[-1] != 4 or rot_a.shape[-1] != 4:
        raise ValueError(
            f"rotations must be (..., J, 4) wxyz, got {tuple(rot_b.shape)}, {tuple(rot_a.shape)}"
        )
    rot_term = (quat_to_matrix(rot_b) - quat_to_matrix(rot_a)).pow(2).sum((-1, -2, -3))
    target_vel = _batch_scalar(leg_ratio, root_vel_b, 1) * root_vel_a
    return rho * rot_term + (root_vel_b - target_vel).pow(2).sum(-1)


def end_effector_energy_per_frame(
    pos_b: Tensor, pos_a: Tensor, height_b: Scalar, height_a: Scalar
) -> Tensor:
    """``Eee(t) = Σ_(j∈ee) ‖ġ^B_j / h_B − ġ^A_j / h_A‖²`` for every frame (Eq. 9).

    Args:
        pos_b: ``(..., T, 22, 3)`` output global joint positions (metres).
        pos_a: ``(..., T, 22, 3)`` source global joint positions.
        height_b, height_a: ``h_B``, ``h_A`` (metres), floats or ``(...)``.

    Returns:
        ``(..., T)`` (1/frame²); frame 0 is 0 (zero velocities).
    """
    ee = list(END_EFFECTOR_IDS)
    vel_b = frame_velocities(pos_b[..., ee, :]) / _batch_scalar(height_b, pos_b, 3)
    vel_a = frame_velocities(pos_a[..., ee, :]) / _batch_scalar(height_a, pos_b, 3)
    return (vel_b - vel_a).pow(2).sum((-1, -2))


def end_effector_energy(pos_b: Tensor, pos_a: Tensor, height_b: Scalar, height_a: Scalar) -> Tensor:
    """``Eee`` of a clip: mean over frames of :func:`end_effector_energy_per_frame` (Eq. 9).

    Returns:
        ``(...)``.
    """
    return end_effector_energy_per_frame(pos_b, pos_a, height_b, height_a).mean(-1)


# ----------------------------------------------------------------------------- combinations
def _with_total(terms: dict[str, Tensor]) -> dict[str, Tensor]:
    terms["total"] = sum(terms.values())
    return terms


def skeleton_energy(
    output: MotionQuantities,
    source: MotionQuantities,
    leg_ratio: Scalar,
    weights: ContactEnergyWeights,
) -> dict[str, Tensor]:
    """``Eskel = Eweak + ω Eee`` (Eq. 7) of a clip, each term averaged over frames.

    Args:
        output: :class:`~retarget_lib.core.quantities.MotionQuantities` of the retargeted motion
            (``B``), ``(..., T, ...)``.
        source: :class:`~retarget_lib.core.quantities.MotionQuantities` of the source motion
            (``A``), same frames.
        leg_ratio: ``h_legs_B / h_legs_A``, float or ``(...)``.
        weights: :class:`ContactEnergyWeights` (``ρ``, ``ω``).

    Returns:
        ``{"weak", "ee", "total"}``, each ``(...)``, weighted, lengths in ``weights.length_unit``
        (``"ee"`` is ``ω Eee``).
    """
    per_clip = torch.as_tensor(
        leg_ratio, dtype=output.root_velocity.dtype, device=output.root_velocity.device
    )
    ratio = (
        per_clip.unsqueeze(-1) if per_clip.dim() else per_clip
    )  # (...) -> (..., 1): broadcast over frames
    unit = weights.length_unit  # ‖Δo‖² in length_unit²: velocities divided by the unit
    weak = weak_energy(
        output.rotations,
        source.rotations,
        output.root_velocity / unit,
        source.root_velocity / unit,
        ratio,
        weights.rho,
    ).mean(-1)
    source_height = weights.ee_source_height(output.height, source.height, per_clip)
    ee = end_effector_energy(output.positions, source.positions, output.height, source_height)
    return _with_total({"weak": weak, "ee": weights.omega * ee})


def geometry_energy(
    vertices: Tensor,
    contact_pairs: Tensor | np.ndarray | None,
    positions: Tensor,
    foot_contacts: Tensor | np.ndarray,
    ground_heights: Tensor | np.ndarray,
    height: Scalar,
    weights: ContactEnergyWeights,
    interpenetration: Callable[[Tensor], Tensor] | None = None,
    contact_mask: Tensor | None = None,
) -> dict[str, Tensor]:
    """``Egeo = λ Ej2j + β Eint + γ Efoot`` (Eq. 2), switched terms left out.

    Ej2j and Eint are evaluated on ``vertices`` (App. B.1 samples one frame per sequence for
    them), Efoot on every frame of ``positions``.

    Args:
        vertices: ``(..., V, 3)`` posed output mesh (metres).
        contact_pairs: ``(K, 2)`` or ``(..., K, 2)`` target-mesh vertex pairs, or ``None``.
        positions: ``(..., T, 22, 3)`` output global joint positions.
        foot_contacts: ``(..., T, 4)`` bool
            (:data:`retarget_lib.core.skeleton.FOOT_CONTACT_JOINTS`).
        ground_heights: ``(4,)`` rest heights of those joints.
        height: ``h_B``.
        weights: :class:`ContactEnergyWeights`.
        interpenetration: ``vertices (..., V, 3) -> (...)`` Eint (Eq. 4), e.g. a
            ``penetration.InterpenetrationEnergy`` built with ``weights.geodesic_weights``;
            required when ``weights.use_int``.
        contact_mask: optional ``(..., K)`` bool for padded per-element pairs.

    Returns:
        dict of the used weighted terms among ``"j2j"``, ``"int"``, ``"foot"`` (lengths in
        ``weights.length_unit``), plus ``"total"``.
    """
    w = weights
    terms: dict[str, Tensor] = {}
    if w.use_j2j and contact_pairs is not None:
        terms["j2j"] = w.lambda_j2j * w.in_units(
            "j2j", self_contact_energy(vertices, contact_pairs, contact_mask)
        )
    if w.use_int:
        if interpenetration is None:
            raise ValueError("weights.use_int is set but no interpenetration energy was given")
        terms["int"] = w.beta_int * w.in_units("int", interpenetration(vertices))
    if w.use_foot:
        foot = foot_contact_energy(positions, foot_contacts, ground_heights, height)
        terms["foot"] = w.gamma_foot * w.in_units("foot", foot)
    if not terms:
        return {"total": positions.new_zeros(positions.shape[:-3])}
    return _with_total(terms)


def full_energy(
    output: MotionQuantities,
    source: MotionQuantities,
    vertices: Tensor,
    contact_pairs: Tensor | np.ndarray | None,
    foot_contacts: Tensor | np.ndarray,
    ground_heights: Tensor | np.ndarray,
    leg_ratio: Scalar,
    weights: ContactEnergyWeights,
    interpenetration: Callable[[Tensor], Tensor] | None = None,
    contact_mask: Tensor | None = None,
) -> dict[str, Tensor]:
    """``Efull = Egeo + Eskel`` (Eq. 1): every weighted term and ``"total"``, each ``(...)``.

    Args: see :func:`geometry_energy` and :func:`skeleton_energy` (``output.height`` is ``h_B``).

    Returns:
        ``{"weak", "ee", ["j2j"], ["int"], ["foot"], "total"}``.
    """
    skel = skeleton_energy(output, source, leg_ratio, weights)
    geo = geometry_energy(
        vertices,
        contact_pairs,
        output.positions,
        foot_contacts,
        ground_heights,
        output.height,
        weights,
        interpenetration,
        contact_mask,
    )
    skel.pop("total")
    geo.pop("total")
    return _with_total({**skel, **geo})
