"""The glTF container and its JSON, decoded under limits: the GLB chunks, the typed
JSON fields the reader uses, buffers (embedded, or beside a ``.gltf`` file only) and accessors
checked for their role before anything is allocated."""

from __future__ import annotations

import base64
import binascii
import os
import struct
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ...errors import GLTFError, LimitError
from ...files import read_beside, readable_file
from ..untrusted import (
    ANY,
    COUNT,
    FLAG,
    INDEX,
    INT,
    MAX_ARRAY_BYTES,
    NUMBER,
    TEXT,
    Arr,
    JsonObject,
    Obj,
    check_array_bytes,
    check_count,
    parse_json,
    typed_json,
)

__all__ = [
    "NoSkinError",
    "MAX_FILE_BYTES",
    "MAX_NODES",
    "MAX_JOINTS",
    "MAX_VERTICES",
    "MAX_TRIANGLES",
    "MAX_FRAMES",
    "DEFAULT_FPS",
    "parse_gltf_bytes",
]


MAX_FILE_BYTES = 256 * 2**20


MAX_NODES = 100_000


MAX_JOINTS = 1000


MAX_VERTICES = 2_000_000


MAX_TRIANGLES = 4_000_000


MAX_FRAMES = 1_000_000


#: frame rate of a sampled animation that does not say its own
DEFAULT_FPS = 30.0


_SCALE_TOL = 1e-3


#: joint-frames sampled at once (about 60 MB of intermediate transforms)
_BLOCK_SAMPLES = 100_000


_FLOAT, _BYTE, _UBYTE, _SHORT, _USHORT, _UINT = 5126, 5120, 5121, 5122, 5123, 5125


_DTYPES = {
    _BYTE: np.int8,
    _UBYTE: np.uint8,
    _SHORT: np.int16,
    _USHORT: np.uint16,
    _UINT: np.uint32,
    _FLOAT: np.float32,
}


_WIDTH = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT4": 16}


_TRIANGLES = 4


#: the name part of the pivot helper nodes assimp adds when it converts an FBX
_ASSIMP_HELPER = "$AssimpFbx$"


_GLB_MAGIC, _JSON_CHUNK, _BIN_CHUNK = b"glTF", 0x4E4F534A, 0x004E4942


#: extensions that change how geometry is stored; a file that uses one cannot be decoded here
_GEOMETRY_EXTENSIONS = (
    "KHR_draco_mesh_compression",
    "EXT_meshopt_compression",
    "KHR_meshopt_compression",
    "KHR_mesh_quantization",
)


#: every field of the glTF JSON the reader uses, with its type (checked before any use)
_GLTF_JSON = Obj(
    {
        "asset!": Obj({"version!": TEXT}),
        "extras": ANY,
        "extensionsRequired": Arr(TEXT),
        "extensionsUsed": Arr(TEXT),
        "extensions": Obj(
            {
                "VRM": Obj(
                    {"humanoid": Obj({"humanBones": Arr(Obj({"bone": TEXT, "node": INDEX}))})}
                ),
                "VRMC_vrm": Obj({"humanoid": Obj({"humanBones": Obj(rest=Obj({"node": INDEX}))})}),
            }
        ),
        "nodes": Arr(
            Obj(
                {
                    "name": TEXT,
                    "children": Arr(INDEX),
                    "mesh": INDEX,
                    "skin": INDEX,
                    "matrix": Arr(NUMBER, 16),
                    "translation": Arr(NUMBER, 3),
                    "rotation": Arr(NUMBER, 4),
                    "scale": Arr(NUMBER, 3),
                }
            )
        ),
        "skins": Arr(Obj({"joints!": Arr(INDEX), "inverseBindMatrices": INDEX})),
        "meshes": Arr(
            Obj(
                {
                    "primitives!": Arr(
                        Obj(
                            {
                                "attributes!": Obj(rest=INDEX),
                                "indices": INDEX,
                                "mode": INT,
                                "extensions": Obj(rest=ANY),
                            }
                        )
                    )
                }
            )
        ),
        "accessors": Arr(
            Obj(
                {
                    "bufferView": INDEX,
                    "byteOffset": COUNT,
                    "componentType!": INT,
                    "normalized": FLAG,
                    "count!": COUNT,
                    "type!": TEXT,
                    "sparse": ANY,
                }
            )
        ),
        "bufferViews": Arr(
            Obj({"buffer!": INDEX, "byteOffset": COUNT, "byteLength!": COUNT, "byteStride": COUNT})
        ),
        "buffers": Arr(Obj({"uri": TEXT, "byteLength!": COUNT})),
        "animations": Arr(
            Obj(
                {
                    "name": TEXT,
                    "extras": ANY,
                    "channels!": Arr(
                        Obj({"sampler!": INDEX, "target!": Obj({"node": INDEX, "path!": TEXT})})
                    ),
                    "samplers!": Arr(
                        Obj({"input!": INDEX, "output!": INDEX, "interpolation": TEXT})
                    ),
                }
            )
        ),
    }
)


