"""Character shape ``.npz`` files: the layout used by public Mixamo preprocessing
(``mixamo-local``).

Keys (units are the BVH's, usually centimetres):

========================  ===========  ==========================================================
key                       shape        meaning
========================  ===========  ==========================================================
``rest_vertices``         ``(V, 3)``   rest-pose vertices **relative to the root** (hips at 0)
``rest_faces``            ``(F, 3)``   triangle vertex indices, int
``skinning_weights``      ``(V, 22)``  LBS weights, rows sum to 1, columns in ``joint_names`` order
``skeleton``              ``(22, 3)``  rest **offsets** (each joint relative to its parent; row of
                                       the root = the root's rest position, as in the BVH)
``joint_names``           ``(22,)``    joint names of any rig convention (Mixamo's, with or
                                       without ``mixamorig:`` prefixes, usually) or of a joint
                                       map; each row's parent is its canonical parent
========================  ===========  ==========================================================

:func:`load_shape_npz` returns a :class:`~retarget_lib.core.character.Character` in the library's
conventions (canonical joint order, metres, vertices in the world rest pose = file vertices + the
root's rest position); :func:`save_shape_npz` writes one back.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import numpy as np

from ..core.character import Character
from ..core.skeleton import canonical22_skeleton
from ..errors import RetargetInputError
from ..files import atomic_write, readable_file
from .rig_maps import JointMapLike, map_joints, read_mapping, strip_prefix
from .untrusted import check_count, is_real_dtype, read_npz

__all__ = ["SHAPE_KEYS", "ShapeError", "load_shape_npz", "save_shape_npz"]

SHAPE_KEYS = ("rest_vertices", "rest_faces", "skinning_weights", "skeleton", "joint_names")
_UNITS = {"m": 1.0, "cm": 0.01, "mm": 0.001}
_WEIGHT_TOL = 1e-3
#: rows whose sum is off by more than _WEIGHT_TOL but at most this are renormalised (real Mixamo
#: exports store float32 weights whose rows sum to 0.997-1.0), with one line on stderr
_RENORMALIZE_TOL = 1e-2
#: bounds of a shape file (as the glTF reader's), checked from the arrays' headers before reading
MAX_VERTICES, MAX_FACES = 2_000_000, 4_000_000


class ShapeError(RetargetInputError):
    """A shape ``.npz`` that is not a valid character (the message names the file and the
    problem)."""


def _unit_scale(unit: str | float) -> float:
    """Metres per file unit for ``"m"``, ``"cm"``, ``"mm"`` or a positive number."""
    if isinstance(unit, str):
        if unit not in _UNITS:
            raise ValueError(
                f"unit must be one of {sorted(_UNITS)} or metres per unit, got {unit!r}"
            )
        return _UNITS[unit]
    if not unit > 0:
        raise ValueError(f"unit must be positive metres per file unit, got {unit!r}")
    return float(unit)


def _infer_scale(height: float) -> float:
    """Centimetres if the skeleton's NKN height exceeds 5 units (no character is 5 m), else
    metres."""
    return 0.01 if height > 5.0 else 1.0


def load_shape_npz(
    path: str | os.PathLike, unit: str | float | None = None, mapping: JointMapLike = None
) -> Character:
    """Read a character shape ``.npz``.

    Args:
        path: the file.
        unit: the file's length unit: ``"cm"``, ``"m"``, ``"mm"`` or metres per unit; ``None``
            infers cm vs m from the skeleton's size.
        mapping: a joint map file or its entries for joint names no rig convention covers
            (:mod:`~retarget_lib.io.rig_maps`; a shape file has all 22 joints: no ``null``).

    Returns:
        The :class:`~retarget_lib.core.character.Character` (named after the file stem), joints
        in canonical order, metres, vertices in the world rest pose.

    Raises:
        ShapeError: naming the problem: not a readable ``.npz`` (truncated, corrupt, pickled
            objects, a ``.npy``), missing keys, wrong shapes, NaN/inf values, face indices out of
            range, weight rows not summing to 1 (which rows).
        JointSetError: joints that cannot be mapped (all of them named), a bad joint map.
        InputFileError: missing, a directory, unreadable or empty.
        LimitError: more than :data:`MAX_VERTICES` vertices or :data:`MAX_FACES` faces, or an array
            beyond the budget (read from its header, before it is inflated).
    """
    path = readable_file(path, "shape .npz file")
    arrays = read_npz(
        path, SHAPE_KEYS, ShapeError, shape_check=lambda key, shape: _check_shape(path, key, shape)
    )
    missing = [k for k in SHAPE_KEYS if k not in arrays]
    if missing:
        raise ShapeError(f"{path}: missing keys {missing} (a shape file needs {list(SHAPE_KEYS)})")
    vertices, faces, weights, offsets, names = _validated(arrays, path)
    order = _canonical_order(names, path, mapping)
    offsets, weights = offsets[order], weights[:, order]
    scale = (
        _unit_scale(unit)
        if unit is not None
        else _infer_scale(canonical22_skeleton(offsets).height())
    )
    offsets = offsets * scale
    vertices = vertices * scale + offsets[0]
    return Character(
        path.stem,
        canonical22_skeleton(offsets),
        vertices,
        faces,
        weights,
        style=dict(source=str(path), unit_scale=scale),
    )


def _check_shape(path: Path, key: str, shape: tuple[int, ...]) -> None:
    """Refuse more vertices or faces than the bounds, from an array's header."""
    if key in ("rest_vertices", "skinning_weights") and shape:
        check_count(shape[0], MAX_VERTICES, f"vertices in {key}", str(path))
    if key == "rest_faces" and shape:
        check_count(shape[0], MAX_FACES, "faces", str(path))


