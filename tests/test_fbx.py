"""FBX in (the optional extra: Debian libassimp5 + PyPI impasse) and out (our pure-Python binary
writer, ``retarget_lib/io/fbx_write.py``).

Reading tests skip, with the reason, when the extra is not installed; CI installs it, so the
round trips through assimp always run there. Two extra checks run only where their tool exists:
Blender's own importer (``bpy`` in a separate virtual environment, ``$RETARGET_BPY_PYTHON``, default
``/work/bpy-venv/bin/python``; it pins ``numpy<2`` so it is never a dependency of the library) and
the Autodesk FBX SDK through ``FBX2glTF`` (``$RETARGET_FBX2GLTF``, default the npm package
``fbx2gltf`` that ``.ci/node-deps.sh`` installs beside the virtual environment, as for the glTF
validator).
"""

import json
import os
import struct
import subprocess
import sys
import zlib
from pathlib import Path

import numpy as np
import pytest
import torch
from scipy.spatial import cKDTree
from test_gltf import _unreal_rig, random_motion

from retarget_lib.cli import main
from retarget_lib.core.motion import Motion
from retarget_lib.core.rig import Rig
from retarget_lib.core.rotations import (
    quat_angle,
    quat_conjugate,
    quat_from_axis_angle,
    quat_from_euler,
    quat_mul,
    quat_to_euler,
)
from retarget_lib.data.synthetic.amass_clip import AMASS_CLIP_PATH
from retarget_lib.data.synthetic.characters import make_character
from retarget_lib.errors import FBXError, GLTFError
from retarget_lib.io.fbx import fbx_missing, load_fbx_motion, load_fbx_rig
from retarget_lib.io.fbx_write import (
    KTIME_PER_SECOND,
    _continuous_euler_xyz,
    fbx_time_mode,
    save_fbx,
)
from retarget_lib.io.gltf import load_gltf_motion, load_gltf_rig
from retarget_lib.io.gltf_write import save_glb

pytestmark = pytest.mark.tooling  # nothing here depends on the thread count (make unit-threads)

FBX = "/usr/share/assimp/models/FBX"
needs_assimp = pytest.mark.skipif(
    fbx_missing() is not None, reason=f"fbx extra not installed: {fbx_missing()}"
)
#: the file stores positions as float64 and key values (degrees, metres) as float32: float32's
#: 6e-8 relative error on ~100° and ~1 m keys, through FK of <= 28 joints, stays below 1e-6 m;
#: assimp's FBX -> glTF conversion stores float32 again (see test_gltf's F32_FK)
FK_TOL = 5e-5
#: degrees: float32 keys of Euler angles up to a few hundred degrees (~3e-5°), composed three times
ROT_TOL_DEG = 1e-3


def _rotation_error_deg(a: Motion, b: Motion) -> float:
    diff = quat_mul(torch.from_numpy(a.rotations), quat_conjugate(torch.from_numpy(b.rotations)))
    return float(np.degrees(quat_angle(diff).numpy()).max())


