"""BVH (Biovision Hierarchy) reading and writing, for any joint set.

A BVH file has a ``HIERARCHY`` section (a tree of ``JOINT`` blocks, each with an ``OFFSET``, a
``CHANNELS`` line and optional ``End Site`` leaves) and a ``MOTION`` section (``Frames:``,
``Frame Time:`` and one line of channel values per frame).

Semantics used here (the common ones, e.g. Blender's and Holden's readers):

* rotation channels are Euler angles in degrees, composed in the order listed:
  ``Zrotation Xrotation Yrotation`` means ``R = Rz(a) @ Rx(b) @ Ry(c)``
  (:func:`~retarget_lib.core.rotations.quat_from_euler`); any permutation of the three axes is
  accepted;
* position channels *replace* the joint's ``OFFSET``: the root's become ``Motion.root_positions``
  (the root ``OFFSET`` is kept as the skeleton's rest root position); a non-root joint's constant
  position channels become its offset; varying ones cannot be represented by a
  :class:`~retarget_lib.core.skeleton.Skeleton` and are replaced by their mean (recorded in
  ``meta["position_channels_dropped"]``);
* lengths are converted to metres on load and back to the file's unit on save (see
  :func:`infer_unit_scale`).

The ``MOTION`` block is parsed with NumPy in one conversion, not value by value: the CMU clips
(3-5k frames x 96 channels) load in well under a second. Loading is linear in the file's size.

Bounds (:class:`BVHError` naming the line and the bound, or
:class:`~retarget_lib.errors.InputFileError` for the file size), each far beyond any real clip:

=========================  ==============  ==================================================
bound                      value           why
=========================  ==============  ==================================================
file size                  64 MiB          CMU's longest clips are ~10 MiB; checked before
                                           reading, and a file whose first word is not
                                           ``HIERARCHY`` is refused after its first line
joints                     1000            Mixamo with fingers has 65, SMPL-X 55, CMU 31
nesting depth              100             the longest human chain (root to a fingertip) ~25
frames (declared)          1,000,000       9 h at 30 fps
frame time                 0.001-1 s       1 to 1000 frames per second
rotation values            |a| <= 1e5 deg  larger angles have lost all precision (1e308 would
                                           turn into noise, not a rotation)
offsets and positions      |x| <= 1e6      file units: 10 km in centimetres
=========================  ==============  ==================================================

:func:`save_bvh` refuses what :func:`load_bvh` would refuse (non-finite values, a frame rate
outside those bounds, lengths beyond them), so every file it writes loads back.
"""

from __future__ import annotations

import math
import os
import re
from itertools import chain
from pathlib import Path
from typing import cast

import numpy as np
import torch

from ..core.motion import Motion
from ..core.rotations import quat_angle, quat_from_euler, quat_to_euler
from ..core.skeleton import Skeleton
from ..errors import RetargetInputError
from ..files import atomic_write, readable_file
from .joint_maps import to_canonical22
from .rig_maps import JointMapLike, strip_prefix

__all__ = [
    "BVHError",
    "UNIT_SCALES",
    "infer_unit_scale",
    "load_bvh",
    "save_bvh",
    "MAX_FILE_BYTES",
    "MAX_JOINTS",
    "MAX_DEPTH",
    "MAX_FRAMES",
    "MIN_FRAME_TIME",
    "MAX_FRAME_TIME",
    "MAX_ANGLE_DEG",
    "MAX_LENGTH",
]

#: Metres per file unit of the length units met in BVH files. ``"cmu"`` is the ASF/AMC length unit
#: of the CMU database (``length = 1/0.45`` inch), kept by the cgspeed BVH conversion.
UNIT_SCALES: dict[str, float] = {
    "m": 1.0,
    "cm": 0.01,
    "mm": 0.001,
    "inch": 0.0254,
    "cmu": 0.0254 / 0.45,
}
#: The height (metres) a unit is chosen to reproduce when the file does not say.
HUMAN_HEIGHT = 1.7

_CHANNELS = {
    c.lower(): c
    for c in ("Xposition", "Yposition", "Zposition", "Xrotation", "Yrotation", "Zrotation")
}
# bounds (module docstring: why each)
MAX_FILE_BYTES = 64 * 2**20
MAX_JOINTS = 1000
MAX_DEPTH = 100
MAX_FRAMES = 1_000_000
MIN_FRAME_TIME, MAX_FRAME_TIME = 1e-3, 1.0
MAX_ANGLE_DEG = 1e5
MAX_LENGTH = 1e6

