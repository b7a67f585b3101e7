"""Retarget a file to a target skeleton or character with a method of the registry (the
``retarget retarget`` command).

Sources and targets are read by suffix (:mod:`.inputs`: BVH, SMPL-X/AMASS ``.npz``, glTF/GLB, FBX
through the optional extra; a target may also be a shape ``.npz`` or a character name). The
methods run on the canonical 22 joints at :data:`METHOD_FPS` (:func:`method_times`: the source's
last frame included); the result is brought back to the source's frame rate with the source's frame
count, or to ``fps`` with the count the duration implies (:func:`at_output_rate`), put on the ground
there by one rule for every method (:func:`on_the_ground`: where the source's feet stand on its
floor, the target's stand on ``y = 0``), and written by the output's suffix:

* ``.bvh``: on a BVH target's *full* joint set, names, channel layout and length unit
  (:func:`~retarget_lib.core.canonical.unfold_from_canonical22`), so it loads next to the target's
  own clips; on a GLB/FBX target's own joints; a target given by name in the source file's unit;
* ``.glb``: the target's mesh, skin and all its joints (fingers and extra joints follow their
  parents) performing the result: a skinned, animated glTF 2.0 file
  (:func:`~retarget_lib.io.gltf_write.save_glb`); needs a target with a mesh (a GLB/FBX/shape file,
  a character name, or ``--target-mesh``);
* ``.fbx``: the same skinned, animated character as a binary FBX 7.4 file
  (:func:`~retarget_lib.io.fbx_write.save_fbx`, pure Python: writing needs no optional extra),
  keyed at the output frame rate.

``--method contact`` uses the target file's own mesh (a GLB/FBX/shape file or a name) unless
``--target-mesh`` is given, and a GLB/FBX source's mesh as the source character.

Everything the user gives is checked before any work: the output path
(:func:`~retarget_lib.files.check_output`: a supported suffix, never an input unless ``force``),
options the method would ignore (a mesh for a skeleton-only method), a target mesh whose skeleton
differs from the target file's by more than :data:`MESH_LIMIT` of its height (rebound, with a
warning, beyond :data:`MESH_WARN`), target joint names the output format cannot hold
(:func:`~retarget_lib.io.untrusted.name_problem`). The run is one
:func:`~retarget_lib.files.input_ledger`: every file it reads (the inputs, a ``.gltf``'s buffers,
joint maps, meshes, checkpoints) is recorded by inode and no output replaces one. An error while
reading an input names that input. A result that is non-finite or implausibly far away (a corrupt
checkpoint) is refused, not written, and so is one whose body lies, stands on its head or sinks
under the floor where the source stands (:func:`check_posture`: what a wrong joint map, up axis
or rest convention gives).
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from ..core.canonical import unfold_from_canonical22
from ..core.character import Character
from ..core.ground import clip_ground, floor_offset, sole_heights
from ..core.measures import estimated_standing_height, mesh_standing_height
from ..core.motion import Motion
from ..core.skeleton import Skeleton
from ..errors import CheckpointError, OutputPathError, RetargetInputError
from ..files import check_output, input_ledger, refuse_overwriting_inputs
from ..io.bvh import save_bvh
from ..io.fbx_write import save_fbx
from ..io.gltf_write import save_glb
from ..io.shape import load_shape_npz
from ..io.untrusted import check_motion_samples, name_problem
from .inputs import MESH_LIMIT, MESH_WARN, Target, load_source, load_target
from .registry import Method, get_method

__all__ = [
    "METHOD_FPS",
    "OUTPUT_SUFFIXES",
    "MESH_WARN",
    "MESH_LIMIT",
    "resolve_target",
    "retarget_file",
    "method_times",
    "output_count",
    "at_output_rate",
    "on_the_ground",
    "check_posture",
]

#: the frame rate every method works at (the models were trained on 30 fps windows)
METHOD_FPS = 30.0
#: what ``out`` can be
OUTPUT_SUFFIXES = (".bvh", ".glb", ".fbx")
#: a result body is *lying* where its spine (hips -> neck) is more than 60 degrees from vertical,
#: *upside down* where more than 120, in frames where the source's is within 30 of it
LYING_COS, UPSIDE_DOWN_COS, UPRIGHT_COS = 0.5, -0.5, np.cos(np.radians(30.0))
#: ... in more than this fraction of those frames (a roll or a handstand in the source is not one)
POSTURE_FRACTION = 0.5
#: a result whose lowest point is more than this fraction of its standing height under the floor
#: in a frame where the source stands is refused
UNDER_FLOOR_FRACTION = 0.05
#: at most this many standing frames are skinned for the floor check
FLOOR_CHECK_FRAMES = 60
#: a result whose root goes further from the origin than this many times the source's range
#: (scaled to the target's size) plus the target's height is refused: no retargeting moves a root
#: that far; a corrupt checkpoint does
ROOT_RANGE_FACTOR = 10.0


def resolve_target(target: str) -> tuple[Skeleton, Motion | None]:
    """``(canonical-22 skeleton, full target BVH motion or None)`` of ``--target`` (see
    :mod:`.inputs`)."""
    resolved = load_target(target)
    return resolved.skeleton, resolved.bvh


def _check_options(
    chosen: Method, target: str, target_mesh, source_mesh, checkpoint, eso: bool = True
) -> None:
    """Refuse options that ``chosen`` would silently ignore."""
    if not chosen.needs_mesh:
        for flag, value in (("--target-mesh", target_mesh), ("--source-mesh", source_mesh)):
            if value is not None:
                raise RetargetInputError(
                    f"{value}: {flag} is only used by methods that need meshes (contact); "
                    f"--method {chosen.name} would ignore it"
                )
        if not eso:
            raise RetargetInputError(
                f"{target}: --no-eso is only used by --method contact; "
                f"--method {chosen.name} has no encoder-space optimisation"
            )
    if not chosen.needs_checkpoint and checkpoint is not None:
        raise RetargetInputError(
            f"{checkpoint}: --method {chosen.name} has no checkpoint; --checkpoint would be ignored"
        )


@contextmanager
def _naming(path, *also) -> Iterator[None]:
    """Make an input error raised while reading ``path`` (and the files ``also`` read with it: a
    joint map, a mesh) name a file: prefixed with ``path`` when its message names none of them, as
    one :class:`~retarget_lib.errors.RetargetInputError` (a ``ValueError`` of the core, e.g. an
    inconsistent rig, becomes one)."""
    try:
        yield
    except ValueError as e:
        if any(str(p) in str(e) or str(Path(p)) in str(e) for p in (path, *also) if p is not None):
            raise
        kind = type(e) if isinstance(e, RetargetInputError) else RetargetInputError
        raise kind(f"{path}: {e}") from None


def _check_writable_names(tgt: Target, target, out: Path) -> None:
    """Refuse a GLB/FBX target whose joint names ``out``'s format cannot hold (a line break in a
    BVH name would inject a line; ``\\x00\\x01`` in an FBX name, a class)."""
    suffix = out.suffix.lower()
    if tgt.rig is None or suffix == ".glb" or (suffix == ".bvh" and tgt.bvh is not None):
        return
    for name in tgt.rig.skeleton.joint_names:
        problem = name_problem(name, bvh=suffix == ".bvh")
        if problem:
            raise OutputPathError(
                f"{out}: cannot write the joint name {name!r} of {target} in a {suffix} file: it "
                f"{problem}; rename the joint or write a .glb"
            )


def _check_plausible(
    result: Motion, source: Motion, target_skeleton: Skeleton, method: str, checkpoint, source_path
) -> None:
    """Refuse a non-finite result or one whose root leaves :data:`ROOT_RANGE_FACTOR` times the
    source's range."""
    scale = max(1.0, target_skeleton.height() / source.skeleton.height())
    limit = ROOT_RANGE_FACTOR * (
        np.abs(source.root_positions).max() * scale + target_skeleton.height()
    )
    finite = np.isfinite(result.rotations).all() and np.isfinite(result.root_positions).all()
    reach = float(np.abs(result.root_positions).max()) if finite else float("inf")
    if reach > limit:
        what = (
            "non-finite values"
            if not finite
            else f"a root {reach:.3g} m from the origin (limit {limit:.3g} m)"
        )
        if checkpoint is not None or get_method(method).needs_checkpoint:
            raise CheckpointError(
                f"{checkpoint or method}: --method {method} produced {what}; the checkpoint is "
                "corrupt or not trained for this input"
            )
        raise RetargetInputError(f"{source_path}: --method {method} produced {what}")


