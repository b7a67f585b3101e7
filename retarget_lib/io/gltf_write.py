"""Writing a skinned, animated character as a binary glTF 2.0 file (``.glb``).

The file holds one scene: the rig's joints as a node tree, one skinned mesh and (optionally) one
animation. It is written in the library's rest convention, which glTF allows directly: every joint
node has identity rest rotation and its world-axis rest offset as translation, the inverse bind
matrices are ``translate(-rest position)``, and the animation keys every joint's local rotation
(wxyz converted to glTF's xyzw) and the root's translation at ``1 / fps`` steps; the frame rate is
also stored in the animation's ``extras`` (``{"fps": ...}``) so
:func:`~retarget_lib.io.gltf.load_gltf_motion` reads the same frames back, and the rig's joint map
in the file's ``extras`` (``{"retarget_lib_canonical22": {canonical name: joint name}}``, the
canonical joints the rig has) when its names alone would not map it (a rig mapped by a joint map
or a VRM humanoid), so that the result reads back mapped. Skinning weights are
written as ``JOINTS_n`` / ``WEIGHTS_n`` sets of four (as many sets as the widest vertex needs),
renormalised in float32. Positions, rotations and weights are float32 (round trips agree to float32
precision); materials are not written.

Every file passes the Khronos glTF validator with 0 errors (``tests/test_gltf.py``).
"""

from __future__ import annotations

import os

import numpy as np
import pygltflib

from ..core.motion import Motion
from ..core.rig import Rig
from ..core.skeleton import CANONICAL22, JointSetError
from ..core.virtual_joints import MAY_BE_ABSENT
from ..errors import RetargetInputError
from ..files import atomic_write
from .gltf.skin import JOINT_MAP_EXTRAS
from .rig_maps import map_joints

__all__ = ["save_glb"]

_ARRAY_BUFFER, _ELEMENT_ARRAY_BUFFER = 34962, 34963
_FLOAT, _USHORT, _UINT = 5126, 5123, 5125
_TYPES = {1: "SCALAR", 3: "VEC3", 4: "VEC4", 16: "MAT4"}


class _Builder:
    """Accumulates accessors and buffer views in one binary chunk (4-byte aligned)."""

    def __init__(self) -> None:
        self.gltf = pygltflib.GLTF2(
            asset=pygltflib.Asset(version="2.0", generator="retarget-notebooks")
        )
        self.blob = bytearray()

    def add(
        self, array: np.ndarray, component: int, target: int | None = None, bounds: bool = False
    ) -> int:
        """Append ``array`` ``(count, width)`` as one accessor; return its index."""
        array = np.ascontiguousarray(array)
        count, width = array.shape[0], int(np.prod(array.shape[1:], dtype=int))
        self.blob.extend(b"\0" * (-len(self.blob) % 4))
        view = pygltflib.BufferView(
            buffer=0, byteOffset=len(self.blob), byteLength=array.nbytes, target=target
        )
        self.blob.extend(array.astype(array.dtype.newbyteorder("<")).tobytes())
        self.gltf.bufferViews.append(view)
        flat = array.reshape(count, width)
        acc = pygltflib.Accessor(
            bufferView=len(self.gltf.bufferViews) - 1,
            componentType=component,
            count=count,
            type=_TYPES[width],
            min=flat.min(0).tolist() if bounds else None,
            max=flat.max(0).tolist() if bounds else None,
        )
        self.gltf.accessors.append(acc)
        return len(self.gltf.accessors) - 1

    def to_bytes(self) -> bytes:
        self.blob.extend(b"\0" * (-len(self.blob) % 4))
        self.gltf.buffers.append(pygltflib.Buffer(byteLength=len(self.blob)))
        self.gltf.set_binary_blob(bytes(self.blob))
        return b"".join(self.gltf.save_to_bytes())


