"""Method ``copy-rest``: copy with rest-pose compensation (the same global bone directions and
twists; :mod:`retarget_lib.core.transfer`)."""

from __future__ import annotations

from collections.abc import Callable

from ..core.motion import Motion
from ..core.skeleton import Skeleton
from ..core.transfer import retarget_ground_truth

__all__ = ["copy_rotations_rest_compensated", "load"]


def copy_rotations_rest_compensated(motion: Motion, target_skeleton: Skeleton) -> Motion:
    """Baseline "copy with rest-pose compensation".

    This is the same mathematics as :func:`~retarget_lib.core.transfer.retarget_ground_truth`
    (which is implemented as a rest-compensated copy), so on synthetic pairs it scores zero error
    by construction; it is listed separately so that evaluation tables can name it. On real Mixamo
    data the ground truth comes from Mixamo's own retargeter and the two differ.
    """
    out = retarget_ground_truth(motion, target_skeleton)
    out.meta["retargeted"] = "copy_rest_compensated"
    return out


def load(checkpoint: None = None, device: None = None) -> Callable[..., Motion]:
    """The registry's loader: :func:`copy_rotations_rest_compensated` (nothing to load; NumPy, no
    device)."""
    return copy_rotations_rest_compensated