def _nearest(reference: np.ndarray, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(index into reference, distance)`` of each point's nearest reference vertex."""
    dist, idx = cKDTree(reference).query(points)
    return idx, dist


# ------------------------------------------------------------------ reading (assimp)
@needs_assimp
def test_a_real_rigged_fbx_is_read_and_checked():
    """assimp's test rig (14 bones in two chains, Bone ... and Bone.007 ...) parses; it is not one
    skeleton, and the error names the FBX (not the temporary GLB) and both roots."""
    with pytest.raises(
        GLTFError,
        match=r"animation_with_skeleton.fbx: the skin's joints form 2 trees "
        r"\(roots \['Bone', 'Bone.007'\]\)",
    ) as e:
        load_fbx_rig(f"{FBX}/animation_with_skeleton.fbx")
    assert ".glb" not in str(e.value)


@needs_assimp
def test_fbx_without_a_skin_and_not_fbx(tmp_path):
    with pytest.raises(GLTFError, match="box.fbx: no skin"):
        load_fbx_rig(f"{FBX}/box.fbx")
    text = tmp_path / "notes.fbx"
    text.write_text("not an fbx file")
    with pytest.raises(FBXError, match="cannot read it as FBX"):
        load_fbx_rig(text)


@needs_assimp
def test_an_ascii_fbx_character_with_animation_reads_like_its_glb(tmp_path):
    """A character converted to FBX by assimp itself reads back with the same skeleton, mesh and
    key count (assimp's own FBX export is used only here, to make an FBX with a humanoid rig).
    assimp's exporter labels its lengths centimetres (``UnitScaleFactor`` 1) without converting
    the GLB's metres, so the reader, which honours the label, sees a character 1/100 the size."""
    import impasse

    character = make_character("hana")
    glb, fbx = tmp_path / "hana.glb", tmp_path / "hana.fbx"
    save_glb(Rig.from_character(character), glb, random_motion(character.skeleton, frames=5))
    impasse.export(impasse.load(str(glb)), str(fbx), "fbxa")
    rig = load_fbx_rig(fbx)
    assert rig.meta["rig"] == "mixamo" and rig.meta["source"] == str(fbx)
    got = rig.character()
    assert rig.meta["unit_scale"] == 0.01
    np.testing.assert_allclose(got.skeleton.offsets * 100, character.skeleton.offsets, atol=1e-5)
    np.testing.assert_allclose(
        np.sort(got.rest_vertices, axis=0) * 100,
        np.sort(character.rest_vertices, axis=0),
        atol=1e-5,
    )
    motion, _ = load_fbx_motion(fbx)
    assert motion.skeleton.num_joints == 22


# ------------------------------------------------------------------ writing: round trips
def _assert_round_trip(rig: Rig, motion: Motion, path: Path) -> None:
    """``path`` (written from rig and motion) reads back through assimp with the same joints, rest
    pose, mesh, weights, frame rate, frame count and poses."""
    back = load_fbx_rig(path)
    assert back.skeleton.joint_names == rig.skeleton.joint_names
    assert list(back.skeleton.parents) == list(rig.skeleton.parents)
    np.testing.assert_allclose(
        back.skeleton.rest_positions(), rig.skeleton.rest_positions(), atol=1e-6
    )
    idx, dist = _nearest(rig.rest_vertices, back.rest_vertices)  # assimp reorders the vertices
    assert len(back.rest_vertices) == len(rig.rest_vertices) and len(set(idx)) == len(idx)
    assert dist.max() < 1e-6  # float64 in the file, float32 in assimp's glTF
    np.testing.assert_allclose(back.weights, rig.weights[idx], atol=1e-6)  # float32 weights
    read, _ = load_fbx_motion(path)  # the file's own frame rate
    assert read.fps == motion.fps and read.num_frames == motion.num_frames
    assert _rotation_error_deg(read, motion) < ROT_TOL_DEG
    np.testing.assert_allclose(read.global_positions(), motion.global_positions(), atol=FK_TOL)


@needs_assimp
def test_a_synthetic_character_round_trips_through_assimp(tmp_path):
    rig = Rig.from_character(make_character("hana"))
    motion = random_motion(rig.skeleton, frames=40, deg=40.0)
    save_fbx(rig, tmp_path / "hana.fbx", motion)
    _assert_round_trip(rig, motion, tmp_path / "hana.fbx")


@needs_assimp
@pytest.mark.parametrize("fps", [24.0, 120.0, 29.97])
def test_extra_joints_and_frame_rates_round_trip(tmp_path, fps):
    """An Unreal-named rig with a root above the pelvis, a spine_04 and weightless fingers keeps
    every joint; standard (24, 120) and custom (29.97) frame rates come back as written."""
    character = make_character("kato")
    rig, _ = _unreal_rig(character)
    motion = rig.motion_from_canonical(
        random_motion(character.skeleton, frames=30, deg=40.0, fps=fps)
    )
    path = tmp_path / "manny.fbx"
    save_fbx(rig, path, motion)
    assert load_fbx_rig(path).meta["rig"] == "unreal"
    _assert_round_trip(rig, motion, path)


@needs_assimp
def test_centimetre_files_read_in_metres(tmp_path):
    """``UnitScaleFactor`` 1 (centimetres, as Mixamo and Maya write) reads back in metres."""
    character = make_character("kato")
    rig, _ = _unreal_rig(character)
    motion = rig.motion_from_canonical(random_motion(character.skeleton, frames=10))
    path = tmp_path / "manny_cm.fbx"
    save_fbx(rig, path, motion, unit_scale_factor=1.0)
    assert load_fbx_rig(path).meta["unit_scale"] == 0.01  # the file is in centimetres
    _assert_round_trip(rig, motion, path)
    with pytest.raises(FBXError, match="unit_scale_factor 0.0 must be a positive"):
        save_fbx(rig, tmp_path / "bad.fbx", motion, unit_scale_factor=0.0)


@needs_assimp
def test_a_rest_pose_file_has_no_animation(tmp_path):
    rig = Rig.from_character(make_character("kato"))
    save_fbx(rig, tmp_path / "kato.fbx")
    back = load_fbx_rig(tmp_path / "kato.fbx")
    np.testing.assert_allclose(back.skeleton.offsets, rig.skeleton.offsets, atol=1e-6)
    with pytest.raises(GLTFError, match="kato.fbx: has 0 animations"):
        load_fbx_motion(tmp_path / "kato.fbx")


def test_euler_curves_are_continuous_and_exact():
    """A spin about a tilted axis through two turns: every key reproduces the quaternion, and
    consecutive keys never jump by 180° or more (a 360° wrap or a flip between the two equivalent
    Euler triples, which the per-frame angles have), so linear interpolation takes the short way.
    (Near gimbal lock, Y at ±90°, X and Z legitimately move faster than the 3.6° per frame.)"""
    frames = 200
    axis = np.array([0.3, 1.0, -0.2]) / np.linalg.norm([0.3, 1.0, -0.2])
    angle = np.linspace(0.0, 4 * np.pi, frames)  # two turns, 3.6° per frame
    q = quat_from_axis_angle(torch.from_numpy(axis[None] * angle[:, None])).numpy()[:, None]
    euler = _continuous_euler_xyz(q)
    back = quat_from_euler(torch.from_numpy(euler[..., ::-1].copy()), "ZYX", degrees=True)
    err = np.degrees(quat_angle(quat_mul(back, quat_conjugate(torch.from_numpy(q)))).numpy())
    assert err.max() < 1e-6
    naive = quat_to_euler(torch.from_numpy(q), "ZYX", degrees=True).numpy()
    assert np.abs(np.diff(naive, axis=0)).max() > 180.0  # what the unwrapping removes
    step = np.abs(np.diff(euler, axis=0)).max()
    assert step < 90.0, step


# ------------------------------------------------------------------ writing: the container
def _records(data: bytes, start: int, end: int) -> list[tuple[str, int, int]]:
    """``(name, property count, end offset)`` of the FBX 7.4 records in ``data[start:end]``."""
    out, at = [], start
    while at < end:
        stop, count, _, length = struct.unpack_from("<3IB", data, at)
        if stop == 0:
            break
        out.append((data[at + 13 : at + 13 + length].decode(), count, stop))
        at = stop
    return out


def test_the_container_is_well_formed_and_deterministic(tmp_path):
    """Magic, version, top-level records chained by their end offsets up to the closing zero
    record, the 16-byte aligned footer; the same input gives the same bytes; arrays are zlib."""
    rig = Rig.from_character(make_character("hana"))
    motion = random_motion(rig.skeleton, frames=10)
    a, b = tmp_path / "a.fbx", tmp_path / "b.fbx"
    save_fbx(rig, a, motion)
    save_fbx(rig, b, motion)
    data = a.read_bytes()
    assert data == b.read_bytes()
    assert (
        data[:23] == b"Kaydara FBX Binary  \x00\x1a\x00"
        and struct.unpack_from("<I", data, 23)[0] == 7400
    )
    top = _records(data, 27, len(data))
    assert [name for name, _, _ in top] == [
        "FBXHeaderExtension",
        "FileId",
        "CreationTime",
        "Creator",
        "GlobalSettings",
        "Documents",
        "References",
        "Definitions",
        "Objects",
        "Connections",
        "Takes",
    ]
    last = top[-1][2]
    assert data[last : last + 13] == b"\x00" * 13
    assert len(data) % 16 == 0 and struct.unpack_from("<I", data, len(data) - 140)[0] == 7400
    vertices = data.index(b"Vertices")  # its one property: a float64 array, zlib-compressed
    code, count, encoding, size = struct.unpack_from("<c3I", data, vertices + 8)
    assert (code, count, encoding) == (b"d", rig.rest_vertices.size, 1)
    raw = zlib.decompress(data[vertices + 21 : vertices + 21 + size])
    np.testing.assert_array_equal(np.frombuffer(raw, "<f8").reshape(-1, 3), rig.rest_vertices)
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "a.fbx",
        "b.fbx",
    ]  # no temporary file left


