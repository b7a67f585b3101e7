"""Stable public API: forward kinematics.

``from retarget_lib.kinematics import forward_kinematics`` is part of the suite's public contract
(`docs/architecture.md`, "Public contract"), so this module keeps it importable whatever moves
inside the library. It only re-exports :mod:`retarget_lib.core.kinematics`, where the code lives;
the library itself imports from there.
"""

from .core.kinematics import FKResult, forward_kinematics, local_positions

__all__ = ["FKResult", "forward_kinematics", "local_positions"]
