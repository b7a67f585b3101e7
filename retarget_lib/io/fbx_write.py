"""Writing a skinned, animated character as a binary FBX 7.4 file (``.fbx``), in pure Python.

Why our own writer: assimp 5.2.5's FBX exporter writes binary files assimp itself cannot read back
and ASCII files whose key times come back 1000x too late, and Blender as a module (PyPI ``bpy``) is
an 821 MB install pinned to ``numpy<2`` (see :mod:`~retarget_lib.io.fbx`). The binary format is a
small, documented node tree (Blender Foundation, "FBX binary file format specification", 2013), so
this module writes it with ``struct`` and ``zlib`` only: no optional dependency is needed to write.

**Container.** The 23-byte magic ``Kaydara FBX Binary  \\0\\x1a\\0``, the version (7400), then node
records ``(end offset, property count, property bytes: uint32; name: uint8 length + bytes;
properties; children; a 13-byte zero record closing a child list)``, a zero record closing the top
level and the footer (a 16-byte id, zero padding to a multiple of 16, 4 zero bytes, the version,
120 zero bytes, a fixed 16-byte end), so the file's length is a multiple of 16. Properties are typed
by one letter: ``C`` bool, ``I`` int32, ``L`` int64, ``D`` float64, ``S`` string, ``R`` bytes, and
arrays ``i l f d`` (``count, encoding, byte length`` then the data, zlib-compressed when longer than
128 bytes). Object names are ``b"Name\\0\\x01Class"``. ``FileId``, ``CreationTime`` and the footer
use the fixed values other writers use (the FBX SDK checks them against each other), so a file's
bytes depend only on its content.

**Scene** (the library's conventions: metres, +Y up, facing +Z, rest pose = identity local
rotations with world-axis offsets):

* ``GlobalSettings``: Y up, Z front, X right (right-handed), ``UnitScaleFactor`` 100 (one unit is
  a metre, the value Blender writes; ``unit_scale_factor=1`` writes centimetres), ``TimeMode``
  the motion's frame rate (a standard mode when one matches, else ``eCustom`` with
  ``CustomFrameRate``).
* One ``Model`` ``LimbNode`` per joint (with its ``NodeAttribute`` ``LimbNode``), parented as the
  skeleton, ``Lcl Translation`` = the joint's rest offset, ``Lcl Rotation`` 0 (rest).
* One ``Model`` ``Mesh`` at the origin with its ``Geometry``: ``Vertices`` (rest, metres),
  triangles in ``PolygonVertexIndex`` (the last index of a polygon stored as ``-(i + 1)``) and
  smooth per-vertex normals.
* A ``Deformer`` ``Skin`` with one ``Cluster`` per joint (every joint, also weightless ones, so
  readers keep every bone): ``Indexes``/``Weights`` (the rig's non-zero weights),
  ``TransformLink`` = the joint's rest world matrix, ``Transform`` = its inverse (mesh at the
  origin); and a ``Pose`` ``BindPose`` with the same matrices. Matrices are 16 float64,
  column-major (translation in elements 12-14).
* With a motion: one ``AnimationStack`` / ``AnimationLayer``; per joint a ``Lcl Rotation``
  ``AnimationCurveNode`` with three ``AnimationCurve`` (X, Y, Z Euler degrees, FBX's default
  order ``eEulerXYZ``: ``R = Rz Ry Rx``, unwrapped frame to frame so linear interpolation never
  takes the long way round), and the root's ``Lcl Translation``; keys at every frame, times in
  FBX ticks (:data:`KTIME_PER_SECOND`), linear interpolation, values float32.

Round trips through the Open Asset Import Library (``tests/test_fbx.py``) and, where a ``bpy``
virtual environment exists, Blender's importer check joints, rest pose, weights and animation.
"""

from __future__ import annotations

import os
import struct
import zlib

import numpy as np
import torch

from ..core.motion import Motion
from ..core.rig import Rig
from ..core.rotations import quat_to_euler
from ..errors import FBXError
from ..files import atomic_write
from ..geometry.normals import vertex_normals
from .untrusted import name_problem

__all__ = ["KTIME_PER_SECOND", "FBX_VERSION", "save_fbx", "fbx_time_mode"]

#: FBX time ticks per second ("KTime")
KTIME_PER_SECOND = 46_186_158_000
#: the binary version written (7.4: 32-bit record offsets, read by every FBX importer in use)
FBX_VERSION = 7400
#: an array property is compressed when its raw bytes exceed this (what the FBX SDK does)
_COMPRESS_ABOVE = 128

