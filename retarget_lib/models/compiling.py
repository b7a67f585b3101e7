"""``torch.compile`` for the recurrent decoders' per-frame step (NKN's GRU, the contact-aware RNN)."""

from __future__ import annotations

import warnings
from typing import Callable

import torch


def compile_frame_step(step: Callable) -> Callable:
    """``step`` compiled by ``torch.compile`` (inductor; needs a C++ compiler on the CPU).

    A recurrent decoder runs one frame at a time: a few hundred small tensor operations per frame
    (GRU cells, the rotation head, FK joint by joint), so the eager step is dominated by
    per-operation overhead; compiled, they fuse into a few kernels. Shapes are fixed for a training
    run (``dynamic=False``). The module's weights and ``state_dict`` are unchanged.

    Args:
        step: a bound ``decode_step`` method.

    Returns:
        The compiled callable, to assign over the instance's ``decode_step``.
    """
    # dynamo traces through core.kinematics._plan's lru_cache (a pure function of ``parents``)
    warnings.filterwarnings("ignore", message=".*lru_cache.*", category=UserWarning)
    return torch.compile(step, dynamic=False)
