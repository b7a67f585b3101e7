"""Method ``copy-rest``: copy the rotation deltas from the retarget pose (each rig's canonical
T-pose, :mod:`retarget_lib.core.retarget_pose`; :mod:`retarget_lib.core.transfer`)."""

from __future__ import annotations

from collections.abc import Callable

from ..core.motion import Motion
from ..core.skeleton import Skeleton
from ..core.transfer import retarget_ground_truth

__all__ = ["copy_rotations_rest_compensated", "load"]


def copy_rotations_rest_compensated(motion: Motion, target_skeleton: Skeleton) -> Motion:
    """Baseline "copy with rest-pose compensation": the source's rotation deltas from its
    retarget pose, on the target's retarget pose (``G^B_j = G^A_j (P^A_j)^-1 P^B_j``), the root
    scaled by the leg ratio.

    Between two rigs of one T-pose convention (Mixamo's binds) it is ``copy`` exactly, each
    character keeping its own shape; between conventions (an A-pose, splayed legs, a rig lying at
    rest) it removes the convention. The same mathematics as
    :func:`~retarget_lib.core.transfer.retarget_ground_truth`, so on synthetic pairs it scores zero
    error by construction; it is listed separately so that evaluation tables can name it. On real
    Mixamo data the ground truth comes from Mixamo's own retargeter.
    """
    out = retarget_ground_truth(motion, target_skeleton)
    out.meta["retargeted"] = "copy_rest_compensated"
    return out


def load(checkpoint: None = None, device: None = None) -> Callable[..., Motion]:
    """The registry's loader: :func:`copy_rotations_rest_compensated` (nothing to load; NumPy, no
    device)."""
    return copy_rotations_rest_compensated