def _validated(
    arrays: dict, path: Path
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, list[str]]:
    """Check shapes, finiteness, face indices and weight sums; return the arrays as
    ``(vertices, faces, weights, offsets, names)``."""
    vertices, faces, weights, offsets, names = (arrays[k] for k in SHAPE_KEYS)
    nv = len(vertices)
    expected = {
        "rest_vertices": (nv, 3),
        "rest_faces": (len(faces), 3),
        "skinning_weights": (nv, 22),
        "skeleton": (22, 3),
        "joint_names": (22,),
    }
    for key, shape in expected.items():
        if arrays[key].shape != shape:
            raise ShapeError(f"{path}: {key} must have shape {shape}, got {arrays[key].shape}")
    if not np.issubdtype(faces.dtype, np.integer):
        raise ShapeError(f"{path}: rest_faces must be integers, got {faces.dtype}")
    for key in ("rest_vertices", "skinning_weights", "skeleton"):
        if not is_real_dtype(arrays[key].dtype):
            raise ShapeError(f"{path}: {key} must be real numbers, got {arrays[key].dtype}")
    for key in ("rest_vertices", "skinning_weights", "skeleton"):
        bad = ~np.isfinite(arrays[key]).all(axis=-1)
        if bad.any():
            raise ShapeError(f"{path}: {key} has NaN or inf in rows {_rows(bad)}")
    if faces.size and (faces.min() < 0 or faces.max() >= nv):
        raise ShapeError(f"{path}: rest_faces index vertices outside 0..{nv - 1}")
    negative = (weights < 0).any(axis=1)
    if negative.any():
        raise ShapeError(
            f"{path}: skinning_weights must be >= 0; rows {_rows(negative)} have negative weights"
        )
    sums = weights.sum(axis=1)
    empty = sums <= 0
    if empty.any():
        raise ShapeError(
            f"{path}: skinning_weights rows {_rows(empty)} are all zero (vertices bound to no "
            "joint)"
        )
    off = np.abs(sums - 1.0) > _RENORMALIZE_TOL
    if off.any():
        raise ShapeError(
            f"{path}: skinning_weights rows must sum to 1 (within {_RENORMALIZE_TOL}); rows "
            f"{_rows(off)} "
            "do not"
        )
    drift = np.abs(sums - 1.0) > _WEIGHT_TOL
    if drift.any():
        print(
            f"{path}: renormalised {int(drift.sum())} skinning-weight rows that sum to "
            f"{sums[drift].min():.4f}..{sums[drift].max():.4f} (float32 export rounding)",
            file=sys.stderr,
        )
    weights = weights / sums[:, None]
    return (
        vertices.astype(np.float64),
        faces.astype(np.int64),
        weights.astype(np.float64),
        offsets.astype(np.float64),
        [strip_prefix(str(n)) for n in names],
    )


def _rows(mask: np.ndarray, limit: int = 10) -> str:
    """The indices where ``mask`` holds, the first ``limit`` of them, and how many in all."""
    idx = np.flatnonzero(mask)
    shown = ", ".join(str(i) for i in idx[:limit])
    return f"[{shown}{', ...' if len(idx) > limit else ''}] ({len(idx)} in all)"


def _canonical_order(names: list[str], path: Path, mapping: JointMapLike) -> list[int]:
    """File row of each canonical joint, by the rig conventions and ``mapping``
    (:func:`~retarget_lib.io.rig_maps.map_joints`; its errors name the file)."""
    entries, source = read_mapping(mapping)
    found, _ = map_joints(names, None, entries, what=str(path), mapping_source=source)
    row_of = {c: i for i, c in found.items()}
    return [row_of[c] for c in range(22)]


def save_shape_npz(
    character: Character,
    path: str | os.PathLike,
    unit: str | float = "cm",
    prefix: str = "mixamorig:",
) -> None:
    """Write a character in the shape ``.npz`` layout (atomically).

    Args:
        character: any :class:`~retarget_lib.core.character.Character`.
        path: destination file (written as given; use a ``.npz`` suffix).
        unit: the file's length unit (``"cm"`` like Mixamo BVH, ``"m"``, ``"mm"`` or metres per
            unit).
        prefix: put before each joint name (``""`` for none).
    """
    scale = _unit_scale(unit)
    offsets = character.skeleton.offsets
    with atomic_write(path) as f:
        np.savez(
            f,
            rest_vertices=(character.rest_vertices - offsets[0]) / scale,
            rest_faces=character.faces.astype(np.int64),
            skinning_weights=character.weights,
            skeleton=offsets / scale,
            joint_names=np.array([prefix + n for n in character.skeleton.joint_names]),
        )
