"""Eq. 6 of Kim et al. 2020: the loss weights (paper values, Sec. 5) and the generator's weighted
total, each term checked finite."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import torch

from .tensors import check_finite

Tensor = torch.Tensor

__all__ = ["TERM_WEIGHTS", "TDCNLossWeights", "total_generator_loss"]


@dataclass(frozen=True)
class TDCNLossWeights:
    """Weights of Eq. 6 (paper values, Sec. 5) and λg of Eq. 17.

    Any weight may be 0 to ablate its term (A3 "ours w/o Lh":
    ``dataclasses.replace(TDCNLossWeights(), lambda_h=0.0)``); a zero-weighted term is neither
    required nor added. ``lambda_c`` is not in the paper (Lc is unweighted there); it stays 1.

    ``lambda_g`` is used *inside* :func:`height_loss`, not by :func:`total_generator_loss`.
    ``lambda_d`` (Ld, ours) and ``lambda_s`` (the NKN authors' code's root smoothness Ls,
    :func:`~retarget_lib.losses.tdcn.terms.root_smoothness_loss`) are in neither paper: 0 here.
    """

    lambda_c: float = 1.0
    lambda_t: float = 10.0
    lambda_h: float = 10.0
    lambda_a: float = 1.0
    lambda_r: float = 0.1
    lambda_o: float = 1.0
    lambda_g: float = 5.0
    lambda_d: float = 0.0
    lambda_s: float = 0.0


#: term name (as in Eq. 6, also the CSV column) -> its weight's field in :class:`TDCNLossWeights`
TERM_WEIGHTS: dict[str, str] = {
    "Lc": "lambda_c",
    "Lt": "lambda_t",
    "Lh": "lambda_h",
    "La": "lambda_a",
    "Lr": "lambda_r",
    "Lo": "lambda_o",
    "Ld": "lambda_d",
    "Ls": "lambda_s",
}


def total_generator_loss(
    terms: Mapping[str, Tensor], weights: TDCNLossWeights | None = None, check: bool = True
) -> tuple[Tensor, dict[str, float]]:
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
