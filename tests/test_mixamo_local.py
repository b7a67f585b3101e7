"""mixamo-local: a fixture written in the exact Mixamo download layout loads back correctly, in
every format of a download (BVH, GLB and FBX clips; shape.npz, GLB and FBX character files)."""

import numpy as np
import pytest

from retarget_lib.cli import main
from retarget_lib.core.character import Character
from retarget_lib.core.rig import Rig
from retarget_lib.core.skeleton import canonical22_skeleton
from retarget_lib.data import manifest
from retarget_lib.data.sources.mixamo_fixture import (
    extend_motion_to_mixamo,
    mixamo_rig,
    write_mixamo_character,
)
from retarget_lib.data.sources.mixamo_local import (
    load_mixamo_folder,
    load_mixamo_motion,
    scan_mixamo_folder,
)
from retarget_lib.data.status import check_sources
from retarget_lib.data.synthetic.characters import make_character
from retarget_lib.data.synthetic.dataset import load_synthetic
from retarget_lib.data.synthetic.motions import make_motion
from retarget_lib.errors import FBXError, GLTFError, MixamoFolderError
from retarget_lib.files import DataError
from retarget_lib.io import load_bvh, load_shape_npz
from retarget_lib.io.fbx import fbx_missing
from retarget_lib.io.fbx_write import save_fbx

pytestmark = pytest.mark.tooling  # nothing here depends on the thread count (make unit-threads)


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
    for token in (
        "ROOT mixamorig:Hips",
        "mixamorig:HeadTop_End",
        "mixamorig:LeftHandIndex3",
        "mixamorig:RightHandPinky4",
        "End Site",
    ):
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
        np.testing.assert_allclose(
            m.global_positions(), clip.motion.slice(0, 60).global_positions(), atol=2e-5
        )


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
    assert set(lists["tdcn"]["scenarios"]) == {
        "1_seen_motion_seen_character",
        "2_seen_motion_unseen_character",
        "3_unseen_motion_seen_character",
        "4_unseen_motion_unseen_character",
    }


# --- the folder in the formats of a real download: FBX/GLB clips, FBX/GLB character files
# -----------


def _clip(character, family="walk", frames=20, name="Walking", seed=3):
    motion = make_motion(family, character.skeleton, seed, duration=(frames + 1) / 30.0).slice(
        0, frames
    )
    motion.name = name
    return motion


@pytest.fixture(scope="module")
def formats_dir(tmp_path_factory):
    """One character written three ways: BVH + shape.npz (the reference), GLB clips without a skin
    + a T-pose ``<Character>.glb``, GLB clips that carry the skin and no other mesh file."""
    cleo = make_character("cleo")
    clips = [_clip(cleo), _clip(cleo, "clap", 30, "Sitting Clap", seed=8)]
    root = tmp_path_factory.mktemp("formats")
    for name, clip_format, mesh in (
        ("Ref", "bvh", "shape"),
        ("Glb", "glb", "glb"),
        ("Skinned", "glb-skinned", "none"),
    ):
        write_mixamo_character(
            root, cleo.copy(), clips, name=name, clip_format=clip_format, mesh=mesh
        )
    return root, cleo


def test_glb_clips_and_character_files_read_like_bvh_and_shape(formats_dir):
    root, cleo = formats_dir
    found = {f.name: f for f in scan_mixamo_folder(root)}
    assert set(found["Glb"].motions) == set(found["Ref"].motions) == {"Walking", "Sitting Clap"}
    # the T-pose character file is the mesh, not a motion
    assert found["Glb"].character_file.name == "Glb.glb" and found["Glb"].shape is None
    assert found["Skinned"].character_file is None and found["Skinned"].shape is None
    folder = load_mixamo_folder(root)
    for name in ("Glb", "Skinned"):
        for motion in ("Walking", "Sitting Clap"):
            got, ref = folder.clips[name, motion], folder.clips["Ref", motion]
            assert (
                got.skeleton.is_canonical22()
                and got.num_frames == ref.num_frames
                and got.fps == ref.fps
            )
            # GLB stores float32 metres, the BVH 6 decimals of cm: both ~1e-7 m
            np.testing.assert_allclose(got.global_positions(), ref.global_positions(), atol=1e-6)
        character, reference = folder.character(name), folder.character("Ref")
        assert character.name == name
        np.testing.assert_allclose(
            character.skeleton.offsets, reference.skeleton.offsets, atol=1e-6
        )
        np.testing.assert_allclose(
            character.rest_vertices, reference.rest_vertices, atol=1e-6
        )  # float32 metres
        np.testing.assert_allclose(
            character.weights, reference.weights, atol=1e-6
        )  # float32 weights
        np.testing.assert_array_equal(character.faces, cleo.faces)
    # mesh files: the character file, else the first clip (by motion name) that carries a skin
    assert folder.mesh_file("Glb").name == "Glb.glb"
    assert folder.mesh_file("Skinned").name == "Sitting Clap.glb"
    assert folder.mesh_file("Ref").name == "shape.npz"
    assert folder.clip_path("Glb", "Walking").name == "Walking.glb"
    assert folder.clip_path("Ref", "Walking").name == "Walking.bvh"
    with pytest.raises(KeyError, match="no clip of 'Jumping' by 'Ref'"):
        folder.clip_path("Ref", "Jumping")


