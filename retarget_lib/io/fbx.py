"""FBX characters and animations through the Open Asset Import Library (the optional ``fbx`` extra).

Set-up: Debian's ``libassimp5`` (the C++ library, 12.7 MB installed with its two dependencies) and
the PyPI binding ``impasse`` (``pip install -e .[fbx]``). Chosen over Blender as a Python module
(PyPI ``bpy`` 5.0.1: a 374 MB download, 821 MB installed, and it pins ``numpy<2``, which the
suite's environment cannot take); ``pyassimp`` 5.2.5 fails on Debian's ``libassimp5`` 5.2.5 with a
NULL pointer access on the first skinned file, ``impasse`` (its maintained fork, cffi) reads it.

How: assimp converts the FBX into a binary glTF in a temporary folder, and the glTF reader does
the rest (:func:`~retarget_lib.io.gltf.load_gltf_rig`, :func:`~retarget_lib.io.gltf.load_gltf_motion`:
world rest pose including the FBX's armature scale, rig maps, skin). Errors name the FBX file, not
the temporary one.

Units: FBX lengths are in units of ``UnitScaleFactor`` centimetres (``GlobalSettings``; 1 = cm,
what Mixamo and Maya write; 100 = m, what Blender and :mod:`~retarget_lib.io.fbx_write` write), and
assimp passes them through unconverted, so rigs and motions are scaled to metres here by
``UnitScaleFactor / 100`` (a file without the setting is taken as centimetres, FBX's default).

Animations are sampled at the file's own frame rate (its ``GlobalSettings`` ``TimeMode`` /
``CustomFrameRate``, which assimp reports as the animation's ticks per second) unless ``fps`` is
given.

Writing FBX is :mod:`~retarget_lib.io.fbx_write` (pure Python, no extra needed): assimp 5.2.5's
own FBX exporter writes binary files that assimp itself cannot read back, and ASCII files (which
it can) come back with every keyframe time 1000 times too late (its glTF importer counts ticks in
milliseconds, the FBX exporter ignores the tick rate).
"""

from __future__ import annotations

import os
import tempfile
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator

import numpy as np

from ..core.motion import Motion
from ..core.rig import Rig
from ..errors import FBXError, RetargetInputError
from ..files import readable_file
from .gltf import MAX_FILE_BYTES, load_gltf_animation, load_gltf_motion, load_gltf_rig

__all__ = ["FBXError", "fbx_missing", "load_fbx_rig", "load_fbx_motion", "load_fbx_animation"]

_INSTALL = "install the fbx extra: `sudo apt-get install libassimp5` and `pip install -e .[fbx]`"


def _impasse():
    """The ``impasse`` module (:class:`~retarget_lib.errors.FBXError` naming the set-up if missing)."""
    try:
        import impasse  # noqa: PLC0415 (optional dependency)
    except (ImportError, OSError) as e:  # OSError: the binding is there but libassimp is not
        raise FBXError(f"FBX needs the Open Asset Import Library ({type(e).__name__}: {e}); {_INSTALL}") from None
    return impasse


def fbx_missing() -> str | None:
    """Why FBX files cannot be read or written here, or ``None`` when they can."""
    try:
        _impasse()
    except FBXError as e:
        return str(e)
    return None