def _load_retargeter(chosen: Method, checkpoint, device):
    """``chosen.retargeter(checkpoint, device)``, with a checkpoint that does not fit its model
    (missing keys, wrong shapes or config) reported as
    :class:`~retarget_lib.errors.CheckpointError`."""
    try:
        return chosen.retargeter(checkpoint, device)
    except (KeyError, TypeError, AttributeError, RuntimeError) as e:
        problem = str(e).strip().splitlines()[0][:200] if str(e).strip() else type(e).__name__
        raise CheckpointError(
            f"{checkpoint or chosen.default_checkpoint()}: not a valid {chosen.name} checkpoint: "
            f"{type(e).__name__}: {problem}"
        ) from None


def retarget_file(
    source: str | os.PathLike,
    target: str,
    method: str,
    out: str | os.PathLike,
    checkpoint: str | os.PathLike | None = None,
    target_mesh: str | os.PathLike | None = None,
    source_mesh: str | os.PathLike | None = None,
    fps: float | None = None,
    force: bool = False,
    joint_map: str | os.PathLike | None = None,
    source_joint_map: str | os.PathLike | None = None,
    device: str | None = None,
    eso: bool = True,
) -> Path:
    """Load ``source``, retarget it to ``target`` with the registry's ``method`` and write ``out``.

    Args:
        source: source motion: ``.bvh``, SMPL-X/AMASS ``.npz``, ``.glb``/``.gltf``, ``.fbx``.
        target: target: ``.bvh``, ``.glb``/``.gltf``, ``.fbx``, shape or AMASS ``.npz``, or a
            character name (:mod:`.inputs`).
        method: a name of :data:`~retarget_lib.methods.registry.REGISTRY`.
        out: output ``.bvh``, ``.glb`` or ``.fbx`` (module docstring).
        checkpoint: manifest id or path for a learned method (default: the method's default in the
            manifest).
        target_mesh: target shape ``.npz``, for a method that needs the target's mesh when the
            target has none (a BVH).
        source_mesh: source shape ``.npz``: its hand self-contacts are preserved by ``contact``.
        fps: output frame rate (default: the source's).
        force: allow ``out`` to be one of the inputs.
        joint_map: mapping file for a GLB/FBX target the rig name maps do not cover.
        source_joint_map: the same for a GLB/FBX source.
        device: where a learned method's network (and ESO) runs: ``auto``, ``cpu``, ``cuda``,
            ``mps`` (default the CPU).
        eso: ``contact`` only: ``False`` keeps the network's output without encoder-space
            optimisation (faster; on real meshes without a source mesh it is as good on every
            measure of ``retarget evaluate --table real`` and smoother).

    Returns:
        the output path.

    Raises:
        RetargetInputError: any bad input (its subclasses name the file and the problem):
            :class:`~retarget_lib.errors.OutputPathError`, :class:`~retarget_lib.io.bvh.BVHError`,
            :class:`~retarget_lib.errors.GLTFError`, :class:`~retarget_lib.errors.AMASSError`,
            :class:`~retarget_lib.errors.FBXError`,
            :class:`~retarget_lib.core.skeleton.JointSetError`,
            :class:`~retarget_lib.io.shape.ShapeError`,
            :class:`~retarget_lib.errors.CheckpointError`, :class:`~retarget_lib.errors.LimitError`,
            :class:`~retarget_lib.errors.InputFileError`, :class:`~retarget_lib.errors.DeviceError`.
    """
    chosen = get_method(method)
    _check_options(chosen, str(target), target_mesh, source_mesh, checkpoint, eso)
    with input_ledger(force):
        check_output(
            out,
            [source, target, target_mesh, source_mesh, checkpoint, joint_map, source_joint_map],
            OUTPUT_SUFFIXES,
            force,
        )
        with _naming(source, source_joint_map):
            src = load_source(source, source_joint_map)
        with _naming(target, joint_map, target_mesh):
            tgt = load_target(str(target), target_mesh, joint_map)
        refuse_overwriting_inputs(out)  # also the files the inputs named (a .gltf's buffers)
        _check_target_fits(tgt, target, Path(out))
        out_fps = float(fps) if fps is not None else src.motion.fps
        if not (np.isfinite(out_fps) and 1.0 <= out_fps <= 1000.0):
            raise RetargetInputError(f"--fps {fps}: the output frame rate must be within 1-1000")
        _check_result_size(src.motion, tgt, out_fps, source)
        times = method_times(src.motion)
        motion = (
            src.motion.copy()
            if _same_rate(src.motion.fps, METHOD_FPS)
            else src.motion.at_times(times, fps=METHOD_FPS)
        )
        if chosen.needs_mesh:
            if tgt.character is None:
                raise RetargetInputError(
                    f"{target}: --method contact needs the target's mesh: give a .glb/.fbx/shape "
                    ".npz target, --target-mesh SHAPE.npz or a character name"
                )
            with _naming(source_mesh):
                source_character = (
                    load_shape_npz(source_mesh) if source_mesh is not None else src.character
                )
            result = _load_retargeter(chosen, checkpoint, device)(
                motion,
                tgt.character,
                source_character=source_character,
                eso=eso,
            )
        else:
            result = _load_retargeter(chosen, checkpoint, device)(motion, tgt.skeleton)
        _check_plausible(result, motion, tgt.skeleton, method, checkpoint, source)
        result = at_output_rate(result, times, src.motion, out_fps)
        source_out = (
            src.motion
            if result.num_frames == src.motion.num_frames
            else at_output_rate(motion, times, src.motion, out_fps)
        )
        grounded = on_the_ground(result, source_out, tgt.character, src.character)
        check_posture(grounded, source_out, tgt.character, method, source)
        _write(grounded, tgt, src.meta, Path(out))
    return Path(out)


