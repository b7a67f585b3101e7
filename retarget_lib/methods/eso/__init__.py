"""Encoder-space optimisation (ESO) of Villegas et al. 2021 (Sec. 3.3, Eqs. 10-11, App. B.1): the
algorithm and its speed are described in :mod:`.optimise`; the source's preparation is
:mod:`.source`, one frame's fixed problem :mod:`.frame`, its energy ``Efull(t)`` :mod:`.energy`,
and one Adam step (compiled or not) :mod:`.step`."""

from .energy import TERMS
from .frame import reachable_pairs, reached_joints
from .optimise import EsoResult, encoder_space_optimization, eso_throughput
from .source import EsoSource, eso_source
from .step import COMPILE_FROM_FRAMES, use_compiled

__all__ = [
    "COMPILE_FROM_FRAMES",
    "EsoResult",
    "EsoSource",
    "TERMS",
    "encoder_space_optimization",
    "eso_source",
    "eso_throughput",
    "reachable_pairs",
    "reached_joints",
    "use_compiled",
]
