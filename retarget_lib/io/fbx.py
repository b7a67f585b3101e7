"""FBX characters and animations through the Open Asset Import Library (the optional ``fbx`` extra).

Set-up: Debian's ``libassimp5`` (the C++ library, 12.7 MB installed with its two dependencies) and
the PyPI binding ``impasse`` (``pip install -e .[fbx]``). Chosen over Blender as a Python module
(PyPI ``bpy`` 5.0.1: a 374 MB download, 821 MB installed, and it pins ``numpy<2``, which the
suite's environment cannot take); ``pyassimp`` 5.2.5 fails on Debian's ``libassimp5`` 5.2.5 with a
NULL pointer access on the first skinned file, ``impasse`` (its maintained fork, cffi) reads it.

How: assimp converts the FBX into a binary glTF, and the glTF reader does the rest
(:func:`~retarget_lib.io.gltf.rig_from`, :func:`~retarget_lib.io.gltf.motion_from`: world rest pose
including the FBX's armature scale, rig maps, skin). Errors name the FBX file.

**Untrusted files** (``SECURITY.md``): assimp is C++ and crashes on some malformed files (a
segmentation fault on a connection cycle or deeply nested records, an assertion on an
out-of-range cluster index). So a binary FBX is first scanned here, in pure Python and
iteratively (:func:`_scan_binary_fbx`): every record within its parent, nesting at most
:data:`MAX_DEPTH`, at most :data:`MAX_RECORDS` records, every array's declared size within the
budget of :mod:`~retarget_lib.io.untrusted` and its bytes, no cycle in the object connections, and
every cluster index a vertex of its mesh. Then assimp runs in a child process
(:data:`_CONVERTER`) that gets the file's bytes on stdin and returns the GLB on stdout: it opens
no file, its address space is capped (:func:`_child_memory`) and its time limited
(:data:`TIMEOUT_SECONDS`), and a crash of the child is one :class:`~retarget_lib.errors.FBXError`.
No temporary file or folder is made.

Units: FBX lengths are in units of ``UnitScaleFactor`` centimetres (``GlobalSettings``; 1 = cm,
what Mixamo and Maya write; 100 = m, what Blender and :mod:`~retarget_lib.io.fbx_write` write), and
assimp passes them through unconverted, so rigs and motions are scaled to metres here by
``UnitScaleFactor / 100`` (a file without the setting is taken as centimetres, FBX's default).

Animations are sampled at the file's own frame rate (its ``GlobalSettings`` ``TimeMode`` /
``CustomFrameRate``, which assimp reports as the animation's ticks per second) unless ``fps`` is
given.

Writing FBX is :mod:`~retarget_lib.io.fbx_write` (pure Python, no extra needed): assimp 5.2.5's
own FBX exporter writes binary files that assimp itself cannot read back, and ASCII files (which
it can) come back with every keyframe time 1000 times too late (its glTF importer counts ticks in
milliseconds, the FBX exporter ignores the tick rate).
"""

from __future__ import annotations

import json
import os
import signal
import struct
import subprocess
import sys
import zlib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..core.motion import Motion
from ..core.rig import Rig
from ..errors import FBXError
from ..files import readable_file
from .gltf import MAX_FILE_BYTES, animation_from, motion_from, parse_gltf_bytes, rig_from
from .gltf.document import GLTFDocument
from .gltf.skin import _inverse_binds
from .untrusted import check_array_bytes

__all__ = [
    "FBXError",
    "MAX_DEPTH",
    "MAX_RECORDS",
    "TIMEOUT_SECONDS",
    "fbx_missing",
    "load_fbx_rig",
    "load_fbx_motion",
    "load_fbx_animation",
]