@contextmanager
def _as_glb(path: str | os.PathLike) -> Iterator[tuple[Path, float | None, float]]:
    """``(the FBX path converted to a temporary .glb, the first animation's frame rate or None,
    metres per file unit)``; errors of the glTF reader inside are re-raised naming ``path``."""
    path = readable_file(path, "FBX file", MAX_FILE_BYTES)
    try:
        impasse = _impasse()
    except FBXError as e:
        raise FBXError(f"{path}: {e}") from None
    with tempfile.TemporaryDirectory(prefix="retarget-fbx-") as tmp:
        glb = Path(tmp) / f"{path.stem}.glb"
        try:
            scene = impasse.load(str(path))
            impasse.export(scene, str(glb), "glb2")
        except impasse.errors.AssimpError as e:
            raise FBXError(f"{path}: the Open Asset Import Library cannot read it as FBX ({e})") from None
        # assimp keeps the rate in single precision (29.97 -> 29.969999...): rounded to 1/1000 fps,
        # which every rate in use (23.976, 29.97, 59.94 ...) is exact in
        rate = round(float(scene.animations[0].ticks_per_second), 3) if len(scene.animations) else None
        settings = dict(scene.metadata) if scene.metadata is not None else {}
        metres = float(settings.get("UnitScaleFactor", 1.0)) / 100.0
        if not (np.isfinite(metres) and 1e-6 <= metres <= 1e6):
            raise FBXError(f"{path}: UnitScaleFactor {settings['UnitScaleFactor']} is not a length unit")
        try:
            yield glb, (rate if rate is not None and 1.0 <= rate <= 1000.0 else None), metres
        except RetargetInputError as e:
            raise type(e)(str(e).replace(str(glb), str(path))) from None


def _in_metres(rig: Rig, metres: float) -> Rig:
    """``rig`` with every length multiplied by ``metres`` (metres per file unit)."""
    if metres == 1.0:
        return rig
    return Rig(rig.name, rig.skeleton.scaled(metres), rig.rest_vertices * metres, rig.faces, rig.weights,
               rig.joint_map, dict(rig.meta, unit_scale=metres))


def load_fbx_rig(path: str | os.PathLike, mapping: str | os.PathLike | dict | None = None) -> Rig:
    """Read a skinned character from an FBX file (see :func:`~retarget_lib.io.gltf.load_gltf_rig`).

    Raises:
        FBXError: the extra is missing or assimp cannot read the file; the glTF reader's errors
            (no skin, unmappable joints ...) naming the FBX file.
    """
    with _as_glb(path) as (glb, _, metres):
        rig = _in_metres(load_gltf_rig(glb, mapping), metres)
    rig.name, rig.meta["source"] = Path(path).stem, str(path)
    return rig


def load_fbx_motion(path: str | os.PathLike, fps: float | None = None,
                    mapping: str | os.PathLike | dict | None = None) -> tuple[Motion, Rig]:
    """Sample the first animation of a skinned FBX file (see :func:`~retarget_lib.io.gltf.load_gltf_motion`)
    at ``fps``, by default the file's own frame rate (else 30)."""
    with _as_glb(path) as (glb, rate, metres):
        motion, rig = load_gltf_motion(glb, fps=fps or rate, mapping=mapping)
    rig = _in_metres(rig, metres)
    motion = motion.copy(skeleton=rig.skeleton, root_positions=motion.root_positions * metres)
    rig.name, rig.meta["source"], motion.meta["source"] = Path(path).stem, str(path), str(path)
    return motion, rig


def load_fbx_animation(path: str | os.PathLike, fps: float | None = None,
                       mapping: str | os.PathLike | dict | None = None) -> tuple[Motion, dict[int, int]]:
    """Sample the first animation of an FBX file with or without a skin (a Mixamo clip downloaded
    "With Skin" or "Without Skin"; see :func:`~retarget_lib.io.gltf.load_gltf_animation`).

    Sampled at ``fps``, by default the file's own frame rate (else the keys' rate, else 30); lengths
    in metres (``UnitScaleFactor``, as :func:`load_fbx_motion`).

    Returns:
        ``(motion on the file's joints, {file joint index: canonical index})``.
    """
    with _as_glb(path) as (glb, rate, metres):
        motion, joint_map = load_gltf_animation(glb, fps=fps or rate, mapping=mapping)
    motion = motion.copy(skeleton=motion.skeleton.scaled(metres), root_positions=motion.root_positions * metres)
    motion.meta["source"] = str(path)
    return motion, joint_map
