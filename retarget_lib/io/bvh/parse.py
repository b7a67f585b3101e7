"""The BVH text under limits: the tokenizer, the HIERARCHY block (joints, offsets, channels) and
the MOTION block (frame count, frame time, channel values), checked before anything is built."""

from __future__ import annotations

import re
from itertools import chain

import numpy as np

from ...errors import RetargetInputError

__all__ = [
    "BVHError",
    "UNIT_SCALES",
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
