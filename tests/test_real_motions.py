"""The second real mocap source (data/real_motions): present, intact, upright, on the floor."""

from pathlib import Path

import numpy as np
import pytest

from retarget_lib.core.ground import clip_floor, foot_positions, sole_heights, standing_feet
from retarget_lib.core.skeleton import J
from retarget_lib.data.sources import real_motions
from retarget_lib.data.sources.real_characters import load_real_character, real_character_names
from retarget_lib.data.sources.real_motions import (
    load_real_motion,
    real_motion_names,
    real_motion_path,
)
from retarget_lib.evaluation.real import CLIP_FRAMES, ROM_START
from retarget_lib.files import DataError
from retarget_lib.io.bvh import load_bvh, save_bvh
from retarget_lib.io.fbx import fbx_missing
from retarget_lib.io.gltf import load_gltf_animation
from retarget_lib.methods.registry import get_method
from retarget_lib.methods.retarget import on_the_ground


def test_the_range_of_motion_clip_reads_as_a_standing_person():
    assert real_motion_names() == ["motion_capture_rom"]
    raw = load_bvh(real_motion_path("motion_capture_rom"), unit="inch")
    assert raw.num_frames == 272 and raw.fps == pytest.approx(6.0)  # keys every 5 frames at 30 fps
    assert (
        raw.skeleton.joint_names[0] == "Bip01"
        and "Bip01 L Oberschenkel" in raw.skeleton.joint_names
    )
    m = load_real_motion("motion_capture_rom")
    # 45.2 s at 30 fps (the duration of 272 keys at 6 per second), 1.4-1.7 m tall in inches
    assert m.fps == 30 and m.num_frames == 1356 and 1.4 < m.skeleton.height() < 1.7
    pos = m.global_positions()
    upright = pos[:, J["Head"], 1] > pos[:, J["Hips"], 1] + 0.3
    assert (
        upright.mean() > 0.8 and upright[ROM_START : ROM_START + CLIP_FRAMES].all()
    )  # bends down once (25 s)
    soles = sole_heights(pos, m.skeleton)
    floor = clip_floor(soles)
    on_floor = (soles.min(axis=1) - floor) < 0.03  # a foot within 3 cm of the clip's floor
    assert on_floor.mean() > 0.9, on_floor.mean()
    assert np.ptp(pos[:, J["Hips"], 1]) < 0.5  # a range-of-motion capture: no jumps


def test_a_changed_file_is_refused_by_name(tmp_path, monkeypatch):
    copy = tmp_path / "motion_capture_rom.bvh"
    copy.write_bytes(
        real_motion_path("motion_capture_rom").read_bytes().replace(b"Frames: 272", b"Frames: 271")
    )
    monkeypatch.setattr(real_motions, "MOTIONS_DIR", tmp_path)
    with pytest.raises(DataError, match=r"motion_capture_rom.bvh does not match its sha256"):
        load_real_motion("motion_capture_rom")
    with pytest.raises(
        DataError, match="unknown real motion 'walk'; known: \\['motion_capture_rom'\\]"
    ):
        load_real_motion("walk")


@pytest.mark.parametrize("name", real_character_names())
def test_the_range_of_motion_clip_stands_on_every_real_characters_floor(name):
    # issue 28's bound: where the source stands, the target's feet are on its floor within 3 cm;
    # here a foot joint standing in the source is within 3 cm of the target's floor (its rest mesh's
    # soles) in at least 99 % of such frames (the measured worst is 99.4 %, a Quaternius rig)
    source = load_real_motion("motion_capture_rom")
    pos = source.global_positions()
    soles = sole_heights(pos, source.skeleton)
    standing = standing_feet(
        foot_positions(pos, source.skeleton),
        soles,
        clip_floor(soles),
        source.skeleton.height(),
        source.fps,
    )
    character = load_real_character(name).character()
    result = on_the_ground(
        get_method("copy-rest").retargeter()(source, character.skeleton), source, character
    )
    assert result.num_frames == source.num_frames
    target = sole_heights(result.global_positions(), result.skeleton, character.rest_vertices)
    best = np.where(standing, np.abs(target), np.inf).min(axis=1)[standing.any(axis=1)]
    assert standing.any(axis=1).mean() > 0.8 and (best < 0.03).mean() >= 0.99, (best < 0.03).mean()


def test_the_range_of_motion_clip_round_trips_through_bvh(tmp_path):
    raw = load_bvh(real_motion_path("motion_capture_rom"), unit="inch")
    out = tmp_path / "rom.bvh"
    save_bvh(raw, out, unit="inch")
    back = load_bvh(out, unit="inch")
    assert back.num_frames == raw.num_frames and back.fps == raw.fps
    assert back.skeleton.joint_names == raw.skeleton.joint_names
    # 6-decimal text in inches: 1e-6 inch, through FK of ~25 joints with 6-decimal angles
    np.testing.assert_allclose(back.global_positions(), raw.global_positions(), atol=1e-5)


ASE = Path("/usr/share/assimp/models/ASE/MotionCaptureROM.ase")


@pytest.mark.skipif(
    fbx_missing() is not None or not ASE.is_file(),
    reason="needs the fbx extra (assimp) and assimp-testmodels' MotionCaptureROM.ase",
)
def test_the_original_capture_reads_through_gltf_as_shipped(tmp_path):
    """The real file in its own format (3ds Max ASE), converted to a skinless glTF clip by assimp
    as ``tools/real_motions.py`` does, reads as the shipped BVH: the glTF clip path on real
    mocap."""
    impasse = pytest.importorskip("impasse")  # the fbx extra's binding of assimp
    scene = impasse.load(str(ASE))
    glb = tmp_path / "rom.glb"
    glb.write_bytes(bytes(impasse.export_blob(scene, "glb2")[0].data))
    path = real_motion_path("motion_capture_rom")
    motion, _ = load_gltf_animation(glb, mapping=path.with_suffix(".joints.yaml"))
    shipped = load_bvh(path, unit="m")  # the file's numbers (inches), as the tool wrote them
    assert motion.num_frames == shipped.num_frames == 272 and motion.fps == pytest.approx(6.0)
    assert motion.skeleton.joint_names == shipped.skeleton.joint_names
    # float32 glTF against 6-decimal BVH text, in file units of ~1-60
    np.testing.assert_allclose(motion.global_positions(), shipped.global_positions(), atol=1e-4)
