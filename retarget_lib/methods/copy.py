"""Methods ``copy`` and ``copy-unscaled``: copy the local rotations; the root either scaled by the
leg-length ratio (our stronger baseline) or moved by the source's own displacements, unscaled (the
papers' "copy input quaternions and velocities" row: NKN's Table 1, the row TDCN's Baseline is
measured against)."""

from __future__ import annotations

from collections.abc import Callable

from ..core.motion import Motion
from ..core.quantities import leg_ratio
from ..core.skeleton import Skeleton

__all__ = ["copy_rotations", "copy_unscaled", "load", "load_unscaled"]


def copy_rotations(motion: Motion, target_skeleton: Skeleton) -> Motion:
    """Baseline: copy the local rotations unchanged, scale the root by the leg-length ratio.

    Correct only when both characters share the same rest pose (bone *directions*); otherwise
    every rest-pose difference shows up as a pose error (NKN/TDCN "Copy" baseline).

    Args:
        motion: source motion on the canonical 22 joints.
        target_skeleton: canonical-22 target character.
    """
    root = motion.root_positions * leg_ratio(motion.skeleton, target_skeleton)
    return motion.copy(
        skeleton=target_skeleton.copy(),
        root_positions=root,
        meta=dict(motion.meta, retargeted="copy"),
    )


def copy_unscaled(motion: Motion, target_skeleton: Skeleton) -> Motion:
    """The papers' copy row: the local rotations copied (root included), the root starting where
    the leg-scaled copy starts and then moved by the source's per-frame displacements **unscaled**:
    ``r^B_t = r^A_0 l_B / l_A + (r^A_t - r^A_0)``.

    This is what NKN's test script writes as its copy (``_cpy.bvh`` in rubenvillegas/cvpr2018nkn:
    the input's quaternions and its unscaled global velocities, started at the target's first root
    position). A target half the source's size thus walks as far as the source, and its error grows
    with the distance covered: on a 120-frame window it is ``(1 - s)^2 v^2 (T - 1)(2T - 1) / (6 H)``
    for a target ``s`` times the source walking at ``v`` per frame (``tests/test_evaluate.py``).

    Args:
        motion: source motion on the canonical 22 joints.
        target_skeleton: canonical-22 target character.
    """
    start = motion.root_positions[:1]
    root = start * leg_ratio(motion.skeleton, target_skeleton) + (motion.root_positions - start)
    return motion.copy(
        skeleton=target_skeleton.copy(),
        root_positions=root,
        meta=dict(motion.meta, retargeted="copy-unscaled"),
    )


def load_unscaled(checkpoint: None = None, device: None = None) -> Callable[..., Motion]:
    """The registry's loader of ``copy-unscaled``: :func:`copy_unscaled`."""
    return copy_unscaled


def load(checkpoint: None = None, device: None = None) -> Callable[..., Motion]:
    """The registry's loader: :func:`copy_rotations` (nothing to load; NumPy, no device)."""
    return copy_rotations