def test_a_character_without_any_mesh(tmp_path):
    """Skinless GLB clips and no mesh file: the clips load, the character has no mesh."""
    cleo = make_character("cleo")
    write_mixamo_character(
        tmp_path, cleo, [_clip(cleo)], name="Kaya", clip_format="glb", mesh="none"
    )
    folder = load_mixamo_folder(tmp_path)
    assert folder.clips["Kaya", "Walking"].num_frames == 20
    assert folder.character("Kaya") is None and folder.mesh_file("Kaya") is None


def test_layout_errors_name_the_files(tmp_path, capsys):
    cleo = make_character("cleo")
    write_mixamo_character(tmp_path, cleo, [_clip(cleo)], name="Kaya")
    write_mixamo_character(
        tmp_path, cleo, [_clip(cleo)], name="Kaya", clip_format="glb", mesh="glb"
    )
    with pytest.raises(
        MixamoFolderError, match=r"Kaya/Walking.glb: motion 'Walking' is also in Walking.bvh"
    ):
        scan_mixamo_folder(tmp_path)
    (tmp_path / "Kaya" / "Walking.glb").unlink()
    (tmp_path / "Kaya" / "T-Pose.glb").write_bytes((tmp_path / "Kaya" / "Kaya.glb").read_bytes())
    with pytest.raises(
        MixamoFolderError, match=r"Kaya: 2 character files \(Kaya.glb, T-Pose.glb\); keep one"
    ):
        scan_mixamo_folder(tmp_path)
    (tmp_path / "Kaya" / "T-Pose.glb").unlink()
    # a malformed clip: the reader's error names it, and the command line says so on one line,
    # status 2
    (tmp_path / "Kaya" / "Broken.glb").write_bytes(b"glTF\x02\x00\x00\x00\xff\xff\x00\x00")
    with pytest.raises(GLTFError, match=r"Kaya/Broken.glb: truncated GLB"):
        load_mixamo_folder(tmp_path)
    assert (
        main(
            [
                "evaluate",
                "--table",
                "tdcn",
                "--data",
                "mixamo-local",
                "--mixamo",
                str(tmp_path),
                "--methods",
                "copy",
                "--out",
                str(tmp_path / "out"),
            ]
        )
        == 2
    )
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Broken.glb: truncated GLB" in err


@pytest.mark.skipif(fbx_missing() is not None, reason=f"fbx extra not installed: {fbx_missing()}")
def test_fbx_clips_and_character_files(tmp_path):
    """The fixture's FBX variant (binary FBX in centimetres, written by ``save_fbx``, read through
    assimp): a T-pose ``<Character>.fbx`` beside BVH clips, and skinned FBX clips (at 60 fps, read
    at the file's rate) whose first clip gives the mesh; both read like BVH + shape.npz."""
    cleo = make_character("cleo")
    walk, clap = _clip(cleo), _clip(cleo, "clap", 30, "Sitting Clap", seed=8)
    write_mixamo_character(tmp_path, cleo.copy(), [walk, clap], name="Ref")
    write_mixamo_character(tmp_path, cleo.copy(), [walk, clap], name="Kaya", mesh="fbx")
    write_mixamo_character(
        tmp_path, cleo.copy(), [walk, clap], name="Claire", clip_format="fbx", mesh="none", fps=60.0
    )
    folder = load_mixamo_folder(tmp_path)
    assert (
        folder.mesh_file("Kaya").name == "Kaya.fbx"
        and folder.mesh_file("Claire").name == "Sitting Clap.fbx"
    )
    for motion in ("Walking", "Sitting Clap"):
        got, ref = folder.clips["Claire", motion], folder.clips["Ref", motion]
        assert got.fps == 60.0 and got.num_frames == 2 * ref.num_frames - 1
        # 60 fps frames 2k are the 30 fps frames k; float32 centimetres: ~1e-6 m
        np.testing.assert_allclose(got.global_positions()[::2], ref.global_positions(), atol=1e-5)
    reference = folder.character("Ref")
    for name in ("Kaya", "Claire"):
        character = folder.character(name)
        assert character.name == name
        np.testing.assert_allclose(
            character.skeleton.offsets, reference.skeleton.offsets, atol=1e-5
        )
        # assimp may reorder vertices: compare them sorted
        np.testing.assert_allclose(
            np.sort(character.rest_vertices, axis=0),
            np.sort(reference.rest_vertices, axis=0),
            atol=1e-5,
        )