def test_time_modes_and_errors(tmp_path):
    assert (fbx_time_mode(30), fbx_time_mode(24.0), fbx_time_mode(29.97)) == (6, 11, 14)
    assert KTIME_PER_SECOND == 46_186_158_000
    rig = Rig.from_character(make_character("hana"))
    other = random_motion(_unreal_rig(make_character("kato"))[0].skeleton, frames=2)
    with pytest.raises(
        FBXError, match="o.fbx: the motion's joints are not the rig 'hana''s joints"
    ):
        save_fbx(rig, tmp_path / "o.fbx", other)
    assert not any(tmp_path.iterdir())


# ------------------------------------------------------------------ the command line
@needs_assimp
def test_cli_writes_fbx_like_glb(tmp_path):
    """``--out X.fbx`` writes the same result as ``--out X.glb`` (the GLB target's joints, mesh and
    skin performing the AMASS clip at its frame rate), from a GLB and from an FBX target."""
    manny, _ = _unreal_rig(make_character("gus"))
    save_glb(manny, tmp_path / "manny.glb")
    save_fbx(manny, tmp_path / "manny_target.fbx")
    glb_out, fbx_out, fbx_out2 = (
        tmp_path / "walk.glb",
        tmp_path / "walk.fbx",
        tmp_path / "walk2.fbx",
    )
    for target, out in (
        (tmp_path / "manny.glb", glb_out),
        (tmp_path / "manny.glb", fbx_out),
        (tmp_path / "manny_target.fbx", fbx_out2),
    ):
        assert (
            main(
                [
                    "retarget",
                    "--source",
                    str(AMASS_CLIP_PATH),
                    "--target",
                    str(target),
                    "--method",
                    "copy-rest",
                    "--out",
                    str(out),
                ]
            )
            == 0
        )
    expected, _ = load_gltf_motion(glb_out)
    rig = load_gltf_rig(glb_out)
    for out in (fbx_out, fbx_out2):
        got, got_rig = load_fbx_motion(out)
        assert got_rig.skeleton.joint_names == rig.skeleton.joint_names
        assert got.fps == expected.fps and got.num_frames == expected.num_frames
        np.testing.assert_allclose(got.global_positions(), expected.global_positions(), atol=FK_TOL)


