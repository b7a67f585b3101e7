"""Reading skinned characters and their animations from glTF 2.0 files (``.glb`` / ``.gltf``).

The file is parsed with ``pygltflib`` (the JSON and the GLB container); accessors are decoded here
with NumPy, within bounds. glTF's conventions are the library's: metres, +Y up, the asset facing
+Z, quaternions stored ``(x, y, z, w)`` (converted to wxyz on read).

What is read (:func:`load_gltf_rig`):

* **Skeleton** = the union of the joints of every skin used by a mesh node, as one tree (the
  nearest joint ancestor of a joint is its parent; exactly one root). Rest pose = the nodes' own
  transforms (the file as it shows without animation), including any non-joint ancestors such as
  an ``Armature`` node with a 0.01 scale: rest joint positions are world positions. Joints
  themselves must not scale (scale 1 within 1e-3, else :class:`~retarget_lib.errors.GLTFError`).
* **Mesh** = every triangle primitive of every skinned mesh node, merged, posed into the rest pose
  by the file's own skinning (``world(joint) @ inverseBindMatrix``), so the rest vertices are
  what a viewer shows. Materials, UVs and morph targets are not read.
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

Bounds: file size 256 MiB, 1000 joints, 2,000,000 vertices, 1,000,000 frames; external buffers only
next to the ``.gltf`` file (no ``..``, no absolute paths, no URLs).
"""

from __future__ import annotations

import base64
import heapq
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pygltflib
import torch

from ..core.motion import Motion
from ..core.rig import Rig
from ..core.rotations import matrix_to_quat, quat_slerp, quat_to_matrix
from ..core.skeleton import Skeleton
from ..errors import GLTFError, LimitError
from ..files import readable_file
from .rig_maps import RIG_MAPS, joint_key, load_mapping_file, map_joints

__all__ = ["GLTFError", "NoSkinError", "MAX_FILE_BYTES", "MAX_JOINTS", "MAX_VERTICES", "MAX_FRAMES", "DEFAULT_FPS",
           "key_rate", "load_gltf_rig", "load_gltf_motion", "load_gltf_animation"]

MAX_FILE_BYTES = 256 * 2**20
MAX_JOINTS = 1000
MAX_VERTICES = 2_000_000
MAX_FRAMES = 1_000_000
#: frame rate of a sampled animation that does not say its own
DEFAULT_FPS = 30.0
_SCALE_TOL = 1e-3
_DTYPES = {5120: np.int8, 5121: np.uint8, 5122: np.int16, 5123: np.uint16, 5125: np.uint32, 5126: np.float32}
_WIDTH = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT4": 16}
_TRIANGLES = 4
#: the name part of the pivot helper nodes assimp adds when it converts an FBX
_ASSIMP_HELPER = "$AssimpFbx$"


class NoSkinError(GLTFError):
    """A file without a skinned mesh where a character (mesh and skin) is needed."""


@dataclass
class _Document:
    """A parsed file: the glTF object, its buffers and the file path (for messages)."""

    gltf: pygltflib.GLTF2
    buffers: list[bytes]
    path: Path

    def error(self, problem: str) -> GLTFError:
        return GLTFError(f"{self.path}: {problem}")

    def accessor(self, index: int) -> np.ndarray:
        """Accessor ``index`` as a ``(count, width)`` array (MAT4: ``(count, 4, 4)`` row-major);
        normalized integers become floats."""
        g = self.gltf
        if not 0 <= index < len(g.accessors):
            raise self.error(f"accessor {index} does not exist")
        acc = g.accessors[index]
        if acc.sparse is not None:
            raise self.error(f"accessor {index} is sparse; sparse accessors are not supported")
        if acc.componentType not in _DTYPES or acc.type not in _WIDTH:
            raise self.error(f"accessor {index} has component type {acc.componentType} / type {acc.type!r}")
        dtype, width = np.dtype(_DTYPES[acc.componentType]).newbyteorder("<"), _WIDTH[acc.type]
        if acc.bufferView is None:
            out = np.zeros((acc.count, width), dtype)
        else:
            if not 0 <= acc.bufferView < len(g.bufferViews):
                raise self.error(f"accessor {index} names buffer view {acc.bufferView}, which does not exist")
            view = g.bufferViews[acc.bufferView]
            if not 0 <= view.buffer < len(self.buffers):
                raise self.error(f"buffer view {acc.bufferView} names buffer {view.buffer}, which does not exist")
            buf = self.buffers[view.buffer]
            element = width * dtype.itemsize
            stride = view.byteStride or element
            start = (view.byteOffset or 0) + (acc.byteOffset or 0)
            end = start + stride * max(acc.count - 1, 0) + element * (acc.count > 0)
            if end > (view.byteOffset or 0) + view.byteLength or end > len(buf) or stride < element:
                raise self.error(f"accessor {index} reads past the end of its buffer (truncated file?)")
            out = np.ndarray((acc.count, width), dtype, buffer=buf, offset=start,
                             strides=(stride, dtype.itemsize)).copy()
        if acc.normalized and np.issubdtype(dtype, np.integer):
            out = np.maximum(out / np.iinfo(dtype).max, -1.0)
        if acc.type == "MAT4":
            out = out.reshape(-1, 4, 4).transpose(0, 2, 1)  # column-major in the file
        if np.issubdtype(out.dtype, np.floating) and not np.isfinite(out).all():
            raise self.error(f"accessor {index} holds NaN or inf")
        return out


