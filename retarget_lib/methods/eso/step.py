"""One ESO step as one pure function (:func:`adam_step`: ``Efull(t)``, its gradient and Adam's
update), so that ``torch.compile`` fuses it into one graph (:func:`compiled_step`), and when to
compile it (:func:`use_compiled`)."""

from __future__ import annotations

import functools
import shutil
import warnings
from collections.abc import Callable
from typing import NamedTuple

import torch

from ...losses.contact import ContactEnergyWeights
from ...models.compiling import compile_function
from ...models.georet import DecoderState, GeometryConditionedRNN
from .energy import frame_terms
from .frame import Constants, FrameInputs, Pose

Tensor = torch.Tensor

__all__ = [
    "ADAM_BETAS",
    "ADAM_EPS",
    "AdamState",
    "COMPILE_FROM_FRAMES",
    "adam_step",
    "compiled_step",
    "use_compiled",
]

#: from this many frames, :func:`use_compiled` compiles ESO's step by default: the one-off
#: compilation (about 2 minutes the first time on a machine, 19 s from inductor's disk cache after)
#: is then repaid by the faster steps (0.27 -> 0.07 s a frame on MakeHuman's body at 10,000
#: vertices, one thread; ``retarget bench --only eso``)
COMPILE_FROM_FRAMES = 240


def use_compiled(frames: int, compile: bool | None = None) -> bool:
    """Whether ESO on a clip of ``frames`` should run compiled: ``compile`` when given, else
    (``None``) when the clip has :data:`COMPILE_FROM_FRAMES` frames or this process has compiled
    it already. Never without a C++ compiler (inductor's requirement; a warning says so once).
    """
    wanted = (
        compile
        if compile is not None
        else (frames >= COMPILE_FROM_FRAMES or _compiled_in_process())
    )
    if wanted and not _have_compiler():
        warnings.warn(
            "no C++ compiler (g++, c++ or clang++) on PATH: ESO runs uncompiled", stacklevel=2
        )
        return False
    return wanted


def _compiled_in_process() -> bool:
    return compiled_step.cache_info().currsize > 0


@functools.lru_cache(maxsize=1)
def _have_compiler() -> bool:
    return any(shutil.which(name) for name in ("g++", "c++", "clang++"))


@functools.lru_cache(maxsize=1)
def compiled_step() -> Callable[..., tuple[tuple[Tensor, Tensor], AdamState, Tensor, Pose]]:
    """:func:`adam_step` compiled once per process (sizes dynamic: one compilation serves every
    frame, character and pair count; inductor caches it on disk for the next process)."""
    return compile_function(adam_step, dynamic=True)


#: Adam's moment decays and epsilon in ESO (App. B.1)
ADAM_BETAS, ADAM_EPS = (0.5, 0.999), 1e-8


class AdamState(NamedTuple):
    """Adam's state for ESO's two variables ``(h^enc_t, o_(t−1))``: first and second moments and
    the steps taken (a 0-d tensor, so a compiled step does not specialise on it)."""

    first: tuple[Tensor, Tensor]
    second: tuple[Tensor, Tensor]
    steps: Tensor

    @classmethod
    def start(cls, variables: tuple[Tensor, Tensor]) -> AdamState:
        zeros = tuple(torch.zeros_like(v) for v in variables)
        return cls(zeros, zeros, variables[0].new_zeros(()))  # type: ignore[arg-type]


def adam_step(
    model: GeometryConditionedRNN,
    weights: ContactEnergyWeights,
    blend: float,
    cone: dict[str, float],
    constants: Constants,
    frame: FrameInputs,
    variables: tuple[Tensor, Tensor],
    adam: AdamState,
    lr: Tensor,
) -> tuple[tuple[Tensor, Tensor], AdamState, Tensor, Pose]:
    """One ESO step: ``Efull(t)`` at ``variables = (h^enc_t, o_(t−1))`` (:func:`frame_terms`), its
    gradient (``torch.func.grad``) and Adam's update (Kingma & Ba 2015, the arithmetic of
    ``torch.optim.Adam``: ``m ← β1 m + (1 − β1) g``, ``v ← β2 v + (1 − β2) g²``,
    ``x ← x − lr/(1 − β1^n) · m / (√v / √(1 − β2^n) + ε)``).

    One pure function, so a compiled step is one call of one fused graph (forward, backward and
    update), without autograd's engine or the optimiser's bookkeeping in between.

    Returns:
        ``(the updated variables, Adam's state, the terms and total at the given variables,
        the pose decoded from them)``.
    """

    def energy(
        h_enc: Tensor, o_prev: Tensor
    ) -> tuple[Tensor, tuple[Tensor, Tensor, DecoderState, Tensor]]:
        values, pose = frame_terms(model, weights, blend, cone, constants, frame, h_enc, o_prev)
        return values[-1], (values, pose.rotations, pose.state, pose.positions)  # tensors only

    if torch.compiler.is_compiling():  # functorch's transform is what a compiled graph can trace
        grads, (values, rotations, state, positions) = torch.func.grad(
            energy, argnums=(0, 1), has_aux=True
        )(*variables)
    else:  # eager, autograd's engine costs less per operation than the transform's wrappers
        with torch.enable_grad():
            leaves = tuple(v.detach().requires_grad_(True) for v in variables)
            total, (values, rotations, state, positions) = energy(*leaves)
            grads = torch.autograd.grad(total, leaves)
        values, rotations, positions = values.detach(), rotations.detach(), positions.detach()
        state = DecoderState(*(x.detach() for x in state))
    pose = Pose(rotations, state, positions, None)
    (beta1, beta2), count = ADAM_BETAS, adam.steps + 1
    step = lr / (1 - beta1**count)
    root_correction = (1 - beta2**count).sqrt()
    first = tuple(m + (1 - beta1) * (g - m) for m, g in zip(adam.first, grads, strict=False))
    second = tuple(
        beta2 * v + (1 - beta2) * g * g for v, g in zip(adam.second, grads, strict=False)
    )
    moved = tuple(
        x - step * m / (v.sqrt() / root_correction + ADAM_EPS)
        for x, m, v in zip(variables, first, second, strict=False)
    )
    return moved, AdamState(first, second, count), values, pose  # type: ignore[arg-type]