_INSTALL = "install the fbx extra: `sudo apt-get install libassimp5` and `pip install -e .[fbx]`"
#: records nested deeper than this are refused (FBX SDK files nest 6 deep)
MAX_DEPTH = 64
#: more records than this are refused (a rigged, animated Mixamo character has ~20,000)
MAX_RECORDS = 2_000_000
#: the converter child is stopped after this long
TIMEOUT_SECONDS = 300
_BINARY_MAGIC = b"Kaydara FBX Binary  \x00"
_ARRAY_ITEM = {"f": 4, "d": 8, "l": 8, "i": 4, "b": 1}
_SCALAR = {"Y": 2, "C": 1, "I": 4, "F": 4, "D": 8, "L": 8}
#: the child that converts: FBX bytes on stdin -> (8-byte length, JSON of the frame rate, the
#: unit and every mesh's bind matrices, GLB bytes) on stdout; exit 3 with assimp's message on
#: stderr when it refuses the file
_CONVERTER = """
import io, json, math, resource, struct, sys
limit = int(sys.argv[1])
hard = resource.getrlimit(resource.RLIMIT_AS)[1]
soft = limit if hard == resource.RLIM_INFINITY else min(limit, hard)
resource.setrlimit(resource.RLIMIT_AS, (soft, hard))
import impasse
from impasse.core import ffi
try:
    scene = impasse.load(io.BytesIO(sys.stdin.buffer.read()), file_type="fbx")
    glb = bytes(impasse.export_blob(scene, "glb2")[0].data)
except impasse.errors.AssimpError as e:
    sys.stderr.write(str(e))
    sys.exit(3)
settings = dict(scene.metadata) if scene.metadata is not None else {}
# every mesh's own bind matrices (assimp 5.2.5's aiBone: mName is 1028 bytes, then mNumWeights,
# mArmature, mNode, mWeights, and mOffsetMatrix at byte 1056, row-major; impasse declares the
# first four in another order, so its offset_matrix is read 8 bytes late); the glTF export keeps
# only the first mesh's for each joint
binds = []
for mesh in scene.meshes:
    bones = {}
    for bone in mesh.bones:
        m = struct.unpack_from("<16f", ffi.buffer(bone.struct, 1120), 1056)
        affine = max(map(abs, (m[12], m[13], m[14], m[15] - 1))) < 1e-6
        if all(math.isfinite(v) for v in m) and affine:
            bones[bone.name] = m
    binds.append(dict(vertices=len(mesh.vertices), bones=bones))
info = dict(rate=float(scene.animations[0].ticks_per_second) if len(scene.animations) else None,
            unit=settings.get("UnitScaleFactor", 1.0), binds=binds)
head = json.dumps(info).encode()
sys.stdout.buffer.write(len(head).to_bytes(8, "little") + head + glb)
"""


def _impasse():
    """The ``impasse`` module (:class:`~retarget_lib.errors.FBXError` naming the set-up if missing).

    Imported lazily: it is the optional ``fbx`` extra, and here only to say whether it is there
    (the conversion itself imports it in the child process)."""
    try:
        import impasse  # noqa: PLC0415 (optional dependency)
    except (ImportError, OSError) as e:  # OSError: the binding is there but libassimp is not
        raise FBXError(
            f"FBX needs the Open Asset Import Library ({type(e).__name__}: {e}); {_INSTALL}"
        ) from None
    return impasse


def fbx_missing() -> str | None:
    """Why FBX files cannot be read or written here, or ``None`` when they can."""
    try:
        _impasse()
    except FBXError as e:
        return str(e)
    return None


# ----------------------------------------------------------------------- the structural scan
@dataclass
class _Scan:
    """What the scan of a binary FBX collects: object names and classes by id, ``OO`` connections
    (child -> parents), the index range of every cluster and the vertex count of every geometry."""

    objects: dict[int, tuple[str, str]] = field(default_factory=dict)
    parents: dict[int, list[int]] = field(default_factory=dict)
    cluster_range: dict[int, tuple[int, int]] = field(default_factory=dict)
    vertices: dict[int, int] = field(default_factory=dict)