def _read(path: str | os.PathLike) -> _Document:
    """Parse a ``.glb`` or ``.gltf`` file and load its buffers (:class:`GLTFError` if malformed)."""
    path = readable_file(path, "glTF/GLB file", MAX_FILE_BYTES)
    data = path.read_bytes()
    try:
        if data[:4] == b"glTF":
            if len(data) < 12 or int.from_bytes(data[8:12], "little") > len(data):
                raise GLTFError(f"{path}: truncated GLB file (its header declares more bytes than it has)")
            gltf = pygltflib.GLTF2.load_from_bytes(data)
            blob = gltf.binary_blob()
        else:
            gltf = pygltflib.GLTF2.from_json(data.decode("utf-8"))
            blob = None
    except GLTFError:
        raise
    except Exception as e:  # noqa: BLE001 (pygltflib raises anything from struct, json, dataclasses)
        raise GLTFError(f"{path}: not a readable glTF 2.0 / GLB file: {type(e).__name__}: "
                        f"{str(e).splitlines()[0] if str(e) else ''}") from None
    if gltf is None or not str(getattr(gltf.asset, "version", "")).startswith("2"):
        raise GLTFError(f"{path}: not a glTF 2.0 file (asset.version must be 2.x)")
    return _Document(gltf, [_buffer(b, i, blob, path) for i, b in enumerate(gltf.buffers)], path)


def _buffer(buffer: pygltflib.Buffer, index: int, blob: bytes | None, path: Path) -> bytes:
    """The bytes of one buffer: the GLB chunk, a ``data:`` URI, or a file next to ``path``."""
    uri = buffer.uri
    if uri is None:
        if blob is None:
            raise GLTFError(f"{path}: buffer {index} has no URI and the file has no binary chunk")
        data = blob
    elif uri.startswith("data:"):
        try:
            data = base64.b64decode(uri.split(",", 1)[1], validate=True)
        except (IndexError, ValueError):
            raise GLTFError(f"{path}: buffer {index} has a malformed data URI") from None
    else:
        rel = Path(uri)
        if rel.is_absolute() or ".." in rel.parts or ":" in uri:
            raise GLTFError(f"{path}: buffer {index} URI {uri!r} is not a file next to the glTF file")
        data = readable_file(path.parent / rel, "glTF buffer file", MAX_FILE_BYTES).read_bytes()
    if len(data) < buffer.byteLength:
        raise GLTFError(f"{path}: buffer {index} has {len(data)} bytes, fewer than its byteLength "
                        f"{buffer.byteLength} (truncated file?)")
    return data


def _local_matrix(node: pygltflib.Node) -> np.ndarray:
    """``(4, 4)`` a node's local transform (its ``matrix``, else T @ R @ S)."""
    if node.matrix is not None and len(node.matrix) == 16:
        return np.asarray(node.matrix, dtype=np.float64).reshape(4, 4).T
    return _trs(np.asarray(node.translation or (0, 0, 0), dtype=np.float64),
                np.asarray(node.rotation or (0, 0, 0, 1), dtype=np.float64),
                np.asarray(node.scale or (1, 1, 1), dtype=np.float64))


