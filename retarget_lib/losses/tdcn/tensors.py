"""What TDCN's losses compare and how they reduce it: the motion container :class:`MotionTensors`,
the authors' z-scores :class:`PositionScale`, the reductions, Eq. 14's smooth L1, and
:func:`check_finite`, which stops a diverging run naming the term.

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
metres; 123 against 15.9 with frame sums of z-scores), which is why the paper-form network, trained
with the means, does not even learn identity. ``loss.reduction: frame_sum`` and ``loss.standardize:
true`` in a config restore the authors' balance (``configs/tdcn_paper_code_scale.yaml``).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Literal, NamedTuple

import torch

Tensor = torch.Tensor
Reduction = Literal["mean", "per_sample", "frame_sum", "per_sample_frame_sum"]

__all__ = [
    "MotionTensors",
    "NonFiniteLossError",
    "PositionScale",
    "Reduction",
    "check_finite",
    "check_last_dim",
    "motion_mse",
    "per_sample",
    "reduce_elements",
    "smooth_l1",
]


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
    def fit(cls, p: Tensor, r: Tensor, min_std: float = 0.01) -> PositionScale:
        """Fit on ``p (B, T, J, 3)`` and ``r (B, T, 3)``; ``min_std`` in metres (1 cm)."""
        check_last_dim("p", p, 3, 4)
        check_last_dim("r", r, 3, 3)
        p_flat, r_flat = p.reshape(-1, *p.shape[2:]), r.reshape(-1, 3)
        return cls(
            p_flat.mean(0),
            p_flat.std(0).clamp_min(min_std),
            r_flat.mean(0),
            r_flat.std(0).clamp_min(min_std),
        )

    def apply(self, x: MotionTensors) -> MotionTensors:
        """``x`` with ``p`` and ``r`` standardised (``q`` unchanged)."""
        return MotionTensors(
            (x.p - self.p_mean) / self.p_std, x.q, (x.r - self.r_mean) / self.r_std
        )


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
            f"loss term {name!r} is not finite: {n_nan} NaN, {n_inf} inf of {t.numel()} values"
        )
    return tensor


def reduce_elements(x: Tensor, reduction: Reduction) -> Tensor:
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
        per_frame = (
            x.reshape(x.shape[0], x.shape[1], -1).sum(-1)
            if x.dim() > 2
            else x.reshape(x.shape[0], -1)
        )
        return per_frame.mean() if reduction == "frame_sum" else per_frame.mean(dim=1)
    raise ValueError(
        "reduction must be 'mean', 'per_sample', 'frame_sum' or 'per_sample_frame_sum', "
        f"got {reduction!r}"
    )


def per_sample(reduction: Reduction) -> Reduction:
    """The per-sample form of ``reduction`` (``"mean"`` → ``"per_sample"``, ``"frame_sum"`` →
    ``"per_sample_frame_sum"``; a per-sample one is returned unchanged)."""
    return {"mean": "per_sample", "frame_sum": "per_sample_frame_sum"}.get(reduction, reduction)  # type: ignore[return-value]


def check_last_dim(name: str, x: Tensor, channels: int, ndim: int) -> None:
    if x.dim() != ndim or x.shape[-1] != channels:
        raise ValueError(f"{name} must have {ndim} dims ending in {channels}, got {tuple(x.shape)}")


def smooth_l1(x: Tensor, reduction: Reduction = "mean") -> Tensor:
    """Eq. 14: ``0.5 x²`` if ``|x| < 1``, else ``|x| − 0.5`` (Huber with threshold 1), reduced.

    Args:
        x: ``(B, ...)`` differences.
        reduction: mean over all elements, or per sample ``(B,)``.
    """
    ax = x.abs()
    return reduce_elements(torch.where(ax < 1.0, 0.5 * x * x, ax - 0.5), reduction)


def motion_mse(
    x: MotionTensors,
    y: MotionTensors,
    reduction: Reduction,
    quaternion_weight: float = 1.0,
    joints: Sequence[int] | None = None,
) -> Tensor:
    """``‖p − p'‖² + w_q ‖q − q'‖² + ‖r − r'‖²``, each part reduced on its own, then summed.

    Args:
        x, y: the two motions (``p (B,T,J,3)``, ``q (B,T,J,4)``, ``r (B,T,3)``).
        reduction: see :func:`reduce_elements`.
        quaternion_weight: ``w_q`` (1 as printed in Eq. 7; the authors' released code uses 10,
            its ``quatW``).
        joints: compare ``p`` at these joints only (default all; the authors' code compares the
            end effectors, :data:`~retarget_lib.losses.tdcn.terms.CODE_END_EFFECTOR_IDS`).
    """
    for name, a, b in (("p", x.p, y.p), ("q", x.q, y.q), ("r", x.r, y.r)):
        if a.shape != b.shape:
            raise ValueError(f"{name}: shapes differ, {tuple(a.shape)} vs {tuple(b.shape)}")
    dp = x.p - y.p if joints is None else x.p[:, :, list(joints)] - y.p[:, :, list(joints)]
    return (
        reduce_elements(dp**2, reduction)
        + quaternion_weight * reduce_elements((x.q - y.q) ** 2, reduction)
        + reduce_elements((x.r - y.r) ** 2, reduction)
    )
