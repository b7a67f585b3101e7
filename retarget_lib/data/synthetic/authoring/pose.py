"""The canonical pose an author writes: :class:`Pose`, joint angles in degrees on the canonical
rest pose (see :mod:`retarget_lib.data.synthetic.authoring`, step 1)."""

from __future__ import annotations

import numpy as np
import torch

from ....core.rotations import (
    quat_from_axis_angle,
    quat_from_euler,
    quat_identity,
    quat_mul,
)
from ....core.skeleton import J


def _yxz(yaw=0.0, pitch=0.0, roll=0.0, T: int = 1) -> torch.Tensor:
    """``(T, 4)`` rotations ``Ry(yaw) Rx(pitch) Rz(roll)``, degrees (scalars or ``(T,)``)."""
    ang = np.stack(np.broadcast_arrays(*(np.asarray(x, float) for x in (yaw, pitch, roll))), -1)
    ang = np.array(np.broadcast_to(ang, (T, 3)))
    return quat_from_euler(torch.from_numpy(ang), "YXZ", degrees=True)


def axis_rotation(axis: int, deg, T: int) -> torch.Tensor:
    """``(T, 4)`` rotations by ``deg`` (scalar or ``(T,)``) about axis ``axis`` (0=X, 1=Y, 2=Z)."""
    aa = np.zeros((T, 3))
    aa[:, axis] = np.radians(np.broadcast_to(np.asarray(deg, float), (T,)))
    return quat_from_axis_angle(torch.from_numpy(aa))


class Pose:
    """Canonical local rotations ``(T, 22, 4)`` plus the root trajectory being authored."""

    def __init__(self, T: int):
        self.T = T
        self.q = quat_identity((T, 22), dtype=torch.float64)
        self.root = np.zeros((T, 3))

    def set(self, joint: str, q: torch.Tensor) -> None:
        self.q[:, J[joint]] = q

    def pelvis(self, yaw, lean=0.0, roll=0.0) -> None:
        """Root orientation: heading ``yaw``, forward ``lean``, ``roll`` down towards the left."""
        self.set("Hips", _yxz(yaw, lean, roll, T=self.T))

    def spine(self, bend=0.0, twist=0.0, side=0.0) -> None:
        """Spread a forward ``bend``, a ``twist`` and a ``side`` bend (both to the left) over the
        spine."""
        twist, bend, side = (np.asarray(x, float) for x in (twist, bend, side))
        for name, w in (("Spine", 0.3), ("Spine1", 0.35), ("Spine2", 0.35)):
            self.set(name, _yxz(w * twist, w * bend, -w * side, T=self.T))

    def head(self, nod=0.0, yaw=0.0, tilt=0.0) -> None:
        """Neck and head: ``nod`` down, ``yaw`` to the left, ``tilt`` to the left."""
        nod, yaw, tilt = (np.asarray(x, float) for x in (nod, yaw, tilt))
        for name, w in (("Neck", 0.4), ("Head", 0.6)):
            self.set(name, _yxz(w * yaw, w * nod, -w * tilt, T=self.T))

    def arm(
        self,
        side: str,
        sign: float,
        down=80.0,
        fwd=0.0,
        elbow=15.0,
        twist=0.0,
        shrug=0.0,
        reach=0.0,
    ) -> None:
        """One arm: lowered by ``down`` from the T-pose, swung ``fwd``, ``elbow`` flexion,
        clavicle raised by ``shrug`` and pushed forward by ``reach`` (all degrees)."""
        T = self.T
        shrug, reach = np.asarray(shrug, float), np.asarray(reach, float)
        self.set(
            f"{side}Shoulder",
            quat_mul(axis_rotation(2, sign * shrug, T), axis_rotation(1, -sign * reach, T)),
        )
        lower = quat_mul(axis_rotation(2, -sign * np.asarray(down), T), axis_rotation(0, twist, T))
        self.set(f"{side}Arm", quat_mul(axis_rotation(0, -np.asarray(fwd), T), lower))
        self.set(f"{side}ForeArm", axis_rotation(1, -sign * np.asarray(elbow), T))
