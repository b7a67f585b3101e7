"""The second real mocap source (data/real_motions): present, intact, upright, on the floor."""

import numpy as np
import pytest

from retarget_lib.core.ground import clip_floor, sole_heights
from retarget_lib.core.skeleton import J
from retarget_lib.data.sources import real_motions
from retarget_lib.data.sources.real_motions import load_real_motion, real_motion_names, real_motion_path
from retarget_lib.evaluation.real import CLIP_FRAMES, ROM_START
from retarget_lib.files import DataError
from retarget_lib.io.bvh import load_bvh


def test_the_range_of_motion_clip_reads_as_a_standing_person():
    assert real_motion_names() == ["motion_capture_rom"]
    raw = load_bvh(real_motion_path("motion_capture_rom"), unit="inch")
    assert raw.num_frames == 272 and raw.fps == pytest.approx(6.0)  # keys every 5 frames at 30 fps
    assert raw.skeleton.joint_names[0] == "Bip01" and "Bip01 L Oberschenkel" in raw.skeleton.joint_names
    m = load_real_motion("motion_capture_rom")
    # 45.2 s at 30 fps (the duration of 272 keys at 6 per second), 1.4-1.7 m tall in inches
    assert m.fps == 30 and m.num_frames == 1356 and 1.4 < m.skeleton.height() < 1.7
    pos = m.global_positions()
    upright = pos[:, J["Head"], 1] > pos[:, J["Hips"], 1] + 0.3
    assert upright.mean() > 0.8 and upright[ROM_START:ROM_START + CLIP_FRAMES].all()  # bends down once (25 s)
    soles = sole_heights(pos, m.skeleton)
    floor = clip_floor(soles)
    on_floor = (soles.min(axis=1) - floor) < 0.03  # a foot within 3 cm of the clip's floor
    assert on_floor.mean() > 0.9, on_floor.mean()
    assert np.ptp(pos[:, J["Hips"], 1]) < 0.5  # a range-of-motion capture: no jumps


def test_a_changed_file_is_refused_by_name(tmp_path, monkeypatch):
    copy = tmp_path / "motion_capture_rom.bvh"
    copy.write_bytes(real_motion_path("motion_capture_rom").read_bytes().replace(b"Frames: 272", b"Frames: 271"))
    monkeypatch.setattr(real_motions, "MOTIONS_DIR", tmp_path)
    with pytest.raises(DataError, match=r"motion_capture_rom.bvh does not match its sha256"):
        load_real_motion("motion_capture_rom")
    with pytest.raises(DataError, match="unknown real motion 'walk'; known: \\['motion_capture_rom'\\]"):
        load_real_motion("walk")