def _trs(t: np.ndarray, q_xyzw: np.ndarray, s: np.ndarray) -> np.ndarray:
    """``(..., 4, 4)`` from translations ``(..., 3)``, quaternions ``(..., 4)`` xyzw, scales ``(..., 3)``."""
    q = torch.from_numpy(np.ascontiguousarray(q_xyzw[..., [3, 0, 1, 2]]))
    q = q / q.norm(dim=-1, keepdim=True).clamp_min(1e-12)
    m = np.zeros(q.shape[:-1] + (4, 4))
    m[..., :3, :3] = quat_to_matrix(q).numpy() * s[..., None, :]
    m[..., :3, 3] = t
    m[..., 3, 3] = 1.0
    return m


def _parents_of_nodes(gltf: pygltflib.GLTF2, doc: _Document) -> list[int]:
    """``parent[n]`` of every node (``-1`` at a scene root); refuses cycles and shared children."""
    parent = [-1] * len(gltf.nodes)
    for n, node in enumerate(gltf.nodes):
        for c in node.children or []:
            if not 0 <= c < len(gltf.nodes) or parent[c] != -1 or c == n:
                raise doc.error(f"node {n} lists child {c}, which does not exist or has another parent")
            parent[c] = n
    for n in range(len(parent)):  # a cycle never reaches -1
        seen, k = set(), n
        while k >= 0:
            if k in seen:
                raise doc.error(f"the node hierarchy has a cycle through node {n}")
            seen.add(k)
            k = parent[k]
    return parent


def _world(node_parent: list[int], local: dict[int, np.ndarray], nodes: list[int]) -> dict[int, np.ndarray]:
    """World transforms ``(..., 4, 4)`` of ``nodes`` and their ancestors from per-node local ones."""
    out: dict[int, np.ndarray] = {}

    def world(n: int) -> np.ndarray:
        if n not in out:
            p = node_parent[n]
            out[n] = local[n] if p < 0 else world(p) @ local[n]
        return out[n]

    for n in nodes:
        world(n)
    return out


@dataclass
class _Skeleton:
    """The joint tree of a file: joint node indices (parents first), parents, names, node parents."""

    nodes: list[int]
    parents: list[int]
    names: list[str]
    node_parent: list[int]


def _joint_tree(doc: _Document, skinned: list[int]) -> _Skeleton:
    """The joint tree of the skins used by the ``skinned`` mesh nodes."""
    g = doc.gltf
    joint_set: set[int] = set()
    for n in skinned:
        skin = g.skins[g.nodes[n].skin]
        if not skin.joints or any(not 0 <= j < len(g.nodes) for j in skin.joints):
            raise doc.error(f"skin {g.nodes[n].skin} has no joints or names nodes that do not exist")
        joint_set.update(skin.joints)
    order = list(dict.fromkeys(j for n in skinned for j in g.skins[g.nodes[n].skin].joints))
    return _tree_of(doc, joint_set, order, "the skin's joints")


def _animated_tree(doc: _Document, animation: int) -> _Skeleton:
    """The joint tree of a file without a skin (an armature and its animation, e.g. a Mixamo clip
    downloaded "Without Skin"): every node an animation channel of ``animation`` moves, and every
    node below one, except mesh nodes and assimp's FBX pivot helpers (``..._$AssimpFbx$_...``),
    which stay non-joint ancestors (their transforms are still applied)."""
    g = doc.gltf
    if not 0 <= animation < len(g.animations):
        raise doc.error(f"has no skin and {len(g.animations)} animations; a motion file without a skin needs "
                        f"animation {animation} to find its joints")
    node_parent = _parents_of_nodes(g, doc)
    animated = {c.target.node for c in g.animations[animation].channels
                if c.target.node is not None and 0 <= c.target.node < len(g.nodes)}

    def is_joint(n: int) -> bool:
        if g.nodes[n].mesh is not None or _ASSIMP_HELPER in (g.nodes[n].name or ""):
            return False
        while n >= 0 and n not in animated:
            n = node_parent[n]
        return n >= 0

    joint_set = {n for n in range(len(g.nodes)) if is_joint(n)}
    if not joint_set:
        raise doc.error(f"has no skin and animation {animation} moves no node; it is not a character's motion")
    return _tree_of(doc, joint_set, sorted(joint_set), f"the joints animation {animation} moves")


