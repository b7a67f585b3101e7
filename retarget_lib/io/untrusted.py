"""Budgets and types for the content of untrusted files: the half of the trust boundary that
starts once the bytes are read (paths, the inputs of a run, temporary files and YAML are
:mod:`retarget_lib.files`; ``SECURITY.md`` states both).

Every count a file declares is checked against a limit, and the memory it implies against
:data:`MAX_ARRAY_BYTES`, *before* anything of that size is allocated; every JSON field a reader
uses is checked for its type first (:func:`typed_json`); every tree is walked iteratively.

=========================  ===============  ===================================================
budget                     value            why
=========================  ===============  ===================================================
one decoded array          1 GiB            a 2,000,000-vertex character's dense weights
                                            on 65 joints take 1.04 GB; a run stays ~2 GB
motion samples             3,000,000        frames x joints of one decoded motion, and of a
                                            result on the target's joints (96 MB of float64
                                            quaternions; 25 min of a 65-joint rig at 30 fps,
                                            75 min of 22 joints): measured, ``retarget`` to a
                                            BVH peaks at 1.8 GB there
JSON nesting               64               glTF nests 6 deep; extras/extensions a few more
JSON array                 100,000 items    nodes, accessors, a skin's joints ...
npz arrays                 1 GiB, and       decompressed size read from each member's header
                           <= member size   before anything is inflated (a zip bomb is refused)
=========================  ===============  ===================================================
"""

from __future__ import annotations

import json
import math
import os
import unicodedata
import zipfile
import zlib
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import LimitError, RetargetInputError, short_repr

__all__ = [
    "MAX_ARRAY_BYTES",
    "MAX_MOTION_SAMPLES",
    "MAX_JSON_DEPTH",
    "MAX_JSON_ITEMS",
    "check_count",
    "check_array_bytes",
    "check_motion_samples",
    "Leaf",
    "Arr",
    "Obj",
    "JsonObject",
    "INDEX",
    "COUNT",
    "INT",
    "NUMBER",
    "TEXT",
    "FLAG",
    "ANY",
    "parse_json",
    "typed_json",
    "name_problem",
    "is_real_dtype",
    "npz_keys",
    "read_npz",
]

MAX_ARRAY_BYTES = 2**30
MAX_MOTION_SAMPLES = 3_000_000
MAX_JSON_DEPTH = 64
MAX_JSON_ITEMS = 100_000


# ----------------------------------------------------------------------------------- budgets
def check_count(count: int, limit: int, what: str, where: str) -> None:
    """Raise :class:`~retarget_lib.errors.LimitError` if ``count`` exceeds ``limit``.

    Args:
        count: what the file declares.
        limit: the documented bound.
        what: the counted things (``"vertices"``), for the message.
        where: the file, and the part of it, for the message.
    """
    if count > limit:
        raise LimitError(f"{where}: {count:,} {what} exceed the limit of {limit:,}")


def check_array_bytes(shape: Sequence[int], itemsize: int, what: str, where: str) -> None:
    """Raise :class:`~retarget_lib.errors.LimitError` if an array of ``shape`` would take more than
    :data:`MAX_ARRAY_BYTES` (computed in Python integers: no overflow)."""
    nbytes = math.prod(int(n) for n in shape) * int(itemsize)
    if nbytes > MAX_ARRAY_BYTES:
        dims = " x ".join(f"{int(n):,}" for n in shape)
        raise LimitError(
            f"{where}: {what} ({dims}) would take {nbytes / 2**30:.1f} GiB, beyond the "
            f"{MAX_ARRAY_BYTES / 2**30:.0f} GiB budget for one array"
        )


def check_motion_samples(frames: int, joints: int, where: str, hint: str = "") -> None:
    """Raise :class:`~retarget_lib.errors.LimitError` if a motion of ``frames`` x ``joints``
    exceeds :data:`MAX_MOTION_SAMPLES` (``hint`` is appended to the message)."""
    if frames * joints > MAX_MOTION_SAMPLES:
        raise LimitError(
            f"{where}: {frames:,} frames x {joints} joints = {frames * joints:,} joint-frames "
            "exceed the "
            f"limit of {MAX_MOTION_SAMPLES:,} for one motion{hint}"
        )