# ----------------------------------------------------------------- other importers, where installed
def _tool(env: str, default: str | None) -> str | None:
    path = os.environ.get(env) or default
    return path if path and Path(path).exists() else None


def _manny_fbx(tmp_path, fps: float):
    """An Unreal-named rig (extra and weightless joints) on kato's body, one second of random motion
    at ``fps``, written to ``tmp_path/manny.fbx``: what the external readers are given."""
    character = make_character("kato")
    rig, _ = _unreal_rig(character)
    frames = int(fps)
    motion = rig.motion_from_canonical(
        random_motion(character.skeleton, frames=frames, deg=40.0, fps=fps)
    )
    path = tmp_path / "manny.fbx"
    save_fbx(rig, path, motion)
    return rig, motion, path


BPY_PYTHON = _tool("RETARGET_BPY_PYTHON", "/work/bpy-venv/bin/python")
FBX2GLTF = _tool(
    "RETARGET_FBX2GLTF",
    str(Path(sys.prefix) / "node" / "node_modules" / "fbx2gltf" / "bin" / "Linux" / "FBX2glTF"),
)


@pytest.mark.skipif(
    BPY_PYTHON is None, reason="no Python with Blender's bpy (set RETARGET_BPY_PYTHON)"
)
def test_blender_imports_the_armature_mesh_weights_and_action(tmp_path):
    rig, motion, path = _manny_fbx(tmp_path, fps=24.0)
    probe = Path(__file__).with_name("blender_fbx_probe.py")
    run = subprocess.run(
        [BPY_PYTHON, str(probe), str(path)],
        capture_output=True,
        text=True,
        timeout=300,
        env={**os.environ, "OMP_NUM_THREADS": "1"},
    )
    assert run.returncode == 0, run.stderr[-2000:]
    out = json.loads(run.stdout.strip().splitlines()[-1])
    assert out["import"] == ["FINISHED"] and out["armatures"] == 1 and out["meshes"] == 1
    names = list(rig.skeleton.joint_names)
    assert sorted(out["bones"]) == sorted(names)
    order = [out["bones"].index(n) for n in names]
    parents = [out["parents"][k] for k in order]
    assert [names.index(p) if p else -1 for p in parents] == list(rig.skeleton.parents)
    assert out["fps"] == 24.0 and out["frame_range"] == [1, 24]  # Blender starts at frame 1
    heads = np.array(out["heads"])[:, order]
    np.testing.assert_allclose(heads, motion.global_positions(), atol=FK_TOL)
    mesh = np.array(out["mesh_vertices"])
    idx, dist = _nearest(rig.rest_vertices, mesh)
    assert len(mesh) == len(rig.rest_vertices) and dist.max() < 1e-6
    weights = np.zeros_like(rig.weights)
    for name, group in out["weights"].items():
        for v, w in group.items():
            weights[int(v), names.index(name)] = w
    np.testing.assert_allclose(weights, rig.weights[idx], atol=1e-6)  # Blender stores float32
    # Blender's skinning of the last frame is the library's: the bind matrices mean what we meant
    expected = rig.posed_vertices(motion)[-1][idx]
    np.testing.assert_allclose(np.array(out["deformed_last_frame"]), expected, atol=FK_TOL)


@pytest.mark.skipif(
    FBX2GLTF is None,
    reason="no FBX2glTF (the Autodesk FBX SDK's converter): run .ci/node-deps.sh or set "
    "RETARGET_FBX2GLTF",
)
def test_the_autodesk_fbx_sdk_reads_it(tmp_path):
    rig, motion, path = _manny_fbx(tmp_path, fps=30.0)
    run = subprocess.run(
        [
            FBX2GLTF,
            "--binary",
            "--anim-framerate",
            "bake30",
            "--input",
            str(path),
            "--output",
            str(tmp_path / "sdk"),
        ],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert run.returncode == 0 and "Warning" not in run.stdout + run.stderr, run.stdout + run.stderr
    back = load_gltf_rig(tmp_path / "sdk.glb")
    assert back.skeleton.joint_names == rig.skeleton.joint_names
    idx, dist = _nearest(rig.rest_vertices, back.rest_vertices)
    assert dist.max() < 1e-6
    np.testing.assert_allclose(back.weights, rig.weights[idx], atol=1e-6)
    read, _ = load_gltf_motion(tmp_path / "sdk.glb", fps=30.0)
    np.testing.assert_allclose(read.global_positions(), motion.global_positions(), atol=FK_TOL)