def _weight_sets(weights: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
    """``(JOINTS (V, 4) uint16, WEIGHTS (V, 4) float32)`` sets covering every non-zero weight,
    strongest first; unused slots are joint 0 with weight 0; float32 rows sum to 1."""
    order = np.argsort(-weights, axis=1, kind="stable")
    width = max(1, int((weights > 0).sum(axis=1).max()))
    width = 4 * -(-width // 4)
    idx = order[:, :width]
    w = np.take_along_axis(weights, idx, 1).astype(np.float32)
    w /= w.sum(axis=1, keepdims=True, dtype=np.float32)
    idx = np.where(w > 0, idx, 0).astype(np.uint16)
    return [(idx[:, k : k + 4], w[:, k : k + 4]) for k in range(0, width, 4)]


def _joint_map_to_write(rig: Rig) -> dict[str, str] | None:
    """``{canonical name: joint name}`` for the canonical joints ``rig`` has, when its joint names
    alone would not map the same way on reading (a rig mapped by a joint map or a VRM humanoid),
    else None (nothing written)."""
    sk = rig.skeleton
    try:
        detected, _ = map_joints(sk.joint_names, sk.parents, may_be_absent=MAY_BE_ABSENT)
    except JointSetError:
        detected = None
    if detected == rig.joint_map:
        return None
    canonical = {c: i for i, c in rig.joint_map.items()}
    return {
        name: sk.joint_names[canonical[c]] for c, name in enumerate(CANONICAL22) if c in canonical
    }


def save_glb(
    rig: Rig, path: str | os.PathLike, motion: Motion | None = None, skin: bool = True
) -> None:
    """Write ``rig`` (mesh, skin, all its joints) and optionally ``motion`` as a ``.glb``
    (atomically).

    Args:
        rig: the character; ``Rig.from_character`` makes one from a canonical-22 character.
        path: destination ``.glb``.
        motion: a motion on ``rig.skeleton`` (same joint names), e.g.
            ``rig.motion_from_canonical(result)``; ``None`` writes the character in its rest pose.
        skin: ``False`` writes the joints and the motion only, no mesh or skin (like a Mixamo clip
            downloaded "Without Skin"; :func:`~retarget_lib.io.gltf.load_gltf_animation` reads it).

    Raises:
        RetargetInputError: ``motion`` is on another joint set or has more than 65536 joints, or
            ``skin=False`` without a motion.
    """
    if not skin and motion is None:
        raise RetargetInputError(
            f"{path}: a file without a skin needs a motion (it would hold only joints)"
        )
    sk = rig.skeleton
    if motion is not None and motion.skeleton.joint_names != sk.joint_names:
        raise RetargetInputError(
            f"{path}: the motion's joints are not the rig {rig.name!r}'s joints"
        )
    if sk.num_joints > 65536:
        raise RetargetInputError(
            f"{path}: {sk.num_joints} joints do not fit glTF's 16-bit joint indices"
        )
    b = _Builder()
    g = b.gltf
    written_map = _joint_map_to_write(rig)
    if written_map is not None:
        g.extras = {JOINT_MAP_EXTRAS: written_map}
    rest = sk.rest_positions()
    for j, name in enumerate(sk.joint_names):
        g.nodes.append(
            pygltflib.Node(
                name=name,
                translation=sk.offsets[j].astype(np.float32).tolist(),
                children=sk.children(j) or None,
            )
        )
    if not skin:
        assert motion is not None  # refused above
        g.scenes.append(pygltflib.Scene(nodes=[0]))
        g.scene = 0
        _add_animation(b, motion)
        with atomic_write(path) as f:
            f.write(b.to_bytes())
        return
    attributes = pygltflib.Attributes(
        POSITION=b.add(rig.rest_vertices.astype(np.float32), _FLOAT, _ARRAY_BUFFER, True)
    )
    for k, (joints, weights) in enumerate(_weight_sets(rig.weights)):
        setattr(attributes, f"JOINTS_{k}", b.add(joints, _USHORT, _ARRAY_BUFFER))
        setattr(attributes, f"WEIGHTS_{k}", b.add(weights, _FLOAT, _ARRAY_BUFFER))
    faces = b.add(rig.faces.astype(np.uint32).reshape(-1, 1), _UINT, _ELEMENT_ARRAY_BUFFER)
    g.meshes.append(
        pygltflib.Mesh(
            name=rig.name, primitives=[pygltflib.Primitive(attributes=attributes, indices=faces)]
        )
    )
    ibm = np.tile(np.eye(4, dtype=np.float32), (sk.num_joints, 1, 1))
    ibm[:, :3, 3] = -rest
    g.skins.append(
        pygltflib.Skin(
            joints=list(range(sk.num_joints)),
            skeleton=0,
            inverseBindMatrices=b.add(ibm.transpose(0, 2, 1).copy(), _FLOAT),
        )
    )
    g.nodes.append(pygltflib.Node(name=rig.name, mesh=0, skin=0))
    g.scenes.append(pygltflib.Scene(nodes=[0, sk.num_joints]))
    g.scene = 0
    if motion is not None:
        _add_animation(b, motion)
    with atomic_write(path) as f:
        f.write(b.to_bytes())


def _add_animation(b: _Builder, motion: Motion) -> None:
    """One animation: every joint's local rotation and the root's translation, keyed per frame."""
    times = b.add(
        (np.arange(motion.num_frames) / motion.fps).astype(np.float32).reshape(-1, 1),
        _FLOAT,
        bounds=True,
    )
    q = motion.rotations / np.linalg.norm(motion.rotations, axis=-1, keepdims=True)
    q = q[..., [1, 2, 3, 0]].astype(np.float32)
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    samplers = [
        pygltflib.AnimationSampler(
            input=times,
            output=b.add(motion.root_positions.astype(np.float32), _FLOAT),
            interpolation="LINEAR",
        )
    ]
    channels = [
        pygltflib.AnimationChannel(
            sampler=0, target=pygltflib.AnimationChannelTarget(node=0, path="translation")
        )
    ]
    for j in range(motion.skeleton.num_joints):
        samplers.append(
            pygltflib.AnimationSampler(
                input=times, output=b.add(q[:, j], _FLOAT), interpolation="LINEAR"
            )
        )
        channels.append(
            pygltflib.AnimationChannel(
                sampler=len(samplers) - 1,
                target=pygltflib.AnimationChannelTarget(node=j, path="rotation"),
            )
        )
    b.gltf.animations.append(
        pygltflib.Animation(
            name=motion.name or "motion",
            samplers=samplers,
            channels=channels,
            extras={"fps": motion.fps},
        )
    )