_MAGIC = b"Kaydara FBX Binary  \x00\x1a\x00"
_CREATION_TIME = b"1970-01-01 10:00:00:000"
_FILE_ID = bytes.fromhex("28b32aebb624ccc2bfc8b02aa92bfcf1")
_FOOTER_ID = bytes.fromhex("fabcab09d0c8d466b176fb831cf7267e")
_FOOTER_END = bytes.fromhex("f85a8c6adef5d97eece90ce3758f290b")
_NULL_RECORD = b"\x00" * 13
#: records closed by a zero record even without children (as FBX SDK files have them)
_ALWAYS_CLOSED = {"AnimationStack", "AnimationLayer"}
#: FBX ``TimeMode`` enum values of the standard frame rates (``eCustom`` = 14 otherwise)
_TIME_MODES = {
    120.0: 1,
    100.0: 2,
    60.0: 3,
    50.0: 4,
    48.0: 5,
    30.0: 6,
    25.0: 10,
    24.0: 11,
    1000.0: 12,
    96.0: 15,
    72.0: 16,
}
_CUSTOM_TIME_MODE = 14
_LINEAR_KEY = 4  # KeyAttrFlags: eInterpolationLinear


def fbx_time_mode(fps: float) -> int:
    """The FBX ``GlobalSettings`` ``TimeMode`` of a frame rate (``eCustom`` = 14 for other
    rates)."""
    return _TIME_MODES.get(float(fps), _CUSTOM_TIME_MODE)


# ------------------------------------------------------------------ the node tree and its encoding
class _Node:
    """One FBX record: a name, typed properties ``[(type letter, python value)]`` and children."""

    __slots__ = ("name", "props", "children")

    def __init__(self, name: str, *props) -> None:
        self.name, self.props = name, [_typed(p) for p in props]
        self.children: list[_Node] = []

    def add(self, name: str, *props) -> _Node:
        """Append a child record and return it."""
        child = _Node(name, *props)
        self.children.append(child)
        return child


class _Typed:
    """A property whose FBX type letter is given explicitly (``I`` int32, ``D`` double, ``R``
    bytes)."""

    __slots__ = ("code", "value")

    def __init__(self, code: str, value) -> None:
        self.code, self.value = code, value


def _typed(value) -> tuple[str, object]:
    """``(type letter, value)``: bool ``C``, int ``L``, float ``D``, str ``S``, bytes ``S``
    (object names), numpy arrays by dtype (``i l f d``), or an explicit :class:`_Typed`."""
    if isinstance(value, _Typed):
        return value.code, value.value
    if isinstance(value, (bool, np.bool_)):
        return "C", bool(value)
    if isinstance(value, (int, np.integer)):
        return "L", int(value)
    if isinstance(value, (float, np.floating)):
        return "D", float(value)
    if isinstance(value, str):
        return "S", value.encode("utf-8")
    if isinstance(value, bytes):
        return "S", value
    if isinstance(value, np.ndarray):
        codes = {
            np.dtype(np.int32): "i",
            np.dtype(np.int64): "l",
            np.dtype(np.float32): "f",
            np.dtype(np.float64): "d",
        }
        return codes[value.dtype], np.ascontiguousarray(value.ravel())
    raise TypeError(f"no FBX property type for {type(value).__name__}")


def _i32(v: int) -> _Typed:
    return _Typed("I", int(v))


def _encode_prop(code: str, value) -> bytes:
    """One property's bytes: its type letter then its data."""
    tag = code.encode()
    if code == "C":
        return tag + struct.pack("<?", value)
    if code == "I":
        return tag + struct.pack("<i", value)
    if code == "L":
        return tag + struct.pack("<q", value)
    if code == "D":
        return tag + struct.pack("<d", value)
    if code in "SR":
        return tag + struct.pack("<I", len(value)) + value
    raw = value.astype(value.dtype.newbyteorder("<"), copy=False).tobytes()
    encoding = 1 if len(raw) > _COMPRESS_ABOVE else 0
    data = zlib.compress(raw) if encoding else raw
    return tag + struct.pack("<3I", value.size, encoding, len(data)) + data


