"""Writing BVH files: :func:`save_bvh` with the file's own joint layout (channels, order, units)
when a motion came from a BVH."""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np
import torch

from ...core.motion import Motion
from ...core.rotations import quat_angle, quat_to_euler
from ...files import atomic_write
from ..rig_maps import strip_prefix
from .parse import (
    _DEFAULT_CHANNELS,
    _DEFAULT_ROOT_CHANNELS,
    MAX_FRAME_TIME,
    MAX_LENGTH,
    MIN_FRAME_TIME,
    UNIT_SCALES,
    BVHError,
)
from .read import _euler_groups, _resolve_unit

__all__ = ["save_bvh"]


# ---------------------------------------------------------------------------------- writing
def _file_layout(motion: Motion) -> tuple[list[str], list[list[str]]]:
    """File joint names and channel lists for writing: the loaded file's when they still describe
    this skeleton, else the skeleton's names and the default channels."""
    names = motion.skeleton.joint_names
    meta_names = motion.meta.get("file_joint_names")
    meta_channels = motion.meta.get("channels")
    fits = (
        meta_names is not None
        and meta_channels is not None
        and len(meta_names) == len(names) == len(meta_channels)
        and all(strip_prefix(f) == n or f == n for f, n in zip(meta_names, names, strict=False))
    )
    if fits:
        file_names = [str(n) for n in meta_names or ()]  # fits: neither is None
        channels = [list(c) for c in meta_channels or ()]
    else:
        file_names = list(names)
        channels = [
            list(_DEFAULT_ROOT_CHANNELS if j == 0 else _DEFAULT_CHANNELS) for j in range(len(names))
        ]
    # keep the motion representable: root translation and every non-identity rotation need channels
    if (
        not any(c.endswith("position") for c in channels[0])
        and np.abs(motion.root_positions - motion.skeleton.offsets[0]).max() > 1e-9
    ):
        channels[0] = _DEFAULT_ROOT_CHANNELS[:3] + channels[0]
    angles = quat_angle(torch.from_numpy(motion.rotations)).amax(dim=0).numpy()  # (J,)
    for j, ch in enumerate(channels):
        if not any(c.endswith("rotation") for c in ch) and angles[j] > 1e-9:
            channels[j] = ch + _DEFAULT_CHANNELS
    return file_names, channels


def _check_writable(motion: Motion, scale: float, path: Path) -> None:
    """Raise :class:`BVHError` if ``motion`` cannot be written as a BVH that :func:`load_bvh` reads
    back (``scale``: metres per file unit)."""
    fps = float(motion.fps)
    if not (math.isfinite(fps) and fps > 0 and MIN_FRAME_TIME <= 1.0 / fps <= MAX_FRAME_TIME):
        raise BVHError(
            f"{path}: cannot write frame rate {fps:g} fps: the frame time must be positive and "
            "within "
            f"{MIN_FRAME_TIME:g}-{MAX_FRAME_TIME:g} s"
        )
    arrays = {
        "rotations": motion.rotations,
        "root positions": motion.root_positions / scale,
        "offsets": motion.skeleton.offsets / scale,
    }
    for what, values in arrays.items():
        if not np.isfinite(values).all():
            raise BVHError(f"{path}: cannot write non-finite (NaN or inf) {what}")
    for what in ("root positions", "offsets"):
        if np.abs(arrays[what]).max() > MAX_LENGTH:
            raise BVHError(
                f"{path}: cannot write {what} beyond the limit |x| <= {MAX_LENGTH:g} file units"
            )