def _tree_of(doc: _Document, joint_set: set[int], order_hint: list[int], what: str) -> _Skeleton:
    """``joint_set`` as one tree, parents first, otherwise in ``order_hint`` order; ``what`` names
    the joint set in messages."""
    g = doc.gltf
    if len(joint_set) > MAX_JOINTS:
        raise LimitError(f"{doc.path}: {len(joint_set)} joints exceed the limit of {MAX_JOINTS}")
    node_parent = _parents_of_nodes(g, doc)

    def joint_parent(j: int) -> int:
        a = node_parent[j]
        while a >= 0 and a not in joint_set:
            a = node_parent[a]
        return a

    roots = sorted(j for j in joint_set if joint_parent(j) < 0)
    if len(roots) != 1:
        names = [g.nodes[r].name or f"node{r}" for r in roots]
        raise doc.error(f"{what} form {len(roots)} trees (roots {names}); a character needs one skeleton")
    # parents first, otherwise in the hint's order (the skins' joint order: a file's own order survives a round trip)
    rank = {j: k for k, j in enumerate(order_hint)}
    kids: dict[int, list[int]] = {}
    for j in joint_set:
        kids.setdefault(joint_parent(j), []).append(j)
    order, heap = [], [(rank[roots[0]], roots[0])]
    while heap:
        n = heapq.heappop(heap)[1]
        order.append(n)
        for c in kids.get(n, []):
            heapq.heappush(heap, (rank[c], c))
    index = {n: i for i, n in enumerate(order)}
    parents = [index[joint_parent(n)] if joint_parent(n) >= 0 else -1 for n in order]
    names, seen = [], set()
    for n in order:
        name = g.nodes[n].name or f"joint{n}"
        names.append(name if name not in seen else f"{name}.{n}")
        seen.add(name)
    return _Skeleton(order, parents, names, node_parent)


def _rotation_part(m: np.ndarray, doc: _Document, what: str) -> np.ndarray:
    """``(..., 3, 3)`` the rotation of similarity transforms ``(..., 4, 4)`` (uniform scale removed)."""
    a = m[..., :3, :3]
    scale = np.cbrt(np.linalg.det(a))
    if np.any(np.abs(scale) < 1e-12):
        raise doc.error(f"{what} has a singular transform")
    r = a / scale[..., None, None]
    if np.abs(r @ np.swapaxes(r, -1, -2) - np.eye(3)).max() > _SCALE_TOL:
        raise doc.error(f"{what} has a non-uniform scale or shear, which a skeleton cannot represent")
    return r


def _skinned_nodes(doc: _Document) -> list[int]:
    g = doc.gltf
    nodes = [n for n, node in enumerate(g.nodes) if node.mesh is not None and node.skin is not None]
    if not nodes:
        raise NoSkinError(f"{doc.path}: no skin: the file has no mesh node with a skin, so it is not a rigged "
                          "character (export it with its armature / skinning)")
    for n in nodes:
        if not 0 <= g.nodes[n].mesh < len(g.meshes) or not 0 <= g.nodes[n].skin < len(g.skins):
            raise doc.error(f"node {n} names a mesh or skin that does not exist")
    return nodes