def _encode(node: _Node, offset: int, is_last: bool, out: list[bytes]) -> int:
    """Append ``node``'s record (starting at file ``offset``) to ``out``; return its end offset."""
    props = b"".join(_encode_prop(c, v) for c, v in node.props)
    name = node.name.encode()
    head = len(props) + 13 + len(name)
    at = len(out)
    out.append(b"")  # the record header, known once the children are encoded
    out.append(props)
    end = offset + head
    for i, child in enumerate(node.children):
        end = _encode(child, end, i == len(node.children) - 1, out)
    if node.children or node.name in _ALWAYS_CLOSED or (not node.props and not is_last):
        out.append(_NULL_RECORD)
        end += len(_NULL_RECORD)
    if end >= 2**32:
        raise FBXError("the FBX file would exceed 4 GiB, the limit of FBX 7.4 record offsets")
    out[at] = struct.pack("<3IB", end, len(node.props), len(props), len(name)) + name
    return end


def _file_bytes(top: list[_Node]) -> bytes:
    """The whole binary file: magic, version, the top-level records, the zero record, the footer."""
    out = [_MAGIC, struct.pack("<I", FBX_VERSION)]
    offset = len(_MAGIC) + 4
    for i, node in enumerate(top):
        offset = _encode(node, offset, i == len(top) - 1, out)
    out += [_NULL_RECORD, _FOOTER_ID]
    offset += len(_NULL_RECORD) + len(_FOOTER_ID)
    out.append(
        b"\x00" * (-offset % 16)
    )  # 0-15 bytes: what follows is 16-byte aligned, as in SDK files
    out += [b"\x00" * 4, struct.pack("<I", FBX_VERSION), b"\x00" * 120, _FOOTER_END]
    return b"".join(out)


# ------------------------------------------------------------------ helpers for the scene
def _object_name(name: str, cls: str) -> bytes:
    return name.encode("utf-8") + b"\x00\x01" + cls.encode()


def _properties(*entries: tuple) -> _Node:
    """A ``Properties70`` block; each entry ``(name, type, label, flags, *values)``."""
    block = _Node("Properties70")
    for entry in entries:
        block.add("P", *entry)
    return block


def _vec3(name: str, kind: str, v, flags: str = "A") -> tuple:
    return (name, kind, "", flags, float(v[0]), float(v[1]), float(v[2]))


def _matrix(rotation: np.ndarray | None, translation: np.ndarray) -> np.ndarray:
    """A 4x4 transform as FBX's 16 column-major float64 (translation in elements 12-14)."""
    m = np.eye(4)
    if rotation is not None:
        m[:3, :3] = rotation
    m[:3, 3] = translation
    return m.T.ravel().copy()


def _continuous_euler_xyz(rotations: np.ndarray) -> np.ndarray:
    """``(T, J, 3)`` FBX ``eEulerXYZ`` angles in degrees (``R = Rz(z) Ry(y) Rx(x)``) of wxyz
    quaternions ``(T, J, 4)``, each frame choosing, of the two equivalent triples and their 360°
    shifts, the one closest to the previous frame."""
    zyx = quat_to_euler(torch.from_numpy(rotations), "ZYX", degrees=True).numpy()
    angles = zyx[..., ::-1].copy()  # (x, y, z)
    other = np.stack(
        [angles[..., 0] + 180.0, 180.0 - angles[..., 1], angles[..., 2] + 180.0], axis=-1
    )
    for t in range(1, len(angles)):
        prev = angles[t - 1]
        candidates = np.stack([angles[t], other[t]])  # (2, J, 3)
        candidates = candidates - 360.0 * np.round((candidates - prev) / 360.0)
        pick = np.abs(candidates - prev).sum(-1).argmin(0)  # (J,)
        angles[t] = np.take_along_axis(candidates, pick[None, :, None], 0)[0]
    return angles


# ------------------------------------------------------------------ the writer
class _Scene:
    """Objects and connections under construction (ids are consecutive int64 from 1,000,000)."""

    def __init__(self) -> None:
        self.objects = _Node("Objects")
        self.connections = _Node("Connections")
        self.counts: dict[str, int] = {}
        self._next = 1_000_000

    def new(self, kind: str, name: str, cls: str, subtype: str) -> tuple[int, _Node]:
        uid, self._next = self._next, self._next + 1
        self.counts[kind] = self.counts.get(kind, 0) + 1
        return uid, self.objects.add(kind, uid, _object_name(name, cls), subtype)

    def link(self, child: int, parent: int, prop: str | None = None) -> None:
        if prop is None:
            self.connections.add("C", "OO", child, parent)
        else:
            self.connections.add("C", "OP", child, parent, prop)


