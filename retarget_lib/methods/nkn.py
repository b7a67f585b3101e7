"""Method ``nkn`` — the NKN baselines of TDCN's Table 4 (Villegas et al. 2018 as re-implemented
by Kim et al. 2020: GRU, dense or dilated backbones), run like TDCN (:mod:`.tdcn`)."""

from __future__ import annotations

import os
from collections.abc import Callable

import torch

from ..core.motion import Motion
from ..core.skeleton import Skeleton
from .tdcn import generator_retargeter

__all__ = ["load"]


def load(
    checkpoint: str | os.PathLike,
    device: str | torch.device | None = None,
) -> Callable[[Motion, Skeleton], Motion]:
    """The registry's loader: :func:`~retarget_lib.methods.tdcn.retarget_motion_with` an NKN
    generator (a Baseline row of Table 4) on ``device`` (default the CPU)."""
    return generator_retargeter(checkpoint, "nkn", device)
