"""Method ``copy``: copy the local rotations, scale the root by the leg-length ratio (the NKN/TDCN
"Copy" baseline)."""

from __future__ import annotations

from collections.abc import Callable

from ..core.motion import Motion
from ..core.quantities import leg_ratio
from ..core.skeleton import Skeleton

__all__ = ["copy_rotations", "load"]


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


def load(checkpoint: None = None, device: None = None) -> Callable[..., Motion]:
    """The registry's loader: :func:`copy_rotations` (nothing to load; NumPy, no device)."""
    return copy_rotations
