"""Animations of a glTF document sampled into a :class:`Motion`: channels, keys and
interpolation, the frame rate, and the skeleton-only clips (:func:`load_gltf_motion`,
:func:`load_gltf_animation`)."""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np
import torch

from ...core.motion import Motion
from ...core.rig import Rig
from ...core.rotations import matrix_to_quat, quat_slerp
from ...core.skeleton import Skeleton
from ..untrusted import (
    JsonObject,
    check_count,
    check_motion_samples,
)
from .document import (
    _ASSIMP_HELPER,
    _BLOCK_SAMPLES,
    _KEY_TIMES,
    _KEY_VALUES,
    DEFAULT_FPS,
    MAX_FRAMES,
    GLTFDocument,
    _read,
)
from .skin import _armature, _load, _skinned_nodes
from .transforms import (
    _animated_tree,
    _framed,
    _joint_tree,
    _local_matrix,
    _rotation_part,
    _Skeleton,
    _trs,
    _with_ancestors,
    _world,
)

__all__ = ["key_rate", "load_gltf_motion", "load_gltf_animation", "motion_from", "animation_from"]


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
    rest_of = _fold_assimp_pivots(doc, tree.node_parent, moving, static)
    rotations, root = np.empty((count, len(tree.nodes), 4)), np.empty((count, 3))
    block = max(1, _BLOCK_SAMPLES // (len(tree.nodes) + len(moving)))
    for lo in range(0, count, block):
        t = start + np.arange(lo, min(count, lo + block)) / rate
        local = dict(static)
        local.update(
            {
                n: _animated_local(
                    g.nodes[n], [ch for ch in used if ch.node == n], t, rest_of.get(n)
                )
                for n in moving
            }
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


def _fold_assimp_pivots(
    doc: GLTFDocument, node_parent: list[int], moving: set[int], static: dict[int, np.ndarray]
) -> dict[int, tuple]:
    """Fold the pivot helpers assimp inserts above an animated FBX node into its channels.

    assimp converts an FBX node with a pre-rotation (every Mixamo joint but the hips) into a chain
    ``X_$AssimpFbx$_Translation -> X_$AssimpFbx$_PreRotation -> ... -> X`` whose static
    transforms make the rest pose, but it bakes that whole chain into the animation keys of ``X``
    (translation and pre-rotation included), so applying both turns the joint twice (issue 28: a
    Mixamo clip's legs folded up, the body 0.8 m tall in every frame). For every animated node
    whose helpers no channel moves, the helpers become the identity in ``static`` (edited in
    place) and the node's rest ``(translation, rotation xyzw, scale)`` is the whole chain's, for
    the properties it has no channel for. Returns ``{node: that rest}``."""
    g = doc.gltf
    out: dict[int, tuple] = {}
    for n in moving:
        helpers, k = [], node_parent[n]
        prefix = f"{g.nodes[n].name or ''}_{_ASSIMP_HELPER}_"
        while k >= 0 and k not in moving and (g.nodes[k].name or "").startswith(prefix):
            helpers.append(k)
            k = node_parent[k]
        if not helpers or not g.nodes[n].name or any(h not in static for h in helpers):
            continue
        chain = _local_matrix(g.nodes[n])
        for h in helpers:
            chain = static[h] @ chain
            static[h] = np.eye(4)
        scale = np.linalg.norm(chain[:3, :3], axis=0)
        q = matrix_to_quat(torch.from_numpy(chain[:3, :3] / scale)).numpy()
        out[n] = (chain[:3, 3], q[[1, 2, 3, 0]], scale)
    return out


def _animated_local(
    node: JsonObject, channels: list[_Channel], t: np.ndarray, rest: tuple | None = None
) -> np.ndarray:
    """``(T, 4, 4)`` the local transforms of an animated node at times ``t`` (``rest``: the
    ``(translation, rotation xyzw, scale)`` of properties without a channel, else the node's
    own)."""
    trs = [
        np.broadcast_to(np.asarray(v, dtype=np.float64), (len(t), len(v)))
        for v in rest
        or (
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
