"""A character file in other axes (Z up as 3ds Max and Unreal FBX files, facing -Z as VRM 0.x
avatars, a quarter turn) is read standing up, facing +Z, left at +X: the rest pose, the mesh and
the animation alike (issue 28); a ``.vrm`` file is read as the glTF it is."""

import numpy as np
import pytest
import torch

from retarget_lib.cli import main
from retarget_lib.core.character import Character
from retarget_lib.core.rig import Rig
from retarget_lib.core.rotations import matrix_to_quat, quat_conjugate, quat_mul
from retarget_lib.data.synthetic.characters import make_character
from retarget_lib.data.synthetic.motions import make_motion
from retarget_lib.io import save_glb
from retarget_lib.io.gltf import load_gltf_motion, load_gltf_rig

pytestmark = pytest.mark.tooling  # nothing here depends on the thread count (make unit-threads)

#: file axes -> library axes of the cases: Z up (the character lies along +Z), facing -Z, a quarter
#: turn about the vertical, and Z up facing +X
TURNS = {
    "z-up": np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]]),
    "facing -z": np.diag([-1.0, 1.0, -1.0]),
    "quarter turn": np.array([[0.0, 0, 1], [0, 1, 0], [-1, 0, 0]]),
    "z-up facing x": np.array([[0.0, 0, 1], [1, 0, 0], [0, 1, 0]]),
}


def _turned(character: Character, motion, turn: np.ndarray):
    """``character`` and ``motion`` as a file with other axes stores them: every point ``p`` at
    ``turn.T @ p`` (``turn`` takes the file's axes to the library's)."""
    inv = turn.T
    skeleton = character.skeleton.copy()
    skeleton.offsets = skeleton.offsets @ inv.T
    turned = Character(
        character.name,
        skeleton,
        character.rest_vertices @ inv.T,
        character.faces,
        character.weights,
        character.bulk,
        dict(character.style),
    )
    q = matrix_to_quat(torch.from_numpy(inv))
    rot = torch.from_numpy(motion.rotations)
    rot = quat_mul(quat_mul(q.expand_as(rot), rot), quat_conjugate(q).expand_as(rot))  # R q R^-1
    return turned, motion.copy(
        skeleton=skeleton, rotations=rot.numpy(), root_positions=motion.root_positions @ inv.T
    )


@pytest.fixture(scope="module")
def gus():
    character = make_character("gus")
    return character, make_motion("walk", character.skeleton, 0, 0.5)


@pytest.mark.parametrize("case", list(TURNS))
def test_a_turned_file_is_read_standing_facing_z(gus, tmp_path, case):
    character, motion = gus
    turned, turned_motion = _turned(character, motion, TURNS[case])
    path = tmp_path / "turned.glb"
    save_glb(Rig.from_character(turned), path, turned_motion)
    rig = load_gltf_rig(path)
    # the rest pose and mesh come back in the library's axes (float32 file)
    np.testing.assert_allclose(
        rig.character().rest_joint_positions(), character.rest_joint_positions(), atol=1e-5
    )
    np.testing.assert_allclose(rig.rest_vertices, character.rest_vertices, atol=1e-5)
    # and so does the animation
    read, read_rig = load_gltf_motion(path)
    np.testing.assert_allclose(
        read_rig.motion_to_canonical(read).global_positions(), motion.global_positions(), atol=1e-4
    )


def test_a_file_in_the_librarys_axes_is_not_turned(gus, tmp_path):
    character, motion = gus
    save_glb(Rig.from_character(character), tmp_path / "gus.glb", motion)
    rig = load_gltf_rig(tmp_path / "gus.glb")
    np.testing.assert_allclose(
        rig.rest_vertices, character.rest_vertices, atol=1e-6
    )  # float32 file


def test_a_vrm_avatar_facing_minus_z_is_a_target(gus, tmp_path):
    character, motion = gus
    turned, _ = _turned(character, motion, TURNS["facing -z"])
    avatar = tmp_path / "avatar.vrm"
    save_glb(Rig.from_character(turned), tmp_path / "avatar.glb")
    avatar.write_bytes((tmp_path / "avatar.glb").read_bytes())
    out = tmp_path / "walk_avatar.glb"
    assert (
        main(
            [
                "retarget",
                "--source",
                str(tmp_path / "avatar.vrm"),
                "--target",
                str(avatar),
                "--method",
                "copy",
                "--out",
                str(out),
            ]
        )
        == 2
    )  # the avatar has no animation: one clear error
    source = tmp_path / "walk.glb"
    save_glb(Rig.from_character(character), source, motion)
    assert (
        main(
            [
                "retarget",
                "--source",
                str(source),
                "--target",
                str(avatar),
                "--method",
                "copy",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    result, rig = load_gltf_motion(out)
    pos = rig.motion_to_canonical(result).global_positions()
    c = rig.character().skeleton
    left = pos[:, c.index("LeftUpLeg")] - pos[:, c.index("RightUpLeg")]
    up = pos[:, c.index("Head")] - pos[:, c.index("Hips")]
    assert (up[:, 1] > 0.9 * np.linalg.norm(up, axis=1)).all()  # standing
    assert (left[:, 0] > 0.9 * np.linalg.norm(left, axis=1)).all()  # left at +X: facing +Z


def test_a_z_up_fbx_character_is_read_standing(gus, tmp_path):
    """The FBX reader converts through glTF (assimp): the same turn applies (a Z-up character as
    the Unreal mannequin's FBX stores it)."""
    from retarget_lib.io import fbx
    from retarget_lib.io.fbx_write import save_fbx

    if fbx.fbx_missing():
        pytest.skip(fbx.fbx_missing())
    character, motion = gus
    turned, turned_motion = _turned(character, motion, TURNS["z-up"])
    save_fbx(Rig.from_character(turned), tmp_path / "z_up.fbx", turned_motion)
    rig = fbx.load_fbx_rig(tmp_path / "z_up.fbx")
    np.testing.assert_allclose(
        rig.character().rest_joint_positions(), character.rest_joint_positions(), atol=1e-4
    )
    read, read_rig = fbx.load_fbx_motion(tmp_path / "z_up.fbx")
    np.testing.assert_allclose(
        read_rig.motion_to_canonical(read).global_positions(), motion.global_positions(), atol=1e-3
    )  # float32 keys through two converters
