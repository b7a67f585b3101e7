"""`retarget retarget` with GLB/glTF characters, SMPL-X/AMASS motion and skinned GLB output (issue
12).

No built data needed: the sources are the shipped AMASS-format clip and GLB files written here from
the synthetic characters. Every GLB the command writes passes the Khronos validator.
"""

import numpy as np
import pytest
from skeletons import assert_same_up_to_floor_shift
from test_bad_inputs import assert_cli_error
from test_gltf import _unreal_rig, assert_valid

from retarget_lib.cli import main
from retarget_lib.core.rig import Rig
from retarget_lib.core.transfer import retarget_ground_truth
from retarget_lib.data.synthetic.amass_clip import AMASS_CLIP_PATH
from retarget_lib.data.synthetic.characters import make_character
from retarget_lib.data.synthetic.motions import make_motion
from retarget_lib.io import load_bvh, save_glb
from retarget_lib.io.amass import load_amass, save_amass
from retarget_lib.io.gltf import load_gltf_motion, load_gltf_rig
from retarget_lib.io.rig_maps import map_joints
from retarget_lib.skeleton import fold_to_canonical22, to_canonical22


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    folder = tmp_path_factory.mktemp("formats")
    kato = Rig.from_character(make_character("kato"))
    save_glb(kato, folder / "kato.glb")
    manny, _ = _unreal_rig(make_character("gus"))  # Unreal names, a root above the pelvis, fingers
    save_glb(manny, folder / "manny.glb")
    hana = make_character("hana")
    save_glb(
        Rig.from_character(hana),
        folder / "hana_wave.glb",
        make_motion("wave", hana.skeleton, 0, 1.5),
    )
    clip = load_amass(AMASS_CLIP_PATH)
    save_amass(clip.slice(0, 40), folder / "walk40.npz", clip.meta["betas"])
    return folder


