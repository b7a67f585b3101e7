"""BVH files into motions: units, rotation orders and the canonical-22 fold (:func:`load_bvh`,
:func:`load_canonical_bvh`, :func:`infer_unit_scale`)."""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import cast

import numpy as np
import torch

from ...core.motion import Motion
from ...core.rotations import quat_from_euler
from ...core.skeleton import Skeleton
from ...files import readable_file
from ..joint_maps import to_canonical22
from ..rig_maps import JointMapLike, strip_prefix
from .parse import (
    HUMAN_HEIGHT,
    MAX_FILE_BYTES,
    UNIT_SCALES,
    BVHError,
    _parse_hierarchy,
    _parse_motion,
)

__all__ = ["infer_unit_scale", "load_bvh"]


# ------------------------------------------------------------------------------------ units
def _resolve_unit(unit: str | float) -> tuple[str, float]:
    """``(name, metres per file unit)`` of a unit name or a positive float."""
    if isinstance(unit, str):
        key = unit.lower()
        if key not in UNIT_SCALES:
            raise ValueError(
                f"unknown unit {unit!r}; use one of {list(UNIT_SCALES)} or a float "
                "(metres per file unit)"
            )
        return key, UNIT_SCALES[key]
    scale = float(unit)
    if not scale > 0 or not math.isfinite(scale):
        raise ValueError(
            f"unit scale must be a positive number of metres per file unit, got {unit!r}"
        )
    name = next(
        (k for k, v in UNIT_SCALES.items() if math.isclose(v, scale, rel_tol=1e-9)), "custom"
    )
    return name, scale


def infer_unit_scale(points: np.ndarray) -> tuple[str, float]:
    """Guess a skeleton's length unit from its size.

    The height proxy is the largest extent along any axis of the rest-pose points (joints and end
    sites), i.e. the standing height for a T-pose or A-pose in any up-axis convention. The unit of
    :data:`UNIT_SCALES` whose scaled height is closest to :data:`HUMAN_HEIGHT` in log space wins.

    Args:
        points: ``(N, 3)`` rest-pose joint and end-site positions in file units.

    Returns:
        ``(unit name, metres per file unit)``; ``("cm", 0.01)`` for a degenerate (zero-size)
        skeleton.
    """
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    extent = float(np.ptp(pts, axis=0).max()) if len(pts) else 0.0
    if not extent > 0:
        return "cm", UNIT_SCALES["cm"]
    name = min(UNIT_SCALES, key=lambda k: abs(math.log(extent * UNIT_SCALES[k] / HUMAN_HEIGHT)))
    return name, UNIT_SCALES[name]


# ---------------------------------------------------------------------------------- loading
def _skeleton_names(file_names: list[str]) -> list[str]:
    """Names without namespace prefixes (``mixamorig:Hips`` -> ``Hips``) unless that collides."""
    stripped = [strip_prefix(n) for n in file_names]
    return stripped if len(set(stripped)) == len(stripped) else list(file_names)


def _euler_groups(channels: list[list[str]]) -> dict[str, list[int]]:
    """Joints grouped by their rotation order (e.g. ``"ZXY"``); joints without rotations omitted."""
    groups: dict[str, list[int]] = {}
    for j, ch in enumerate(channels):
        order = "".join(c[0] for c in ch if c.endswith("rotation"))
        if order:
            groups.setdefault(order, []).append(j)
    return groups


def load_bvh(path: str | os.PathLike, unit: str | float | None = None) -> Motion:
    """Read a BVH file into a :class:`~retarget_lib.core.motion.Motion` (lengths in metres).

    Args:
        path: the ``.bvh`` file (any channel order per joint, any joint count, tabs/CRLF fine).
        unit: the file's length unit: ``"m"``, ``"cm"``, ``"mm"``, ``"inch"``, ``"cmu"``, or a float
            (metres per file unit); ``None`` infers it from the skeleton's size
            (:func:`infer_unit_scale`).

    Returns:
        A Motion with ``rotations (T, J, 4)`` local wxyz, ``root_positions (T, 3)`` metres,
        ``fps = 1 / Frame Time`` (rounded to an integer when within 1e-4 relative), joint names
        without namespace prefixes, and ``meta``: ``unit``, ``unit_scale`` (metres per file unit),
        ``channels`` (per-joint channel names as in the file), ``file_joint_names``,
        ``source_path``, ``position_channels_folded`` / ``position_channels_dropped`` (non-root
        joints whose constant / varying position channels became their offset / were replaced by
        their mean), ``extra_frame_lines`` (lines after the ``Frames:`` count, ignored as assimp
        does; ``Boxing_Toes.bvh`` has one).

    Raises:
        BVHError: a malformed file or one beyond a bound (module docstring; the message names the
            line and the problem).
        InputFileError: missing, a directory, unreadable, empty or larger than
            :data:`MAX_FILE_BYTES`.
    """
    path = readable_file(path, "BVH file", MAX_FILE_BYTES)
    try:
        with open(path, encoding="utf-8", errors="replace") as f:
            _check_first_word(f.readline(4096))
            f.seek(0)
            lines = f.read().splitlines()
        return _build_motion(lines, path, unit)
    except BVHError as e:
        raise BVHError(f"{path}: {e}") from None


