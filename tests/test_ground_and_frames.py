"""The ground rule (:mod:`retarget_lib.core.ground`) and the frames of ``retarget retarget``: feet
on the floor where the source's are, for every method and output format, and every source frame
kept."""

import numpy as np
import pytest
from skeletons import make_skeleton

from retarget_lib.cli import main
from retarget_lib.core.ground import (
    clip_floor,
    floor_offset,
    foot_positions,
    ground_contacts,
    sole_heights,
    standing_feet,
    touching_feet,
)
from retarget_lib.core.measures import foot_rest_heights, rest_ground
from retarget_lib.core.rig import Rig
from retarget_lib.data.sources.cmu import cmu_clip_path
from retarget_lib.data.synthetic.amass_clip import AMASS_CLIP_PATH
from retarget_lib.data.synthetic.characters import make_character
from retarget_lib.io import load_bvh, save_bvh, save_glb
from retarget_lib.io.amass import load_amass
from retarget_lib.io.gltf import load_gltf_motion, load_gltf_rig
from retarget_lib.io.joint_maps import to_canonical22


# ----------------------------------------------------------------------------- the rule, by hand
def test_floor_offset_by_hand():
    """Frames 1 and 3 stand: the shift puts the lowest standing joint at the source's height x
    ratio there, is interpolated at 2 and held at 0 and 4."""
    standing = np.zeros((5, 4), bool)
    standing[1, 0] = standing[3, [0, 2]] = True
    source = np.full((5, 4), 0.5)
    source[1, 0], source[3, 0], source[3, 2] = 0.11, 0.10, 0.12  # floor 0.10: 1 cm, 0, 2 cm above
    target = np.zeros((5, 4))
    target[1, 0], target[3, 0], target[3, 2] = 0.20, -0.05, -0.01
    shift = floor_offset(target, source, 0.10, standing, ratio=2.0)
    # frame 1: 2 * 0.01 - 0.20 = -0.18; frame 3: max(0 - (-0.05), 0.04 - (-0.01)) = 0.05
    np.testing.assert_allclose(
        shift, [-0.18, -0.18, -0.065, 0.05, 0.05], atol=1e-12
    )  # exact arithmetic


def test_no_standing_frame_gives_no_shift():
    assert not floor_offset(
        np.ones((3, 4)), np.ones((3, 4)), 0.0, np.zeros((3, 4), bool), 1.0
    ).any()


def test_a_run_is_held_where_its_feet_touch_the_floor():
    """No foot joint is ever still: the ground rule holds the ones at the floor instead; a clip
    with one still foot joint is held by that one only."""
    feet = np.zeros((4, 4, 3))
    feet[:, :, 2] = 0.1 * np.arange(4)[:, None]  # every joint moves 10 cm a frame
    soles = np.full((4, 4), 0.5)
    soles[1, 0] = soles[3, 2] = 0.01  # touching the floor (at 0) twice, never still
    assert not standing_feet(feet, soles, 0.0, 1.8, 30.0).any()
    expected = np.zeros((4, 4), bool)
    expected[1, 0] = expected[3, 2] = True
    np.testing.assert_array_equal(touching_feet(soles, 0.0, 1.8), expected)
    np.testing.assert_array_equal(ground_contacts(feet, soles, 0.0, 1.8, 30.0), expected)
    feet[:, 3, 2] = 0.0  # one joint still and at the floor in every frame: only it is held
    soles[:, 3] = 0.0
    held = ground_contacts(feet, soles, 0.0, 1.8, 30.0)
    assert held[:, 3].all() and not held[:, :3].any()


def test_clip_floor_ignores_a_few_frames_through_the_floor():
    soles = np.full((100, 4), 0.2)
    soles[:, 0] = 0.05
    soles[:3, 0] = -0.5  # 3 % of the frames: a glitch, under the 5th percentile
    assert clip_floor(soles) == pytest.approx(0.05)


def test_standing_needs_low_and_still_at_the_characters_scale():
    feet = np.zeros((4, 4, 3))
    feet[2:, 1] += [[0.02, 0, 0], [0.04, 0, 0]]  # joint 1 moves 2 cm, then 4 cm per frame
    soles = np.zeros((4, 4))
    soles[:, 3] = 0.05  # above the 3 cm band at 1.8 m
    got = standing_feet(feet, soles, 0.0, height=1.8, fps=30.0)
    assert got[:, 0].all() and got[:, 2].all() and not got[:, 3].any()
    assert got[:2, 1].all() and not got[2:, 1].any()
    # at twice the height the band and the step double; at 60 fps the allowed step halves
    assert standing_feet(feet, soles, 0.0, height=3.6, fps=30.0)[:, 3].all()
    assert standing_feet(feet, soles, 0.0, height=3.6, fps=30.0)[2, 1]
    slow = np.zeros((4, 4, 3))
    slow[:, :, 0] = 0.007 * np.arange(4)[:, None]  # 0.7 cm per frame: still at 30 fps, not at 60
    assert standing_feet(slow, np.zeros((4, 4)), 0.0, height=1.8, fps=30.0).all()
    assert not standing_feet(slow, np.zeros((4, 4)), 0.0, height=1.8, fps=60.0).any()


