"""The :class:`Motion` container: a skeleton plus per-frame local rotations and root positions.

Arrays are NumPy float64 (exact file round trips); :meth:`Motion.torch` hands out tensors.
Operations return new motions: windows, resampling, mirroring, root normalisation.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, cast

import numpy as np
import torch

from ..errors import LimitError
from .kinematics import FKResult, forward_kinematics
from .quantities import hip_facing
from .rotations import quat_canonical, quat_from_axis_angle, quat_mul, quat_rotate, quat_slerp
from .skeleton import Skeleton


def _t(x: np.ndarray) -> torch.Tensor:
    return torch.from_numpy(np.ascontiguousarray(x, dtype=np.float64))


#: most frames :meth:`Motion.resample` produces: 9 h at 30 fps, 1.8 GB of rotations for 22 joints
#: (a higher count is a wrong frame rate or frame time, not a motion)
MAX_FRAMES = 1_000_000


@dataclass
class Motion:
    """A clip of skeletal animation.

    Attributes:
        skeleton: the :class:`~retarget_lib.core.skeleton.Skeleton` (rest offsets in metres).
        rotations: ``(T, J, 4)`` local joint rotations, unit wxyz, float64.
        root_positions: ``(T, 3)`` root (Hips) world positions in metres.
        fps: frames per second.
        name: free-form clip name.
        meta: free-form metadata (source file, unit scale, BVH channel layout for writing, ...).
    """

    skeleton: Skeleton
    rotations: np.ndarray
    root_positions: np.ndarray
    fps: float
    name: str = ""
    meta: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.rotations = np.asarray(self.rotations, dtype=np.float64)
        self.root_positions = np.asarray(self.root_positions, dtype=np.float64)
        T, nj = self.rotations.shape[:2]
        if self.rotations.shape != (T, self.skeleton.num_joints, 4):
            raise ValueError(
                f"rotations must be (T, {self.skeleton.num_joints}, 4), got {self.rotations.shape}"
            )
        if self.root_positions.shape != (T, 3):
            raise ValueError(f"root_positions must be ({T}, 3), got {self.root_positions.shape}")
        if T == 0:
            raise ValueError("a Motion needs at least one frame")
        if not (np.isfinite(self.rotations).all() and np.isfinite(self.root_positions).all()):
            raise ValueError(f"motion {self.name!r} contains NaN or inf")
        self.fps = float(self.fps)

    # ------------------------------------------------------------------ basics
    @property
    def num_frames(self) -> int:
        return self.rotations.shape[0]

    @property
    def duration(self) -> float:
        """Length in seconds."""
        return self.num_frames / self.fps

    def copy(self, **changes) -> Motion:
        kw: dict[str, Any] = dict(
            skeleton=self.skeleton.copy(),
            rotations=self.rotations.copy(),
            root_positions=self.root_positions.copy(),
            fps=self.fps,
            name=self.name,
            meta=dict(self.meta),
        )
        kw.update(changes)
        return Motion(**kw)

    def torch(self, dtype=torch.float32) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """``(rotations (T,J,4), root_positions (T,3), offsets (J,3))`` as tensors."""
        return (
            torch.as_tensor(self.rotations, dtype=dtype),
            torch.as_tensor(self.root_positions, dtype=dtype),
            torch.as_tensor(self.skeleton.offsets, dtype=dtype),
        )

    def fk(self) -> FKResult:
        """Global joint positions ``(T, J, 3)`` and rotations ``(T, J, 4)`` (NumPy float64)."""
        return forward_kinematics(
            self.rotations, self.skeleton.offsets, self.skeleton.parents, self.root_positions
        )

    def global_positions(self) -> np.ndarray:
        """``(T, J, 3)`` world joint positions."""
        return cast(np.ndarray, self.fk().positions)  # NumPy in, NumPy out

    # ---------------------------------------------------------------- editing
    def slice(self, start: int, stop: int | None = None) -> Motion:
        """Frames ``start:stop`` as a new motion."""
        return self.copy(
            rotations=self.rotations[start:stop].copy(),
            root_positions=self.root_positions[start:stop].copy(),
        )

    def windows(
        self, length: int, stride: int | None = None, pad_last: bool = False
    ) -> list[Motion]:
        """Cut into fixed-length windows.

        Args:
            length: frames per window (e.g. 81 for TDCN training, 120 for "short" evaluation).
            stride: step between window starts (default ``length``: non-overlapping).
            pad_last: also emit a final window that ends at the last frame, overlapping the previous
                one, so that every frame is covered (clips shorter than ``length`` give one window
                padded by repeating the edge frames).

        Returns:
            list of motions of exactly ``length`` frames.
        """
        stride = stride or length
        T = self.num_frames
        if T < length:
            if not pad_last:
                return []
            idx = np.clip(np.arange(length), 0, T - 1)
            return [
                self.copy(rotations=self.rotations[idx], root_positions=self.root_positions[idx])
            ]
        starts = list(range(0, T - length + 1, stride))
        if pad_last and starts[-1] + length < T:
            starts.append(T - length)
        return [self.slice(s, s + length) for s in starts]

    def resample(self, fps: float) -> Motion:
        """Resample in time: slerp for rotations, linear for root positions.

        Args:
            fps: new frame rate (e.g. 30 from CMU's 120 or the Biovision file's 100).

        Raises:
            LimitError: ``fps`` is not positive, or the result would have more than
                :data:`MAX_FRAMES` frames.
        """
        if not (np.isfinite(fps) and fps > 0):
            raise LimitError(f"frame rate must be a positive number, got {fps!r}")
        if abs(fps - self.fps) < 1e-9:
            return self.copy()
        T = self.num_frames
        n_new = max(1, int(np.floor((T - 1) * fps / self.fps + 1e-9)) + 1)
        if n_new > MAX_FRAMES:
            raise LimitError(
                f"resampling {self.name or 'the motion'} ({T} frames at {self.fps:g} fps) to "
                f"{fps:g} fps "
                f"gives {n_new} frames, beyond the limit of {MAX_FRAMES}"
            )
        return self._at_frames(np.arange(n_new) * (self.fps / fps), fps)

    def at_times(self, seconds: np.ndarray, fps: float | None = None) -> Motion:
        """The motion at arbitrary times: slerp for rotations, linear for root positions.

        Args:
            seconds: ``(N,)`` times since the first frame (clamped to the clip).
            fps: the ``fps`` of the result (default this motion's); the times need not be uniform.

        Returns:
            an ``N``-frame motion.
        """
        return self._at_frames(
            np.asarray(seconds, dtype=np.float64) * self.fps, self.fps if fps is None else fps
        )

    def _at_frames(self, t: np.ndarray, fps: float) -> Motion:
        """Frames at fractional frame positions ``t (N,)`` (clamped), with frame rate ``fps``."""
        T, n_new = self.num_frames, len(t)
        t = np.clip(t, 0.0, T - 1)
        i0 = np.clip(np.floor(t).astype(int), 0, T - 1)
        i1 = np.clip(i0 + 1, 0, T - 1)
        a = t - i0
        rot = quat_slerp(
            _t(self.rotations[i0]),
            _t(self.rotations[i1]),
            _t(np.broadcast_to(a[:, None], (n_new, self.skeleton.num_joints))),
        )
        root = self.root_positions[i0] * (1 - a[:, None]) + self.root_positions[i1] * a[:, None]
        return self.copy(rotations=rot.numpy(), root_positions=root, fps=fps)

    def mirror(self) -> Motion:
        """Left/right mirror image across the YZ plane (x -> -x); needs a symmetric joint set.

        Left and right joints swap (names with Left/Right); rotations and root are reflected
        (:meth:`~retarget_lib.core.skeleton.Skeleton.mirror_pose`) and the skeleton is mirrored
        (:meth:`~retarget_lib.core.skeleton.Skeleton.mirror`).
        """
        rot, root = self.skeleton.mirror_pose(self.rotations, self.root_positions)
        return self.copy(
            skeleton=self.skeleton.mirror(),
            rotations=rot,
            root_positions=root,
            name=(self.name + "_mirror") if self.name else "mirror",
        )

    def facing(self) -> np.ndarray:
        """``(T, 3)`` horizontal facing direction (unit, y = 0) of the root frame at each frame.

        Uses the hips when both up-legs exist (:func:`~retarget_lib.core.quantities.hip_facing`),
        else the root's rotated +Z.
        """
        pos, grot = self.fk()
        names = self.skeleton.joint_names
        if "LeftUpLeg" in names and "RightUpLeg" in names:
            f = hip_facing(  # fk() of a NumPy motion gives NumPy positions
                _t(pos[:, names.index("LeftUpLeg")]),  # type: ignore[arg-type]
                _t(pos[:, names.index("RightUpLeg")]),  # type: ignore[arg-type]
            ).numpy()
            fwd = np.stack((f[:, 0], np.zeros(len(f)), f[:, 1]), -1)
        else:
            fwd = quat_rotate(
                _t(cast(np.ndarray, grot)[:, 0]), _t(np.array([0.0, 0.0, 1.0]))
            ).numpy()
        fwd[:, 1] = 0.0
        return fwd / np.maximum(np.linalg.norm(fwd, axis=-1, keepdims=True), 1e-9)

    def normalize_root(self, face_z: bool = True, on_ground: bool = True) -> Motion:
        """Put frame 0's root above the origin, facing +Z; optionally feet on the ground (y = 0).

        Rotates the whole clip about world +Y so the character faces +Z at frame 0, translates so
        the root starts at ``x = z = 0``, and (``on_ground``) shifts vertically so that the lowest
        joint over the clip's first second touches ``y = 0``.
        """
        rot = self.rotations.copy()
        root = self.root_positions.copy()
        if face_z:
            f0 = self.slice(0, 1).facing()[0]
            yaw = np.arctan2(f0[0], f0[2])  # angle from +Z towards +X
            qy = quat_from_axis_angle(_t(np.array([0.0, -yaw, 0.0])))
            rot[:, 0] = quat_canonical(quat_mul(qy, _t(rot[:, 0]))).numpy()
            root = quat_rotate(qy, _t(root)).numpy()
        root[:, [0, 2]] -= root[0, [0, 2]]
        out = self.copy(rotations=rot, root_positions=root)
        if on_ground:
            n = max(1, min(self.num_frames, int(round(self.fps))))
            low = out.slice(0, n).global_positions()[:, :, 1].min()
            out.root_positions[:, 1] -= low
        return out

    def with_skeleton(self, skeleton: Skeleton) -> Motion:
        """The same local rotations on another skeleton with the same joint names (a 'copy')."""
        if skeleton.joint_names != self.skeleton.joint_names:
            raise ValueError("with_skeleton needs the same joint names")
        return self.copy(skeleton=skeleton.copy())