def save_fbx(
    rig: Rig,
    path: str | os.PathLike,
    motion: Motion | None = None,
    unit_scale_factor: float = 100.0,
) -> None:
    """Write ``rig`` (mesh, skin, all its joints) and optionally ``motion`` as a binary ``.fbx``
    (atomically; see the module docstring for what the file holds).

    Args:
        rig: the character; ``Rig.from_character`` makes one from a canonical-22 character.
        path: destination ``.fbx``.
        motion: a motion on ``rig.skeleton`` (same joint names), e.g.
            ``rig.motion_from_canonical(result)``, keyed at its own frame rate; ``None`` writes the
            character in its rest pose without animation.
        unit_scale_factor: centimetres per file unit, FBX's ``UnitScaleFactor``: 100 (default)
            writes metres, 1 centimetres (what Mixamo and Maya write); importers convert either.

    Raises:
        FBXError: ``motion`` is on another joint set, ``unit_scale_factor`` is not positive, a
            joint name FBX cannot hold (a control character: ``\\x00\\x01`` separates a name
            from its class), or the file would exceed FBX 7.4's 4 GiB.
        OutputPathError: ``path`` cannot be created (from :func:`~retarget_lib.files.atomic_write`).
    """
    sk = rig.skeleton
    if motion is not None and motion.skeleton.joint_names != sk.joint_names:
        raise FBXError(f"{path}: the motion's joints are not the rig {rig.name!r}'s joints")
    if not (np.isfinite(unit_scale_factor) and unit_scale_factor > 0):
        raise FBXError(
            f"{path}: unit_scale_factor {unit_scale_factor} must be a positive number of "
            "centimetres"
        )
    for name in sk.joint_names:
        if name_problem(name):
            raise FBXError(f"{path}: cannot write the joint name {name!r}: it {name_problem(name)}")
    to_file = 100.0 / float(unit_scale_factor)  # file units per metre
    if to_file != 1.0:
        rig = Rig(
            rig.name,
            sk.scaled(to_file),
            rig.rest_vertices * to_file,
            rig.faces,
            rig.weights,
            rig.joint_map,
        )
        if motion is not None:
            motion = motion.copy(
                skeleton=rig.skeleton, root_positions=motion.root_positions * to_file
            )
    fps = float(motion.fps) if motion is not None else 30.0
    scene = _Scene()
    joint_ids = _add_skeleton(scene, rig)
    _add_mesh(scene, rig, joint_ids)
    if motion is not None:
        _add_animation(scene, motion, joint_ids)
    frames = motion.num_frames if motion is not None else 1
    stop = round((frames - 1) * KTIME_PER_SECOND / fps)
    top = [
        _header(),
        _Node("FileId", _Typed("R", _FILE_ID)),
        _Node("CreationTime", _CREATION_TIME),
        _Node("Creator", "retarget-notebooks"),
        _global_settings(fps, stop, float(unit_scale_factor)),
        _documents(_take_name(motion) if motion is not None else ""),
        _Node("References"),
        _definitions(scene.counts),
        scene.objects,
        scene.connections,
        _takes(motion, stop),
    ]
    data = _file_bytes(top)
    with atomic_write(path) as f:
        f.write(data)


def _add_skeleton(scene: _Scene, rig: Rig) -> list[int]:
    """One LimbNode model (and node attribute) per joint, parented as the skeleton; their ids."""
    sk = rig.skeleton
    size = max(
        float(np.linalg.norm(sk.offsets[1:], axis=1).mean()) if sk.num_joints > 1 else 0.1, 1e-3
    )
    ids: list[int] = []
    for j, name in enumerate(sk.joint_names):
        attr_id, attr = scene.new("NodeAttribute", name, "NodeAttribute", "LimbNode")
        attr.children.append(_properties(("Size", "double", "Number", "", size * 100.0)))
        attr.add("TypeFlags", "Skeleton")
        model_id, model = scene.new("Model", name, "Model", "LimbNode")
        model.add("Version", _i32(232))
        model.children.append(
            _properties(
                _vec3("Lcl Translation", "Lcl Translation", sk.offsets[j]),
                _vec3("Lcl Rotation", "Lcl Rotation", (0.0, 0.0, 0.0)),
                _vec3("Lcl Scaling", "Lcl Scaling", (1.0, 1.0, 1.0)),
                ("InheritType", "enum", "", "", _i32(1)),
                ("DefaultAttributeIndex", "int", "Integer", "", _i32(0)),
            )
        )
        model.add("Shading", True)
        model.add("Culling", "CullingOff")
        scene.link(attr_id, model_id)
        parent = sk.parents[j]
        scene.link(model_id, ids[parent] if parent >= 0 else 0)
        ids.append(model_id)
    return ids


