"""TDCN loss functions (Kim, Park, Kwon, Han, Eurographics 2020, Sec. 4.2, Eqs. 6-23).

Every loss is a small differentiable function on plain tensors — no model objects — so that
notebook 03 can evaluate each term on hand-made motions and the trainer can combine them.

Notation (paper → here). ``A`` is the source character, ``B`` the target; a hat marks network
output. The cycle is ``x̂^B = G(x^A, s̄^B)`` (Eq. 4) and ``x̂^A = G(x̂^B, s̄^A)`` (Eq. 5).

============  =====================================================  ====================
paper         meaning                                                 tensor here
============  =====================================================  ====================
``p_t``       joint positions relative to the root (Eq. 1/3)         ``(B, T, J, 3)``
``q_t``       local joint rotations, unit wxyz quaternions            ``(B, T, J, 4)``
``r_t``       root (hips) position                                    ``(B, T, 3)``
``θ_t``       root joint's rotation (``q_t`` of joint 0)              ``(B, T, 4)``
``H(s̄)``      character height, :meth:`Skeleton.height`               ``(B,)`` or a float
``h``         discriminator scores, one per frame pair (patch GAN)    ``(B, ...)``
``E(q)``      rotation angle of ``q`` in ``[0, π]`` (radians)         :func:`quat_angle`
============  =====================================================  ====================

In shapes, ``B`` is the batch size; ``B^A``, ``B^B`` in Eqs. 19/20 are bone lengths.

Reductions
----------
The paper writes squared L2 norms ``‖·‖²₂`` and ``smoothL1(·)`` of whole sequences without saying
how they are reduced. By default every loss is a **mean over its elements** (batch × frames ×
joints × channels, exactly which is said in each docstring), so a weight ``λ`` means the same thing
for any clip length, batch size or joint count. ``reduction="per_sample"`` returns the ``(B,)``
per-sample means instead (their batch mean equals ``"mean"``, since every sample has the same
element count); :func:`adversarial_loss` uses that to pick Eq. 21's case per sample.

``reduction="frame_sum"`` is the authors' released code's reduction (``medialab-ku/
retargetting-tdcn``): **summed** over each frame's joints and channels, averaged over batch ×
frames. The paper's ``λ`` (Sec. 5) were tuned with it, and with the reconstruction and cycle
terms comparing **standardised** positions (z-scores with the training set's per-joint mean and
std; :class:`PositionScale`). Under per-element means in metres, a 22-joint reconstruction term
is about two orders of magnitude weaker against ``λh·Lh`` than in the authors' balance (measured
at initialisation on the synthetic data: ``Lc`` 0.61 against ``λh·Lh`` 15.9 with means in
metres; 123 against 15.9 with frame sums of z-scores), which is why the paper-form network, trained with the means,
does not even learn identity. ``loss.reduction: frame_sum`` and ``loss.standardize: true`` in a
config restore the authors' balance (``configs/tdcn_paper_code_scale.yaml``).

Two readings of the printed equations (decided here, argued in the docstrings):

* **Eq. 8** prints ``max(0, |E(q) − α|)``, which penalises angles *below* α as well; the text
  ("Any angle exceeding α is penalized") and the authors' code use ``max(0, E(q) − α)``.
  :func:`twist_loss` implements the intended hinge (``reading="literal"`` gives the printed one).
* **Eq. 21** prints ``(h^A)² + (1 − h^B)²`` inside ``min_G max_D`` (Eq. 6). Read as a min-max, G
  minimises ``(1 − h^B)²`` (fake scores → 1) and D pushes real scores up and fake scores away
  from 1; the bounded least-squares form of that game is standard LSGAN with labels real = 1,
  fake = 0: D minimises ``(h_real − 1)² + h_fake²``, G minimises ``(h_fake − 1)²``.

Baseline-height (TDCN Sec. 6 (iv): NKN + ``Lh`` with the *root offsets* normalised by height) is
the same maths as :func:`height_loss` — pass NKN's per-frame root offsets
``Δr_t = r_t − r_{t−1}`` as ``r_a``/``r_b_hat``; see that docstring. No separate function.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Literal, Mapping, NamedTuple, Sequence

import torch
import torch.nn.functional as F

from ..core.quantities import normalized_joint_displacements, normalized_root_distances
from ..core.rotations import quat_angle

Tensor = torch.Tensor
Reduction = Literal["mean", "per_sample", "frame_sum", "per_sample_frame_sum"]

__all__ = [
    "MotionTensors",
    "NonFiniteLossError",
    "PositionScale",
    "TDCNLossWeights",
    "TERM_WEIGHTS",
    "check_finite",
    "per_sample",
    "smooth_l1",
    "cycle_loss",
    "reconstruction_loss",
    "twist_penalty",
    "twist_loss",
    "height_loss",
    "adversarial_loss_generator",
    "adversarial_loss_discriminator",
    "adversarial_loss",
    "regularization_loss",
    "orientation_loss",
    "sigmoid_ce_generator_loss",
    "sigmoid_ce_discriminator_loss",
    "total_generator_loss",
]


# --------------------------------------------------------------------------------------------
# containers and helpers
# --------------------------------------------------------------------------------------------


class MotionTensors(NamedTuple):
    """A motion ``x_{1:T}`` as TDCN's losses see it (Sec. 3.1).

    Attributes:
        p: ``(B, T, J, 3)`` joint positions relative to the root (``f_FK``, Eq. 1/3).
        q: ``(B, T, J, 4)`` local joint rotations, wxyz (network output may be unnormalised).
        r: ``(B, T, 3)`` root positions.
    """

    p: Tensor
    q: Tensor
    r: Tensor


class PositionScale(NamedTuple):
    """Per-channel standardisation of positions, ``(x − mean) / std`` (the authors' z-scores).

    The authors' released code compares standardised local joint positions and root positions in
    its reconstruction and cycle terms (``get_normalized_data``: the training set's mean and std).
    Fitted once on training windows (:meth:`fit`); ``std`` is floored at ``min_std`` so that a
    channel that never moves (the root joint's local position is always 0) does not divide by 0.

    Attributes:
        p_mean, p_std: ``(J, 3)`` of root-relative joint positions, metres.
        r_mean, r_std: ``(3,)`` of root positions, metres.
    """

    p_mean: Tensor
    p_std: Tensor
    r_mean: Tensor
    r_std: Tensor

    @classmethod
    def fit(cls, p: Tensor, r: Tensor, min_std: float = 0.01) -> "PositionScale":
        """Fit on ``p (B, T, J, 3)`` and ``r (B, T, 3)``; ``min_std`` in metres (1 cm)."""
        _check_last("p", p, 3, 4)
        _check_last("r", r, 3, 3)
        p_flat, r_flat = p.reshape(-1, *p.shape[2:]), r.reshape(-1, 3)
        return cls(p_flat.mean(0), p_flat.std(0).clamp_min(min_std),
                   r_flat.mean(0), r_flat.std(0).clamp_min(min_std))

    def apply(self, x: MotionTensors) -> MotionTensors:
        """``x`` with ``p`` and ``r`` standardised (``q`` unchanged)."""
        return MotionTensors((x.p - self.p_mean) / self.p_std, x.q, (x.r - self.r_mean) / self.r_std)


class NonFiniteLossError(FloatingPointError):
    """A loss term (or its input) became NaN or infinite; the message names the term."""


def check_finite(name: str, tensor: Tensor) -> Tensor:
    """Raise :class:`NonFiniteLossError` naming ``name`` if ``tensor`` has a NaN or an inf.

    Training calls this on every loss term so that a diverging run stops with a message such as
    ``"loss term 'Lh' is not finite: 1 NaN, 0 inf of 1 values"`` rather than silently writing NaN
    weights.

    Args:
        name: the term's name, e.g. ``"Lh"``.
        tensor: any shape.

    Returns:
        ``tensor`` unchanged (so it can wrap an expression).
    """
    if not isinstance(tensor, Tensor):
        tensor = torch.as_tensor(tensor)
    if not torch.isfinite(tensor).all():
        t = tensor.detach()
        n_nan = int(torch.isnan(t).sum())
        n_inf = int(torch.isinf(t).sum())
        raise NonFiniteLossError(
            f"loss term {name!r} is not finite: {n_nan} NaN, {n_inf} inf of {t.numel()} values")
    return tensor


def _reduce(x: Tensor, reduction: Reduction) -> Tensor:
    """Reduce a ``(B, T, ...)`` tensor of per-element losses.

    ``"mean"``: over all elements; ``"per_sample"``: over all but the batch dim, ``(B,)``;
    ``"frame_sum"``: **summed** over each frame's elements (joints × channels) and averaged over
    batch × frames, the authors' released code's reduction; ``"per_sample_frame_sum"``: the same
    per sample, ``(B,)``. A tensor with one value per frame (``(B, T)``) is the same under
    ``"mean"`` and ``"frame_sum"``.
    """
    if reduction == "mean":
        return x.mean()
    if reduction == "per_sample":
        return x.reshape(x.shape[0], -1).mean(dim=1)
    if reduction in ("frame_sum", "per_sample_frame_sum"):
        per_frame = x.reshape(x.shape[0], x.shape[1], -1).sum(-1) if x.dim() > 2 else x.reshape(x.shape[0], -1)
        return per_frame.mean() if reduction == "frame_sum" else per_frame.mean(dim=1)
    raise ValueError("reduction must be 'mean', 'per_sample', 'frame_sum' or 'per_sample_frame_sum', "
                     f"got {reduction!r}")


def per_sample(reduction: Reduction) -> Reduction:
    """The per-sample form of ``reduction`` (``"mean"`` → ``"per_sample"``, ``"frame_sum"`` →
    ``"per_sample_frame_sum"``; a per-sample one is returned unchanged)."""
    return {"mean": "per_sample", "frame_sum": "per_sample_frame_sum"}.get(reduction, reduction)  # type: ignore[return-value]


def _check_last(name: str, x: Tensor, channels: int, ndim: int) -> None:
    if x.dim() != ndim or x.shape[-1] != channels:
        raise ValueError(f"{name} must have {ndim} dims ending in {channels}, got {tuple(x.shape)}")


def smooth_l1(x: Tensor, reduction: Reduction = "mean") -> Tensor:
    """Eq. 14: ``0.5 x²`` if ``|x| < 1``, else ``|x| − 0.5`` (Huber with threshold 1), reduced.

    Args:
        x: ``(B, ...)`` differences.
        reduction: mean over all elements, or per sample ``(B,)``.
    """
    ax = x.abs()
    return _reduce(torch.where(ax < 1.0, 0.5 * x * x, ax - 0.5), reduction)


def _motion_mse(x: MotionTensors, y: MotionTensors, reduction: Reduction) -> Tensor:
    for name, a, b in (("p", x.p, y.p), ("q", x.q, y.q), ("r", x.r, y.r)):
        if a.shape != b.shape:
            raise ValueError(f"{name}: shapes differ, {tuple(a.shape)} vs {tuple(b.shape)}")
    return (_reduce((x.p - y.p) ** 2, reduction) + _reduce((x.q - y.q) ** 2, reduction)
            + _reduce((x.r - y.r) ** 2, reduction))


# --------------------------------------------------------------------------------------------
# Lc, La (A = B case)
# --------------------------------------------------------------------------------------------


def cycle_loss(x_a: MotionTensors, x_a_hat: MotionTensors, reduction: Reduction = "mean") -> Tensor:
    """Cycle-consistency loss ``Lc = ‖x^A − x̂^A‖²₂`` (Eq. 7).

    ``x`` holds ``p``, ``q`` and ``r``. Reduction: the squared errors of each part are averaged
    over all of that part's elements (``p``: B·T·J·3, ``q``: B·T·J·4, ``r``: B·T·3) and the
    three means are **summed**, so ``r`` (3 numbers a frame) is not drowned by ``p`` and ``q``
    (~150 numbers a frame) — the authors' code also sums the three parts.

    ``q`` is compared component-wise, as printed (``q`` and ``−q`` are the same rotation but
    count as different here; the network's quaternions are compared as it outputs them).

    Args:
        x_a: the source motion, :class:`MotionTensors` with ``p (B,T,J,3)``, ``q (B,T,J,4)``,
            ``r (B,T,3)``.
        x_a_hat: the motion after the cycle A → B → A (Eq. 5), same shapes.
        reduction: ``"mean"`` → scalar; ``"per_sample"`` → ``(B,)``.
    """
    return _motion_mse(x_a, x_a_hat, reduction)


def reconstruction_loss(x_a: MotionTensors, x_b_hat: MotionTensors,
                        reduction: Reduction = "mean") -> Tensor:
    """``‖x^A − x̂^B‖²₂`` — Eq. 21's second case, used in place of the GAN term when ``A = B``.

    When the sampled target is the source itself, the right answer is known (``x̂^B = x^A``), so
    La is a direct reconstruction error. Same parts and reduction as :func:`cycle_loss`.

    Args:
        x_a: the source motion (``p (B,T,J,3)``, ``q (B,T,J,4)``, ``r (B,T,3)``).
        x_b_hat: the generator's output for target ``B = A``, same shapes.
        reduction: ``"mean"`` → scalar; ``"per_sample"`` → ``(B,)``.
    """
    return _motion_mse(x_a, x_b_hat, reduction)


# --------------------------------------------------------------------------------------------
# Lt
# --------------------------------------------------------------------------------------------


def _sum_over_rotations(per_element, q_b_hat: Tensor, q_a_hat: Tensor | None, reduction: Reduction) -> Tensor:
    """``reduce(per_element(q̂B)) + reduce(per_element(q̂A))`` (Eqs. 8 and 22 sum one term per
    rotation set); ``q_a_hat=None`` omits the second. Both are ``(B, T, J, 4)``."""
    total = 0.0
    for name, q in (("q_b_hat", q_b_hat), ("q_a_hat", q_a_hat)):
        if q is None:
            continue
        _check_last(name, q, 4, 4)
        total = total + _reduce(per_element(q), reduction)
    return total


def twist_penalty(q: Tensor, alpha_deg: float = 100.0,
                  reading: Literal["intended", "literal"] = "intended") -> Tensor:
    """Element-wise joint-twist penalty of Eq. 8 (before reduction), for plots.

    Args:
        q: ``(..., 4)`` wxyz (any norm; :func:`quat_angle` normalises).
        alpha_deg: the threshold α in degrees (paper: 100°).
        reading: ``"intended"`` → ``max(0, E(q) − α)²``; ``"literal"`` → ``max(0, |E(q) − α|)²``.

    Returns:
        ``(...)`` squared excess angle in **radians²**.
    """
    excess = quat_angle(q) - math.radians(alpha_deg)
    if reading == "intended":
        return torch.clamp(excess, min=0.0) ** 2
    if reading == "literal":
        return torch.clamp(excess.abs(), min=0.0) ** 2  # the printed max(0, |·|) is a no-op
    raise ValueError(f"reading must be 'intended' or 'literal', got {reading!r}")


def twist_loss(q_b_hat: Tensor, q_a_hat: Tensor | None = None, alpha_deg: float = 100.0,
               reading: Literal["intended", "literal"] = "intended", exclude_root: bool = False,
               reduction: Reduction = "mean") -> Tensor:
    """Joint-twist loss ``Lt`` (Eq. 8): penalise joint rotation angles beyond α.

    ``Lt = ‖max(0, E(q̂^B) − α)‖²₂ + ‖max(0, E(q̂^A) − α)‖²₂`` with ``E`` the rotation angle
    (:func:`quat_angle`, in ``[0, π]``) and α = 100°. Angles and α are in **radians** inside the
    penalty, so one unit of loss is one rad² of excess.

    **Reading of Eq. 8.** The paper prints ``max(0, |E(q) − α|)``. Since ``|E − α| ≥ 0`` the
    ``max`` does nothing and that form penalises *every* deviation from α — a 0° (identity) joint
    would cost (100°)² — contradicting the next sentence, "Any angle exceeding α is penalized",
    and the purpose (stop excessive twisting). We implement the intended hinge ``max(0, E − α)``;
    ``reading="literal"`` gives the printed form for comparison (notebook 03).

    (The authors' released code differs again: it excludes the root and measures one Euler
    component instead of ``E``. ``exclude_root=True`` gives the first difference; we keep ``E`` as
    printed.)

    Reduction: the squared excess is averaged over B·T·J (or B·T·(J−1)) for each of ``q̂^B`` and
    ``q̂^A``; the two means are summed, as Eq. 8 sums two norms.

    Args:
        q_b_hat: ``(B, T, J, 4)`` retargeted rotations ``q̂^B`` (Eq. 4).
        q_a_hat: ``(B, T, J, 4)`` cycle rotations ``q̂^A`` (Eq. 5), or ``None`` to omit that term.
        alpha_deg: α in degrees.
        reading: ``"intended"`` (default) or ``"literal"``, see above.
        exclude_root: skip joint 0 (the root's orientation is the heading, not a twist).
        reduction: ``"mean"`` → scalar; ``"per_sample"`` → ``(B,)``.
    """
    def penalty(q: Tensor) -> Tensor:
        return twist_penalty(q[:, :, 1:] if exclude_root else q, alpha_deg, reading)

    return _sum_over_rotations(penalty, q_b_hat, q_a_hat, reduction)


# --------------------------------------------------------------------------------------------
# Lh and the discriminator's inputs
# --------------------------------------------------------------------------------------------


def height_loss(p_a: Tensor, p_b_hat: Tensor, r_a: Tensor, r_b_hat: Tensor, h_a, h_b,
                lambda_g: float = 5.0, reduction: Reduction = "mean") -> Tensor:
    """Height loss ``Lh`` (Eqs. 9-17): B's motion should be A's, scaled by the height ratio.

    ``Lh = smoothL1(l^A_{2:T} − l̂^B_{2:T}) + λg · smoothL1(m^A_{2:T} − m̂^B_{2:T})`` with
    ``l`` the per-joint frame-to-frame displacement magnitudes over ``H`` (Eqs. 9-12, see
    :func:`~retarget_lib.core.quantities.normalized_joint_displacements`), ``m`` the root's
    distance from the origin over ``H`` (Eqs. 15-16) and ``smoothL1`` Eq. 14. Frame 1 of ``m`` is not used (Eq. 17 says ``2:T``; the
    authors' code uses ``1:T−1`` — immaterial for long clips).

    Example: a joint moving 3 cm in a frame on a 1.5 m character (l = 0.02) matches the same
    joint moving 4 cm on a 2 m character (l = 0.02): zero loss.

    Reduction: the first smoothL1 is averaged over B·(T−1)·J, the second over B·(T−1).

    **Baseline-height** (TDCN Sec. 6 (iv), NKN + ``Lh`` with root *offsets* normalised): NKN
    outputs per-frame root offsets ``Δr_t = r_t − r_{t−1}`` instead of positions; its height loss
    is this function called with those offsets in place of positions::

        height_loss(p_a, p_b_hat, dr_a, dr_b_hat, h_a, h_b)   # dr: (B, T, 3), dr[:, 0] unused

    (the root term then compares ``‖Δr‖/H``, i.e. Eq. 18's ``δ``). Same maths, no extra function.

    Args:
        p_a: ``(B, T, J, 3)`` source root-relative joint positions ``p^A``.
        p_b_hat: ``(B, T, J, 3)`` retargeted ``p̂^B`` (FK of ``q̂^B`` on B's skeleton, Eq. 3).
        r_a: ``(B, T, 3)`` source root positions ``r^A``.
        r_b_hat: ``(B, T, 3)`` retargeted root positions ``r̂^B``.
        h_a: ``H(s̄^A)``, float or ``(B,)``, metres.
        h_b: ``H(s̄^B)``, float or ``(B,)``, metres.
        lambda_g: weight of the root term (paper: 5).
        reduction: ``"mean"`` → scalar; ``"per_sample"`` → ``(B,)``.
    """
    if p_a.shape != p_b_hat.shape or r_a.shape != r_b_hat.shape:
        raise ValueError(f"shape mismatch: p {tuple(p_a.shape)} vs {tuple(p_b_hat.shape)}, "
                         f"r {tuple(r_a.shape)} vs {tuple(r_b_hat.shape)}")
    l_a = normalized_joint_displacements(p_a, h_a)
    l_b = normalized_joint_displacements(p_b_hat, h_b)
    m_a = normalized_root_distances(r_a, h_a)[:, 1:]
    m_b = normalized_root_distances(r_b_hat, h_b)[:, 1:]
    return smooth_l1(l_a - l_b, reduction) + lambda_g * smooth_l1(m_a - m_b, reduction)


def bone_direction_loss(p_a: Tensor, p_b_hat: Tensor, parents: Sequence[int],
                        reduction: Reduction = "mean") -> Tensor:
    """Bone-direction term ``Ld = mean_j ‖u^B_j − u^A_j‖²`` — not in the TDCN paper (weight 0 there).

    ``u_j = (p_j − p_parent(j)) / ‖p_j − p_parent(j)‖`` is the world direction of the bone that ends
    at joint ``j`` (root-relative positions, root rotation applied). It is the skeleton-level
    "weak supervision" of Villegas et al. 2021 (their Eq. 8 keeps local rotations close to the
    source's) written on global bone *directions*, so that it holds between characters whose rest
    poses differ (an A-pose and a T-pose): none of the TDCN terms can see a rest-pose difference
    (they compare magnitudes, Eqs. 9-18, or the same character, Eqs. 7, 21), so without such a
    term copying local rotations is a minimum of Eq. 6. Lengths and proportions are untouched.

    Args:
        p_a: ``(B, T, J, 3)`` source root-relative positions.
        p_b_hat: ``(B, T, J, 3)`` retargeted root-relative positions.
        parents: ``J`` parents (root first, ``-1``).
        reduction: ``"mean"`` → scalar; ``"per_sample"`` → ``(B,)``.
    """
    if p_a.shape != p_b_hat.shape:
        raise ValueError(f"shape mismatch: {tuple(p_a.shape)} vs {tuple(p_b_hat.shape)}")
    child = list(range(1, len(parents)))
    par = list(parents[1:])

    def directions(p: Tensor) -> Tensor:
        bone = p[..., child, :] - p[..., par, :]
        return bone / bone.norm(dim=-1, keepdim=True).clamp_min(1e-8)

    sq = (directions(p_a) - directions(p_b_hat)).pow(2).sum(-1)  # (B, T, J-1)
    return _reduce(sq, reduction)


# --------------------------------------------------------------------------------------------
# La
# --------------------------------------------------------------------------------------------


def adversarial_loss_generator(h_fake: Tensor, reduction: Reduction = "mean") -> Tensor:
    """Generator side of the least-squares adversarial loss (Eq. 21, case ``A ≠ B``): ``(h^B − 1)²``.

    **Reading of Eq. 21.** The paper prints ``La = (h^A)² + (1 − h^B)²`` (real scores ``h^A``,
    fake ``h^B``) inside ``min_G max_D`` (Eq. 6). Only ``(1 − h^B)²`` depends on G, so G
    minimises it: fake scores are pushed to **1**, the "real" label. D maximises the printed
    expression, i.e. drives ``h^A`` up and ``h^B`` away from 1 — unbounded as printed. Its
    bounded least-squares form is standard LSGAN (Mao et al. 2017) with labels real = 1,
    fake = 0 (:func:`adversarial_loss_discriminator`); the authors' code does the same.

    Reduction: mean over all score elements (batch × patches/frames), or per sample.

    Args:
        h_fake: ``(B, ...)`` discriminator scores ``h^B_{2:T}`` of the retargeted motion (Eq. 20).
    """
    return _reduce((h_fake - 1.0) ** 2, reduction)


def adversarial_loss_discriminator(h_real: Tensor, h_fake: Tensor,
                                   fake_mask: Tensor | None = None) -> Tensor:
    """Discriminator side of Eq. 21 (LSGAN, real → 1, fake → 0): ``(h_real − 1)² + h_fake²``.

    See :func:`adversarial_loss_generator` for how this maps onto the printed equation. No 1/2
    factor (the paper has none).

    Reduction: each of the two terms is a mean over its own score elements; then summed.

    Args:
        h_real: ``(B, ...)`` scores of real clips performed by the target character (Eq. 19;
            Sec. 5: "we sampled the motion clips performed by the character, which was taken as
            the target by the generator").
        h_fake: ``(B', ...)`` scores of retargeted clips (Eq. 20), generator detached.
        fake_mask: optional ``(B',)`` bool: which fake samples count (e.g. ``~same_character``:
            when ``A = B`` the output should equal real motion, so calling it fake is moot). If
            no sample is selected the fake term is 0.
    """
    real = ((h_real - 1.0) ** 2).mean()
    fake = h_fake ** 2
    if fake_mask is None:
        return real + fake.mean()
    per_sample = _reduce(fake, "per_sample")
    w = fake_mask.to(per_sample.dtype)
    return real + (per_sample * w).sum() / w.sum().clamp_min(1.0)


def adversarial_loss(h_fake: Tensor, x_a: MotionTensors, x_b_hat: MotionTensors,
                     same_character: Tensor, gan: Literal["lsgan", "sigmoid_ce"] = "lsgan",
                     reduction: Reduction = "mean") -> Tensor:
    """Generator's ``La`` with Eq. 21's two cases chosen per sample, averaged over the batch.

    For sample ``i``: ``‖x^A − x̂^B‖²`` (:func:`reconstruction_loss`) if ``same_character[i]``
    (the target is the source, 50 % of pairs in the paper), else the GAN term
    (:func:`adversarial_loss_generator`, or :func:`sigmoid_ce_generator_loss` for NKN).
    Each per-sample value is a mean over that sample's elements; the result is their batch mean.

    Args:
        h_fake: ``(B, ...)`` scores of ``x̂^B`` (entries of same-character samples are ignored).
        x_a: source motion (``p (B,T,J,3)``, ``q (B,T,J,4)``, ``r (B,T,3)``).
        x_b_hat: retargeted motion, same shapes.
        same_character: ``(B,)`` bool, ``True`` where ``A = B``.
        gan: ``"lsgan"`` (TDCN) or ``"sigmoid_ce"`` (NKN baseline).
        reduction: ``"mean"`` or ``"frame_sum"`` (see the module docstring): how each sample's
            reconstruction error is reduced; the GAN scores are one per frame pair either way.
    """
    if reduction not in ("mean", "frame_sum"):
        raise ValueError(f"reduction must be 'mean' or 'frame_sum', got {reduction!r}")
    if gan == "lsgan":
        adv = adversarial_loss_generator(h_fake, "per_sample")
    elif gan == "sigmoid_ce":
        adv = sigmoid_ce_generator_loss(h_fake, "per_sample")
    else:
        raise ValueError(f"gan must be 'lsgan' or 'sigmoid_ce', got {gan!r}")
    rec = reconstruction_loss(x_a, x_b_hat, per_sample(reduction))
    same = torch.as_tensor(same_character, dtype=torch.bool, device=rec.device)
    if same.shape != rec.shape:
        raise ValueError(f"same_character must be ({rec.shape[0]},), got {tuple(same.shape)}")
    return torch.where(same, rec, adv).mean()


# --------------------------------------------------------------------------------------------
# Lr, Lo
# --------------------------------------------------------------------------------------------


def regularization_loss(q_b_hat: Tensor, q_a_hat: Tensor | None = None,
                        reduction: Reduction = "mean") -> Tensor:
    """Quaternion-norm regulariser ``Lr = (1 − ‖q̂^B‖)² + (1 − ‖q̂^A‖)²`` (Eq. 22, after Pavllo 2018).

    Apply to the network's **raw** quaternions, before normalisation (normalised ones cost 0).

    Reduction: ``(1 − ‖q‖)²`` is averaged over B·T·J for each input; the two means are summed.

    Args:
        q_b_hat: ``(B, T, J, 4)`` raw ``q̂^B``.
        q_a_hat: ``(B, T, J, 4)`` raw ``q̂^A``, or ``None`` to omit.
        reduction: ``"mean"`` → scalar; ``"per_sample"`` → ``(B,)``.
    """
    return _sum_over_rotations(lambda q: (1.0 - torch.linalg.vector_norm(q, dim=-1)) ** 2,
                               q_b_hat, q_a_hat, reduction)


def orientation_loss(theta_a: Tensor, theta_b_hat: Tensor, reduction: Reduction = "mean") -> Tensor:
    """Orientation loss ``Lo = smoothL1(E(θ^A) − E(θ̂^B))`` (Eq. 23) on the root's rotations.

    ``E`` is the rotation angle in radians (:func:`quat_angle`), so 30° vs 50° of yaw costs
    ``0.5·(20° in rad)²``. As printed it compares angles only, not axes (a 30° yaw and a 30° roll
    cost nothing); the authors' code compares the yaw of the relative rotation instead.

    Reduction: mean over B·T.

    Args:
        theta_a: ``(B, T, 4)`` source root rotations ``θ^A`` (``q^A[:, :, 0]``).
        theta_b_hat: ``(B, T, 4)`` retargeted root rotations ``θ̂^B``.
        reduction: ``"mean"`` → scalar; ``"per_sample"`` → ``(B,)``.
    """
    _check_last("theta_a", theta_a, 4, 3)
    _check_last("theta_b_hat", theta_b_hat, 4, 3)
    return smooth_l1(quat_angle(theta_a) - quat_angle(theta_b_hat), reduction)


# --------------------------------------------------------------------------------------------
# NKN baseline (Villegas et al. 2018): vanilla GAN
# --------------------------------------------------------------------------------------------


def sigmoid_ce_generator_loss(h_fake: Tensor, reduction: Reduction = "mean") -> Tensor:
    """NKN's (vanilla GAN) generator loss, non-saturating: ``−log σ(h_fake)``.

    TDCN replaces this by least squares (Sec. 4.2 (i)); kept for the NKN baselines.

    Args:
        h_fake: ``(B, ...)`` discriminator **logits** of retargeted motion.
        reduction: mean over all elements, or per sample.
    """
    return _reduce(F.softplus(-h_fake), reduction)  # = BCE(σ(h), 1), numerically stable


def sigmoid_ce_discriminator_loss(h_real: Tensor, h_fake: Tensor) -> Tensor:
    """NKN's discriminator loss: ``−log σ(h_real) − log(1 − σ(h_fake))`` (real → 1, fake → 0).

    Reduction: each term a mean over its own elements; then summed.

    Args:
        h_real: ``(B, ...)`` logits of real motion.
        h_fake: ``(B', ...)`` logits of retargeted motion.
    """
    return F.softplus(-h_real).mean() + F.softplus(h_fake).mean()


# --------------------------------------------------------------------------------------------
# Eq. 6: the weighted total
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class TDCNLossWeights:
    """Weights of Eq. 6 (paper values, Sec. 5) and λg of Eq. 17.

    Any weight may be 0 to ablate its term (A3 "ours w/o Lh":
    ``dataclasses.replace(TDCNLossWeights(), lambda_h=0.0)``); a zero-weighted term is neither
    required nor added. ``lambda_c`` is not in the paper (Lc is unweighted there); it stays 1.

    ``lambda_g`` is used *inside* :func:`height_loss`, not by :func:`total_generator_loss`.
    """

    lambda_c: float = 1.0
    lambda_t: float = 10.0
    lambda_h: float = 10.0
    lambda_a: float = 1.0
    lambda_r: float = 0.1
    lambda_o: float = 1.0
    lambda_g: float = 5.0
    lambda_d: float = 0.0

    def as_dict(self) -> dict[str, float]:
        return asdict(self)


#: term name (as in Eq. 6, also the CSV column) -> its weight's field in :class:`TDCNLossWeights`
TERM_WEIGHTS: dict[str, str] = {
    "Lc": "lambda_c", "Lt": "lambda_t", "Lh": "lambda_h",
    "La": "lambda_a", "Lr": "lambda_r", "Lo": "lambda_o", "Ld": "lambda_d",
}


def total_generator_loss(terms: Mapping[str, Tensor],
                         weights: TDCNLossWeights | None = None,
                         check: bool = True) -> tuple[Tensor, dict[str, float]]:
    """Generator side of Eq. 6: ``Lc + λt Lt + λh Lh + λa La + λr Lr + λo Lo``.

    Args:
        terms: scalar tensors keyed ``"Lc", "Lt", "Lh", "La", "Lr", "Lo"``. A term whose weight
            is 0 may be missing (and is not added even if given, so a NaN there cannot leak into
            the total); a term with a non-zero weight must be present.
        weights: :class:`TDCNLossWeights`, paper values by default.
        check: run :func:`check_finite` on each weighted term and on the total.

    Returns:
        ``(total, log)``: the differentiable scalar total, and a dict of plain floats for a CSV
        row — each given term's *unweighted* value under its own name, plus ``"total"``.

    Raises:
        KeyError: an unknown term name, or a missing term whose weight is non-zero.
        NonFiniteLossError: (``check=True``) a weighted term or the total is NaN/inf.
    """
    weights = weights or TDCNLossWeights()
    unknown = set(terms) - set(TERM_WEIGHTS)
    if unknown:
        raise KeyError(f"unknown loss terms {sorted(unknown)}; expected {list(TERM_WEIGHTS)}")
    total = None
    log: dict[str, float] = {}
    for name, field in TERM_WEIGHTS.items():
        w = float(getattr(weights, field))
        if name in terms:
            log[name] = float(torch.as_tensor(terms[name]).detach())
        if w == 0.0:
            continue
        if name not in terms:
            raise KeyError(f"loss term {name!r} is missing but its weight {field}={w} is non-zero")
        value = terms[name]
        if check:
            check_finite(name, value)
        total = w * value if total is None else total + w * value
    if total is None:
        raise ValueError("every loss weight is 0: nothing to optimise")
    if check:
        check_finite("total", total)
    log["total"] = float(total.detach())
    return total, log