def test_rest_ground_is_the_rest_meshs_lowest_point_else_the_lowest_foot_joint():
    character = make_character("gus")
    mesh_low = character.rest_vertices[:, 1].min()
    assert rest_ground(character.skeleton, character.rest_vertices) == pytest.approx(mesh_low)
    lifted = character.skeleton.copy()
    lifted.offsets[0, 1] -= 1.0  # a BVH-like skeleton whose feet are below y = 0
    feet = lifted.rest_positions()[
        [lifted.index("LeftToeBase"), lifted.index("RightToeBase")], 1
    ].min()
    assert rest_ground(lifted) == pytest.approx(
        min(
            feet,
            lifted.rest_positions()[[lifted.index("LeftFoot"), lifted.index("RightFoot")], 1].min(),
        )
    )
    # a toe joint resting on the mesh's sole reads its height above it
    assert (foot_rest_heights(character.skeleton, character.rest_vertices) >= 0).all()


def test_a_foot_flat_on_the_floor_reads_zero():
    skeleton = make_skeleton()
    rest = skeleton.rest_positions()[None]
    np.testing.assert_allclose(
        sole_heights(rest, skeleton).min(), 0.0, atol=1e-12
    )  # copied rest values
    assert foot_positions(rest, skeleton).shape == (1, 4, 3)


# ----------------------------------------------------------------------------- through the command
@pytest.fixture(scope="module")
def files(tmp_path_factory):
    folder = tmp_path_factory.mktemp("ground")
    walk = load_bvh(cmu_clip_path("01_01.bvh")).slice(0, 240)  # 2 s at 120 fps, feet on its floor
    save_bvh(walk, folder / "walk.bvh")
    raised = walk.copy()
    raised.root_positions[:, 1] += 0.50  # its floor 50 cm up (positions are in metres)
    save_bvh(raised, folder / "raised.bvh")
    # a run as the ground rule sees one: every foot on the floor still rolls on (here the whole
    # walk slides forward at 3 m/s, 2.5 cm a frame at 120 fps), on a floor 50 cm up
    run = raised.copy()
    run.root_positions[:, 2] += 3.0 * np.arange(run.num_frames) / run.fps
    save_bvh(run, folder / "run.bvh")
    for name in ("gus", "hana"):  # a tall and a small character, each with its mesh
        save_glb(Rig.from_character(make_character(name)), folder / f"{name}.glb")
    return folder


def _source_soles(source_path):
    """The source's sole heights above its own floor ``(T, 4)`` and where it stands ``(T, 4)``."""
    source = (
        load_amass(source_path)
        if source_path.suffix == ".npz"
        else to_canonical22(load_bvh(source_path))
    )
    pos = source.global_positions()
    soles = sole_heights(pos, source.skeleton)
    floor = clip_floor(soles)
    standing = standing_feet(
        foot_positions(pos, source.skeleton), soles, floor, source.skeleton.height(), source.fps
    )
    return soles - floor, standing, source.skeleton.height()


def _errors(out, target_glb, source_path):
    """``(T, 4)`` each result sole's height minus the source's above its floor (scaled), and where
    the source stands."""
    rig = load_gltf_rig(target_glb)
    if out.suffix == ".glb":
        motion, written_rig = load_gltf_motion(out)
        result = written_rig.motion_to_canonical(motion)
    else:
        result = to_canonical22(load_bvh(out))
    soles = sole_heights(result.global_positions(), result.skeleton, rig.character().rest_vertices)
    source, standing, source_height = _source_soles(source_path)
    return soles - source * result.skeleton.height() / source_height, standing


def _run(files, tmp_path, method, suffix, target, source="walk.bvh"):
    out = tmp_path / f"{method}_{target}{suffix}"
    assert (
        main(
            [
                "retarget",
                "--source",
                str(files / source),
                "--target",
                str(files / f"{target}.glb"),
                "--method",
                method,
                "--out",
                str(out),
            ]
        )
        == 0
    )
    return out