def _properties(data: bytes, pos: int, end: int, count: int, path: Path) -> list:
    """The ``count`` properties in ``data[pos:end]``: scalars as numbers, strings as bytes, arrays
    as ``(type letter, length, encoding, payload)`` (not decoded; sizes checked)."""
    out: list[int | bytes | tuple[str, int, int, bytes]] = []
    for _ in range(count):
        if pos >= end:
            raise FBXError(f"{path}: malformed FBX: a record's properties run past its end")
        code = chr(data[pos])
        pos += 1
        if code in _SCALAR:
            size = _SCALAR[code]
            value = data[pos : pos + size]
            out.append(int.from_bytes(value, "little", signed=True) if code in "YIL" else value)
        elif code in "SR":
            size = 4 + int.from_bytes(data[pos : pos + 4], "little")
            out.append(data[pos + 4 : pos + size])
        elif code in _ARRAY_ITEM:
            if pos + 12 > end:
                raise FBXError(f"{path}: malformed FBX: a record's properties run past its end")
            length, encoding, size = struct.unpack_from("<III", data, pos)
            check_array_bytes(
                (length,), _ARRAY_ITEM[code], f"an FBX array property ({code})", str(path)
            )
            if encoding not in (0, 1) or (encoding == 0 and size != length * _ARRAY_ITEM[code]):
                raise FBXError(
                    f"{path}: malformed FBX: an array of {length} '{code}' items holds {size} bytes"
                )
            out.append((code, length, encoding, data[pos + 12 : pos + 12 + size]))
            size += 12
        else:
            raise FBXError(
                f"{path}: malformed FBX: unknown property type {code!r} at byte {pos - 1}"
            )
        pos += size
        if pos > end:
            raise FBXError(f"{path}: malformed FBX: a record's properties run past its end")
    return out


def _int_array(prop, path: Path) -> np.ndarray:
    """An ``i`` / ``l`` array property decoded (its inflated size bounded by its declared
    length)."""
    code, length, encoding, payload = prop
    size = length * _ARRAY_ITEM[code]
    try:  # max_length 0 would mean "all of it": an empty array is not inflated at all
        raw = (
            payload
            if encoding == 0 or size == 0
            else zlib.decompressobj().decompress(payload, size)
        )
    except zlib.error:
        raw = b""
    if len(raw) != size:
        raise FBXError(
            f"{path}: malformed FBX: a compressed array does not hold its declared {length} items"
        )
    return np.frombuffer(raw, "<i4" if code == "i" else "<i8")


def _collect(
    scan: _Scan, name: str, parent: str, owner: int | None, props: list, path: Path
) -> int | None:
    """Note what the checks need from one record; return the object id its children belong to."""
    if parent == "Objects" and props and isinstance(props[0], int):
        label = props[1] if len(props) > 1 and isinstance(props[1], bytes) else b""
        class_name = props[2] if len(props) > 2 and isinstance(props[2], bytes) else b""
        name_part = label.split(b"\x00\x01")[0]
        scan.objects[props[0]] = (
            name_part.decode("utf-8", "replace"),
            class_name.decode("utf-8", "replace"),
        )
        return props[0]
    if (
        name == "C"
        and parent == "Connections"
        and len(props) >= 3
        and props[0] == b"OO"
        and isinstance(props[1], int)
        and isinstance(props[2], int)
    ):
        scan.parents.setdefault(props[1], []).append(props[2])
    if owner is None or not props or not isinstance(props[0], tuple):
        return owner
    array, kind = props[0], scan.objects[owner][1]
    if name == "Indexes" and kind == "Cluster" and array[0] in "il":
        indices = _int_array(array, path)
        if indices.size:
            scan.cluster_range[owner] = (int(indices.min()), int(indices.max()))
    elif name == "Vertices" and kind == "Mesh":
        scan.vertices[owner] = array[1] // 3
    return owner


