"""``torch.compile`` for the recurrent decoders' per-frame step (NKN's GRU, the contact-aware RNN)
and ESO's per-frame energy."""

from __future__ import annotations

import functools
import warnings
from collections.abc import Callable

import torch
import torch.fx.experimental._config as shape_config


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
    return compile_function(step, dynamic=False)


def compile_function(function: Callable, dynamic: bool) -> Callable:
    """``function`` compiled by ``torch.compile`` (inductor).

    ``dynamic``: one compilation for every input size (else one per set of sizes). Sizes are then
    traced as symbols without "duck sizing" (which gives sizes that happen to be equal when traced
    one symbol: a count of 3 pairs would be tied to the 3 of xyz and compiled again for 4).
    """
    # dynamo traces through core.kinematics._plan's lru_cache (a pure function of ``parents``)
    warnings.filterwarnings("ignore", message=".*lru_cache.*", category=UserWarning)
    compiled = torch.compile(function, dynamic=dynamic)
    if not dynamic:
        return compiled

    @functools.wraps(function)
    def without_duck_sizing(*args, **kwargs):
        with shape_config.patch(use_duck_shape=False):
            return compiled(*args, **kwargs)

    return without_duck_sizing
