"""Reading skinned characters and their animations from glTF 2.0 files (``.glb`` / ``.gltf``).

The GLB container and the JSON are parsed here (:func:`parse_gltf_bytes`), and every JSON field
the reader uses is type-checked before use (:data:`_GLTF_JSON`, through
:func:`~retarget_lib.io.untrusted.typed_json`); accessors are decoded with NumPy, each checked for
its role (type, component type, count within a limit) before anything is allocated. glTF's
conventions are the library's: metres, +Y up, the asset facing +Z, quaternions stored
``(x, y, z, w)`` (converted to wxyz on read).

What is read (:func:`load_gltf_rig`):

* **Skeleton** = the union of the joints of every skin used by a mesh node, as one tree (the
  nearest joint ancestor of a joint is its parent; one root: a second, smaller tree, a prop rigged
  to its own armature, is hung under the skeleton's nearest joint, :func:`_hang_small_trees`). Rest
  pose = the nodes' own transforms (the file as it shows without animation), including any non-joint
  ancestors such as an ``Armature`` node with a 0.01 scale: rest joint positions are world
  positions. Joints themselves must not scale (scale 1 within 1e-3, else
  :class:`~retarget_lib.errors.GLTFError`).
* **Mesh** = every triangle primitive of every skinned mesh node, merged, posed into the rest pose
  by the file's own skinning (``world(joint) @ inverseBindMatrix``; every inverse bind matrix must
  be an invertible affine matrix), so the rest vertices are what a viewer shows. Materials, UVs
  and morph targets are not read; a Draco- or meshopt-compressed mesh is refused by name.
* **Weights** = ``JOINTS_n`` / ``WEIGHTS_n`` (any number of sets) as a dense ``(V, J)`` array.
* **Joint map** onto the canonical 22 by :func:`~retarget_lib.io.rig_maps.map_joints`: the rig's
  names, a VRM file's humanoid bones (``VRM`` / ``VRMC_vrm`` extension), then a mapping file.

:func:`load_gltf_motion` samples an animation of the same file at a frame rate (the ``fps`` the
library wrote into the animation's ``extras``, else the rate of the keys when they lie on one
regular grid (:func:`key_rate`: an export with a key on every frame, as Mixamo's), else 30):
rotations and the root's translation (LINEAR = slerp / lerp, STEP, CUBICSPLINE = its key values);
other joints' translation and scale channels are not representable in a
:class:`~retarget_lib.core.motion.Motion` and are ignored.
Library rotations are relative to the rest pose: ``Q_j(t) = G_j(t) R_j^T`` with ``G_j`` the
animated and ``R_j`` the rest world rotation of joint ``j``.

:func:`load_gltf_animation` samples the same way from a file **with or without a skin** (a motion
exported "Without Skin": an armature and its animation): without a skinned mesh the joints are the
nodes the animation moves and every node below them (end sites), except mesh nodes and the pivot
helpers assimp inserts when it converts an FBX (``..._$AssimpFbx$_...``), whose transforms are
applied as those of any non-joint ancestor.

Bounds (:class:`~retarget_lib.errors.LimitError` naming the limit): file size 256 MiB, 100,000
nodes, 1000 joints, 2,000,000 vertices, 4,000,000 triangles, 1,000,000 keys per channel and
frames per animation, and the budgets of :mod:`~retarget_lib.io.untrusted` (1 GiB per decoded
array and for all the accessors of a file, 3,000,000 joint-frames per sampled motion, JSON
nesting 64); vertices and triangles are counted over all primitives, and each property of a node
may have one animation channel. External buffers only beside
the ``.gltf`` file (:func:`~retarget_lib.files.read_beside`: no ``..``, no absolute paths, no
URLs, no symbolic link leading out of its folder). Node hierarchies are walked iteratively (any
depth, linear time).
"""

from __future__ import annotations

import base64
import binascii
import heapq
import os
import struct
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch

from ..core.canonical import upright_rotation
from ..core.motion import Motion
from ..core.rig import Rig
from ..core.rotations import matrix_to_quat, quat_slerp, quat_to_matrix
from ..core.skeleton import J, Skeleton
from ..core.virtual_joints import MAY_BE_ABSENT
from ..errors import GLTFError, LimitError
from ..files import read_beside, readable_file
from .rig_maps import RIG_MAPS, joint_key, map_joints, read_mapping
from .untrusted import (
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
    check_motion_samples,
    parse_json,
    typed_json,
)