def save_bvh(motion: Motion, path: str | os.PathLike, unit: str | float | None = None) -> None:
    """Write a motion as BVH (atomically), in the file's own unit and channel layout.

    Args:
        motion: the motion (``rotations (T, J, 4)``, ``root_positions (T, 3)`` metres).
        path: output ``.bvh`` path.
        unit: length unit to write (a :data:`UNIT_SCALES` name or metres per file unit); default
            ``motion.meta["unit_scale"]`` (the unit it was loaded in), else centimetres.

    Joint names and channel orders come from ``motion.meta`` (``file_joint_names``, ``channels``)
    when they match the skeleton, else the joint names with root
    ``Xposition Yposition Zposition Zrotation Xrotation Yrotation`` and ``Zrotation Xrotation
    Yrotation`` elsewhere. Non-root position channels are written as the constant offset.

    Raises:
        BVHError: the motion holds what :func:`load_bvh` would refuse (non-finite values, a frame
            rate outside 1-1000 fps, lengths beyond :data:`MAX_LENGTH` file units); nothing is
            written.
    """
    if unit is not None:
        _, scale = _resolve_unit(unit)
    else:
        scale = float(motion.meta.get("unit_scale", UNIT_SCALES["cm"]))
    _check_writable(motion, scale, Path(path))
    sk = motion.skeleton
    file_names, channels = _file_layout(motion)
    T, nj = motion.num_frames, sk.num_joints
    offsets = sk.offsets / scale

    # BVH stores joints depth-first: hierarchy and motion columns both follow that order
    children: list[list[int]] = [[] for _ in range(nj)]
    for j, p in enumerate(sk.parents):
        if p >= 0:
            children[p].append(j)
    order: list[int] = []
    stack = [0]
    while stack:
        j = stack.pop()
        order.append(j)
        stack.extend(reversed(children[j]))

    # motion block, (T, C), columns in depth-first joint order
    width = {j: len(channels[j]) for j in range(nj)}
    start, col = {}, 0
    for j in order:
        start[j], col = col, col + width[j]
    data = np.zeros((T, col))
    for j, ch in enumerate(channels):
        xyz = motion.root_positions / scale if j == 0 else np.broadcast_to(offsets[j], (T, 3))
        for k, c in enumerate(ch):
            if c.endswith("position"):
                data[:, start[j] + k] = xyz[:, "XYZ".index(c[0])]
    rot = torch.from_numpy(motion.rotations)
    for euler_order, idx in _euler_groups(channels).items():
        euler = quat_to_euler(rot[:, idx], euler_order, degrees=True).numpy()  # (T, k, 3)
        for n, j in enumerate(idx):
            cols = [start[j] + k for k, c in enumerate(channels[j]) if c.endswith("rotation")]
            data[:, cols] = euler[:, n]

    # hierarchy; a leaf without a known end site gets one half its own bone further on, as
    # exporters such as Blender always write an End Site for leaves
    out = ["HIERARCHY"]

    def block(j: int, depth: int) -> None:
        tab = "\t" * depth
        out.append(f"{tab}{'ROOT' if j == 0 else 'JOINT'} {file_names[j]}")
        out.append(f"{tab}{{")
        out.append(f"{tab}\tOFFSET {' '.join(f'{v:.6f}' for v in offsets[j])}")
        out.append(f"{tab}\tCHANNELS {len(channels[j])} {' '.join(channels[j])}".rstrip())
        for c in children[j]:
            block(c, depth + 1)
        end = sk.end_sites.get(j)
        if end is None and not children[j]:
            end = 0.5 * sk.offsets[j]
        if end is not None:
            end = np.asarray(end) / scale
            out.extend(
                [
                    f"{tab}\tEnd Site",
                    f"{tab}\t{{",
                    f"{tab}\t\tOFFSET {' '.join(f'{v:.6f}' for v in end)}",
                    f"{tab}\t}}",
                ]
            )
        out.append(f"{tab}}}")

    block(0, 0)
    out += ["MOTION", f"Frames: {T}", f"Frame Time: {1.0 / motion.fps:.8f}", ""]
    with atomic_write(path, "w") as f:
        f.write("\n".join(out))
        np.savetxt(f, data, fmt="%.6f", delimiter=" ")
