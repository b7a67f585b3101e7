"""The skinned character of a glTF document: the skinned mesh nodes, their inverse bind
matrices, the merged rest mesh and weights, VRM humanoid bones, and the :class:`Rig`
(:func:`load_gltf_rig`)."""

from __future__ import annotations

import os

import numpy as np

from ...core.rig import Rig
from ...core.skeleton import Skeleton
from ...core.virtual_joints import MAY_BE_ABSENT
from ..rig_maps import RIG_MAPS, joint_key, map_joints, read_mapping
from ..untrusted import (
    JsonObject,
    check_array_bytes,
    check_count,
)
from .document import (
    _INDICES,
    _INVERSE_BIND,
    _JOINTS,
    _POSITION,
    _SCALE_TOL,
    _TRIANGLES,
    _WEIGHTS,
    MAX_TRIANGLES,
    MAX_VERTICES,
    GLTFDocument,
    NoSkinError,
    _read,
)
from .transforms import (
    FLOOR_TOLERANCE_M,
    _framed,
    _joint_tree,
    _local_matrix,
    _rotation_part,
    _Skeleton,
    _upright,
    _with_ancestors,
    _world,
)

__all__ = ["load_gltf_rig", "rig_from"]


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


def _rigid_nodes(doc: GLTFDocument, tree: _Skeleton) -> dict[int, int]:
    """``{mesh node: joint tree index}``: the meshes without a skin that hang under a joint (eyes,
    teeth, a helmet parented to a bone in Blender or Maya), each moved rigidly by its nearest joint
    ancestor. Meshes under no joint (a floor, a bone's display shape) are not the character's."""
    g = doc.gltf
    index = {n: i for i, n in enumerate(tree.nodes)}
    out: dict[int, int] = {}
    for n, node in enumerate(g.nodes):
        if node.mesh is None or node.skin is not None or node.mesh >= len(g.meshes):
            continue
        k = tree.node_parent[n]
        while k >= 0 and k not in index:
            k = tree.node_parent[k]
        if k >= 0:
            out[n] = index[k]
    return out


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


def _primitive_binds(
    doc: GLTFDocument, joints: list[int], skin_binds: np.ndarray, primitive: int
) -> np.ndarray:
    """``(K, 4, 4)`` the inverse bind matrices that bind primitive number ``primitive`` (counted
    over every mesh): the skin's, except where the document carries the primitive's own
    (:attr:`GLTFDocument.primitive_inverse_binds`, by joint name; names that several joints share
    keep the skin's)."""
    listed = doc.primitive_inverse_binds
    own = listed[primitive] if listed is not None and primitive < len(listed) else None
    if own is None:
        return skin_binds
    names = [doc.gltf.nodes[j].name for j in joints]
    binds = np.array(skin_binds)
    for k, name in enumerate(names):
        if name in own and names.count(name) == 1:
            binds[k] = own[name]
    return binds


def _rigid_world(doc: GLTFDocument, tree: _Skeleton, node: int, world: dict[int, np.ndarray]):
    """``(4, 4)`` the rest world transform of a mesh node under a joint (its joint's world, then the
    local transforms down to it)."""
    chain, k = [], node
    while k not in world:
        chain.append(k)
        k = tree.node_parent[k]
    out = world[k]
    for c in reversed(chain):
        out = out @ _local_matrix(doc.gltf.nodes[c])
    return out