# ------------------------------------------------------------------------------- typed JSON
@dataclass(frozen=True)
class Leaf:
    """A JSON value of one kind: ``ok(value)`` says whether it fits, ``described`` says what it
    must be (in messages)."""

    described: str
    ok: Callable[[Any], bool]


@dataclass(frozen=True)
class Arr:
    """A JSON array of ``item`` values (exactly ``length`` of them if given)."""

    item: Any
    length: int | None = None


@dataclass(frozen=True)
class Obj:
    """A JSON object: ``fields`` by name (a name ending in ``!`` is required, null counts as
    absent), and ``rest`` for the values of every other key (``None``: other keys are ignored)."""

    fields: dict[str, Any] = field(default_factory=dict)
    rest: Any = None


def _is_int(v: Any) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


def _is_finite_number(v: Any) -> bool:
    if _is_int(v):
        return abs(v) < 2**1000
    return isinstance(v, float) and math.isfinite(v)


INDEX = Leaf("an index (an integer >= 0)", lambda v: _is_int(v) and 0 <= v < 2**31)
COUNT = Leaf("a count (an integer >= 0)", lambda v: _is_int(v) and 0 <= v < 2**53)
INT = Leaf("an integer", lambda v: _is_int(v) and abs(v) < 2**53)
NUMBER = Leaf("a finite number", _is_finite_number)
TEXT = Leaf("a string", lambda v: isinstance(v, str))
FLAG = Leaf("true or false", lambda v: isinstance(v, bool))
ANY = Leaf("any JSON value", lambda v: True)


class JsonObject:
    """A checked JSON object: declared fields as attributes (``None`` when absent, ``[]`` for an
    absent array), other keys of a ``rest`` spec through :meth:`items` and attributes."""

    __slots__ = ("_values",)

    def __init__(self, values: dict[str, Any]) -> None:
        self._values = values

    def __getattr__(self, name: str) -> Any:
        return self._values.get(name)

    def items(self):
        """The ``(key, value)`` pairs present."""
        return self._values.items()


def _kind(value: Any) -> str:
    kinds = {
        dict: "an object",
        list: "an array",
        str: "a string",
        bool: "a boolean",
        type(None): "null",
    }
    return f"{short_repr(value)} ({kinds.get(type(value), 'a number')})"


def _describe(spec: Any) -> str:
    if isinstance(spec, Leaf):
        return spec.described
    if isinstance(spec, Arr):
        return f"an array of {spec.length} items" if spec.length else "an array"
    return "a JSON object"


def _typed(value: Any, spec: Any, where: str) -> Any:
    """``value`` checked against ``spec`` and converted (objects to :class:`JsonObject`); raises
    ``ValueError(problem)`` naming the JSON path ``where``."""
    if isinstance(spec, Leaf):
        if not spec.ok(value):
            raise ValueError(f"{where} must be {spec.described}, got {_kind(value)}")
        return value
    if isinstance(spec, Arr):
        if not isinstance(value, list) or (spec.length is not None and len(value) != spec.length):
            raise ValueError(f"{where} must be {_describe(spec)}, got {_kind(value)}")
        if len(value) > MAX_JSON_ITEMS:
            raise ValueError(
                f"{where} has {len(value):,} items, beyond the limit of {MAX_JSON_ITEMS:,}"
            )
        return [_typed(v, spec.item, f"{where}[{i}]") for i, v in enumerate(value)]
    if not isinstance(value, dict):
        raise ValueError(f"{where} must be a JSON object, got {_kind(value)}")
    out: dict[str, Any] = {}
    for name, sub in spec.fields.items():
        key = name.rstrip("!")
        if value.get(key) is None:
            if name.endswith("!"):
                raise ValueError(
                    f"{where}.{key} is required" + (", got null" if key in value else "")
                )
            if isinstance(sub, Arr):
                out[key] = []
            continue
        out[key] = _typed(value[key], sub, f"{where}.{key}")
    if spec.rest is not None:
        declared = {name.rstrip("!") for name in spec.fields}
        for key, v in value.items():
            if key not in declared and v is not None:
                out[key] = _typed(v, spec.rest, f"{where}.{key}")
    return JsonObject(out)


