"""Joint maps for every format (BVH included), joints a rig does not have (``null``), complete
errors, and the examples of docs/joint-maps.md (issue 28)."""

import ast
import re
from pathlib import Path

import numpy as np
import pytest
import torch
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st
from test_bad_inputs import assert_cli_error

from retarget_lib.cli import main
from retarget_lib.core.canonical import stand_upright
from retarget_lib.core.motion import Motion
from retarget_lib.core.rotations import quat_conjugate, quat_from_axis_angle, quat_mul
from retarget_lib.core.skeleton import CANONICAL22, CANONICAL22_PARENTS, J, JointSetError, Skeleton
from retarget_lib.core.virtual_joints import MAY_BE_ABSENT, with_virtual_joints
from retarget_lib.data.sources.cmu import cmu_clip_path
from retarget_lib.data.sources.real_characters import joint_map_path, real_character_path
from retarget_lib.data.synthetic.amass_clip import AMASS_CLIP_PATH
from retarget_lib.data.synthetic.characters import make_character
from retarget_lib.io import load_bvh, save_bvh
from retarget_lib.io.amass import load_amass
from retarget_lib.io.gltf import load_gltf_motion, load_gltf_rig
from retarget_lib.io.joint_maps import present_map, to_canonical22
from retarget_lib.io.rig_maps import RIG_MAPS, load_mapping_file, map_joints
from retarget_lib.io.shape import save_shape_npz
from retarget_lib.methods.copy import copy_rotations
from retarget_lib.methods.inputs import load_source, load_target

DOC = Path(__file__).resolve().parents[1] / "docs" / "joint-maps.md"


def doc_examples() -> dict[str, dict]:
    """``{section title: map}`` of every YAML block under a ``###`` heading of the doc."""
    text = DOC.read_text(encoding="utf-8")
    out = {}
    for title, body in re.findall(r"^### (.+?)\n(.*?)(?=^### |\Z)", text, flags=re.S | re.M):
        block = re.search(r"```yaml\n(.*?)```", body, flags=re.S)
        if block:
            out[title.strip()] = yaml.safe_load(block.group(1))
    return out


@pytest.fixture(scope="module")
def clip():
    """Two seconds of CMU 01_01 on the canonical 22 joints at 30 fps, the methods' rate (the joint
    names are renamed below)."""
    return to_canonical22(load_bvh(cmu_clip_path("01_01.bvh")).slice(0, 240)).resample(30.0)


def rig_clip(clip: Motion, mapping: dict) -> Motion:
    """``clip`` on a rig named and shaped by ``mapping``: canonical joints renamed, the ``null``
    ones removed (their children re-attached to the nearest kept ancestor), every kept joint in the
    same world place and orientation in every frame."""
    sk = clip.skeleton
    keep = [n for n in CANONICAL22 if mapping.get(n, n) is not None]
    rest = sk.rest_positions()
    parents = []
    for n in keep:
        p = sk.parents[sk.index(n)]
        while p >= 0 and CANONICAL22[p] not in keep:
            p = sk.parents[p]
        parents.append(keep.index(CANONICAL22[p]) if p >= 0 else -1)
    offsets = np.array(
        [
            rest[sk.index(n)] - (rest[sk.index(keep[p])] if p >= 0 else 0.0)
            for n, p in zip(keep, parents, strict=False)
        ]
    )
    offsets[0] = sk.offsets[0]
    _, grot = clip.fk()
    g = torch.from_numpy(grot[:, [sk.index(n) for n in keep]])
    local = g.clone()
    for k, p in enumerate(parents):
        if p >= 0:
            local[:, k] = quat_mul(quat_conjugate(g[:, p]), g[:, k])
    names = tuple(mapping.get(n, n) for n in keep)
    return Motion(
        Skeleton(names, tuple(parents), offsets),
        local.numpy(),
        clip.root_positions.copy(),
        clip.fps,
    )


BANDAI = doc_examples()["Bandai-Namco Research Motion dataset (BVH)"]
SMALL = doc_examples()["A game rig with two spine joints, no clavicles and no toes"]