def _mesh(doc: _Document, skinned: list[int], tree: _Skeleton, world: dict[int, np.ndarray]):
    """Rest vertices ``(V, 3)`` (posed by the file's skinning), faces ``(F, 3)``, weights ``(V, J)``."""
    g = doc.gltf
    index = {n: i for i, n in enumerate(tree.nodes)}
    verts, faces, weights, base = [], [], [], 0
    for n in skinned:
        skin = g.skins[g.nodes[n].skin]
        palette = np.array([index[j] for j in skin.joints])
        ibm = (doc.accessor(skin.inverseBindMatrices) if skin.inverseBindMatrices is not None
               else np.broadcast_to(np.eye(4), (len(skin.joints), 4, 4)))
        if len(ibm) != len(skin.joints):
            raise doc.error(f"skin {g.nodes[n].skin}: {len(ibm)} inverse bind matrices for {len(skin.joints)} joints")
        skin_mats = np.stack([world[j] for j in skin.joints]) @ ibm  # (K, 4, 4)
        for p, prim in enumerate(g.meshes[g.nodes[n].mesh].primitives):
            what = f"mesh {g.nodes[n].mesh} primitive {p}"
            if (prim.mode if prim.mode is not None else _TRIANGLES) != _TRIANGLES:
                raise doc.error(f"{what} is not a triangle list (mode {prim.mode})")
            attrs = prim.attributes
            if attrs.POSITION is None or attrs.JOINTS_0 is None or attrs.WEIGHTS_0 is None:
                raise doc.error(f"{what} lacks POSITION, JOINTS_0 or WEIGHTS_0 (a skinned mesh needs all three)")
            pos = doc.accessor(attrs.POSITION).astype(np.float64)
            if base + len(pos) > MAX_VERTICES:
                raise LimitError(f"{doc.path}: more than {MAX_VERTICES} vertices")
            w = np.zeros((len(pos), len(tree.nodes)))
            k = 0
            while getattr(attrs, f"JOINTS_{k}", None) is not None:
                jk = doc.accessor(getattr(attrs, f"JOINTS_{k}")).astype(np.int64)
                wk = doc.accessor(getattr(attrs, f"WEIGHTS_{k}")).astype(np.float64)
                if jk.shape != (len(pos), 4) or wk.shape != (len(pos), 4):
                    raise doc.error(f"{what}: JOINTS_{k} / WEIGHTS_{k} must be VEC4 per vertex")
                if jk.min() < 0 or jk.max() >= len(palette) or wk.min() < 0:
                    raise doc.error(f"{what}: JOINTS_{k} indexes outside the skin's {len(palette)} joints "
                                    "or WEIGHTS_{k} is negative")
                np.add.at(w, (np.repeat(np.arange(len(pos)), 4), palette[jk].ravel()), wk.ravel())
                k += 1
            sums = w.sum(axis=1)
            if (sums <= 0).any():
                raise doc.error(f"{what}: {int((sums <= 0).sum())} vertices have all skinning weights zero")
            w /= sums[:, None]
            local_w = w[:, palette]  # (V, K)
            blended = np.einsum("vk,kij->vij", local_w, skin_mats)
            verts.append(np.einsum("vij,vj->vi", blended[:, :3, :3], pos) + blended[:, :3, 3])
            idx = (doc.accessor(prim.indices).astype(np.int64).ravel() if prim.indices is not None
                   else np.arange(len(pos)))
            if len(idx) % 3 or (idx.size and (idx.min() < 0 or idx.max() >= len(pos))):
                raise doc.error(f"{what}: triangle indices are not triples of vertices 0..{len(pos) - 1}")
            faces.append(idx.reshape(-1, 3) + base)
            weights.append(w)
            base += len(pos)
    return np.concatenate(verts), np.concatenate(faces), np.concatenate(weights)


def _vrm_mapping(doc: _Document, tree: _Skeleton) -> dict[str, str]:
    """``{canonical name: joint name}`` from a VRM 0.x (``VRM``) or 1.0 (``VRMC_vrm``) humanoid."""
    ext = doc.gltf.extensions or {}
    if "VRMC_vrm" in ext:
        bones = {b: v.get("node") for b, v in ext["VRMC_vrm"].get("humanoid", {}).get("humanBones", {}).items()}
    elif "VRM" in ext:
        bones = {b.get("bone"): b.get("node") for b in ext["VRM"].get("humanoid", {}).get("humanBones", [])}
    else:
        return {}
    canon = {joint_key(k): v for k, v in RIG_MAPS["vrm"].items()}
    name_of = dict(zip(tree.nodes, tree.names))
    return {canon[joint_key(b)]: name_of[n] for b, n in bones.items()
            if b and joint_key(b) in canon and n in name_of}