class NoSkinError(GLTFError):
    """A file without a skinned mesh where a character (mesh and skin) is needed."""


@dataclass(frozen=True)
class _Role:
    """What an accessor must be where it is used: its types, component types and largest count."""

    types: tuple[str, ...]
    components: tuple[int, ...]
    max_count: int


_POSITION = _Role(("VEC3",), (_FLOAT,), MAX_VERTICES)


_JOINTS = _Role(("VEC4",), (_UBYTE, _USHORT, _UINT), MAX_VERTICES)


_WEIGHTS = _Role(("VEC4",), (_FLOAT, _UBYTE, _USHORT), MAX_VERTICES)


_INDICES = _Role(("SCALAR",), (_UBYTE, _USHORT, _UINT), 3 * MAX_TRIANGLES)


_INVERSE_BIND = _Role(("MAT4",), (_FLOAT,), MAX_JOINTS)


_KEY_TIMES = _Role(("SCALAR",), (_FLOAT,), MAX_FRAMES)


_KEY_VALUES = {
    "rotation": _Role(("VEC4",), (_FLOAT, _BYTE, _UBYTE, _SHORT, _USHORT), 3 * MAX_FRAMES),
    "translation": _Role(("VEC3",), (_FLOAT,), 3 * MAX_FRAMES),
    "scale": _Role(("VEC3",), (_FLOAT,), 3 * MAX_FRAMES),
}