_DEFAULT_ROOT_CHANNELS = [
    "Xposition",
    "Yposition",
    "Zposition",
    "Zrotation",
    "Xrotation",
    "Yrotation",
]
_DEFAULT_CHANNELS = ["Zrotation", "Xrotation", "Yrotation"]
_TOKEN = re.compile(r"[{}]|[^\s{}]+")
_FRAMES = re.compile(r"^\s*Frames\s*:\s*(\S*)\s*$", re.IGNORECASE)
_FRAME_TIME = re.compile(r"^\s*Frame\s+Time\s*:\s*(\S*)\s*$", re.IGNORECASE)


class BVHError(RetargetInputError):
    """A malformed BVH file; the message names the file, the line number and the problem."""


# --------------------------------------------------------------------------------- parsing
class _Joint:
    """One parsed ``ROOT``/``JOINT`` block (lengths in file units)."""

    def __init__(self, name: str, parent: int, line: int) -> None:
        self.name = name
        self.parent = parent
        self.line = line
        self.offset: np.ndarray | None = None
        self.channels: list[str] = []
        self.end_site: np.ndarray | None = None


class _Tokens:
    """The hierarchy's tokens with their line numbers; braces are tokens of their own."""

    def __init__(self, lines: list[str], end_line: int, end_what: str) -> None:
        self.items = [(tok, n + 1) for n, line in enumerate(lines) for tok in _TOKEN.findall(line)]
        self.pos = 0
        self.end_line = end_line  # where the hierarchy stops (the MOTION line or the last line)
        self.end_what = end_what

    def done(self) -> bool:
        return self.pos >= len(self.items)

    def next(self, expected: str) -> tuple[str, int]:
        if self.done():
            raise BVHError(
                f"line {self.end_line}: unexpected {self.end_what} in the hierarchy, "
                f"expected {expected} (unbalanced braces?)"
            )
        item = self.items[self.pos]
        self.pos += 1
        return item

    def rest_of_line(self, line: int) -> list[str]:
        """Consume the tokens left on ``line`` up to the next brace."""
        out = []
        while (
            not self.done()
            and self.items[self.pos][1] == line
            and self.items[self.pos][0] not in "{}"
        ):
            out.append(self.items[self.pos][0])
            self.pos += 1
        return out


def _floats(tokens: list[str], count: int, what: str, line: int) -> np.ndarray:
    if len(tokens) != count:
        raise BVHError(f"line {line}: {what} needs {count} numbers, found {len(tokens)}: {tokens}")
    try:
        out = np.array([float(t) for t in tokens])
    except ValueError:
        raise BVHError(f"line {line}: bad number in {what}: {tokens}") from None
    if not np.isfinite(out).all():
        raise BVHError(f"line {line}: non-finite number in {what}: {tokens}")
    if np.abs(out).max() > MAX_LENGTH:
        raise BVHError(
            f"line {line}: {what} value beyond the limit |x| <= {MAX_LENGTH:g} file units: {tokens}"
        )
    return out


def _parse_channels(tokens: list[str], line: int, joint: str) -> list[str]:
    if not tokens:
        raise BVHError(f"line {line}: CHANNELS of joint {joint!r} needs a count")
    try:
        n = int(tokens[0])
    except ValueError:
        raise BVHError(
            f"line {line}: bad channel count {tokens[0]!r} for joint {joint!r}"
        ) from None
    names = tokens[1:]
    if n != len(names):
        raise BVHError(
            f"line {line}: CHANNELS of joint {joint!r} says {n} but lists {len(names)}: {names}"
        )
    out = []
    for name in names:
        canon = _CHANNELS.get(name.lower())
        if canon is None:
            raise BVHError(
                f"line {line}: unknown channel name {name!r} for joint {joint!r} "
                f"(expected one of {sorted(_CHANNELS.values())})"
            )
        out.append(canon)
    for kind in ("position", "rotation"):
        axes = [c[0] for c in out if c.endswith(kind)]
        if axes and sorted(axes) != ["X", "Y", "Z"]:
            raise BVHError(
                f"line {line}: joint {joint!r} has {kind} channels for axes {axes}; "
                f"expected none or each of X, Y, Z once"
            )
    return out


