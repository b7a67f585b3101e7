"""Node transforms and joint trees of a glTF document: local and world matrices, the
rest pose stood upright (+Y up, facing +Z, on ``y = 0``), the joint tree of the skins or of an
animation, and a prop's armature hung under the skeleton."""

from __future__ import annotations

import heapq
from dataclasses import dataclass

import numpy as np
import torch

from ...core.canonical import upright_rotation
from ...core.rotations import quat_to_matrix
from ...core.skeleton import J
from ..untrusted import (
    JsonObject,
    check_count,
)
from .document import _ASSIMP_HELPER, _SCALE_TOL, MAX_JOINTS, GLTFDocument


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