def _armature(doc: _Document, tree: _Skeleton, mapping) -> tuple[Skeleton, dict[int, int], str, np.ndarray, dict]:
    """The rest skeleton of ``tree``, its map onto the canonical 22 (and the rig naming that
    matched), the ``(J, 3, 3)`` rest world rotations of the joints and the rest world transforms."""
    g = doc.gltf
    local = {n: _local_matrix(node) for n, node in enumerate(g.nodes)}
    world = _world(tree.node_parent, local, tree.nodes)
    for n in tree.nodes[1:]:
        _rotation_part(local[n], doc, f"joint {g.nodes[n].name or n}")
        if abs(np.cbrt(np.linalg.det(local[n][:3, :3])) - 1.0) > _SCALE_TOL:
            raise doc.error(f"joint {g.nodes[n].name or n} is scaled; joints below the root must have scale 1")
    rest_rot = np.stack([_rotation_part(world[n], doc, f"joint {g.nodes[n].name or n}") for n in tree.nodes])
    rest = np.stack([world[n][:3, 3] for n in tree.nodes])
    offsets = rest.copy()
    offsets[1:] -= rest[tree.parents[1:]]
    skeleton = Skeleton(tree.names, tree.parents, offsets)
    user = load_mapping_file(mapping) if isinstance(mapping, (str, os.PathLike)) else dict(mapping or {})
    joint_map, rig_name = map_joints(tree.names, tree.parents, _vrm_mapping(doc, tree) | user, what=str(doc.path))
    return skeleton, joint_map, rig_name, rest_rot, world


def _load(path, mapping) -> tuple[_Document, _Skeleton, Rig, np.ndarray]:
    """Everything :func:`load_gltf_rig` and :func:`load_gltf_motion` share; the last item is the
    ``(J, 3, 3)`` rest world rotations of the joints."""
    doc = _read(path)
    skinned = _skinned_nodes(doc)
    tree = _joint_tree(doc, skinned)
    skeleton, joint_map, rig_name, rest_rot, world = _armature(doc, tree, mapping)
    vertices, faces, weights = _mesh(doc, skinned, tree, world)
    rig = Rig(doc.path.stem, skeleton, vertices, faces, weights, joint_map,
              meta=dict(source=str(doc.path), rig=rig_name))
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
        GLTFError: a malformed or truncated file, several skeleton roots, scaled joints,
            unsupported accessors. JointSetError: joints that cannot be mapped (named).
        LimitError: beyond :data:`MAX_JOINTS` / :data:`MAX_VERTICES`. InputFileError: missing,
            empty or larger than :data:`MAX_FILE_BYTES`.
    """
    return _load(path, mapping)[2]


def load_gltf_motion(path: str | os.PathLike, fps: float | None = None, animation: int = 0,
                     mapping: str | os.PathLike | dict | None = None) -> tuple[Motion, Rig]:
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
            :func:`load_gltf_rig` raises.
    """
    doc, tree, rig, rest_rot = _load(path, mapping)
    motion = _sample_motion(doc, tree, rig.skeleton, rest_rot, fps, animation)
    return motion, rig


def load_gltf_animation(path: str | os.PathLike, fps: float | None = None, animation: int = 0,
                        mapping: str | os.PathLike | dict | None = None) -> tuple[Motion, dict[int, int]]:
    """Sample an animation of a glTF/GLB file **with or without a skin** (e.g. a Mixamo clip
    downloaded "Without Skin" and converted): the joints are the skin's when the file has a skinned
    mesh, else every node the animation moves and the nodes below them (see the module docstring
    for the rest pose and sampling; no mesh is read).

    Args:
        path: ``.glb`` or ``.gltf`` with an animation.
        fps, animation, mapping: as in :func:`load_gltf_motion`.

    Returns:
        ``(motion on the file's joints, joint_map)``: ``joint_map`` is ``{file joint index:
        canonical index}``, so ``to_canonical22(motion, joint_map=joint_map)`` folds it.

    Raises:
        GLTFError: no animation, an animation that moves no node, several skeleton roots,
            malformed samplers. JointSetError: joints that cannot be mapped (named).
    """
    doc = _read(path)
    g = doc.gltf
    skinned = [n for n, node in enumerate(g.nodes) if node.mesh is not None and node.skin is not None]
    tree = _joint_tree(doc, _skinned_nodes(doc)) if skinned else _animated_tree(doc, animation)
    skeleton, joint_map, _, rest_rot, _ = _armature(doc, tree, mapping)
    return _sample_motion(doc, tree, skeleton, rest_rot, fps, animation), joint_map