def _same_rate(a: float, b: float) -> bool:
    return abs(a - b) < 1e-9


def method_times(motion: Motion) -> np.ndarray:
    """The times (seconds after the first frame) at which the methods see ``motion``: every
    ``1 / METHOD_FPS`` and, when that grid misses it, the source's last frame (so no source frame
    lies beyond the result). ``(N,)``, increasing, the last one the source's last frame."""
    last = (motion.num_frames - 1) / motion.fps
    n = int(np.ceil(last * METHOD_FPS - 1e-6)) + 1
    return np.minimum(np.arange(n) / METHOD_FPS, last)


def output_count(motion: Motion, fps: float) -> int:
    """How many frames a result at ``fps`` has: the source's own count at its rate, else the
    count its duration implies (``floor((T - 1) / fps_source * fps) + 1``)."""
    if _same_rate(fps, motion.fps):
        return motion.num_frames
    return int(np.floor((motion.num_frames - 1) / motion.fps * fps + 1e-9)) + 1


def at_output_rate(result: Motion, times: np.ndarray, source: Motion, fps: float) -> Motion:
    """The result (one frame per :func:`method_times` entry ``times``) at ``fps``, with
    :func:`output_count` frames: a source at 30 fps comes back frame for frame, any other rate is
    sampled at its own frame times (slerp, linear root)."""
    count = output_count(source, fps)
    if _same_rate(fps, METHOD_FPS) and count == result.num_frames:
        return result
    position = np.interp(
        np.arange(count) / fps, times, np.arange(len(times))
    )  # fractional result frames
    return result.at_times(position / result.fps, fps=fps)