def _parse_block(
    tok: _Tokens,
    joints: list[_Joint],
    by_name: dict[str, _Joint],
    parent: int,
    name_line: int,
    depth: int = 1,
) -> None:
    """Parse one ``ROOT``/``JOINT`` block whose keyword was on ``name_line``, ``depth`` levels deep
    (the root is 1); ``by_name`` indexes ``joints`` by name."""
    name = " ".join(tok.rest_of_line(name_line))
    if not name:
        raise BVHError(f"line {name_line}: joint without a name")
    if name in by_name:
        raise BVHError(
            f"line {name_line}: duplicate joint name {name!r} (first on line {by_name[name].line})"
        )
    if len(joints) >= MAX_JOINTS:
        raise BVHError(
            f"line {name_line}: more than {MAX_JOINTS} joints (the limit; real skeletons have < "
            "100)"
        )
    if depth > MAX_DEPTH:
        raise BVHError(
            f"line {name_line}: joints nested more than {MAX_DEPTH} deep (the limit; human "
            "skeletons nest < 30)"
        )
    joint = _Joint(name, parent, name_line)
    joints.append(joint)
    by_name[name] = joint
    index = len(joints) - 1
    t, line = tok.next(f"'{{' after joint {name!r}")
    if t != "{":
        raise BVHError(f"line {line}: expected '{{' after joint {name!r}, found {t!r}")
    while True:
        t, line = tok.next(f"'}}' closing joint {name!r} (opened on line {name_line})")
        key = t.upper()
        if t == "}":
            break
        if key == "OFFSET":
            joint.offset = _floats(tok.rest_of_line(line), 3, "OFFSET", line)
        elif key == "CHANNELS":
            joint.channels = _parse_channels(tok.rest_of_line(line), line, name)
        elif key == "JOINT":
            _parse_block(tok, joints, by_name, index, line, depth + 1)
        elif key == "END":
            _parse_end_site(tok, joint, line)
        elif key == "ROOT":
            raise BVHError(
                f"line {line}: ROOT inside joint {name!r} (opened on line {name_line}): "
                "unbalanced braces?"
            )
        else:
            raise BVHError(f"line {line}: unexpected {t!r} in joint {name!r}")
    if joint.offset is None:
        raise BVHError(f"line {name_line}: joint {name!r} has no OFFSET")


def _parse_end_site(tok: _Tokens, joint: _Joint, end_line: int) -> None:
    rest = tok.rest_of_line(end_line)
    if [r.upper() for r in rest] != ["SITE"]:
        raise BVHError(f"line {end_line}: expected 'End Site', found {' '.join(['End', *rest])!r}")
    if joint.end_site is not None:
        raise BVHError(f"line {end_line}: joint {joint.name!r} has a second End Site")
    t, line = tok.next("'{' after End Site")
    if t != "{":
        raise BVHError(f"line {line}: expected '{{' after End Site, found {t!r}")
    offset = None
    while True:
        t, line = tok.next(f"'}}' closing the End Site opened on line {end_line}")
        if t == "}":
            break
        if t.upper() != "OFFSET":
            raise BVHError(f"line {line}: unexpected {t!r} in End Site (only OFFSET is allowed)")
        offset = _floats(tok.rest_of_line(line), 3, "OFFSET", line)
    if offset is None:
        raise BVHError(f"line {end_line}: End Site of joint {joint.name!r} has no OFFSET")
    joint.end_site = offset


def _parse_hierarchy(lines: list[str]) -> tuple[list[_Joint], int]:
    """Parse ``HIERARCHY``; return the joints (parents first) and the index of the MOTION line."""
    motion_idx = next(
        (
            i
            for i, line in enumerate(lines)
            if line.split()[:1] and line.split()[0].upper() == "MOTION"
        ),
        None,
    )
    head = lines if motion_idx is None else lines[:motion_idx]
    end_line = len(lines) if motion_idx is None else motion_idx + 1
    tok = _Tokens(head, end_line, "end of file" if motion_idx is None else "MOTION")
    t, line = tok.next("HIERARCHY")
    if t.upper() == "HIERARCHY":
        t, line = tok.next("ROOT")
    if t.upper() != "ROOT":
        raise BVHError(f"line {line}: expected ROOT, found {t!r}")
    joints: list[_Joint] = []
    _parse_block(tok, joints, {}, -1, line)
    if not tok.done():
        t, line = tok.next("")
        if t.upper() == "ROOT":
            raise BVHError(f"line {line}: multiple ROOTs (only one skeleton per file is supported)")
        if t == "}":
            raise BVHError(f"line {line}: unmatched '}}' (unbalanced braces)")
        raise BVHError(f"line {line}: unexpected {t!r} after the ROOT block")
    if motion_idx is None:
        raise BVHError(
            f"line {len(lines)}: missing MOTION section (end of file after the hierarchy)"
        )
    return joints, motion_idx