def _sample_motion(doc: _Document, tree: _Skeleton, skeleton: Skeleton, rest_rot: np.ndarray, fps: float | None,
                   animation: int) -> Motion:
    """Animation ``animation`` of ``doc`` sampled as a motion on ``skeleton`` (the joints of ``tree``)."""
    g = doc.gltf
    if not 0 <= animation < len(g.animations):
        raise doc.error(f"has {len(g.animations)} animations; animation {animation} does not exist")
    anim = g.animations[animation]
    channels = []
    for c in anim.channels:
        if c.target.node is None or c.target.path not in ("rotation", "translation", "scale") \
                or not 0 <= c.sampler < len(anim.samplers):
            continue
        s = anim.samplers[c.sampler]
        times = doc.accessor(s.input).ravel().astype(np.float64)
        values = doc.accessor(s.output).astype(np.float64)
        if s.interpolation == "CUBICSPLINE":
            values = values[1::3]
        if len(times) == 0 or len(values) != len(times) or np.any(np.diff(times) <= 0):
            raise doc.error(f"animation {animation} sampler {c.sampler}: keyframe times must increase and match "
                            "the values")
        channels.append((c.target.node, c.target.path, times, values, s.interpolation or "LINEAR"))
    if not channels:
        raise doc.error(f"animation {animation} has no rotation or translation channels")
    rate = float(fps or (anim.extras or {}).get("fps") or key_rate([ch[2] for ch in channels]) or DEFAULT_FPS)
    if not (np.isfinite(rate) and 1.0 <= rate <= 1000.0):
        raise doc.error(f"frame rate {rate} is outside 1-1000")
    start, end = min(ch[2][0] for ch in channels), max(ch[2][-1] for ch in channels)
    count = int(np.floor((end - start) * rate + 0.01)) + 1  # float32 key times: within 1 % of a frame
    if count > MAX_FRAMES:
        raise LimitError(f"{doc.path}: {count} frames at {rate:g} fps exceed the limit of {MAX_FRAMES}")
    t = start + np.arange(count) / rate
    nodes = set(tree.nodes) | {a for n in tree.nodes for a in _ancestors(n, tree.node_parent)}
    trs = {n: [np.broadcast_to(np.asarray(v, dtype=np.float64), (count, len(v))).copy() for v in
               (g.nodes[n].translation or (0, 0, 0), g.nodes[n].rotation or (0, 0, 0, 1), g.nodes[n].scale or (1, 1, 1))]
           for n in nodes}
    which = {"translation": 0, "rotation": 1, "scale": 2}
    for node, kind, times, values, interp in channels:
        if node in trs and (kind == "rotation" or node not in tree.nodes[1:]):
            trs[node][which[kind]] = _sample(times, values, t, interp, kind == "rotation")
    local = {n: (_trs(*trs[n]) if g.nodes[n].matrix is None else np.broadcast_to(_local_matrix(g.nodes[n]), (count, 4, 4)))
             for n in nodes}
    world = _world(tree.node_parent, local, tree.nodes)
    glob = np.stack([_rotation_part(world[n], doc, f"joint {g.nodes[n].name or n}") for n in tree.nodes], axis=1)
    q_glob = glob @ np.swapaxes(rest_rot, -1, -2)[None]  # rest pose -> identity
    par = np.array(tree.parents[1:])
    q_local = q_glob.copy()
    q_local[:, 1:] = np.swapaxes(q_glob[:, par], -1, -2) @ q_glob[:, 1:]
    rotations = matrix_to_quat(torch.from_numpy(q_local)).numpy()
    root = world[tree.nodes[0]][:, :3, 3]
    return Motion(skeleton.copy(), rotations, root, rate, name=anim.name or doc.path.stem,
                  meta=dict(source=str(doc.path), animation=animation))


def key_rate(key_times: list[np.ndarray], tol: float = 0.01) -> float | None:
    """The frame rate of baked keyframes (an FBX/GLB exported with a key on every frame, as Mixamo's).

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


def _ancestors(n: int, node_parent: list[int]) -> list[int]:
    out = []
    while node_parent[n] >= 0:
        n = node_parent[n]
        out.append(n)
    return out


def _sample(times: np.ndarray, values: np.ndarray, t: np.ndarray, interp: str, rotation: bool) -> np.ndarray:
    """Sample keyframes ``(K,)`` / ``(K, C)`` at times ``(T,)``: STEP, else linear (slerp for
    quaternions ``(K, 4)`` xyzw); held constant outside the keyed range."""
    i1 = np.clip(np.searchsorted(times, t, side="right"), 1, len(times) - 1) if len(times) > 1 else np.zeros(len(t), int)
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