def _add_mesh(scene: _Scene, rig: Rig, joint_ids: list[int]) -> None:
    """The mesh model, its geometry, the skin with one cluster per joint, and the bind pose."""
    vertices, faces = rig.rest_vertices, rig.faces.astype(np.int64)
    geo_id, geo = scene.new("Geometry", rig.name, "Geometry", "Mesh")
    geo.add("GeometryVersion", _i32(124))
    geo.add("Vertices", vertices.astype(np.float64).ravel())
    polygon = faces.copy()
    polygon[:, 2] = -polygon[:, 2] - 1  # FBX closes each polygon with -(index + 1)
    geo.add("PolygonVertexIndex", polygon.astype(np.int32).ravel())
    normals = geo.add("LayerElementNormal", _i32(0))
    normals.add("Version", _i32(101))
    normals.add("Name", "")
    normals.add("MappingInformationType", "ByVertice")
    normals.add("ReferenceInformationType", "Direct")
    normals.add("Normals", vertex_normals(vertices, faces).ravel())
    layer = geo.add("Layer", _i32(0))
    layer.add("Version", _i32(100))
    element = layer.add("LayerElement")
    element.add("Type", "LayerElementNormal")
    element.add("TypedIndex", _i32(0))
    mesh_id, mesh = scene.new("Model", rig.name, "Model", "Mesh")
    mesh.add("Version", _i32(232))
    mesh.children.append(
        _properties(
            ("InheritType", "enum", "", "", _i32(1)),
            ("DefaultAttributeIndex", "int", "Integer", "", _i32(0)),
        )
    )
    mesh.add("Shading", True)
    mesh.add("Culling", "CullingOff")
    scene.link(mesh_id, 0)
    scene.link(geo_id, mesh_id)

    skin_id, skin = scene.new("Deformer", rig.name, "Deformer", "Skin")
    skin.add("Version", _i32(101))
    skin.add("Link_DeformAcuracy", 50.0)
    scene.link(skin_id, geo_id)
    rest = rig.skeleton.rest_positions()
    pose_id, pose = scene.new("Pose", rig.name, "Pose", "BindPose")
    pose.add("Type", "BindPose")
    pose.add("Version", _i32(100))
    pose.add("NbPoseNodes", _i32(len(joint_ids) + 1))
    entry = pose.add("PoseNode")
    entry.add("Node", mesh_id)
    entry.add("Matrix", _matrix(None, np.zeros(3)))
    for j, name in enumerate(rig.skeleton.joint_names):
        cluster_id, cluster = scene.new("Deformer", name, "SubDeformer", "Cluster")
        cluster.add("Version", _i32(100))
        cluster.add("UserData", "", "")
        which = np.flatnonzero(rig.weights[:, j] > 0)
        cluster.add("Indexes", which.astype(np.int32))
        cluster.add("Weights", rig.weights[which, j].astype(np.float64))
        cluster.add("Transform", _matrix(None, -rest[j]))
        cluster.add("TransformLink", _matrix(None, rest[j]))
        scene.link(cluster_id, skin_id)
        scene.link(joint_ids[j], cluster_id)
        entry = pose.add("PoseNode")
        entry.add("Node", joint_ids[j])
        entry.add("Matrix", _matrix(None, rest[j]))


def _take_name(motion: Motion) -> str:
    """The animation stack's (take's) name: the motion's, else ``motion``."""
    return motion.name or "motion"