@dataclass
class GLTFDocument:
    """A parsed, type-checked file: its JSON (:class:`~retarget_lib.io.untrusted.JsonObject`), its
    buffers, the path named in messages, and the bytes its accessors have decoded so far (at most
    :data:`~retarget_lib.io.untrusted.MAX_ARRAY_BYTES` in all, as float64: accessors may overlap,
    so the file's size alone does not bound them)."""

    gltf: JsonObject
    buffers: list[bytes]
    path: Path
    decoded: int = field(default=0)
    #: ``(3, 3)`` rotation from the file's axes to the library's (+Y up, facing +Z, left +X),
    #: applied above its top nodes (:func:`_upright`); identity until a rig is read
    frame: np.ndarray = field(default_factory=lambda: np.eye(3))
    #: metres added to every height above the top nodes so that the rest mesh's lowest point is at
    #: ``y = 0`` (:func:`_load`; a character stands on the floor); 0 until a rig is read
    lift: float = 0.0
    #: per primitive (the meshes' primitives in file order), ``{joint node name: (4, 4) inverse
    #: bind matrix}`` that replaces the skin's for that primitive's vertices, or None. Set by the
    #: FBX reader (:mod:`~retarget_lib.io.fbx`): assimp's glTF export writes one skin for every
    #: mesh of a file, each joint with the bind matrix of the first mesh bound to it, so a mesh
    #: placed by another transform (a Blender export of several meshes) needs its own
    primitive_inverse_binds: list[dict[str, np.ndarray] | None] | None = None

    def error(self, problem: str) -> GLTFError:
        return GLTFError(f"{self.path}: {problem}")

    def accessor(self, index: int, role: _Role, what: str) -> np.ndarray:
        """Accessor ``index`` as a ``(count, width)`` array (MAT4: ``(count, 4, 4)`` row-major);
        normalized integers become floats. ``role`` says what it must be where it is used
        (``what``, for messages); its count is checked before anything is allocated."""
        g = self.gltf
        if not 0 <= index < len(g.accessors):
            raise self.error(f"{what}: accessor {index} does not exist")
        acc = g.accessors[index]
        if acc.sparse is not None:
            raise self.error(
                f"{what}: accessor {index} is sparse; sparse accessors are not supported"
            )
        if acc.type not in role.types or acc.componentType not in role.components:
            raise self.error(
                f"{what}: accessor {index} is {acc.type} of component type {acc.componentType}, "
                f"expected {' or '.join(role.types)} of {', '.join(map(str, role.components))}"
            )
        check_count(
            acc.count, role.max_count, f"elements in accessor {index}", f"{self.path}: {what}"
        )
        dtype, width = np.dtype(_DTYPES[acc.componentType]).newbyteorder("<"), _WIDTH[acc.type]
        check_array_bytes((acc.count, width), 8, f"accessor {index}", f"{self.path}: {what}")
        self.decoded += acc.count * width * 8
        if self.decoded > MAX_ARRAY_BYTES:
            raise LimitError(
                f"{self.path}: {what}: the accessors read from the file would take more than "
                f"{MAX_ARRAY_BYTES / 2**30:.0f} GiB in all (the budget; an accessor read twice "
                "counts "
                "twice)"
            )
        if acc.bufferView is None:
            out = np.zeros((acc.count, width), dtype)
        else:
            out = self._view(index, acc, dtype, width)
        if acc.normalized and np.issubdtype(dtype, np.integer):
            out = np.maximum(out / np.iinfo(dtype.type).max, -1.0)
        if acc.type == "MAT4":
            out = out.reshape(-1, 4, 4).transpose(0, 2, 1)  # column-major in the file
        if np.issubdtype(out.dtype, np.floating) and not np.isfinite(out).all():
            raise self.error(f"{what}: accessor {index} holds NaN or inf")
        return out

    def _view(self, index: int, acc: JsonObject, dtype: np.dtype, width: int) -> np.ndarray:
        """The elements of accessor ``index`` read from its buffer view (bounds checked)."""
        g = self.gltf
        if not 0 <= acc.bufferView < len(g.bufferViews):
            raise self.error(
                f"accessor {index} names buffer view {acc.bufferView}, which does not exist"
            )
        view = g.bufferViews[acc.bufferView]
        if not 0 <= view.buffer < len(self.buffers):
            raise self.error(
                f"buffer view {acc.bufferView} names buffer {view.buffer}, which does not exist"
            )
        buf = self.buffers[view.buffer]
        element = width * dtype.itemsize
        stride = view.byteStride or element
        start = (view.byteOffset or 0) + (acc.byteOffset or 0)
        end = start + stride * max(acc.count - 1, 0) + element * (acc.count > 0)
        if end > (view.byteOffset or 0) + view.byteLength or end > len(buf) or stride < element:
            raise self.error(f"accessor {index} reads past the end of its buffer (truncated file?)")
        return np.ndarray(
            (acc.count, width), dtype, buffer=buf, offset=start, strides=(stride, dtype.itemsize)
        ).copy()


def _read(path: str | os.PathLike) -> GLTFDocument:
    """Parse a ``.glb`` or ``.gltf`` file and load its buffers (:class:`GLTFError` if malformed)."""
    path = readable_file(path, "glTF/GLB file", MAX_FILE_BYTES)
    return parse_gltf_bytes(path.read_bytes(), path, beside=True)


def _split_glb(data: bytes, path: Path) -> tuple[bytes, bytes | None]:
    """The JSON chunk and the binary chunk (or ``None``) of a GLB container."""
    if len(data) < 20:
        raise GLTFError(f"{path}: truncated GLB file (shorter than its headers)")
    version, length = struct.unpack_from("<II", data, 4)
    if version != 2:
        raise GLTFError(
            f"{path}: GLB container version {version}; only version 2 (glTF 2.0) is read"
        )
    if length > len(data):
        raise GLTFError(f"{path}: truncated GLB file (its header declares more bytes than it has)")
    chunks: list[tuple[int, bytes]] = []
    pos = 12
    while pos + 8 <= length:
        size, kind = struct.unpack_from("<II", data, pos)
        if pos + 8 + size > length:
            raise GLTFError(
                f"{path}: truncated GLB file (chunk {len(chunks)} declares more bytes than it has)"
            )
        chunks.append((kind, data[pos + 8 : pos + 8 + size]))
        pos += 8 + size + (-size % 4)
    if not chunks or chunks[0][0] != _JSON_CHUNK:
        raise GLTFError(f"{path}: not a readable GLB file: its first chunk is not JSON")
    blob = chunks[1][1] if len(chunks) > 1 and chunks[1][0] == _BIN_CHUNK else None
    return chunks[0][1], blob