def _scan_binary_fbx(data: bytes, path: Path) -> _Scan:
    """Walk every record of a binary FBX iteratively (module docstring) and collect what the
    connection and cluster checks need.

    Raises:
        FBXError: a record outside its parent, nesting beyond :data:`MAX_DEPTH`, more than
            :data:`MAX_RECORDS` records, a malformed property.
        LimitError: an array beyond the budget.
    """
    version = struct.unpack_from("<I", data, 23)[0] if len(data) >= 27 else 0
    head, layout = (25, "<QQQB") if version >= 7500 else (13, "<IIIB")
    scan, records = _Scan(), 0
    # (next record, end of the list, depth, parent name, owning object)
    stack: list[tuple[int, int, int, str, int | None]] = [(27, len(data), 1, "", None)]
    while stack:
        pos, end, depth, parent, owner = stack[-1]
        if pos + head > end:
            stack.pop()
            continue
        record_end, count, props_size, name_size = struct.unpack_from(layout, data, pos)
        if record_end == 0 and count == 0 and props_size == 0 and name_size == 0:
            stack.pop()
            continue
        props_start = pos + head + name_size
        if not props_start + props_size <= record_end <= end:
            raise FBXError(
                f"{path}: malformed FBX: the record at byte {pos} does not fit inside its parent "
                "(truncated file?)"
            )
        records += 1
        if records > MAX_RECORDS or depth > MAX_DEPTH:
            raise FBXError(
                f"{path}: malformed FBX: "
                + (
                    f"more than {MAX_RECORDS:,} records"
                    if records > MAX_RECORDS
                    else f"records nested more than {MAX_DEPTH} deep"
                )
                + " (the limit)"
            )
        name = data[pos + head : props_start].decode("ascii", "replace")
        props = _properties(data, props_start, props_start + props_size, count, path)
        child_owner = _collect(scan, name, parent, owner, props, path)
        stack[-1] = (record_end, end, depth, parent, owner)
        if props_start + props_size < record_end:
            stack.append((props_start + props_size, record_end, depth + 1, name, child_owner))
    return scan


def _check_connections(scan: _Scan, path: Path) -> None:
    """Refuse a cycle among the ``OO`` connections (iterative depth-first search)."""
    state: dict[int, int] = {}  # 1: on the current path, 2: done
    for start in scan.parents:
        if state.get(start):
            continue
        stack = [(start, iter(scan.parents.get(start, ())))]
        state[start] = 1
        while stack:
            node, parents = stack[-1]
            nxt = next(parents, None)
            if nxt is None:
                state[node] = 2
                stack.pop()
            elif state.get(nxt) == 1:
                on_path = [n for n, _ in stack]
                loop = on_path[on_path.index(nxt) :] + [nxt]
                cycle = " -> ".join(repr(scan.objects.get(n, (str(n), ""))[0]) for n in loop)
                raise FBXError(
                    f"{path}: malformed FBX: the object connections form a cycle ({cycle})"
                )
            elif not state.get(nxt):
                state[nxt] = 1
                stack.append((nxt, iter(scan.parents.get(nxt, ()))))


def _check_clusters(scan: _Scan, path: Path) -> None:
    """Refuse a cluster index that is not a vertex of the mesh its skin deforms."""
    for cluster, (low, high) in scan.cluster_range.items():
        skins = scan.parents.get(cluster, [])
        meshes = [g for s in skins for g in scan.parents.get(s, []) if g in scan.vertices]
        vertices = max(
            (scan.vertices[g] for g in meshes), default=max(scan.vertices.values(), default=0)
        )
        if low < 0 or high >= vertices:
            name = scan.objects.get(cluster, ("?", ""))[0]
            bad = low if low < 0 else high
            raise FBXError(
                f"{path}: malformed FBX: cluster {name!r} binds vertex {bad:,} of a mesh with "
                f"{vertices:,} "
                "vertices"
            )


# --------------------------------------------------------------------------- the conversion
def _child_memory(size: int) -> int:
    """The converter child's address-space cap: 16 x the file, at least 1.5 GiB, at most 8 GiB."""
    return int(min(8 * 2**30, max(1.5 * 2**30, 16 * size)))