def test_amass_source_to_a_glb_character_writes_a_valid_skinned_glb(files, tmp_path):
    out = tmp_path / "walk_manny.glb"
    assert (
        main(
            [
                "retarget",
                "--source",
                str(AMASS_CLIP_PATH),
                "--target",
                str(files / "manny.glb"),
                "--method",
                "copy-rest",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    assert_valid(out)
    motion, rig = load_gltf_motion(out)
    target = load_gltf_rig(files / "manny.glb")
    assert rig.skeleton.joint_names == target.skeleton.joint_names  # fingers, root, spine_04 kept
    np.testing.assert_allclose(rig.rest_vertices, target.rest_vertices, atol=1e-6)
    assert motion.num_frames == 120 and motion.fps == 30.0
    expected = retarget_ground_truth(load_amass(AMASS_CLIP_PATH), target.character().skeleton)
    # float32 file; the root moves vertically by the ground rule only (AMASS's floor onto the
    # target's)
    assert_same_up_to_floor_shift(
        rig.motion_to_canonical(motion).global_positions(), expected.global_positions(), atol=1e-4
    )


def test_glb_source_and_bvh_output_on_the_glb_targets_joints(files, tmp_path):
    out = tmp_path / "wave_manny.bvh"
    assert (
        main(
            [
                "retarget",
                "--source",
                str(files / "hana_wave.glb"),
                "--target",
                str(files / "manny.glb"),
                "--method",
                "copy-rest",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    written = load_bvh(out)
    assert written.skeleton.joint_names[:2] == ("root", "pelvis") and written.num_frames == 45
    source, _ = load_gltf_motion(files / "hana_wave.glb")
    expected = retarget_ground_truth(
        to_canonical22(source), load_gltf_rig(files / "manny.glb").character().skeleton
    )
    joint_map, rig = map_joints(
        written.skeleton.joint_names, written.skeleton.parents
    )  # BVH order is the file's
    assert rig == "unreal"
    got = fold_to_canonical22(written, joint_map)
    assert_same_up_to_floor_shift(
        got.global_positions(), expected.global_positions(), atol=2e-4
    )  # BVH text


def test_a_source_without_a_skin_is_read_as_motion_only(files, tmp_path):
    """A clip downloaded "Without Skin" (joints and animation, no mesh) is a valid source."""
    hana = make_character("hana")
    motion = make_motion("wave", hana.skeleton, 0, 1.5)
    bare = tmp_path / "hana_wave_bare.glb"
    save_glb(Rig.from_character(hana), bare, motion, skin=False)
    a, b = tmp_path / "bare.bvh", tmp_path / "skinned.bvh"
    for src, out in ((bare, a), (files / "hana_wave.glb", b)):
        assert (
            main(
                [
                    "retarget",
                    "--source",
                    str(src),
                    "--target",
                    "kato",
                    "--method",
                    "copy-rest",
                    "--out",
                    str(out),
                ]
            )
            == 0
        )
    np.testing.assert_allclose(
        load_bvh(a).global_positions(), load_bvh(b).global_positions(), atol=1e-6
    )


@pytest.mark.slow
def test_contact_uses_the_target_files_own_mesh(files, tmp_path):
    out = tmp_path / "walk_kato.glb"
    assert (
        main(
            [
                "retarget",
                "--source",
                str(files / "walk40.npz"),
                "--target",
                str(files / "kato.glb"),
                "--method",
                "contact",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    assert_valid(out)
    motion, _ = load_gltf_motion(out)
    assert motion.num_frames == 40


def test_bad_files_exit_2_with_one_line(files, tmp_path, capsys):
    no_skin = "/usr/share/assimp/models/glTF2/BoxTextured-glTF-Binary/BoxTextured.glb"
    assert_cli_error(
        capsys,
        [
            "retarget",
            "--source",
            str(AMASS_CLIP_PATH),
            "--target",
            no_skin,
            "--method",
            "copy",
            "--out",
            str(tmp_path / "o.glb"),
        ],
        "BoxTextured.glb",
        "no skin",
    )
    odd = "/usr/share/assimp/models/glTF2/simple_skin/simple_skin.gltf"
    assert_cli_error(
        capsys,
        [
            "retarget",
            "--source",
            str(AMASS_CLIP_PATH),
            "--target",
            odd,
            "--method",
            "copy",
            "--out",
            str(tmp_path / "o.bvh"),
        ],
        "simple_skin.gltf",
        "cannot map joints",
        "--joint-map",
    )
    data = dict(np.load(AMASS_CLIP_PATH))
    del data["betas"]
    np.savez(tmp_path / "nobetas.npz", **data)
    assert_cli_error(
        capsys,
        [
            "retarget",
            "--source",
            str(tmp_path / "nobetas.npz"),
            "--target",
            "kato",
            "--method",
            "copy",
            "--out",
            str(tmp_path / "o.bvh"),
        ],
        "nobetas.npz",
        "no 'betas'",
    )
    bvh = tmp_path / "kato.bvh"
    assert (
        main(
            [
                "retarget",
                "--source",
                str(AMASS_CLIP_PATH),
                "--target",
                "kato",
                "--method",
                "copy",
                "--out",
                str(bvh),
            ]
        )
        == 0
    )
    assert_cli_error(
        capsys,
        [
            "retarget",
            "--source",
            str(AMASS_CLIP_PATH),
            "--target",
            str(bvh),
            "--method",
            "copy",
            "--out",
            str(tmp_path / "o.glb"),
        ],
        "o.glb",
        "has none",
    )
    assert not (tmp_path / "o.glb").exists()


def test_mapping_file_on_the_command_line(files, tmp_path, capsys):
    mapping = tmp_path / "manny.yaml"
    mapping.write_text("Neck: spine_04\n")  # the neck starts lower; neck_01 then follows it
    out = tmp_path / "o.bvh"
    assert (
        main(
            [
                "retarget",
                "--source",
                str(AMASS_CLIP_PATH),
                "--target",
                str(files / "manny.glb"),
                "--method",
                "copy",
                "--joint-map",
                str(mapping),
                "--out",
                str(out),
            ]
        )
        == 0
    )
    mapping.write_text("Spine2: spine_04\n")  # the clavicles hang from spine_03, above it
    assert_cli_error(
        capsys,
        [
            "retarget",
            "--source",
            str(AMASS_CLIP_PATH),
            "--target",
            str(files / "manny.glb"),
            "--method",
            "copy",
            "--joint-map",
            str(mapping),
            "--out",
            str(out),
        ],
        "manny.glb",
        "'clavicle_l' (mapped to LeftShoulder) is not below 'spine_04'",
    )
    assert_cli_error(
        capsys,
        [
            "retarget",
            "--source",
            str(AMASS_CLIP_PATH),
            "--target",
            "kato",
            "--method",
            "copy",
            "--joint-map",
            str(mapping),
            "--out",
            str(out),
        ],
        "manny.yaml",
        "--joint-map is for",
    )