def _check_first_word(first: str) -> None:
    """Refuse a file whose first word is not ``HIERARCHY`` or ``ROOT`` before reading the rest of
    it (the first line, at most 4096 characters)."""
    word = first.lstrip("\ufeff").split()[:1]
    if not word or word[0].upper() not in ("HIERARCHY", "ROOT"):
        shown = first.strip()[:40]
        raise BVHError(f"line 1: expected HIERARCHY, found {shown!r}: not a BVH file")


def _build_motion(lines: list[str], path: Path, unit: str | float | None) -> Motion:
    joints, motion_idx = _parse_hierarchy(lines)
    channels = [j.channels for j in joints]
    starts = np.cumsum([0] + [len(c) for c in channels])
    data, frame_time, extra = _parse_motion(lines, motion_idx, channels)
    T, nj = data.shape[0], len(joints)

    offsets = np.stack(
        [cast(np.ndarray, j.offset) for j in joints]
    )  # file units; every parsed joint has one
    root_pos = np.repeat(offsets[:1], T, axis=0)
    folded: list[str] = []
    dropped: list[str] = []
    for j, ch in enumerate(channels):
        pos = sorted((c, k) for k, c in enumerate(ch) if c.endswith("position"))  # X, Y, Z
        if not pos:
            continue
        values = data[:, [starts[j] + k for _, k in pos]]  # (T, 3)
        if j == 0:
            root_pos = values
            continue
        offsets[j] = values.mean(axis=0)
        constant = np.ptp(values, axis=0).max() <= 1e-5 * max(1.0, float(np.abs(values).max()))
        (folded if constant else dropped).append(joints[j].name)

    rotations = np.zeros((T, nj, 4))
    rotations[..., 0] = 1.0
    for order, idx in _euler_groups(channels).items():
        cols = [
            [starts[j] + k for k, c in enumerate(channels[j]) if c.endswith("rotation")]
            for j in idx
        ]
        angles = torch.from_numpy(data[:, np.array(cols)])  # (T, k, 3) degrees, in file order
        rotations[:, idx] = quat_from_euler(angles, order, degrees=True).numpy()

    end_sites = {j: jt.end_site for j, jt in enumerate(joints) if jt.end_site is not None}
    rest = offsets.copy()  # rest-pose positions, file units
    for j, jt in enumerate(joints[1:], start=1):
        rest[j] += rest[jt.parent]
    points = np.concatenate([rest] + [rest[j : j + 1] + e for j, e in end_sites.items()])
    unit_name, scale = infer_unit_scale(points) if unit is None else _resolve_unit(unit)

    file_names = [jt.name for jt in joints]
    skeleton = Skeleton(
        tuple(_skeleton_names(file_names)),
        tuple(jt.parent for jt in joints),
        offsets * scale,
        {j: e * scale for j, e in end_sites.items()},
    )
    fps = 1.0 / frame_time
    if abs(fps - round(fps)) <= 1e-4 * fps:
        fps = float(round(fps))
    meta = {
        "source_path": str(path),
        "unit": unit_name,
        "unit_scale": scale,
        "channels": [list(c) for c in channels],
        "file_joint_names": file_names,
        "position_channels_folded": folded,
        "position_channels_dropped": dropped,
        "extra_frame_lines": extra,
    }
    return Motion(skeleton, rotations, root_pos * scale, fps, name=path.stem, meta=meta)


def load_canonical_bvh(
    path: str | os.PathLike,
    fps: float = 30.0,
    convention: str | None = None,
    mapping: JointMapLike = None,
) -> Motion:
    """:func:`load_bvh`, folded onto the canonical 22 joints
    (:func:`~retarget_lib.io.joint_maps.to_canonical22`) and resampled to ``fps``.

    Args:
        path: any BVH whose joints a rig convention of :data:`~retarget_lib.io.rig_maps.RIG_MAPS`
            or ``mapping`` names.
        fps: output frame rate.
        convention: a key of :data:`~retarget_lib.io.rig_maps.RIG_MAPS` (``None``: detected from
            the joint names).
        mapping: a joint map file or its entries (docs/joint-maps.md).

    Returns:
        The canonical-22 motion, ``rotations (T, 22, 4)``, at ``fps``.

    Raises:
        BVHError: a malformed file. JointSetError: joints that cannot be mapped (naming the file).
    """
    return to_canonical22(load_bvh(path), convention, mapping, what=str(path)).resample(fps)