def _ending(returncode: int) -> str:
    """How a child process ended, in words (``signal SIGSEGV``, ``exit status 1``)."""
    if returncode >= 0:
        return f"exit status {returncode}"
    try:
        return f"signal {signal.Signals(-returncode).name}"
    except ValueError:
        return f"signal {-returncode}"


def _convert(data: bytes, path: Path) -> tuple[bytes, float | None, float, list]:
    """``(GLB bytes, the first animation's frame rate or None, metres per file unit, every mesh's
    bind matrices)`` of an FBX file's bytes, converted by assimp in the contained child (module
    docstring)."""
    try:
        done = subprocess.run(
            [sys.executable, "-I", "-c", _CONVERTER, str(_child_memory(len(data)))],
            input=data,
            capture_output=True,
            timeout=TIMEOUT_SECONDS,
            check=False,
        )
    except subprocess.TimeoutExpired:
        raise FBXError(
            f"{path}: the FBX reader (assimp) took longer than {TIMEOUT_SECONDS} s; the file is "
            "malformed "
            "or too large"
        ) from None
    problem = done.stderr.decode("utf-8", "replace").strip().splitlines()
    if done.returncode == 3:
        raise FBXError(
            f"{path}: the Open Asset Import Library cannot read it as FBX "
            f"({problem[-1][:200] if problem else 'no message'})"
        )
    if done.returncode != 0:
        how = _ending(done.returncode)
        raise FBXError(
            f"{path}: the FBX reader (assimp) crashed on it ({how}: "
            f"{problem[-1][:200] if problem else 'no message'}); the file is malformed or needs "
            "more than "
            f"{_child_memory(len(data)) / 2**30:.1f} GiB to read"
        )
    size = int.from_bytes(done.stdout[:8], "little")
    info = json.loads(done.stdout[8 : 8 + size])
    rate = round(float(info["rate"]), 3) if info["rate"] is not None else None
    try:
        metres = float(info["unit"]) / 100.0
    except (TypeError, ValueError):
        metres = float("nan")
    if not (np.isfinite(metres) and 1e-6 <= metres <= 1e6):
        raise FBXError(f"{path}: UnitScaleFactor {info['unit']} is not a length unit")
    return (
        done.stdout[8 + size :],
        (rate if rate is not None and 1.0 <= rate <= 1000.0 else None),
        metres,
        info["binds"],
    )


def _mesh_binds(doc: GLTFDocument, binds: list) -> list[dict[str, np.ndarray] | None] | None:
    """Each glTF primitive's own inverse bind matrices by joint name
    (:attr:`~retarget_lib.io.gltf.GLTFDocument.primitive_inverse_binds`) from the converter's
    per-mesh bind matrices, or None when they cannot be matched with certainty: assimp exports
    each of its meshes as one primitive, in order (checked: as many, none with more vertices;
    the export may join a mesh's duplicate vertices), and writes, for each joint, the bind matrix
    of the first mesh bound to it into the file's one skin (checked: else the matrices were not
    read as assimp lays them out)."""
    g = doc.gltf
    prims = [prim for mesh in g.meshes for prim in mesh.primitives]
    counts = [
        g.accessors[p.attributes.POSITION].count
        if p.attributes.POSITION is not None and p.attributes.POSITION < len(g.accessors)
        else -1
        for p in prims
    ]
    if (
        len(g.skins) != 1
        or g.skins[0].inverseBindMatrices is None
        or len(counts) != len(binds)
        or any(not 0 < c <= b["vertices"] for c, b in zip(counts, binds, strict=True))
    ):
        return None
    own = [
        {name: np.array(m, dtype=np.float64).reshape(4, 4) for name, m in b["bones"].items()}
        for b in binds
    ]
    skin = g.skins[0]
    ibm = _inverse_binds(doc, 0)
    for k, joint in enumerate(skin.joints):
        first = next((o[g.nodes[joint].name] for o in own if g.nodes[joint].name in o), None)
        if first is not None and not np.allclose(
            first, ibm[k], rtol=1e-5, atol=1e-5 * max(1.0, float(np.abs(first).max()))
        ):
            return None
    return [o or None for o in own]