def test_a_glb_in_centimetres_is_read_in_metres(tmp_path):
    """An FBX/GLB whose skeleton is 100 times too tall (assimp keeps an FBX's centimetres) is scaled
    to metres, as shape.npz files are: no character is 5 m tall."""
    cleo = make_character("cleo")
    walk = _clip(cleo)
    cm = Character(
        "Cm",
        canonical22_skeleton(cleo.skeleton.offsets * 100),
        cleo.rest_vertices * 100,
        cleo.faces,
        cleo.weights,
    )
    walk_cm = walk.copy(skeleton=cm.skeleton, root_positions=walk.root_positions * 100)
    write_mixamo_character(tmp_path, cm, [walk_cm], clip_format="glb", mesh="glb")
    folder = load_mixamo_folder(tmp_path)
    got = folder.clips["Cm", "Walking"]
    np.testing.assert_allclose(
        got.global_positions(), walk.global_positions(), atol=1e-5
    )  # float32 of ~100 units
    character = folder.character("Cm")
    np.testing.assert_allclose(character.rest_vertices, cleo.rest_vertices, atol=1e-5)
    np.testing.assert_allclose(character.skeleton.offsets, cleo.skeleton.offsets, atol=1e-5)


def test_fbx_clips_without_the_fbx_extra_name_the_file(tmp_path, monkeypatch):
    import retarget_lib.io.fbx as fbx

    def missing():
        raise FBXError(
            "FBX needs the Open Asset Import Library (ImportError: no impasse); install the fbx "
            "extra"
        )

    monkeypatch.setattr(fbx, "_impasse", missing)
    (tmp_path / "Kaya").mkdir()
    (tmp_path / "Kaya" / "Walking.fbx").write_bytes(b"Kaydara FBX Binary  \x00")
    with pytest.raises(
        FBXError, match=r"Kaya/Walking.fbx: FBX needs the Open Asset Import Library .*fbx extra"
    ):
        load_mixamo_folder(tmp_path)


def test_a_character_with_a_mesh_and_no_clip_is_listed(tmp_path):
    """A target whose mesh is there but none of whose clips is: it is a character of the folder
    (its mesh loads), and the coverage can say "no clip" rather than "no mesh"."""
    cleo = make_character("cleo")
    write_mixamo_character(tmp_path, cleo, [_clip(cleo)], name="Kaya")
    write_mixamo_character(tmp_path, cleo, [], name="Ortiz", mesh="glb")
    (tmp_path / "Empty").mkdir()
    found = {f.name: f for f in scan_mixamo_folder(tmp_path)}
    assert set(found) == {"Kaya", "Ortiz"} and found["Ortiz"].motions == {}
    assert load_mixamo_folder(tmp_path).character("Ortiz") is not None
    (tmp_path / "Kaya" / "Walking.bvh").unlink()
    with pytest.raises(DataError, match="no <Character>/<Motion>.bvh"):
        scan_mixamo_folder(tmp_path)


@pytest.mark.skipif(fbx_missing() is not None, reason=f"fbx extra not installed: {fbx_missing()}")
def test_an_fbx_clip_without_a_skin(tmp_path):
    """A "Without Skin" FBX: written with an empty mesh, which assimp drops, so the file holds the
    armature and its animation only. Its joints are the animated nodes; it gives no mesh."""
    cleo = make_character("cleo")
    walk = _clip(cleo)
    rig = mixamo_rig(cleo)
    bare = Rig(
        "bare",
        rig.skeleton,
        np.zeros((0, 3)),
        np.zeros((0, 3), int),
        np.zeros((0, rig.skeleton.num_joints)),
        rig.joint_map,
    )
    (tmp_path / "Kaya").mkdir()
    save_fbx(
        bare,
        tmp_path / "Kaya" / "Walking.fbx",
        extend_motion_to_mixamo(walk),
        unit_scale_factor=1.0,
    )
    folder = load_mixamo_folder(tmp_path)
    got = folder.clips["Kaya", "Walking"]
    assert got.num_frames == walk.num_frames and got.fps == walk.fps
    np.testing.assert_allclose(
        got.global_positions(), walk.global_positions(), atol=1e-6
    )  # float32 cm
    assert folder.character("Kaya") is None