def _mesh(doc: GLTFDocument, skinned: list[int], tree: _Skeleton, world: dict[int, np.ndarray]):
    """Rest vertices ``(V, 3)`` (posed by the file's skinning), faces ``(F, 3)``, weights ``(V,
    J)``: the skinned meshes, then the meshes that hang rigidly under a joint
    (:func:`_rigid_nodes`, weight 1 on that joint)."""
    g = doc.gltf
    index = {n: i for i, n in enumerate(tree.nodes)}
    first_primitive = np.cumsum([0] + [len(m.primitives) for m in g.meshes])
    verts, faces, weights, base, triangles = [], [], [], 0, 0
    parts = [(n, None) for n in skinned] + list(_rigid_nodes(doc, tree).items())
    for n, joint in parts:
        if joint is None:
            skin = g.skins[g.nodes[n].skin]
            palette = np.array([index[j] for j in skin.joints])
            joint_worlds = np.stack([world[j] for j in skin.joints])  # (K, 4, 4)
            skin_binds = _inverse_binds(doc, g.nodes[n].skin)
        else:
            palette = np.array([joint])
            rigid = _rigid_world(doc, tree, n, world)[None]  # (1, 4, 4)
        for p, prim in enumerate(g.meshes[g.nodes[n].mesh].primitives):
            what = f"mesh {g.nodes[n].mesh} primitive {p}"
            if (prim.mode if prim.mode is not None else _TRIANGLES) != _TRIANGLES:
                raise doc.error(f"{what} is not a triangle list (mode {prim.mode})")
            attrs = prim.attributes
            if attrs.POSITION is None or (
                joint is None and (attrs.JOINTS_0 is None or attrs.WEIGHTS_0 is None)
            ):
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
            if joint is None:
                skin_mats = joint_worlds @ _primitive_binds(
                    doc, skin.joints, skin_binds, int(first_primitive[g.nodes[n].mesh]) + p
                )
                w = _weights(doc, attrs, len(pos), palette, len(tree.nodes), what)
            else:
                skin_mats = rigid
                w = np.zeros((len(pos), len(tree.nodes)))
                w[:, joint] = 1.0
            blended = np.einsum("vk,kij->vij", w[:, palette], skin_mats)
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


def _absent_unless_listed(listed: dict[str, str | None]) -> dict[str, str | None]:
    """A rig's own table of its joints (a VRM humanoid, a written joint map) with every canonical
    joint that may be absent (:data:`~retarget_lib.core.virtual_joints.MAY_BE_ABSENT`) and is not
    listed marked absent; an empty table stays empty (no table: the names are detected)."""
    if not listed:
        return {}
    absent: dict[str, str | None] = dict.fromkeys(MAY_BE_ABSENT)
    return absent | listed


def _vrm_mapping(doc: GLTFDocument, tree: _Skeleton) -> dict[str, str | None]:
    """``{canonical name: joint name}`` from a VRM 0.x (``VRM``) or 1.0 (``VRMC_vrm``) humanoid
    (types checked by :data:`_GLTF_JSON`); a canonical joint whose humanoid bone the file does not
    list (VRM's optional ``upperChest``, ``chest``, shoulders, toes) is absent (``None``: the reader
    inserts it, :mod:`~retarget_lib.core.virtual_joints`) when it may be."""
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
    listed: dict[str, str | None] = {
        canon[joint_key(b)]: name_of[n]
        for b, n in bones.items()
        if b and joint_key(b) in canon and n in name_of
    }
    return _absent_unless_listed(listed)


#: the key of the top-level ``extras`` under which :func:`~retarget_lib.io.gltf_write.save_glb`
#: writes the rig's joint map, ``{canonical name: joint name}`` for the canonical joints the rig
#: has, so that a result on a rig mapped by a joint map or a VRM humanoid reads back as written
JOINT_MAP_EXTRAS = "retarget_lib_canonical22"


def _written_mapping(doc: GLTFDocument) -> dict[str, str | None]:
    """The joint map a file written by the library carries (:data:`JOINT_MAP_EXTRAS`), a canonical
    joint it does not list absent when it may be (as in a VRM humanoid); entries of another type
    are ignored (the map is then the rig naming's, as for any file)."""
    extras = doc.gltf.extras
    table = extras.get(JOINT_MAP_EXTRAS) if isinstance(extras, dict) else None
    if not isinstance(table, dict):
        return {}
    listed: dict[str, str | None] = {
        k: v for k, v in table.items() if isinstance(k, str) and isinstance(v, str)
    }
    return _absent_unless_listed(listed)


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
    in_file = _vrm_mapping(doc, tree) or _written_mapping(doc)
    joint_map, rig_name = map_joints(
        tree.names,
        tree.parents,
        in_file | user,
        what=str(doc.path),
        mapping_source=source if user else "the VRM humanoid or the written joint map",
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