def on_the_ground(
    result: Motion,
    source: Motion,
    target: Character | None = None,
    source_character: Character | None = None,
) -> Motion:
    """``result`` shifted vertically by the ground rule
    (:func:`~retarget_lib.core.ground.floor_offset`): where a foot of ``source`` stands on its
    floor (in a run, where it touches it: :func:`~retarget_lib.core.ground.ground_contacts`), the
    result's is on ``y = 0`` (at the source's sole height times the height ratio).

    Args:
        result: the canonical-22 result on the target skeleton.
        source: the canonical-22 source clip, frame for frame with ``result``.
        target: the target character when it has a mesh (its soles are its rest mesh's lowest
            point), else None (its lowest rest foot joint).
        source_character: the same for the source.

    Returns:
        a copy of ``result`` whose root heights carry the shift (``meta["floor_offset_m"]``: the
        ``(T,)`` shift applied, metres).
    """
    if source.num_frames != result.num_frames:
        raise ValueError(
            f"the result has {result.num_frames} frames and the source {source.num_frames}"
        )
    src_mesh = None if source_character is None else source_character.rest_vertices
    tgt_mesh = None if target is None else target.rest_vertices
    ground = clip_ground(source.global_positions(), source.skeleton, source.fps, src_mesh)
    tgt_soles = sole_heights(result.global_positions(), result.skeleton, tgt_mesh)
    shift = floor_offset(
        tgt_soles,
        ground.soles,
        ground.floor,
        ground.contacts,
        result.skeleton.height() / source.skeleton.height(),
    )
    out = result.copy()
    out.root_positions[:, 1] += shift
    out.meta["floor_offset_m"] = shift
    return out


