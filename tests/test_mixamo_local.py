"""mixamo-local: a fixture written in the exact Mixamo download layout loads back correctly."""

import numpy as np
import pytest

from retarget_lib.data import manifest
from retarget_lib.data.sources.mixamo_local import load_mixamo_motion, scan_mixamo_folder
from retarget_lib.data.status import check_sources
from retarget_lib.data.synthetic.dataset import load_synthetic
from retarget_lib.files import DataError
from retarget_lib.io import load_bvh, load_shape_npz
from retarget_lib.data.sources.mixamo_fixture import write_mixamo_character


@pytest.fixture(scope="module")
def fixture_dir(tmp_path_factory):
    ds = load_synthetic()
    root = tmp_path_factory.mktemp("mixamo")
    clips = [ds.family("walk")[0], ds.family("clap")[0]]
    for clip in clips:
        character = ds.characters[clip.performer]
        write_mixamo_character(root, character, [clip.motion.slice(0, 60)])
    return root, clips, ds


@pytest.mark.data
def test_layout_names_and_units(fixture_dir):
    root, clips, _ = fixture_dir
    found = scan_mixamo_folder(root)
    assert sorted(f.name for f in found) == sorted({c.performer for c in clips})
    folder = found[0]
    assert folder.shape is not None and folder.shape.name == "shape.npz"
    text = next(iter(folder.motions.values())).read_text()
    for token in ("ROOT mixamorig:Hips", "mixamorig:HeadTop_End", "mixamorig:LeftHandIndex3",
                  "mixamorig:RightHandPinky4", "End Site"):
        assert token in text
    raw = load_bvh(next(iter(folder.motions.values())))
    assert raw.skeleton.num_joints == 22 + 1 + 2 + 2 * 5 * 4
    assert raw.meta["unit"] == "cm"


@pytest.mark.data
def test_motion_folds_back_to_the_original(fixture_dir):
    root, clips, ds = fixture_dir
    for clip in clips:
        path = root / clip.performer / f"{clip.name}.bvh"
        m = load_mixamo_motion(path)
        assert m.skeleton.is_canonical22() and m.num_frames == 60
        np.testing.assert_allclose(m.global_positions(), clip.motion.slice(0, 60).global_positions(), atol=2e-5)


@pytest.mark.data
def test_shape_npz_loads_as_the_character(fixture_dir):
    root, clips, ds = fixture_dir
    ch = ds.characters[clips[0].performer]
    back = load_shape_npz(root / ch.name / "shape.npz")
    np.testing.assert_allclose(back.skeleton.offsets, ch.skeleton.offsets, atol=1e-6)
    np.testing.assert_allclose(back.rest_vertices, ch.rest_vertices, atol=1e-6)
    np.testing.assert_allclose(back.weights.sum(1), 1.0, atol=1e-6)


@pytest.mark.data
def test_manifest_sees_the_folder(fixture_dir, monkeypatch, tmp_path):
    root, _, _ = fixture_dir
    monkeypatch.setenv("RETARGET_MIXAMO", str(root))
    status = {s.id: s for s in check_sources()}["mixamo-local"]
    assert status.present and status.verified and "2 characters" in status.detail
    monkeypatch.setenv("RETARGET_MIXAMO", str(tmp_path / "nowhere"))
    status = {s.id: s for s in check_sources()}["mixamo-local"]
    assert not status.present and "optional" in status.detail
    with pytest.raises(DataError, match="RETARGET_MIXAMO"):
        scan_mixamo_folder(tmp_path / "nowhere")


def test_manifest_lists_both_papers_test_lists():
    lists = manifest.source("mixamo-local")["test_lists"]
    assert len(lists["contact"]["motions"]) == 30
    assert lists["contact"]["skinny_targets"] == ["Kaya", "Malcolm", "Liam"]
    assert set(lists["tdcn"]["scenarios"]) == {"1_seen_motion_seen_character", "2_seen_motion_unseen_character",
                                               "3_unseen_motion_seen_character", "4_unseen_motion_unseen_character"}