# ----------------------------------------------------------------------------- the doc's examples
#: the doc's example of each convention of the one table (io.rig_maps.RIG_MAPS)
CONVENTION_OF_EXAMPLE = {
    "Mixamo": "mixamo",
    "Unreal mannequin (UE4/UE5)": "unreal",
    "Rigify (Blender)": "rigify",
    "VRoid (VRM)": "vroid",
    "SMPL / SMPL-H exports": "smpl",
    "CMU (cgspeed BVH conversion)": "cmu",
    "Biovision / MotionBuilder (BVH, 21 joints)": "biovision",
    "SMPL-X body joints (AMASS, mannequin-x)": "smplx",
    "VRM humanoid bones": "vrm",
}


def test_the_doc_has_an_example_per_rig_convention():
    assert set(CONVENTION_OF_EXAMPLE) <= set(doc_examples())
    assert sorted(CONVENTION_OF_EXAMPLE.values()) == sorted(RIG_MAPS)
    assert len(doc_examples()) >= len(RIG_MAPS) + 3  # and rigs no convention names


@pytest.mark.parametrize("title", list(doc_examples()))
def test_every_example_of_the_doc_maps_its_rig(title, clip):
    mapping = doc_examples()[title]
    assert set(mapping) == set(CANONICAL22)
    rig = rig_clip(clip, mapping)
    found, _ = present_map(rig.skeleton, mapping, what=title)
    assert {CANONICAL22[c]: rig.skeleton.joint_names[i] for i, c in found.items()} == {
        k: v for k, v in mapping.items() if v is not None
    }
    if title in CONVENTION_OF_EXAMPLE:  # a known convention: the detection alone finds the same map
        assert present_map(rig.skeleton, what=title) == (found, CONVENTION_OF_EXAMPLE[title])
    folded = to_canonical22(rig, mapping=mapping, what=title)
    present = [c for c in range(22) if mapping[CANONICAL22[c]] is not None]
    own = [rig.skeleton.joint_names.index(mapping[CANONICAL22[c]]) for c in present]
    # the rig's own joints keep their world positions (sums of the same rotated offsets)
    np.testing.assert_allclose(
        folded.global_positions()[:, present], rig.global_positions()[:, own], atol=1e-9
    )


# ----------------------------------------------------------------------------- absent joints
def test_virtual_joints_sit_on_the_bone_and_do_not_move_the_rig(clip):
    rig = rig_clip(clip, SMALL)
    found, _ = present_map(rig.skeleton, SMALL, what="small")
    augmented, full = with_virtual_joints(rig, found)
    names = augmented.skeleton.joint_names
    assert sorted(full.values()) == list(range(22))
    assert {n for n in names if n.endswith("(virtual)")} == {
        f"{c} (virtual)" for c, v in SMALL.items() if v is None
    }
    pos = augmented.global_positions()
    idx = {CANONICAL22[c]: i for i, c in full.items()}
    # Spine1 halfway between Spine and Spine2; a clavicle halfway between Spine2 and the arm;
    # a toe on its foot (zero-length bone); parents before children
    for mid, a, b in (("Spine1", "Spine", "Spine2"), ("LeftShoulder", "Spine2", "LeftArm")):
        np.testing.assert_allclose(
            pos[:, idx[mid]], 0.5 * (pos[:, idx[a]] + pos[:, idx[b]]), atol=1e-9
        )
    np.testing.assert_allclose(pos[:, idx["LeftToeBase"]], pos[:, idx["LeftFoot"]], atol=1e-12)
    assert all(p < k for k, p in enumerate(augmented.skeleton.parents))
    # each virtual joint hangs from its canonical parent's joint, and the arm from its clavicle
    parent_of = {names[k]: names[p] for k, p in enumerate(augmented.skeleton.parents) if p >= 0}
    assert (
        parent_of["LeftShoulder (virtual)"]
        == parent_of["RightShoulder (virtual)"]
        == SMALL["Spine2"]
    )
    assert (
        parent_of[SMALL["LeftArm"]] == "LeftShoulder (virtual)"
        and parent_of[SMALL["Spine2"]] == "Spine1 (virtual)"
    )
    assert parent_of["LeftToeBase (virtual)"] == SMALL["LeftFoot"]
    original = rig.global_positions()
    for i, name in enumerate(rig.skeleton.joint_names):
        np.testing.assert_allclose(pos[:, names.index(name)], original[:, i], atol=1e-9)