__all__ = [
    "GLTFError",
    "NoSkinError",
    "MAX_FILE_BYTES",
    "MAX_NODES",
    "MAX_JOINTS",
    "MAX_VERTICES",
    "MAX_TRIANGLES",
    "MAX_FRAMES",
    "DEFAULT_FPS",
    "key_rate",
    "load_gltf_rig",
    "load_gltf_motion",
    "load_gltf_animation",
    "parse_gltf_bytes",
    "rig_from",
    "motion_from",
    "animation_from",
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


def _local_matrix(node: JsonObject) -> np.ndarray:
    """``(4, 4)`` a node's local transform (its ``matrix``, else T @ R @ S)."""
    if node.matrix:
        return np.asarray(node.matrix, dtype=np.float64).reshape(4, 4).T
    return _trs(
        np.asarray(node.translation or (0, 0, 0), dtype=np.float64),
        np.asarray(node.rotation or (0, 0, 0, 1), dtype=np.float64),
        np.asarray(node.scale or (1, 1, 1), dtype=np.float64),
    )


def _trs(t: np.ndarray, q_xyzw: np.ndarray, s: np.ndarray) -> np.ndarray:
    """``(..., 4, 4)`` from translations ``(..., 3)``, quaternions ``(..., 4)`` xyzw, scales ``(...,
    3)``."""
    q = torch.from_numpy(np.ascontiguousarray(q_xyzw[..., [3, 0, 1, 2]]))
    q = q / q.norm(dim=-1, keepdim=True).clamp_min(1e-12)
    m = np.zeros(q.shape[:-1] + (4, 4))
    m[..., :3, :3] = quat_to_matrix(q).numpy() * s[..., None, :]
    m[..., :3, 3] = t
    m[..., 3, 3] = 1.0
    return m


def _parents_of_nodes(doc: GLTFDocument) -> list[int]:
    """``parent[n]`` of every node (``-1`` at a scene root); refuses cycles and shared children
    (linear time, iterative)."""
    nodes = doc.gltf.nodes
    parent = [-1] * len(nodes)
    for n, node in enumerate(nodes):
        for c in node.children:
            if c >= len(nodes) or parent[c] != -1 or c == n:
                raise doc.error(
                    f"node {n} lists child {c}, which does not exist or has another parent"
                )
            parent[c] = n
    reaches_root = [False] * len(nodes)
    for n in range(len(nodes)):
        path: list[int] = []
        k = n
        while k >= 0 and not reaches_root[k]:
            if len(path) > len(
                nodes
            ):  # every node has one parent: a longer walk goes round a cycle
                raise doc.error(f"the node hierarchy has a cycle through node {n}")
            path.append(k)
            k = parent[k]
        for p in path:
            reaches_root[p] = True
    return parent


def _world(
    node_parent: list[int], local: dict[int, np.ndarray], nodes: list[int]
) -> dict[int, np.ndarray]:
    """World transforms (``(4, 4)`` or ``(T, 4, 4)``) of ``nodes`` and their ancestors from per-node
    local ones (iterative: any depth)."""
    out: dict[int, np.ndarray] = {}
    for n in nodes:
        chain, k = [], n
        while k >= 0 and k not in out:
            chain.append(k)
            k = node_parent[k]
        above = out[k] if k >= 0 else None
        for c in reversed(chain):
            above = local[c] if above is None else above @ local[c]
            out[c] = above
    return out


def _framed(
    local: dict[int, np.ndarray], node_parent: list[int], frame: np.ndarray, lift: float = 0.0
) -> dict[int, np.ndarray]:
    """``local`` with the top nodes' transforms turned by ``frame`` (``(3, 3)``) and raised by
    ``lift`` metres: every world transform then comes out in the library's axes, on its floor."""
    if np.array_equal(frame, np.eye(3)) and lift == 0.0:
        return local
    turn = np.eye(4)
    turn[:3, :3] = frame
    turn[1, 3] = lift
    return {n: turn @ m if node_parent[n] < 0 else m for n, m in local.items()}


#: a rest mesh whose lowest point is further than this from ``y = 0`` is lifted onto it (metres)
FLOOR_TOLERANCE_M = 1e-4


def _upright(rest: np.ndarray, joint_map: dict[int, int]) -> np.ndarray:
    """``(3, 3)`` the quarter turns that stand a rig's rest pose up in the library's axes
    (:func:`~retarget_lib.core.canonical.upright_rotation`): a Z-up FBX (Unreal, 3ds Max), a VRM
    0.x avatar (facing -Z) or an export turned by a quarter are read standing, facing +Z."""
    file_of = {c: j for j, c in joint_map.items()}
    return upright_rotation(
        *(rest[file_of[J[n]]] for n in ("Hips", "Head", "LeftUpLeg", "RightUpLeg"))
    )


def _with_ancestors(nodes: list[int], node_parent: list[int]) -> list[int]:
    """``nodes`` and all their ancestors (each once; linear time)."""
    out: dict[int, None] = {}
    for n in nodes:
        while n >= 0 and n not in out:
            out[n] = None
            n = node_parent[n]
    return list(out)


def _parents_first(node_parent: list[int]) -> list[int]:
    """Every node, each after its parent (breadth first from the roots; iterative)."""
    kids: dict[int, list[int]] = {}
    for n, p in enumerate(node_parent):
        kids.setdefault(p, []).append(n)
    order, k = list(kids.get(-1, [])), 0
    while k < len(order):
        order.extend(kids.get(order[k], []))
        k += 1
    return order


@dataclass
class _Skeleton:
    """The joint tree of a file: joint node indices (parents first), parents, names, node
    parents."""

    nodes: list[int]
    parents: list[int]
    names: list[str]
    node_parent: list[int]


def _joint_tree(doc: GLTFDocument, skinned: list[int]) -> _Skeleton:
    """The joint tree of the skins used by the ``skinned`` mesh nodes."""
    g = doc.gltf
    joint_set: set[int] = set()
    for n in skinned:
        skin = g.skins[g.nodes[n].skin]
        if not skin.joints or any(j >= len(g.nodes) for j in skin.joints):
            raise doc.error(
                f"skin {g.nodes[n].skin} has no joints or names nodes that do not exist"
            )
        joint_set.update(skin.joints)
    order = list(dict.fromkeys(j for n in skinned for j in g.skins[g.nodes[n].skin].joints))
    return _tree_of(doc, joint_set, order, "the skin's joints")


def _animated_tree(doc: GLTFDocument, animation: int) -> _Skeleton:
    """The joint tree of a file without a skin (an armature and its animation, e.g. a Mixamo clip
    downloaded "Without Skin"): every node an animation channel of ``animation`` moves, and every
    node below one (bones drawn as meshes, as 3ds Max's Biped exports them, included), except
    unanimated mesh leaves there (props) and assimp's FBX pivot helpers (``..._$AssimpFbx$_...``),
    which stay non-joint ancestors (their transforms are still applied)."""
    g = doc.gltf
    if not 0 <= animation < len(g.animations):
        raise doc.error(
            f"has no skin and {len(g.animations)} animations; a motion file without a skin needs "
            f"animation {animation} to find its joints"
        )
    node_parent = _parents_of_nodes(doc)
    animated = {
        c.target.node
        for c in g.animations[animation].channels
        if c.target.node is not None and c.target.node < len(g.nodes)
    }
    below = [False] * len(g.nodes)  # the node or an ancestor is animated
    for n in _parents_first(node_parent):
        below[n] = n in animated or (node_parent[n] >= 0 and below[node_parent[n]])
    joint_set = {
        n
        for n in range(len(g.nodes))
        if below[n]
        and _ASSIMP_HELPER not in (g.nodes[n].name or "")
        and (g.nodes[n].mesh is None or n in animated or g.nodes[n].children)
    }
    if not joint_set:
        raise doc.error(
            f"has no skin and animation {animation} moves no node; it is not a character's motion"
        )
    return _tree_of(doc, joint_set, sorted(joint_set), f"the joints animation {animation} moves")


def _tree_of(doc: GLTFDocument, joint_set: set[int], order_hint: list[int], what: str) -> _Skeleton:
    """``joint_set`` as one tree, parents first, otherwise in ``order_hint`` order; ``what`` names
    the joint set in messages."""
    g = doc.gltf
    check_count(len(joint_set), MAX_JOINTS, "joints", str(doc.path))
    node_parent = _parents_of_nodes(doc)
    joint_parent = [-1] * len(g.nodes)  # the nearest joint ancestor of every node
    for n in _parents_first(node_parent):
        p = node_parent[n]
        joint_parent[n] = -1 if p < 0 else (p if p in joint_set else joint_parent[p])
    roots = sorted(j for j in joint_set if joint_parent[j] < 0)
    if len(roots) > 1:
        roots = _hang_small_trees(doc, joint_set, joint_parent, node_parent, roots, what)
    # parents first, otherwise in the hint's order (the skins' joint order: a file's own order
    # survives a round trip)
    rank = {j: k for k, j in enumerate(order_hint)}
    kids: dict[int, list[int]] = {}
    for j in joint_set:
        kids.setdefault(joint_parent[j], []).append(j)
    order, heap = [], [(rank[roots[0]], roots[0])]
    while heap:
        n = heapq.heappop(heap)[1]
        order.append(n)
        for c in kids.get(n, []):
            heapq.heappush(heap, (rank[c], c))
    index = {n: i for i, n in enumerate(order)}
    parents = [index[joint_parent[n]] if joint_parent[n] >= 0 else -1 for n in order]
    names, seen = [], set()
    for n in order:
        name = g.nodes[n].name or f"joint{n}"
        while name in seen:  # a repeated name gets its node index (and again, until unique)
            name = f"{name}.{n}"
        names.append(name)
        seen.add(name)
    return _Skeleton(order, parents, names, node_parent)


#: a second joint tree smaller than this fraction of the largest is a prop's armature (a hat, a
#: weapon) and is hung under the skeleton; a larger one is another character
PROP_TREE_FRACTION = 0.5


def _hang_small_trees(
    doc: GLTFDocument,
    joint_set: set[int],
    joint_parent: list[int],
    node_parent: list[int],
    roots: list[int],
    what: str,
) -> list[int]:
    """Make one tree of several: the largest is the skeleton, and the root of every tree with fewer
    than :data:`PROP_TREE_FRACTION` of its joints (a prop's own armature, as Blender exports a hat
    rigged to a second armature) is given as parent the skeleton's joint nearest to it in the rest
    pose (world positions; nothing moves). Refused when another tree is as large: two characters.
    Edits ``joint_parent`` in place; returns ``[root]``."""
    g = doc.gltf
    tree = {}
    for j in joint_set:  # the root of each joint's tree
        k = j
        while joint_parent[k] >= 0:
            k = joint_parent[k]
        tree[j] = k
    size = {r: sum(1 for j in joint_set if tree[j] == r) for r in roots}
    main = max(roots, key=lambda r: (size[r], -r))
    large = [r for r in roots if r != main and size[r] >= PROP_TREE_FRACTION * size[main]]
    if large:
        names = [g.nodes[r].name or f"node{r}" for r in roots]
        raise doc.error(
            f"{what} form {len(roots)} trees (roots {names}) of "
            f"{sorted(size.values(), reverse=True)} "
            "joints; a character needs one skeleton (a tree under half the largest's size is taken "
            "as a prop's armature and hung under the nearest joint)"
        )
    joints = sorted(joint_set)
    world = _world(
        node_parent,
        {n: _local_matrix(g.nodes[n]) for n in _with_ancestors(joints, node_parent)},
        joints,
    )
    skeleton = sorted(j for j in joint_set if tree[j] == main)
    at = np.array([world[j][:3, 3] for j in skeleton])
    for r in roots:
        if r != main:
            joint_parent[r] = skeleton[int(np.argmin(np.linalg.norm(at - world[r][:3, 3], axis=1)))]
    return [main]


def _rotation_part(m: np.ndarray, doc: GLTFDocument, what: str) -> np.ndarray:
    """``(..., 3, 3)`` the rotation of similarity transforms ``(..., 4, 4)`` (uniform scale
    removed)."""
    a = m[..., :3, :3]
    scale = np.cbrt(np.linalg.det(a))
    if np.any(np.abs(scale) < 1e-12):
        raise doc.error(f"{what} has a singular transform")
    r = a / scale[..., None, None]
    if np.abs(r @ np.swapaxes(r, -1, -2) - np.eye(3)).max() > _SCALE_TOL:
        raise doc.error(
            f"{what} has a non-uniform scale or shear, which a skeleton cannot represent"
        )
    return r


def _skinned_nodes(doc: GLTFDocument) -> list[int]:
    g = doc.gltf
    nodes = [n for n, node in enumerate(g.nodes) if node.mesh is not None and node.skin is not None]
    if not nodes:
        raise NoSkinError(
            f"{doc.path}: no skin: the file has no mesh node with a skin, so it is not a rigged "
            "character (export it with its armature / skinning)"
        )
    for n in nodes:
        if g.nodes[n].mesh >= len(g.meshes) or g.nodes[n].skin >= len(g.skins):
            raise doc.error(f"node {n} names a mesh or skin that does not exist")
    return nodes


def _inverse_binds(doc: GLTFDocument, skin_index: int) -> np.ndarray:
    """``(K, 4, 4)`` the inverse bind matrices of a skin (identity without an accessor), each an
    invertible affine matrix."""
    skin = doc.gltf.skins[skin_index]
    if skin.inverseBindMatrices is None:
        return np.broadcast_to(np.eye(4), (len(skin.joints), 4, 4))
    what = f"skin {skin_index} inverse bind matrices"
    index = skin.inverseBindMatrices
    if index < len(doc.gltf.accessors) and doc.gltf.accessors[index].count != len(skin.joints):
        raise doc.error(
            f"skin {skin_index}: {doc.gltf.accessors[index].count} inverse bind matrices for "
            f"{len(skin.joints)} joints"
        )
    ibm = doc.accessor(index, _INVERSE_BIND, what).astype(np.float64)
    affine = np.abs(ibm[:, 3] - [0.0, 0.0, 0.0, 1.0]).max(axis=1) <= 1e-6
    scale = np.abs(ibm[:, :3, :3]).max(axis=(1, 2))
    invertible = np.abs(np.linalg.det(ibm[:, :3, :3])) > 1e-9 * np.maximum(scale, 1e-300) ** 3
    bad = np.flatnonzero(~(affine & invertible))
    if bad.size:
        name = doc.gltf.nodes[skin.joints[bad[0]]].name or f"node{skin.joints[bad[0]]}"
        raise doc.error(
            f"{what}: {bad.size} of {len(ibm)} are not invertible affine matrices (first: joint "
            f"{name!r}); "
            "every vertex they bind would collapse"
        )
    return ibm


def _mesh(doc: GLTFDocument, skinned: list[int], tree: _Skeleton, world: dict[int, np.ndarray]):
    """Rest vertices ``(V, 3)`` (posed by the file's skinning), faces ``(F, 3)``, weights ``(V,
    J)``."""
    g = doc.gltf
    index = {n: i for i, n in enumerate(tree.nodes)}
    verts, faces, weights, base, triangles = [], [], [], 0, 0
    for n in skinned:
        skin = g.skins[g.nodes[n].skin]
        palette = np.array([index[j] for j in skin.joints])
        skin_mats = np.stack([world[j] for j in skin.joints]) @ _inverse_binds(
            doc, g.nodes[n].skin
        )  # (K, 4, 4)
        for p, prim in enumerate(g.meshes[g.nodes[n].mesh].primitives):
            what = f"mesh {g.nodes[n].mesh} primitive {p}"
            if (prim.mode if prim.mode is not None else _TRIANGLES) != _TRIANGLES:
                raise doc.error(f"{what} is not a triangle list (mode {prim.mode})")
            attrs = prim.attributes
            if attrs.POSITION is None or attrs.JOINTS_0 is None or attrs.WEIGHTS_0 is None:
                raise doc.error(
                    f"{what} lacks POSITION, JOINTS_0 or WEIGHTS_0 (a skinned mesh needs all three)"
                )
            pos = doc.accessor(attrs.POSITION, _POSITION, f"{what} POSITION").astype(np.float64)
            check_count(base + len(pos), MAX_VERTICES, "vertices", str(doc.path))
            check_array_bytes(
                (base + len(pos), len(tree.nodes)),
                8,
                "skinning weights (vertices x joints)",
                str(doc.path),
            )
            w = _weights(doc, attrs, len(pos), palette, len(tree.nodes), what)
            local_w = w[:, palette]  # (V, K)
            blended = np.einsum("vk,kij->vij", local_w, skin_mats)
            verts.append(np.einsum("vij,vj->vi", blended[:, :3, :3], pos) + blended[:, :3, 3])
            idx = (
                doc.accessor(prim.indices, _INDICES, f"{what} indices").astype(np.int64).ravel()
                if prim.indices is not None
                else np.arange(len(pos))
            )
            if len(idx) % 3 or (idx.size and idx.max() >= len(pos)):
                raise doc.error(
                    f"{what}: triangle indices are not triples of vertices 0..{len(pos) - 1}"
                )
            triangles += len(idx) // 3
            check_count(triangles, MAX_TRIANGLES, "triangles", str(doc.path))
            faces.append(idx.reshape(-1, 3) + base)
            weights.append(w)
            base += len(pos)
    return np.concatenate(verts), np.concatenate(faces), np.concatenate(weights)


def _weights(
    doc: GLTFDocument, attrs: JsonObject, count: int, palette: np.ndarray, joints: int, what: str
) -> np.ndarray:
    """``(V, J)`` normalised skinning weights from every ``JOINTS_k`` / ``WEIGHTS_k`` set."""
    w = np.zeros((count, joints))
    k = 0
    while getattr(attrs, f"JOINTS_{k}") is not None:
        if getattr(attrs, f"WEIGHTS_{k}") is None:
            raise doc.error(f"{what}: JOINTS_{k} without WEIGHTS_{k}")
        jk = doc.accessor(getattr(attrs, f"JOINTS_{k}"), _JOINTS, f"{what} JOINTS_{k}").astype(
            np.int64
        )
        wk = doc.accessor(getattr(attrs, f"WEIGHTS_{k}"), _WEIGHTS, f"{what} WEIGHTS_{k}").astype(
            np.float64
        )
        if len(jk) != count or len(wk) != count:
            raise doc.error(f"{what}: JOINTS_{k} / WEIGHTS_{k} must have one VEC4 per vertex")
        if jk.max(initial=0) >= len(palette) or wk.min(initial=0.0) < 0:
            raise doc.error(
                f"{what}: JOINTS_{k} indexes outside the skin's {len(palette)} joints "
                f"or WEIGHTS_{k} is negative"
            )
        np.add.at(w, (np.repeat(np.arange(count), 4), palette[jk].ravel()), wk.ravel())
        k += 1
    sums = w.sum(axis=1)
    if (sums <= 0).any():
        raise doc.error(f"{what}: {int((sums <= 0).sum())} vertices have all skinning weights zero")
    return w / sums[:, None]


def _vrm_mapping(doc: GLTFDocument, tree: _Skeleton) -> dict[str, str]:
    """``{canonical name: joint name}`` from a VRM 0.x (``VRM``) or 1.0 (``VRMC_vrm``) humanoid
    (types checked by :data:`_GLTF_JSON`)."""
    ext = doc.gltf.extensions
    if ext is None:
        return {}
    if ext.VRMC_vrm is not None:
        humanoid = ext.VRMC_vrm.humanoid
        table = humanoid.humanBones if humanoid is not None else None
        bones = {b: v.node for b, v in table.items()} if table is not None else {}
    elif ext.VRM is not None:
        humanoid = ext.VRM.humanoid
        bones = {b.bone: b.node for b in (humanoid.humanBones if humanoid is not None else [])}
    else:
        return {}
    canon = {joint_key(k): v for k, v in RIG_MAPS["vrm"].items()}
    name_of = dict(zip(tree.nodes, tree.names, strict=False))
    return {
        canon[joint_key(b)]: name_of[n]
        for b, n in bones.items()
        if b and joint_key(b) in canon and n in name_of
    }


def _armature(
    doc: GLTFDocument,
    tree: _Skeleton,
    mapping,
    skinless: bool = False,
) -> tuple[Skeleton, dict[int, int], str, np.ndarray, dict]:
    """The rest skeleton of ``tree``, its map onto the canonical 22 (and the rig naming that
    matched), the ``(J, 3, 3)`` rest world rotations of the joints and the rest world transforms.

    Joints below the root must not scale (a rotation cannot carry it), except, in a ``skinless``
    file, a leaf: an end site's scale moves nothing (3ds Max's Biped writes some nubs mirrored,
    scale -1)."""
    g = doc.gltf
    local = {n: _local_matrix(g.nodes[n]) for n in _with_ancestors(tree.nodes, tree.node_parent)}
    world = _world(
        tree.node_parent, _framed(local, tree.node_parent, doc.frame, doc.lift), tree.nodes
    )
    has_child = set(tree.parents)
    for k, n in enumerate(tree.nodes[1:], start=1):
        if skinless and k not in has_child:
            continue
        _rotation_part(local[n], doc, f"joint {g.nodes[n].name or n}")
        if abs(np.cbrt(np.linalg.det(local[n][:3, :3])) - 1.0) > _SCALE_TOL:
            raise doc.error(
                f"joint {g.nodes[n].name or n} is scaled; joints below the root must have scale 1"
            )
    rest_rot = np.stack(
        [_rotation_part(world[n], doc, f"joint {g.nodes[n].name or n}") for n in tree.nodes]
    )
    rest = np.stack([world[n][:3, 3] for n in tree.nodes])
    offsets = rest.copy()
    offsets[1:] -= rest[tree.parents[1:]]
    skeleton = Skeleton(tuple(tree.names), tuple(tree.parents), offsets)
    entries, source = read_mapping(mapping)
    user = entries or {}
    vrm = _vrm_mapping(doc, tree)
    joint_map, rig_name = map_joints(
        tree.names,
        tree.parents,
        vrm | user,
        what=str(doc.path),
        mapping_source=source if user else "the VRM humanoid",
        may_be_absent=MAY_BE_ABSENT,
    )
    turn = _upright(rest, joint_map)
    if not np.array_equal(turn, np.eye(3)):  # once: read again in the library's axes
        doc.frame = turn @ doc.frame
        return _armature(doc, tree, mapping, skinless)
    return skeleton, joint_map, rig_name, rest_rot, world


def rig_from(doc: GLTFDocument, mapping=None) -> Rig:
    """The skinned character of a parsed file (see :func:`load_gltf_rig`)."""
    return _load(doc, mapping)[2]


def _load(doc: GLTFDocument, mapping) -> tuple[GLTFDocument, _Skeleton, Rig, np.ndarray]:
    """Everything :func:`load_gltf_rig` and :func:`load_gltf_motion` share; the last item is the
    ``(J, 3, 3)`` rest world rotations of the joints."""
    skinned = _skinned_nodes(doc)
    tree = _joint_tree(doc, skinned)
    skeleton, joint_map, rig_name, rest_rot, world = _armature(doc, tree, mapping)
    vertices, faces, weights = _mesh(doc, skinned, tree, world)
    low = float(vertices[:, 1].min()) if len(vertices) else 0.0
    if abs(low) > FLOOR_TOLERANCE_M and doc.lift == 0.0:  # once: read again standing on y = 0
        doc.lift = -low
        return _load(doc, mapping)
    rig = Rig(
        doc.path.stem,
        skeleton,
        vertices,
        faces,
        weights,
        joint_map,
        meta=dict(source=str(doc.path), rig=rig_name),
    )
    return doc, tree, rig, rest_rot


def load_gltf_rig(path: str | os.PathLike, mapping: str | os.PathLike | dict | None = None) -> Rig:
    """Read a skinned character from a glTF 2.0 / GLB file.

    Args:
        path: ``.glb`` or ``.gltf``.
        mapping: a mapping file (YAML/JSON ``{canonical name: file joint name}``) or such a dict,
            completing or fixing the detected joint map.

    Returns:
        a :class:`~retarget_lib.core.rig.Rig` (world rest pose, metres, all skin joints kept);
        ``rig.character()`` is the canonical-22 character.

    Raises:
        NoSkinError: the file has no skinned mesh (a :class:`~retarget_lib.errors.GLTFError`).
        GLTFError: a malformed or truncated file, a JSON field of the wrong type, several
            skeleton roots, scaled joints, singular inverse bind matrices, unsupported accessors
            or compression. JointSetError: joints that cannot be mapped (named).
        LimitError: beyond a bound of the module docstring. InputFileError: missing, empty or
            larger than :data:`MAX_FILE_BYTES`.
    """
    return rig_from(_read(path), mapping)


def load_gltf_motion(
    path: str | os.PathLike,
    fps: float | None = None,
    animation: int = 0,
    mapping: str | os.PathLike | dict | None = None,
) -> tuple[Motion, Rig]:
    """Sample an animation of a skinned glTF/GLB file as a motion on the file's own joints.

    Args:
        path: ``.glb`` or ``.gltf`` with a skin and an animation.
        fps: sampling rate (default: the ``fps`` in the animation's ``extras``, else the keys'
            rate (:func:`key_rate`), else :data:`DEFAULT_FPS`).
        animation: which animation.
        mapping: as in :func:`load_gltf_rig`.

    Returns:
        ``(motion on rig.skeleton, rig)``; ``rig.motion_to_canonical(motion)`` folds it.

    Raises:
        GLTFError: no animation, or one whose samplers are malformed; everything
            :func:`load_gltf_rig` raises. LimitError: a time span beyond the frame or sample
            budget.
    """
    return motion_from(_read(path), fps, animation, mapping)


def motion_from(
    doc: GLTFDocument, fps: float | None = None, animation: int = 0, mapping=None
) -> tuple[Motion, Rig]:
    """:func:`load_gltf_motion` of a parsed file."""
    doc, tree, rig, rest_rot = _load(doc, mapping)
    motion = _sample_motion(doc, tree, rig.skeleton, rest_rot, fps, animation)
    return motion, rig


def load_gltf_animation(
    path: str | os.PathLike,
    fps: float | None = None,
    animation: int = 0,
    mapping: str | os.PathLike | dict | None = None,
) -> tuple[Motion, dict[int, int]]:
    """Sample an animation of a glTF/GLB file **with or without a skin** (e.g. a Mixamo clip
    downloaded "Without Skin" and converted): the joints are the skin's when the file has a skinned
    mesh, else every node the animation moves and the nodes below them (see the module docstring
    for the rest pose and sampling; no mesh is read).

    Args:
        path: ``.glb`` or ``.gltf`` with an animation.
        fps, animation, mapping: as in :func:`load_gltf_motion`.

    Returns:
        ``(motion on the file's joints, joint_map)``: ``joint_map`` is ``{file joint index:
        canonical index}``, so ``fold_to_canonical22(motion, joint_map)`` folds it.

    Raises:
        GLTFError: no animation, an animation that moves no node, several skeleton roots,
            malformed samplers. JointSetError: joints that cannot be mapped (named).
    """
    return animation_from(_read(path), fps, animation, mapping)


def animation_from(
    doc: GLTFDocument, fps: float | None = None, animation: int = 0, mapping=None
) -> tuple[Motion, dict[int, int]]:
    """:func:`load_gltf_animation` of a parsed file."""
    g = doc.gltf
    skinned = [
        n for n, node in enumerate(g.nodes) if node.mesh is not None and node.skin is not None
    ]
    tree = _joint_tree(doc, _skinned_nodes(doc)) if skinned else _animated_tree(doc, animation)
    skeleton, joint_map, _, rest_rot, _ = _armature(doc, tree, mapping, skinless=not skinned)
    return _sample_motion(doc, tree, skeleton, rest_rot, fps, animation), joint_map


@dataclass
class _Channel:
    """One animation channel, decoded: the node and property it moves, its keys and
    interpolation."""

    node: int
    path: str
    times: np.ndarray
    values: np.ndarray
    interpolation: str


def _channels(doc: GLTFDocument, animation: int) -> list[_Channel]:
    """The rotation, translation and scale channels of ``animation``, checked and decoded (each
    accessor once, however many channels share it; one channel per node and property, as glTF
    requires)."""
    g = doc.gltf
    if not 0 <= animation < len(g.animations):
        raise doc.error(f"has {len(g.animations)} animations; animation {animation} does not exist")
    anim = g.animations[animation]
    out: list[_Channel] = []
    first: dict[tuple[int, str], int] = {}
    decoded: dict[tuple, tuple[np.ndarray, np.ndarray]] = {}
    for i, c in enumerate(anim.channels):
        where = f"animation {animation} channel {i}"
        if c.target.node is None or c.target.path not in _KEY_VALUES:
            continue
        if c.sampler >= len(anim.samplers) or c.target.node >= len(g.nodes):
            raise doc.error(
                f"{where} names sampler {c.sampler} or node {c.target.node}, which does not exist"
            )
        target = (c.target.node, c.target.path)
        if target in first:
            raise doc.error(
                f"animation {animation} channels {first[target]} and {i} both move node "
                f"{target[0]} "
                f"{target[1]}; a property may have one channel"
            )
        first[target] = i
        s = anim.samplers[c.sampler]
        key = (s.input, s.output, c.target.path, s.interpolation or "LINEAR")
        if key not in decoded:
            decoded[key] = _keys(doc, animation, c.sampler, *key)
        times, values = decoded[key]
        out.append(_Channel(c.target.node, c.target.path, times, values, key[3]))
    if not out:
        raise doc.error(f"animation {animation} has no rotation or translation channels")
    return out


def _keys(
    doc: GLTFDocument,
    animation: int,
    sampler: int,
    times_at: int,
    values_at: int,
    path: str,
    interpolation: str,
) -> tuple[np.ndarray, np.ndarray]:
    """``(key times (K,), key values (K, C))`` of one sampler for the property ``path``."""
    where = f"animation {animation} sampler {sampler}"
    if interpolation not in ("LINEAR", "STEP", "CUBICSPLINE"):
        raise doc.error(
            f"{where}: unknown interpolation {interpolation!r} (LINEAR, STEP or CUBICSPLINE)"
        )
    times = doc.accessor(times_at, _KEY_TIMES, f"{where} input").ravel().astype(np.float64)
    values = doc.accessor(values_at, _KEY_VALUES[path], f"{where} output ({path})").astype(
        np.float64
    )
    if interpolation == "CUBICSPLINE":
        values = values[1::3] if len(values) == 3 * len(times) else values[:0]
    if len(times) == 0 or len(values) != len(times) or np.any(np.diff(times) <= 0):
        raise doc.error(f"{where}: keyframe times must increase and match the values")
    return times, values


def _frame_rate(
    doc: GLTFDocument, animation: int, fps: float | None, channels: list[_Channel]
) -> float:
    """The sampling rate: ``fps``, else the animation's ``extras.fps``, else the keys' rate, else
    30."""
    extras = doc.gltf.animations[animation].extras
    stored = extras.get("fps") if isinstance(extras, dict) else None
    if stored is not None and not (
        isinstance(stored, (int, float)) and not isinstance(stored, bool)
    ):
        raise doc.error(
            f"animation {animation} extras.fps must be a number of frames per second, got "
            f"{stored!r}"
        )
    rate = float(fps or stored or key_rate([ch.times for ch in channels]) or DEFAULT_FPS)
    if not (np.isfinite(rate) and 1.0 <= rate <= 1000.0):
        raise doc.error(f"animation {animation}: frame rate {rate} is outside 1-1000")
    return rate


def _sample_motion(
    doc: GLTFDocument,
    tree: _Skeleton,
    skeleton: Skeleton,
    rest_rot: np.ndarray,
    fps: float | None,
    animation: int,
) -> Motion:
    """Animation ``animation`` of ``doc`` sampled as a motion on ``skeleton`` (the joints of
    ``tree``).

    The frames x (joints + animated ancestors) to sample are checked against the sample budget
    before anything is sampled; nodes no channel moves keep ``(4, 4)`` transforms, and frames are
    sampled in blocks of :data:`_BLOCK_SAMPLES`, so memory beyond the result stays bounded."""
    g = doc.gltf
    channels = _channels(doc, animation)
    rate = _frame_rate(doc, animation, fps, channels)
    start, end = min(ch.times[0] for ch in channels), max(ch.times[-1] for ch in channels)
    count = (
        int(np.floor((end - start) * rate + 0.01)) + 1
    )  # float32 key times: within 1 % of a frame
    where = f"{doc.path}: animation {animation}"
    check_count(count, MAX_FRAMES, f"frames at {rate:g} fps", where)
    nodes = _with_ancestors(tree.nodes, tree.node_parent)
    used = [
        ch
        for ch in channels
        if ch.node in nodes and (ch.path == "rotation" or ch.node not in tree.nodes[1:])
    ]
    moving = {
        ch.node for ch in used if not g.nodes[ch.node].matrix
    }  # a node with a matrix is never animated
    check_motion_samples(
        count,
        len(set(tree.nodes) | moving),
        where,
        f" (keys from {start:g} s to {end:g} s at {rate:g} fps)",
    )
    static = {n: _local_matrix(g.nodes[n]) for n in nodes if n not in moving}
    rotations, root = np.empty((count, len(tree.nodes), 4)), np.empty((count, 3))
    block = max(1, _BLOCK_SAMPLES // (len(tree.nodes) + len(moving)))
    for lo in range(0, count, block):
        t = start + np.arange(lo, min(count, lo + block)) / rate
        local = dict(static)
        local.update(
            {n: _animated_local(g.nodes[n], [ch for ch in used if ch.node == n], t) for n in moving}
        )
        rotations[lo : lo + len(t)], root[lo : lo + len(t)] = _pose(
            doc, tree, rest_rot, local, len(t)
        )
    return Motion(
        skeleton.copy(),
        rotations,
        root,
        rate,
        name=g.animations[animation].name or doc.path.stem,
        meta=dict(source=str(doc.path), animation=animation),
    )


def _animated_local(node: JsonObject, channels: list[_Channel], t: np.ndarray) -> np.ndarray:
    """``(T, 4, 4)`` the local transforms of an animated node at times ``t``."""
    trs = [
        np.broadcast_to(np.asarray(v, dtype=np.float64), (len(t), len(v)))
        for v in (
            node.translation or (0, 0, 0),
            node.rotation or (0, 0, 0, 1),
            node.scale or (1, 1, 1),
        )
    ]
    for ch in channels:
        trs[("translation", "rotation", "scale").index(ch.path)] = _sample(
            ch.times, ch.values, t, ch.interpolation, ch.path == "rotation"
        )
    return _trs(*trs)


def _pose(
    doc: GLTFDocument,
    tree: _Skeleton,
    rest_rot: np.ndarray,
    local: dict[int, np.ndarray],
    frames: int,
) -> tuple[np.ndarray, np.ndarray]:
    """``(rotations (T, J, 4) wxyz relative to the rest pose, root positions (T, 3))`` of ``frames``
    frames from per-node local transforms (``(4, 4)`` or ``(T, 4, 4)``)."""
    g = doc.gltf
    world = _world(
        tree.node_parent, _framed(local, tree.node_parent, doc.frame, doc.lift), tree.nodes
    )
    glob = np.stack(
        [
            np.broadcast_to(
                _rotation_part(world[n], doc, f"joint {g.nodes[n].name or n}"), (frames, 3, 3)
            )
            for n in tree.nodes
        ],
        axis=1,
    )
    q_glob = glob @ np.swapaxes(rest_rot, -1, -2)[None]  # rest pose -> identity
    par = np.array(tree.parents[1:])
    q_local = q_glob.copy()
    q_local[:, 1:] = np.swapaxes(q_glob[:, par], -1, -2) @ q_glob[:, 1:]
    rotations = matrix_to_quat(torch.from_numpy(q_local)).numpy()
    return rotations, np.broadcast_to(world[tree.nodes[0]][..., :3, 3], (frames, 3))


def key_rate(key_times: list[np.ndarray], tol: float = 0.01) -> float | None:
    """The frame rate of baked keyframes (an FBX/GLB exported with a key on every frame, as
    Mixamo's).

    Args:
        key_times: each channel's ``(K,)`` increasing key times in seconds.
        tol: how far (in frames) a key may lie off the grid (float32 times).

    Returns:
        ``1 / spacing`` of the channel with the most keys when it has at least 3 keys, all on one
        regular grid (within ``tol`` of a frame), and the rate is 1-1000 fps (within 1e-4 of an
        integer it is rounded to it); else ``None`` (the caller's default).
    """
    times = max(key_times, key=len)
    if len(times) < 3:
        return None
    dt = float(np.median(np.diff(times)))
    if not dt > 0:
        return None
    steps = (times - times[0]) / dt
    rate = 1.0 / dt
    if np.abs(steps - np.round(steps)).max() > tol or not 1.0 <= rate <= 1000.0:
        return None
    return float(round(rate)) if abs(rate - round(rate)) <= 1e-4 * rate else rate


def _sample(
    times: np.ndarray, values: np.ndarray, t: np.ndarray, interp: str, rotation: bool
) -> np.ndarray:
    """Sample keyframes ``(K,)`` / ``(K, C)`` at times ``(T,)``: STEP, else linear (slerp for
    quaternions ``(K, 4)`` xyzw); held constant outside the keyed range."""
    i1 = (
        np.clip(np.searchsorted(times, t, side="right"), 1, len(times) - 1)
        if len(times) > 1
        else np.zeros(len(t), int)
    )
    i0 = np.maximum(i1 - 1, 0)
    span = np.where(times[i1] > times[i0], times[i1] - times[i0], 1.0)
    a = np.clip((t - times[i0]) / span, 0.0, 1.0)
    if interp == "STEP":
        a = (a >= 1.0).astype(np.float64)
    if not rotation:
        return values[i0] * (1 - a[:, None]) + values[i1] * a[:, None]
    wxyz = torch.from_numpy(np.ascontiguousarray(values[:, [3, 0, 1, 2]]))
    wxyz = wxyz / wxyz.norm(dim=-1, keepdim=True).clamp_min(1e-12)
    q = quat_slerp(wxyz[i0], wxyz[i1], torch.from_numpy(a)).numpy()
    return q[:, [1, 2, 3, 0]]