def _as_glb(path: str | os.PathLike):
    """``(the parsed GLB of the FBX, its first animation's frame rate or None, metres per file
    unit)``; the document's messages name ``path``."""
    path = readable_file(path, "FBX file", MAX_FILE_BYTES)
    try:
        _impasse()
    except FBXError as e:
        raise FBXError(f"{path}: {e}") from None
    data = path.read_bytes()
    if data.startswith(_BINARY_MAGIC):
        scan = _scan_binary_fbx(data, path)
        _check_connections(scan, path)
        _check_clusters(scan, path)
    glb, rate, metres, binds = _convert(data, path)
    doc = parse_gltf_bytes(glb, path, beside=False)
    doc.primitive_inverse_binds = _mesh_binds(doc, binds)
    # assimp keeps the rate in single precision (29.97 -> 29.969999...): rounded to 1/1000 fps,
    # which every rate in use (23.976, 29.97, 59.94 ...) is exact in
    return doc, rate, metres


def _in_metres(rig: Rig, metres: float) -> Rig:
    """``rig`` with every length multiplied by ``metres`` (metres per file unit)."""
    if metres == 1.0:
        return rig
    return Rig(
        rig.name,
        rig.skeleton.scaled(metres),
        rig.rest_vertices * metres,
        rig.faces,
        rig.weights,
        rig.joint_map,
        dict(rig.meta, unit_scale=metres),
    )


def load_fbx_rig(path: str | os.PathLike, mapping: str | os.PathLike | dict | None = None) -> Rig:
    """Read a skinned character from an FBX file (see :func:`~retarget_lib.io.gltf.load_gltf_rig`).

    Raises:
        FBXError: the extra is missing or assimp cannot read the file; the glTF reader's errors
            (no skin, unmappable joints ...) naming the FBX file.
    """
    doc, _, metres = _as_glb(path)
    rig = _in_metres(rig_from(doc, mapping), metres)
    rig.name, rig.meta["source"] = Path(path).stem, str(path)
    return rig


def load_fbx_motion(
    path: str | os.PathLike,
    fps: float | None = None,
    mapping: str | os.PathLike | dict | None = None,
) -> tuple[Motion, Rig]:
    """Sample the first animation of a skinned FBX file (see
    :func:`~retarget_lib.io.gltf.load_gltf_motion`) at ``fps``, by default the file's own frame rate
    (else 30)."""
    doc, rate, metres = _as_glb(path)
    motion, rig = motion_from(doc, fps=fps or rate, mapping=mapping)
    rig = _in_metres(rig, metres)
    motion = motion.copy(skeleton=rig.skeleton, root_positions=motion.root_positions * metres)
    rig.name, rig.meta["source"], motion.meta["source"] = Path(path).stem, str(path), str(path)
    return motion, rig


def load_fbx_animation(
    path: str | os.PathLike,
    fps: float | None = None,
    mapping: str | os.PathLike | dict | None = None,
) -> tuple[Motion, dict[int, int]]:
    """Sample the first animation of an FBX file with or without a skin (a Mixamo clip downloaded
    "With Skin" or "Without Skin"; see :func:`~retarget_lib.io.gltf.load_gltf_animation`).

    Sampled at ``fps``, by default the file's own frame rate (else the keys' rate, else 30); lengths
    in metres (``UnitScaleFactor``, as :func:`load_fbx_motion`).

    Returns:
        ``(motion on the file's joints, {file joint index: canonical index})``.
    """
    doc, rate, metres = _as_glb(path)
    motion, joint_map = animation_from(doc, fps=fps or rate, mapping=mapping)
    motion = motion.copy(
        skeleton=motion.skeleton.scaled(metres), root_positions=motion.root_positions * metres
    )
    motion.meta["source"] = str(path)
    return motion, joint_map