def parse_gltf_bytes(data: bytes, path: Path, beside: bool) -> GLTFDocument:
    """Parse a GLB or glTF file's bytes into a type-checked :class:`GLTFDocument`.

    Args:
        data: the file's bytes.
        path: the file, named in messages (and whose folder holds external buffers).
        beside: whether buffers in files beside ``path`` may be read (``False`` for a file
            converted in memory, e.g. from an FBX).

    Raises:
        GLTFError: a malformed container or JSON, a field of the wrong type, an unsupported
            geometry compression, or buffers that cannot be read.
    """
    if data[:4] == _GLB_MAGIC:
        text, blob = _split_glb(data, path)
    else:
        text, blob = data, None
        try:
            data[:4096].decode("utf-8")
        except UnicodeDecodeError as e:
            if e.start < 4092:  # not a multi-byte character cut by the slice
                raise GLTFError(
                    f"{path}: not a glTF 2.0 file: a binary .glb starts with the bytes 'glTF' and "
                    "a "
                    f".gltf is JSON text; this file is neither (first bytes {data[:4]!r})"
                ) from None
    raw = parse_json(text, f"{path}: not a readable glTF 2.0 / GLB file", GLTFError)
    if not isinstance(raw, dict):
        raise GLTFError(f"{path}: not a readable glTF 2.0 / GLB file (the JSON is not an object)")
    gltf = typed_json(raw, _GLTF_JSON, str(path), GLTFError)
    if not gltf.asset.version.startswith("2"):
        raise GLTFError(f"{path}: not a glTF 2.0 file (asset.version must be 2.x)")
    check_count(len(gltf.nodes), MAX_NODES, "nodes", str(path))
    _check_geometry_extensions(gltf, path)
    buffers = [_buffer(b, i, blob, path, beside) for i, b in enumerate(gltf.buffers)]
    return GLTFDocument(gltf, buffers, path)


def _check_geometry_extensions(gltf: JsonObject, path: Path) -> None:
    """Refuse compressed geometry by name (its accessors have no data this reader can decode)."""
    for m, mesh in enumerate(gltf.meshes):
        for p, prim in enumerate(mesh.primitives):
            used = [
                e
                for e in _GEOMETRY_EXTENSIONS
                if prim.extensions is not None and getattr(prim.extensions, e)
            ]
            if used:
                raise GLTFError(
                    f"{path}: mesh {m} primitive {p} is compressed with {used[0]}, which this "
                    "reader does "
                    "not decode; export the file without mesh compression"
                )
    required = [e for e in gltf.extensionsRequired if e in _GEOMETRY_EXTENSIONS]
    if required:
        raise GLTFError(
            f"{path}: requires the extension {required[0]}, which this reader does not decode; "
            "export the "
            "file without mesh compression or quantization"
        )


def _buffer(buffer: JsonObject, index: int, blob: bytes | None, path: Path, beside: bool) -> bytes:
    """The bytes of one buffer: the GLB chunk, a ``data:`` URI, or a file beside ``path``."""
    uri = buffer.uri
    if uri is None:
        if blob is None:
            raise GLTFError(f"{path}: buffer {index} has no URI and the file has no binary chunk")
        data = blob
    elif uri.startswith("data:"):
        try:
            data = base64.b64decode(uri.split(",", 1)[1], validate=True)
        except (IndexError, ValueError, binascii.Error):
            raise GLTFError(f"{path}: buffer {index} has a malformed data URI") from None
    elif not beside:
        raise GLTFError(
            f"{path}: buffer {index} names a file ({uri!r}), which a converted file may not"
        )
    else:
        data = read_beside(path, uri, f"buffer {index}", MAX_FILE_BYTES, GLTFError)
    if len(data) < buffer.byteLength:
        raise GLTFError(
            f"{path}: buffer {index} has {len(data)} bytes, fewer than its byteLength "
            f"{buffer.byteLength} (truncated file?)"
        )
    return data