@pytest.mark.parametrize(
    "method,suffix,target",
    [
        ("copy", ".bvh", "gus"),
        ("copy-rest", ".glb", "hana"),
        ("tdcn", ".glb", "gus"),
        ("copy", ".fbx", "hana"),
    ],
)
def test_feet_stand_on_the_targets_floor_where_the_sources_do(
    files, tmp_path, method, suffix, target
):
    out = _run(files, tmp_path, method, suffix, target)
    if suffix == ".fbx":  # written; the same run's result read back through its glTF twin
        out = _run(files, tmp_path, method, ".glb", target)
    error, standing = _errors(out, files / f"{target}.glb", files / "walk.bvh")
    assert len(error) == 240 and standing.any(axis=1).mean() > 0.5  # the walk stands in most frames
    # the lowest standing joint is where the source's is (to float32 / 6-decimal files)
    lowest = np.where(standing, error, np.inf).min(axis=1)[standing.any(axis=1)]
    assert np.abs(lowest).max() <= 1e-3
    # each standing foot (its lower standing joint) is on the floor: never in it, and above it by
    # less than 4 cm in most frames. Only the ground is this rule's: the other foot's height is the
    # pose's (CMU subject 01's right leg is 1.6 cm longer than its left, and a rotation copy onto
    # equal legs lifts the right foot by about that and the toe's pitch: 3-4 cm measured)
    for heel, toe in ((0, 2), (1, 3)):
        foot = np.where(standing[:, [heel, toe]], error[:, [heel, toe]], np.inf).min(axis=1)
        foot = foot[np.isfinite(foot)]
        assert foot.min() >= -1e-3 and np.median(foot) <= 0.04, (heel, np.median(foot))


def test_an_amass_clip_stands_on_the_targets_floor(files, tmp_path):
    """SMPL+H clips came out 5-9 cm under the floor before the rule (issue 28)."""
    out = tmp_path / "amass_gus.glb"
    assert (
        main(
            [
                "retarget",
                "--source",
                str(AMASS_CLIP_PATH),
                "--target",
                str(files / "gus.glb"),
                "--method",
                "copy",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    error, standing = _errors(out, files / "gus.glb", AMASS_CLIP_PATH)
    assert standing.any(axis=1).mean() > 0.5
    lowest = np.where(standing, error, np.inf).min(axis=1)[standing.any(axis=1)]
    assert np.abs(lowest).max() <= 1e-3  # float32 GLB


def test_a_runs_feet_touch_the_targets_floor_where_the_sources_do(files, tmp_path):
    """A clip with no still foot (a run) is put on the target's floor where its feet touch the
    source's: it ended 1.4-6 cm under (or, on a raised floor, as far above) before (issue 28)."""
    out = _run(files, tmp_path, "copy", ".bvh", "gus", source="run.bvh")
    source = to_canonical22(load_bvh(files / "run.bvh"))
    pos = source.global_positions()
    soles = sole_heights(pos, source.skeleton)
    floor = clip_floor(soles)
    assert not standing_feet(
        foot_positions(pos, source.skeleton), soles, floor, source.skeleton.height(), source.fps
    ).any()
    touching = touching_feet(soles, floor, source.skeleton.height())
    result = to_canonical22(load_bvh(out))
    ratio = result.skeleton.height() / source.skeleton.height()
    error = (
        sole_heights(
            result.global_positions(),
            result.skeleton,
            Rig.from_character(make_character("gus")).character().rest_vertices,
        )
        - (soles - floor) * ratio
    )
    lowest = np.where(touching, error, np.inf).min(axis=1)[touching.any(axis=1)]
    assert touching.any(axis=1).mean() > 0.5 and np.abs(lowest).max() <= 1e-3  # 6-decimal BVH


def test_a_sources_floor_need_not_be_at_zero(files, tmp_path):
    a = _run(files, tmp_path, "copy", ".bvh", "gus")
    b = _run(files, tmp_path, "copy", ".bvh", "gus", source="raised.bvh")
    np.testing.assert_allclose(
        load_bvh(a).global_positions(), load_bvh(b).global_positions(), atol=2e-4
    )  # 6-decimal BVH text of the same result


# ----------------------------------------------------------------------------- frames
@pytest.mark.parametrize(
    "frames,fps", [(120, 120.0), (60, 60.0), (120, 100.0), (45, 30.0), (7, 24.0)]
)
def test_every_source_frame_is_kept(files, tmp_path, frames, fps):
    clip = load_bvh(cmu_clip_path("01_01.bvh")).slice(0, frames)
    clip.fps = fps
    src = tmp_path / "src.bvh"
    save_bvh(clip, src)
    out = tmp_path / "out.bvh"
    assert (
        main(
            [
                "retarget",
                "--source",
                str(src),
                "--target",
                "kato",
                "--method",
                "copy",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    written = load_bvh(out)
    assert written.num_frames == frames and written.fps == pytest.approx(fps)


def test_a_30_fps_source_comes_back_frame_for_frame(files, tmp_path):
    """At 30 fps the methods see the source's own frames: ``copy`` onto the source's own skeleton
    gives back the source's rotations (to the file's 6 decimals)."""
    clip = load_bvh(cmu_clip_path("01_01.bvh")).slice(0, 30)
    clip.fps = 30.0
    src, out = tmp_path / "src.bvh", tmp_path / "out.bvh"
    save_bvh(clip, src)
    assert (
        main(
            [
                "retarget",
                "--source",
                str(src),
                "--target",
                str(cmu_clip_path("01_03.bvh")),
                "--method",
                "copy",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    written, source = to_canonical22(load_bvh(out)), to_canonical22(load_bvh(src))
    assert written.num_frames == 30
    np.testing.assert_allclose(
        np.abs((written.rotations * source.rotations).sum(-1)), 1.0, atol=1e-6
    )  # text