def _header_value(lines: list[str], idx: int, pattern: re.Pattern, what: str) -> tuple[str, int]:
    """Find ``what`` (``Frames:``/``Frame Time:``) on the first non-blank line at or after
    ``idx``."""
    while idx < len(lines) and not lines[idx].strip():
        idx += 1
    if idx >= len(lines):
        raise BVHError(f"line {len(lines)}: unexpected end of file, expected '{what}'")
    m = pattern.match(lines[idx])
    if m is None:
        raise BVHError(f"line {idx + 1}: expected '{what} <number>', found {lines[idx].strip()!r}")
    return m.group(1), idx


def _parse_motion(
    lines: list[str], motion_idx: int, channels: list[list[str]]
) -> tuple[np.ndarray, float, int]:
    """Parse ``MOTION`` (``channels``: each joint's, in file order).

    Returns:
        ``(values (T, C) in file units and degrees, frame time in seconds, number of ignored
        non-blank lines after the declared frames)``.
    """
    n_channels = sum(len(c) for c in channels)
    value, fi = _header_value(lines, motion_idx + 1, _FRAMES, "Frames:")
    try:
        n_frames = int(value)
    except ValueError:
        raise BVHError(f"line {fi + 1}: bad frame count {value!r}") from None
    if n_frames <= 0:
        raise BVHError(
            f"line {fi + 1}: the file has {n_frames} frames; a motion needs at least one"
        )
    if n_frames > MAX_FRAMES:
        raise BVHError(f"line {fi + 1}: {n_frames} frames exceed the limit of {MAX_FRAMES}")
    value, ti = _header_value(lines, fi + 1, _FRAME_TIME, "Frame Time:")
    try:
        frame_time = float(value)
    except ValueError:
        raise BVHError(f"line {ti + 1}: bad frame time {value!r}") from None
    if not MIN_FRAME_TIME <= frame_time <= MAX_FRAME_TIME:
        raise BVHError(
            f"line {ti + 1}: frame time must be positive and within the limits {MIN_FRAME_TIME:g}-"
            f"{MAX_FRAME_TIME:g} s (1 to 1000 frames per second), got {value!r}"
        )

    rows: list[list[str]] = []
    numbers: list[int] = []  # 1-based line number of each row
    for n, line in enumerate(lines[ti + 1 :], start=ti + 2):
        parts = line.split()
        if parts:
            rows.append(parts)
            numbers.append(n)
    if len(rows) < n_frames:
        raise BVHError(
            f"line {len(lines)}: unexpected end of file: 'Frames: {n_frames}' "
            f"(line {fi + 1}) but the motion block is truncated after {len(rows)} frames"
        )
    extra = len(rows) - n_frames
    rows = rows[:n_frames]  # like assimp, lines beyond the declared count are ignored
    counts = np.fromiter((len(r) for r in rows), dtype=np.int64, count=len(rows))
    bad = np.flatnonzero(counts != n_channels)
    if bad.size:
        k = int(bad[0])
        raise BVHError(
            f"line {numbers[k]}: frame {k} has {counts[k]} values; the hierarchy "
            f"declares {n_channels} channels"
        )
    try:
        data = np.array(list(chain.from_iterable(rows)), dtype=np.float64)
    except ValueError:
        for k, row in enumerate(rows):  # only on error: find the offending token
            for t in row:
                try:
                    float(t)
                except ValueError:
                    raise BVHError(f"line {numbers[k]}: bad number {t!r} in frame {k}") from None
        raise
    data = data.reshape(n_frames, n_channels)
    finite = np.isfinite(data).all(axis=1)
    if not finite.all():
        k = int(np.flatnonzero(~finite)[0])
        raise BVHError(f"line {numbers[k]}: non-finite value in frame {k}")
    _check_magnitudes(data, channels, numbers)
    return data, frame_time, extra


def _check_magnitudes(data: np.ndarray, channels: list[list[str]], numbers: list[int]) -> None:
    """Raise :class:`BVHError` naming the first line with a rotation beyond :data:`MAX_ANGLE_DEG`
    or a position beyond :data:`MAX_LENGTH` (``numbers``: the line of each frame)."""
    names = list(chain.from_iterable(channels))
    rotation = np.array([c.endswith("rotation") for c in names], dtype=bool)
    limit = np.where(rotation, MAX_ANGLE_DEG, MAX_LENGTH)
    over = (np.abs(data) > limit).any(axis=1)
    if over.any():
        k = int(np.flatnonzero(over)[0])
        c = int(np.flatnonzero(np.abs(data[k]) > limit)[0])
        what = (
            f"rotation beyond |a| <= {MAX_ANGLE_DEG:g} degrees"
            if rotation[c]
            else f"position beyond |x| <= {MAX_LENGTH:g} file units"
        )
        raise BVHError(
            f"line {numbers[k]}: {names[c]} value {data[k, c]:g} in frame {k} is a {what} (the "
            "limit)"
        )


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