def _add_animation(scene: _Scene, motion: Motion, joint_ids: list[int]) -> None:
    """One stack and layer; a rotation curve node per joint and the root's translation."""
    times = np.round(np.arange(motion.num_frames) * (KTIME_PER_SECOND / motion.fps)).astype(
        np.int64
    )
    stack_id, stack = scene.new("AnimationStack", _take_name(motion), "AnimStack", "")
    stack.children.append(
        _properties(
            *[
                (name, "KTime", "Time", "", int(t))
                for name, t in (
                    ("LocalStart", 0),
                    ("LocalStop", times[-1]),
                    ("ReferenceStart", 0),
                    ("ReferenceStop", times[-1]),
                )
            ]
        )
    )
    layer_id, _ = scene.new("AnimationLayer", "BaseLayer", "AnimLayer", "")
    scene.link(layer_id, stack_id)
    q = motion.rotations / np.linalg.norm(motion.rotations, axis=-1, keepdims=True)
    euler = _continuous_euler_xyz(q)
    channels = [(j, "R", "Lcl Rotation", euler[:, j]) for j in range(motion.skeleton.num_joints)]
    channels.insert(0, (0, "T", "Lcl Translation", motion.root_positions))
    for j, short, prop, values in channels:
        node_id, node = scene.new("AnimationCurveNode", short, "AnimCurveNode", "")
        node.children.append(
            _properties(
                *[
                    (f"d|{axis}", "Number", "", "A", float(values[0, k]))
                    for k, axis in enumerate("XYZ")
                ]
            )
        )
        scene.link(node_id, layer_id)
        scene.link(node_id, joint_ids[j], prop)
        for k, axis in enumerate("XYZ"):
            curve_id, curve = scene.new("AnimationCurve", "", "AnimCurve", "")
            curve.add("Default", float(values[0, k]))
            curve.add("KeyVer", _i32(4008))
            curve.add("KeyTime", times)
            curve.add("KeyValueFloat", values[:, k].astype(np.float32))
            curve.add("KeyAttrFlags", np.array([_LINEAR_KEY], dtype=np.int32))
            curve.add("KeyAttrDataFloat", np.zeros(4, dtype=np.float32))
            curve.add("KeyAttrRefCount", np.array([len(times)], dtype=np.int32))
            scene.link(curve_id, node_id, f"d|{axis}")


def _header() -> _Node:
    header = _Node("FBXHeaderExtension")
    header.add("FBXHeaderVersion", _i32(1003))
    header.add("FBXVersion", _i32(FBX_VERSION))
    header.add("EncryptionType", _i32(0))
    stamp = header.add("CreationTimeStamp")
    for key, value in (
        ("Version", 1000),
        ("Year", 1970),
        ("Month", 1),
        ("Day", 1),
        ("Hour", 10),
        ("Minute", 0),
        ("Second", 0),
        ("Millisecond", 0),
    ):
        stamp.add(key, _i32(value))
    header.add("Creator", "retarget-notebooks")
    return header


def _global_settings(fps: float, stop: int, unit_scale_factor: float) -> _Node:
    settings = _Node("GlobalSettings")
    settings.add("Version", _i32(1000))
    axes = [
        (name, "int", "Integer", "", _i32(v))
        for name, v in (
            ("UpAxis", 1),
            ("UpAxisSign", 1),
            ("FrontAxis", 2),
            ("FrontAxisSign", 1),
            ("CoordAxis", 0),
            ("CoordAxisSign", 1),
            ("OriginalUpAxis", 1),
            ("OriginalUpAxisSign", 1),
        )
    ]
    settings.children.append(
        _properties(
            *axes,
            ("UnitScaleFactor", "double", "Number", "", unit_scale_factor),
            ("OriginalUnitScaleFactor", "double", "Number", "", unit_scale_factor),
            ("TimeMode", "enum", "", "", _i32(fbx_time_mode(fps))),
            ("TimeSpanStart", "KTime", "Time", "", 0),
            ("TimeSpanStop", "KTime", "Time", "", int(stop)),
            ("CustomFrameRate", "double", "Number", "", float(fps)),
        )
    )
    return settings


def _documents(active_stack: str) -> _Node:
    docs = _Node("Documents")
    docs.add("Count", _i32(1))
    doc = docs.add("Document", 999_999, "Scene", "Scene")
    doc.children.append(
        _properties(
            ("SourceObject", "object", "", ""),
            ("ActiveAnimStackName", "KString", "", "", active_stack),
        )
    )
    doc.add("RootNode", 0)
    return docs


def _definitions(counts: dict[str, int]) -> _Node:
    defs = _Node("Definitions")
    defs.add("Version", _i32(100))
    defs.add("Count", _i32(sum(counts.values()) + 1))
    for kind, count in [("GlobalSettings", 1), *counts.items()]:
        defs.add("ObjectType", kind).add("Count", _i32(count))
    return defs


def _takes(motion: Motion | None, stop: int) -> _Node:
    takes = _Node("Takes")
    takes.add("Current", "")
    if motion is not None:
        take = takes.add("Take", _take_name(motion))
        take.add("FileName", f"{_take_name(motion)}.tak")
        take.add("LocalTime", 0, int(stop))
        take.add("ReferenceTime", 0, int(stop))
    return takes