def _spine_up(positions: np.ndarray, skeleton: Skeleton) -> np.ndarray:
    """``(T,)`` the vertical component of each frame's unit hips -> neck direction."""
    spine = positions[:, skeleton.index("Neck")] - positions[:, skeleton.index("Hips")]
    return spine[:, 1] / np.maximum(np.linalg.norm(spine, axis=-1), 1e-9)


def check_posture(
    result: Motion, source: Motion, target: Character | None, method: str, source_path
) -> None:
    """Refuse a grounded result that no retargeting of ``source`` should give (one line, the
    command's exit code 2): a body lying or upside down where the source stands
    (:data:`LYING_COS`, :data:`POSTURE_FRACTION`), or, in a frame where the source stands on its
    floor, a lowest point (the mesh's, else the lowest of the joints and the feet's soles) more than
    :data:`UNDER_FLOOR_FRACTION` of the target's standing height under ``y = 0``. Both are what a
    wrong joint map, up axis or rest convention gives.

    Args:
        result: the canonical-22 result after :func:`on_the_ground`.
        source: the canonical-22 source, frame for frame with ``result``.
        target: the target character when it has a mesh.
        method: the method's name (for the message).
        source_path: the source file (for the message).
    """
    res_pos, src_pos = result.global_positions(), source.global_positions()
    upright = _spine_up(src_pos, source.skeleton) > UPRIGHT_COS
    if upright.any():
        up = _spine_up(res_pos, result.skeleton)[upright]
        for limit, what in ((UPSIDE_DOWN_COS, "upside down"), (LYING_COS, "lying")):
            share = float(np.mean(up < limit))
            if share > POSTURE_FRACTION:
                raise RetargetInputError(
                    f"{source_path}: --method {method} puts the target's body {what} in "
                    f"{100 * share:.0f} % of the frames where the source stands upright; check "
                    "the joint map (--source-joint-map / --joint-map) and the files' up axis, or "
                    "try --method copy-rest"
                )
    standing = clip_ground(src_pos, source.skeleton, source.fps).contacts.any(axis=1)
    frames = np.flatnonzero(standing)
    if len(frames) == 0:
        return
    frames = frames[
        np.linspace(0, len(frames) - 1, min(len(frames), FLOOR_CHECK_FRAMES)).astype(int)
    ]
    if target is not None:
        verts = target.skinned(result.rotations[frames], result.root_positions[frames])
        lowest = verts[..., 1].min(axis=-1)
        height = mesh_standing_height(target.rest_vertices)
        k = int(np.argmin(lowest))
        part = int(np.argmax(target.weights[int(np.argmin(verts[k, :, 1]))]))
    else:
        soles = sole_heights(res_pos[frames], result.skeleton).min(axis=-1)
        joints = res_pos[frames, :, 1]
        lowest = np.minimum(soles, joints.min(axis=-1))  # a head under the floor
        height = estimated_standing_height(result.skeleton)
        k = int(np.argmin(lowest))
        part = int(np.argmin(joints[k]))
    depth = float(-lowest[k])
    if depth > UNDER_FLOOR_FRACTION * height:
        raise RetargetInputError(
            f"{source_path}: --method {method} puts the target's "
            f"{result.skeleton.joint_names[part]} {100 * depth:.0f} cm under the floor "
            f"({100 * depth / height:.0f} % of its height) at {frames[k] / result.fps:.1f} s, "
            "where the source stands; check the joint map (--source-joint-map / --joint-map) and "
            "the files' up axis, or try another --method or a shorter clip"
        )