def typed_json(value: Any, spec: Obj, where: str, error: type[RetargetInputError]) -> JsonObject:
    """Check the parts of a parsed JSON document that a reader uses against ``spec`` (their types,
    fixed lengths, indices >= 0, finite numbers) and convert them.

    Args:
        value: the parsed document.
        spec: :class:`Obj` / :class:`Arr` / :class:`Leaf` description of what is used.
        where: the file, for messages.
        error: the exception type to raise.

    Raises:
        error: naming the JSON path of the first value of the wrong type.
    """
    try:
        return _typed(value, spec, "the JSON")
    except ValueError as e:
        raise error(f"{where}: {str(e).replace('the JSON.', '', 1)}") from None


def _reject_constant(name: str) -> None:
    raise ValueError(f"holds {name}, which is not a JSON number")


def _depth_exceeds(data: Any, limit: int) -> bool:
    """Whether ``data`` nests deeper than ``limit`` (an iterative walk)."""
    stack = [(data, 1)]
    while stack:
        value, depth = stack.pop()
        if isinstance(value, (dict, list)):
            if depth > limit:
                return True
            stack.extend(
                (v, depth + 1) for v in (value.values() if isinstance(value, dict) else value)
            )
    return False


def parse_json(text: bytes | str, where: str, error: type[RetargetInputError]) -> Any:
    """Parse untrusted JSON: NaN/Infinity refused, nesting at most :data:`MAX_JSON_DEPTH`.

    Raises:
        error: not UTF-8, malformed, a non-number constant, or nested too deep.
    """
    try:
        data = json.loads(text, parse_constant=_reject_constant)
    except RecursionError:
        raise error(
            f"{where}: the JSON is nested more than {MAX_JSON_DEPTH} deep (the limit)"
        ) from None
    except (ValueError, UnicodeDecodeError) as e:
        raise error(f"{where}: not valid JSON: {str(e).splitlines()[0][:200]}") from None
    if _depth_exceeds(data, MAX_JSON_DEPTH):
        raise error(f"{where}: the JSON is nested more than {MAX_JSON_DEPTH} deep (the limit)")
    return data


# ------------------------------------------------------------------------------------ names
def name_problem(name: str, bvh: bool = False) -> str | None:
    """Why a joint name cannot be written safely, or ``None``.

    Every format: the name must be non-empty and hold no control or format character (a line
    break would start a new BVH line; ``\\x00\\x01`` separates an FBX name from its class). A BVH
    name must also hold no brace and no leading, trailing or repeated whitespace (the reader
    takes the rest of the line, split on whitespace, as the name).
    """
    if not name:
        return "is empty"
    if any(unicodedata.category(c) in ("Cc", "Cf", "Zl", "Zp") for c in name):
        return "holds a control character (a line break, tab or NUL)"
    if bvh and ("{" in name or "}" in name):
        return "holds a brace, which BVH uses for nesting"
    if bvh and name != " ".join(name.split()):
        return "has leading, trailing or repeated whitespace, which BVH does not keep"
    return None


# -------------------------------------------------------------------------------------- npz
_NPY_MAGIC = b"\x93NUMPY"
_ZIP_MAGICS = (b"PK\x03\x04", b"PK\x05\x06")


def is_real_dtype(dtype: np.dtype) -> bool:
    """Integers or floats: what numeric arrays of a file may be (not booleans, complex numbers,
    strings or objects, which would fail or warn when used as numbers)."""
    return np.issubdtype(dtype, np.integer) or np.issubdtype(dtype, np.floating)