def test_a_two_spine_bandai_namco_bvh_as_source_and_as_target(clip, tmp_path, capsys):
    rig = rig_clip(clip, BANDAI)
    save_bvh(rig, tmp_path / "bn.bvh")
    (tmp_path / "bn.yaml").write_text(yaml.safe_dump(BANDAI))
    # without a map: one line naming the file, every missing joint and the way to say absent
    capsys.readouterr()
    assert (
        main(
            [
                "retarget",
                "--source",
                str(tmp_path / "bn.bvh"),
                "--target",
                "gus",
                "--method",
                "copy",
                "--out",
                str(tmp_path / "o.bvh"),
            ]
        )
        == 2
    )
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "bn.bvh: cannot map joints" in err[0] and "null" in err[0], err
    assert "'Spine1'" in err[0] and "--source-joint-map" in err[0]
    # as a source
    out = tmp_path / "bn_gus.bvh"
    assert (
        main(
            [
                "retarget",
                "--source",
                str(tmp_path / "bn.bvh"),
                "--source-joint-map",
                str(tmp_path / "bn.yaml"),
                "--target",
                "gus",
                "--method",
                "copy",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    assert load_bvh(out).num_frames == rig.num_frames
    # as a target: the result has exactly the rig's joints, in its order
    out = tmp_path / "cmu_bn.bvh"
    assert (
        main(
            [
                "retarget",
                "--source",
                str(cmu_clip_path("01_03.bvh")),
                "--target",
                str(tmp_path / "bn.bvh"),
                "--joint-map",
                str(tmp_path / "bn.yaml"),
                "--method",
                "copy",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    written = load_bvh(out)
    assert written.skeleton.joint_names == load_bvh(tmp_path / "bn.bvh").skeleton.joint_names


def test_written_on_a_rig_without_some_joints_the_legs_match_the_result(clip, tmp_path):
    """A rig missing Spine1, the clavicles and the toes as target: the hips and legs of the written
    file are where the canonical result puts them (no absent joint on their path); the upper body
    differs only by the bends the result gives the absent joints."""
    rig = rig_clip(clip, SMALL)
    save_bvh(rig, tmp_path / "small.bvh")
    (tmp_path / "small.yaml").write_text(yaml.safe_dump(SMALL))
    out = tmp_path / "o.bvh"
    assert (
        main(
            [
                "retarget",
                "--source",
                str(tmp_path / "small.bvh"),
                "--source-joint-map",
                str(tmp_path / "small.yaml"),
                "--target",
                str(tmp_path / "small.bvh"),
                "--joint-map",
                str(tmp_path / "small.yaml"),
                "--method",
                "copy",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    written, target = load_bvh(out), load_bvh(tmp_path / "small.bvh")
    assert written.skeleton.joint_names == target.skeleton.joint_names
    # onto itself with copy: the virtual joints never rotate, so every joint comes back (6-decimal
    # text, and the ground rule's shift, the same for every joint of a frame)
    got, want = written.global_positions(), target.global_positions()
    shift = got[:, :1, 1] - want[:, :1, 1]
    np.testing.assert_allclose(got[..., [0, 2]], want[..., [0, 2]], atol=1e-4)
    np.testing.assert_allclose(got[..., 1] - shift, want[..., 1], atol=1e-4)


# ----------------------------------------------------------------------------- errors
def test_a_required_joint_cannot_be_absent(clip, tmp_path):
    rig = rig_clip(clip, BANDAI)
    with pytest.raises(
        JointSetError, match=r"rig: the map marks LeftHand absent \(null\); only Spine, "
    ):
        present_map(rig.skeleton, dict(BANDAI, LeftHand=None), what="rig", mapping_source="the map")


def test_null_is_refused_by_the_formats_that_need_every_joint():
    with pytest.raises(JointSetError, match="no joint may be absent in this format"):
        map_joints(CANONICAL22, CANONICAL22_PARENTS, {"Spine1": None}, what="hero.glb")


def test_every_missing_joint_is_listed_with_the_files_joints(clip):
    rig = rig_clip(clip, BANDAI)
    with pytest.raises(JointSetError) as e:
        present_map(rig.skeleton, {"Hips": "Hips"}, what="bn.bvh", mapping_source="m.yaml")
    message = str(e.value)
    missing = re.search(r"cannot map joints (\[.*?\])", message).group(1)
    assert set(ast.literal_eval(missing)) >= {"Spine1", "LeftUpLeg"} and "with m.yaml" in message
    assert "'UpperLeg_L'" in message  # the file's joints to choose from


def test_two_canonical_joints_on_one_bone_name_the_duplicate(tmp_path):
    (tmp_path / "m.yaml").write_text("LeftArm: UpperArm_L\nLeftForeArm: UpperArm_L\n")
    with pytest.raises(JointSetError, match="maps both LeftArm and LeftForeArm to 'UpperArm_L'"):
        load_mapping_file(tmp_path / "m.yaml")


# --------------------------------------------------------------------------- every format, one path
@pytest.fixture(scope="module")
def renamed(tmp_path_factory):
    """Half a second of CMU 01_01 written twice with the same numbers: with its own joint names, and
    with names of no convention (``bone00`` ...), with the joint map that names them."""
    folder = tmp_path_factory.mktemp("renamed")
    raw = load_bvh(cmu_clip_path("01_01.bvh")).slice(0, 60)
    names = [f"bone{k:02d}" for k in range(raw.skeleton.num_joints)]
    sk = raw.skeleton
    save_bvh(raw, folder / "plain.bvh")
    save_bvh(
        raw.copy(
            skeleton=Skeleton(names, sk.parents, sk.offsets, sk.end_sites),
            meta=dict(raw.meta, file_joint_names=names),
        ),
        folder / "renamed.bvh",
    )
    mapping = {canon: names[sk.index(name)] for name, canon in RIG_MAPS["cmu"].items()}
    (folder / "map.yaml").write_text(yaml.safe_dump(mapping))
    return folder, names, mapping


def test_a_bvh_of_no_convention_reads_with_its_map_as_the_clip_it_is(renamed):
    folder, names, _ = renamed
    plain = load_source(folder / "plain.bvh").motion
    mapped = load_source(folder / "renamed.bvh", folder / "map.yaml").motion
    assert mapped.skeleton.joint_names == CANONICAL22
    np.testing.assert_array_equal(mapped.skeleton.offsets, plain.skeleton.offsets)
    np.testing.assert_array_equal(mapped.rotations, plain.rotations)
    np.testing.assert_array_equal(mapped.root_positions, plain.root_positions)
    target = load_target(str(folder / "renamed.bvh"), joint_map=folder / "map.yaml")
    np.testing.assert_array_equal(
        target.skeleton.offsets, load_target(str(folder / "plain.bvh")).skeleton.offsets
    )
    assert len(target.bvh_map) == 22 and target.bvh.skeleton.joint_names == tuple(names)


def test_a_bvh_of_no_convention_with_its_map_as_source_and_target_on_the_command_line(
    renamed, tmp_path
):
    folder, names, _ = renamed
    for kind in ("plain", "renamed"):
        extra = (
            [
                "--source-joint-map",
                str(folder / "map.yaml"),
                "--joint-map",
                str(folder / "map.yaml"),
            ]
            if kind == "renamed"
            else []
        )
        assert (
            main(
                [
                    "retarget",
                    "--source",
                    str(folder / f"{kind}.bvh"),
                    "--target",
                    str(folder / f"{kind}.bvh"),
                    "--method",
                    "copy",
                    "--out",
                    str(tmp_path / f"{kind}.bvh"),
                    *extra,
                ]
            )
            == 0
        )
    plain, mapped = load_bvh(tmp_path / "plain.bvh"), load_bvh(tmp_path / "renamed.bvh")
    assert mapped.skeleton.joint_names == tuple(names)  # the target's own joints and names
    np.testing.assert_array_equal(mapped.global_positions(), plain.global_positions())


def test_without_a_map_every_missing_joint_is_named_on_one_line(renamed, capsys):
    folder, _, mapping = renamed
    line = assert_cli_error(
        capsys,
        [
            "retarget",
            "--source",
            str(folder / "renamed.bvh"),
            "--target",
            "gus",
            "--method",
            "copy",
            "--out",
            str(folder / "o.bvh"),
        ],
        f"{folder / 'renamed.bvh'}: cannot map joints",
        "'bone00'",
    )
    assert ast.literal_eval(re.search(r"cannot map joints (\[.*?\])", line).group(1)) == list(
        CANONICAL22
    )
    # a map that names 20 of them: the other two, at once, and the map
    (folder / "part.yaml").write_text(
        yaml.safe_dump({k: v for k, v in mapping.items() if k not in ("Spine1", "LeftHand")})
    )
    assert_cli_error(
        capsys,
        [
            "retarget",
            "--source",
            str(folder / "plain.bvh"),
            "--target",
            str(folder / "renamed.bvh"),
            "--joint-map",
            str(folder / "part.yaml"),
            "--method",
            "copy",
            "--out",
            str(folder / "o.bvh"),
        ],
        f"{folder / 'renamed.bvh'}: cannot map joints ['Spine1', 'LeftHand']",
        "part.yaml",
    )


def test_two_canonical_joints_on_one_bone_on_the_command_line(renamed, tmp_path, capsys):
    folder, _, mapping = renamed
    (tmp_path / "two.yaml").write_text(
        yaml.safe_dump(dict(mapping, LeftForeArm=mapping["LeftArm"]))
    )
    assert_cli_error(
        capsys,
        [
            "retarget",
            "--source",
            str(folder / "renamed.bvh"),
            "--source-joint-map",
            str(tmp_path / "two.yaml"),
            "--target",
            "gus",
            "--method",
            "copy",
            "--out",
            str(tmp_path / "o.bvh"),
        ],
        "two.yaml: maps both LeftArm and LeftForeArm to",
        repr(mapping["LeftArm"]),
    )
    # a line that takes a bone the detection gave another canonical joint
    (tmp_path / "taken.yaml").write_text("LeftForeArm: LeftArm\n")
    assert_cli_error(
        capsys,
        [
            "retarget",
            "--source",
            str(folder / "plain.bvh"),
            "--source-joint-map",
            str(tmp_path / "taken.yaml"),
            "--target",
            "gus",
            "--method",
            "copy",
            "--out",
            str(tmp_path / "o.bvh"),
        ],
        f"{folder / 'plain.bvh'}: cannot map joints ['LeftArm']",
        "'LeftArm' stood for LeftArm but the joint map",
        "maps LeftForeArm to it",
    )


def test_a_bvh_target_uses_the_names_of_a_glb_rig(clip, tmp_path):
    # Unreal, Rigify and VRM names on a BVH: detected without a map, written back with them
    for title in ("Unreal mannequin (UE4/UE5)", "Rigify (Blender)", "VRM humanoid bones"):
        names = doc_examples()[title]
        target = tmp_path / f"{CONVENTION_OF_EXAMPLE[title]}.bvh"
        save_bvh(rig_clip(clip, names).slice(0, 2), target)
        out = tmp_path / f"out_{target.name}"
        assert (
            main(
                [
                    "retarget",
                    "--source",
                    str(cmu_clip_path("01_03.bvh")),
                    "--target",
                    str(target),
                    "--method",
                    "copy",
                    "--out",
                    str(out),
                ]
            )
            == 0
        )
        assert load_bvh(out).skeleton.joint_names == load_bvh(target).skeleton.joint_names


def test_an_smplx_file_takes_a_joint_map_like_any_other(tmp_path, capsys):
    plain = load_amass(AMASS_CLIP_PATH)
    (tmp_path / "same.yaml").write_text("Hips: pelvis\nLeftHand: left_wrist\n")
    same = load_amass(AMASS_CLIP_PATH, mapping=tmp_path / "same.yaml")
    np.testing.assert_array_equal(same.skeleton.offsets, plain.skeleton.offsets)
    np.testing.assert_array_equal(same.rotations, plain.rotations)
    # Spine2 marked absent: SMPL-X's spine3 is folded away and Spine2 inserted halfway up spine2 ->
    # neck
    (tmp_path / "two_spine.yaml").write_text("Spine2: null\n")
    fewer = load_amass(AMASS_CLIP_PATH, mapping=tmp_path / "two_spine.yaml")
    rest, rest_plain = fewer.skeleton.rest_positions(), plain.skeleton.rest_positions()
    np.testing.assert_allclose(rest[3], 0.5 * (rest_plain[2] + rest_plain[4]), atol=1e-12)
    keep = [c for c in range(22) if CANONICAL22[c] != "Spine2"]
    np.testing.assert_allclose(rest[keep], rest_plain[keep], atol=1e-12)
    legs = [CANONICAL22.index(n) for n in ("Hips", "LeftFoot", "RightToeBase")]
    np.testing.assert_allclose(
        fewer.global_positions()[:, legs], plain.global_positions()[:, legs], atol=1e-9
    )
    out = tmp_path / "o.bvh"
    assert (
        main(
            [
                "retarget",
                "--source",
                str(AMASS_CLIP_PATH),
                "--source-joint-map",
                str(tmp_path / "two_spine.yaml"),
                "--target",
                str(AMASS_CLIP_PATH),
                "--joint-map",
                str(tmp_path / "same.yaml"),
                "--method",
                "copy",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    (tmp_path / "bad.yaml").write_text("Hips: hips_bone\n")
    assert_cli_error(
        capsys,
        [
            "retarget",
            "--source",
            str(AMASS_CLIP_PATH),
            "--source-joint-map",
            str(tmp_path / "bad.yaml"),
            "--target",
            "gus",
            "--method",
            "copy",
            "--out",
            str(out),
        ],
        f"{AMASS_CLIP_PATH}: the joint map {tmp_path / 'bad.yaml'} maps Hips to 'hips_bone', "
        "which is not a joint",
    )


def test_a_shape_file_of_other_names_takes_a_joint_map(tmp_path, capsys):
    character = make_character("gus")
    save_shape_npz(character, tmp_path / "gus.npz")
    data = dict(np.load(tmp_path / "gus.npz"))
    names = [f"b{k}" for k in range(22)]
    np.savez(tmp_path / "renamed.npz", **dict(data, joint_names=np.array(names)))
    (tmp_path / "map.yaml").write_text(yaml.safe_dump(dict(zip(CANONICAL22, names, strict=False))))
    mapped = load_target(str(tmp_path / "renamed.npz"), joint_map=tmp_path / "map.yaml")
    np.testing.assert_array_equal(
        mapped.skeleton.offsets, load_target(str(tmp_path / "gus.npz")).skeleton.offsets
    )
    args = [
        "retarget",
        "--source",
        str(cmu_clip_path("01_03.bvh")),
        "--target",
        str(tmp_path / "renamed.npz"),
        "--method",
        "copy-rest",  # copy would cross gus's legs by CMU's 20-degree splay (check_posture)
        "--out",
        str(tmp_path / "o.bvh"),
    ]
    line = assert_cli_error(capsys, args, f"{tmp_path / 'renamed.npz'}: cannot map joints", "'b0'")
    assert ast.literal_eval(re.search(r"cannot map joints (\[.*?\])", line).group(1)) == list(
        CANONICAL22
    )
    (tmp_path / "null.yaml").write_text(
        yaml.safe_dump(dict(zip(CANONICAL22, names, strict=False), Spine1=None))
    )
    assert_cli_error(
        capsys,
        args + ["--joint-map", str(tmp_path / "null.yaml")],
        "renamed.npz",
        "null.yaml",
        "marks Spine1 absent (null); no joint may be absent in this format",
    )
    assert main(args + ["--joint-map", str(tmp_path / "map.yaml")]) == 0


def test_a_character_name_takes_no_joint_map(tmp_path, capsys):
    (tmp_path / "m.yaml").write_text("Hips: Hips\n")
    assert_cli_error(
        capsys,
        [
            "retarget",
            "--source",
            str(cmu_clip_path("01_03.bvh")),
            "--target",
            "gus",
            "--joint-map",
            str(tmp_path / "m.yaml"),
            "--method",
            "copy",
            "--out",
            str(tmp_path / "o.bvh"),
        ],
        "m.yaml",
        "the character 'gus' is on the canonical 22",
    )


@settings(max_examples=60, deadline=None)
@given(
    st.dictionaries(
        st.sampled_from(list(CANONICAL22) + ["Tail", "hips"]),
        st.one_of(st.none(), st.sampled_from(["Hips", "Spine", "Chest", "UpperArm_L", "nope", ""])),
    )
)
def test_fuzz_maps_give_a_map_or_one_joint_set_error(mapping):
    """Any map applied to the Bandai-Namco rig: a complete map or a JointSetError, never another
    exception."""
    skeleton = Skeleton(tuple(BANDAI_NAMES), tuple(BANDAI_PARENTS), np.ones((len(BANDAI_NAMES), 3)))
    try:
        found, _ = present_map(skeleton, dict(BANDAI, **mapping), what="bn.bvh")
    except JointSetError:
        return
    assert len(set(found.values())) == len(found)
    absent = {c for c in range(22) if c not in found.values()}
    assert {CANONICAL22[c] for c in absent} <= set(MAY_BE_ABSENT)


BANDAI_NAMES = [
    "Hips",
    "Spine",
    "Chest",
    "Neck",
    "Head",
    "Shoulder_L",
    "UpperArm_L",
    "LowerArm_L",
    "Hand_L",
    "Shoulder_R",
    "UpperArm_R",
    "LowerArm_R",
    "Hand_R",
    "UpperLeg_L",
    "LowerLeg_L",
    "Foot_L",
    "Toes_L",
    "UpperLeg_R",
    "LowerLeg_R",
    "Foot_R",
    "Toes_R",
]
BANDAI_PARENTS = [-1, 0, 1, 2, 3, 2, 5, 6, 7, 2, 9, 10, 11, 0, 13, 14, 15, 0, 17, 18, 19]


@pytest.mark.data  # the CMU clip (assimp-testmodels)
def test_a_glb_rig_without_clavicles_and_one_spine_joint_is_retargeted_and_keeps_its_joints(
    tmp_path,
):
    # Mr. Fixit's GLB has the clavicles and Spine1 only as inserted joints without weight; a map
    # that marks them absent (null) treats it as the rig it was: two spine joints, no clavicles
    full = load_mapping_file(joint_map_path("mrfixit"))
    absent = dict(full, Spine1=None, LeftShoulder=None, RightShoulder=None)
    (tmp_path / "map.yaml").write_text(
        "\n".join(f"{k}: {'null' if v is None else v}" for k, v in absent.items())
    )
    rig = load_gltf_rig(real_character_path("mrfixit"), tmp_path / "map.yaml")
    assert len(rig.joint_map) == 19
    character = rig.character()
    with_all = load_gltf_rig(real_character_path("mrfixit"), full).character()
    # the three inserted joints sit where the file's inserted joints are: midway (clavicles on the
    # bone Spine2 -> UpperArm, Spine1 between Spine and Spine2, as the conversion placed them)
    np.testing.assert_allclose(
        character.skeleton.rest_positions(), with_all.skeleton.rest_positions(), atol=0.02
    )
    source = tmp_path / "clip.bvh"
    save_bvh(load_bvh(cmu_clip_path("01_01.bvh")).slice(0, 40), source)
    out = tmp_path / "out.glb"
    assert (
        main(
            [
                "retarget",
                "--source",
                str(source),
                "--target",
                str(real_character_path("mrfixit")),
                "--joint-map",
                str(tmp_path / "map.yaml"),
                "--method",
                "copy",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    motion, written = load_gltf_motion(out, mapping=absent)
    assert (
        written.skeleton.joint_names == rig.skeleton.joint_names
    )  # the file's own joints, none added
    back = written.motion_to_canonical(motion)
    assert back.num_frames == 40
    assert back.global_positions()[..., 1].min() > -0.03  # on the floor


def test_a_bvh_whose_rest_pose_lies_along_x_is_read_standing(tmp_path):
    # the rest skeleton turned by a quarter about Z (lying, its head towards -X), the frames
    # turning it back up: the world poses are those of a standing clip; a source read from it
    # must stand (hips to head along +Y) so that copying its rotations keeps the target standing

    standing = make_character("ada").skeleton
    clip = Motion(
        standing.copy(),
        np.tile([1.0, 0.0, 0.0, 0.0], (5, 22, 1)),
        np.tile(standing.offsets[0], (5, 1)),
        30.0,
    )
    turn = np.array(
        [[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]
    )  # +90 degrees about Z: up -> -X
    q = quat_from_axis_angle(torch.tensor([0.0, 0.0, np.pi / 2], dtype=torch.float64))
    lying = clip.copy(
        skeleton=Skeleton(standing.joint_names, standing.parents, standing.offsets @ turn.T)
    )
    rot = torch.from_numpy(lying.rotations)
    rot[:, 0] = quat_mul(
        rot[:, 0], torch.cat([q[:1], -q[1:]]).expand_as(rot[:, 0])
    )  # frames undo the lie
    lying.rotations = rot.numpy()
    np.testing.assert_allclose(
        lying.global_positions(), clip.global_positions(), atol=1e-9
    )  # float64 FK
    upright = stand_upright(lying)
    np.testing.assert_allclose(upright.global_positions(), clip.global_positions(), atol=1e-9)
    rest = upright.skeleton.rest_positions()
    assert rest[J["Head"], 1] - rest[J["Hips"], 1] > 0.4  # the rest pose stands
    copied = copy_rotations(upright, make_character("bram").skeleton).global_positions()
    assert copied[0, J["Head"], 1] > copied[0, J["Hips"], 1] + 0.4  # and so does the copy
    assert stand_upright(clip) is clip  # a standing rest pose is left alone