def _check_result_size(motion: Motion, tgt: Target, out_fps: float, source) -> None:
    """Refuse, before any work, a result beyond the motion budget of
    :mod:`~retarget_lib.io.untrusted`: the source's duration at the output (or the methods') rate
    x the joints the result is written on."""
    joints = max([22] + [m.skeleton.num_joints for m in (tgt.rig, tgt.bvh) if m is not None])
    frames = max(len(method_times(motion)), output_count(motion, out_fps))
    check_motion_samples(frames, joints, str(source), " (the result, on the target's joints)")


def _check_target_fits(tgt: Target, target, out: Path) -> None:
    """Refuse an output the target cannot make: a mesh result without a mesh, joint names the
    format cannot hold."""
    suffix = out.suffix.lower()
    if suffix != ".bvh" and tgt.rig is None:
        raise OutputPathError(
            f"{out}: a {suffix} result is the target's skinned mesh, and the target {target} has "
            "none; give a .glb/.fbx/shape .npz target, a character name, or --target-mesh"
        )
    _check_writable_names(tgt, target, out)


def _write(result: Motion, tgt: Target, source_layout: dict, out: Path) -> None:
    """Write a canonical result by ``out``'s suffix on the target's own joints (module
    docstring)."""
    suffix = out.suffix.lower()
    if suffix in (".glb", ".fbx"):
        if tgt.rig is None:  # refused before any work by the output check
            raise OutputPathError(f"{out}: the target has no mesh to write")
        save = save_glb if suffix == ".glb" else save_fbx
        save(tgt.rig, out, tgt.rig.motion_from_canonical(result))
    elif tgt.bvh is not None:  # the target's joints, names, channels and unit
        full = unfold_from_canonical22(result, tgt.bvh.skeleton, tgt.bvh_map)
        full.meta.update(
            {
                k: tgt.bvh.meta[k]
                for k in ("unit_scale", "unit", "channels", "file_joint_names")
                if k in tgt.bvh.meta
            }
        )
        save_bvh(full, out)
    else:  # a GLB/FBX target's own joints, else the canonical 22; in the source file's unit
        full = tgt.rig.motion_from_canonical(result) if tgt.rig is not None else result
        full.meta.update(
            {k: source_layout[k] for k in ("unit_scale", "unit") if k in source_layout}
        )
        save_bvh(full, out)