def _check_archive(path: Path, error: type[RetargetInputError]) -> None:
    with open(path, "rb") as f:
        head = f.read(6)
    if head.startswith(_NPY_MAGIC):
        raise error(
            f"{path}: a single .npy array, not an .npz archive of named arrays (write it with "
            "np.savez)"
        )
    if not head.startswith(_ZIP_MAGICS):
        raise error(f"{path}: not an .npz file (an .npz is a zip archive of .npy arrays)")


def npz_keys(path: str | os.PathLike, error: type[RetargetInputError]) -> list[str]:
    """The array names of an ``.npz`` file (nothing is decompressed).

    Raises:
        error: a ``.npy`` file, not a zip archive, or a corrupt one.
    """
    path = Path(path)
    _check_archive(path, error)
    try:
        with zipfile.ZipFile(path) as zf:
            return [n[: -len(".npy")] for n in zf.namelist() if n.endswith(".npy")]
    except (zipfile.BadZipFile, OSError, ValueError, EOFError) as e:
        raise error(f"{path}: not a readable .npz file (truncated or corrupt?): {e}") from None


def _header(
    member, path: Path, key: str, error: type[RetargetInputError]
) -> tuple[tuple[int, ...], np.dtype]:
    """``(shape, dtype)`` from the ``.npy`` header of one member (its data not read)."""
    version = np.lib.format.read_magic(member)
    if version == (1, 0):
        shape, _, dtype = np.lib.format.read_array_header_1_0(member)
    elif version == (2, 0):
        shape, _, dtype = np.lib.format.read_array_header_2_0(member)
    else:
        raise error(
            f"{path}: array {key!r} has .npy format version {version}, which is not read here"
        )
    return tuple(int(n) for n in shape), dtype


def read_npz(
    path: str | os.PathLike,
    keys: Sequence[str],
    error: type[RetargetInputError],
    objects_skipped: Sequence[str] = (),
    shape_check: Callable[[str, tuple], None] | None = None,
) -> dict[str, np.ndarray]:
    """The arrays ``keys`` of an ``.npz`` file (those present), each checked before it is inflated:
    its header's size must fit :data:`MAX_ARRAY_BYTES` and the member's declared size.

    Args:
        path: the file (already checked by :func:`~retarget_lib.files.readable_file`).
        keys: the array names wanted.
        error: the exception type to raise.
        objects_skipped: names whose pickled (object) arrays are left out instead of refused.
        shape_check: ``shape_check(key, shape)`` raises for a shape the caller cannot take (e.g.
            too many frames), before the array is read.

    Raises:
        error: not an ``.npz``, truncated or corrupt, a pickled object array, a header that
            declares more data than its member holds.
        LimitError: an array beyond the budget.
    """
    path = Path(path)
    _check_archive(path, error)
    out: dict[str, np.ndarray] = {}
    try:
        with zipfile.ZipFile(path) as zf:
            members = {
                n[: -len(".npy")]: zf.getinfo(n) for n in zf.namelist() if n.endswith(".npy")
            }
            for key in (k for k in keys if k in members):
                info = members[key]
                with zf.open(info) as member:
                    shape, dtype = _header(member, path, key, error)
                if dtype.hasobject:
                    if key in objects_skipped:
                        continue
                    raise error(
                        f"{path}: key {key!r} is a pickled object array; store plain numbers"
                    )
                check_array_bytes(shape, dtype.itemsize, f"array {key!r}", str(path))
                if math.prod(shape) * dtype.itemsize > info.file_size:
                    raise error(
                        f"{path}: array {key!r} declares {shape} of {dtype}, more than its "
                        f"{info.file_size:,} bytes hold (truncated or corrupt)"
                    )
                if shape_check is not None:
                    shape_check(key, shape)
                with zf.open(info) as member:
                    out[key] = np.lib.format.read_array(member, allow_pickle=False)
    except RetargetInputError:
        raise
    except (
        zipfile.BadZipFile,
        OSError,
        ValueError,
        EOFError,
        zlib.error,
        NotImplementedError,
    ) as e:
        raise error(f"{path}: not a readable .npz file (truncated or corrupt?): {e}") from None
    return out
