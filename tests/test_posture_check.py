"""`retarget retarget` never writes an implausible body silently (methods.retarget.check_posture):
a body lying or upside down where the source stands, or sinking under the floor, stops with exit
code 2 and one line; the rigs here are built for it (a file whose zero pose lies down)."""

import math

import numpy as np
import pytest
import torch
from skeletons import make_skeleton

from retarget_lib.cli import main
from retarget_lib.core.ground import sole_heights
from retarget_lib.core.rotations import quat_from_axis_angle, quat_mul
from retarget_lib.core.skeleton import J, canonical22_skeleton
from retarget_lib.core.transfer import retarget_ground_truth
from retarget_lib.data.synthetic.motions import make_motion
from retarget_lib.errors import RetargetInputError
from retarget_lib.io import load_bvh, save_bvh
from retarget_lib.io.joint_maps import to_canonical22
from retarget_lib.methods.retarget import check_posture

SOURCE = make_skeleton(1.7, arm_deg=0.0)
TARGET = make_skeleton(1.9, arm_deg=30.0)


@pytest.fixture(scope="module")
def walk():
    return make_motion("walk", SOURCE, 1, duration=3.0)


def straight_line_file(motion):
    """The motion on a rig whose zero rotations lie in a straight line along +X (every bone, as
    some research mocap files rest), performed by the ground truth's rule (the rotation deltas from
    the retarget pose): the body stands, walks and keeps its feet on the floor."""
    lengths = np.linalg.norm(motion.skeleton.offsets, axis=-1)
    off = np.zeros((22, 3))
    off[1:, 0] = lengths[1:]
    off[0] = motion.skeleton.offsets[0]
    for side, sz in (("Left", 1.0), ("Right", -1.0)):
        off[J[f"{side}UpLeg"]] = (0.0, 0.0, sz * lengths[J[f"{side}UpLeg"]])
        off[J[f"{side}Shoulder"]] = (lengths[J[f"{side}Shoulder"]], 0.0, sz * 0.05)
    return retarget_ground_truth(motion, canonical22_skeleton(off))


def test_the_straight_line_file_still_stands(walk):
    pos = straight_line_file(walk).global_positions()
    spine = pos[:, J["Neck"]] - pos[:, J["Hips"]]
    assert (spine[:, 1] / np.linalg.norm(spine, axis=-1)).min() > 0.9


def run(source, method, tmp_path, capsys):
    src, tgt, out = tmp_path / "src.bvh", tmp_path / "tgt.bvh", tmp_path / f"{method}.bvh"
    save_bvh(source, src)
    save_bvh(walk_on(TARGET, source), tgt)
    code = main(
        [
            "retarget",
            "--source",
            str(src),
            "--target",
            str(tgt),
            "--method",
            method,
            "--out",
            str(out),
        ]
    )
    return code, capsys.readouterr().err, out


def walk_on(skeleton, like):
    """A one-frame clip on ``skeleton`` (a target file is read for its skeleton)."""
    return like.copy(
        skeleton=skeleton,
        rotations=np.tile([1.0, 0, 0, 0], (1, 22, 1)),
        root_positions=skeleton.offsets[:1].copy(),
    )


def test_copy_from_a_straight_line_rig_is_refused_with_one_line(walk, tmp_path, capsys):
    code, err, out = run(straight_line_file(walk), "copy", tmp_path, capsys)
    assert code == 2
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert "lying" in err or "upside down" in err or "under the floor" in err
    assert "joint map" in err and "--method" in err  # what to try
    assert not out.exists()


def test_copy_rest_from_a_straight_line_rig_stands_on_the_floor(walk, tmp_path, capsys):
    code, err, out = run(straight_line_file(walk), "copy-rest", tmp_path, capsys)
    assert code == 0, err
    result = load_bvh(out)
    pos = result.global_positions()
    spine = pos[:, result.skeleton.index("Neck")] - pos[:, result.skeleton.index("Hips")]
    assert (spine[:, 1] / np.linalg.norm(spine, axis=-1)).min() > 0.9  # upright in every frame
    soles = sole_heights(to_canonical22(result).global_positions(), to_canonical22(result).skeleton)
    stance = walk.meta["joint_contacts"][: len(soles)]
    assert np.abs(soles[stance]).max() < 0.02  # planted feet within 2 cm of the floor


def test_a_result_under_the_floor_or_on_its_head_is_refused(walk):
    good = walk.copy()
    check_posture(good, walk, None, "copy", "src.bvh")  # the source itself passes
    sunk = walk.copy()
    sunk.root_positions = sunk.root_positions - [0.0, 0.2, 0.0]  # 20 cm: 12 % of 1.7 m
    with pytest.raises(RetargetInputError, match="under the floor"):
        check_posture(sunk, walk, None, "copy", "src.bvh")
    slightly = walk.copy()
    slightly.root_positions = slightly.root_positions - [0.0, 0.03, 0.0]  # 3 cm: within 5 %
    check_posture(slightly, walk, None, "copy", "src.bvh")
    flip = quat_from_axis_angle(torch.tensor([math.pi, 0.0, 0.0], dtype=torch.float64))
    upside = walk.copy()
    upside.rotations = upside.rotations.copy()
    upside.rotations[:, 0] = quat_mul(flip, torch.from_numpy(walk.rotations[:, 0])).numpy()
    with pytest.raises(RetargetInputError, match="upside down"):
        check_posture(upside, walk, None, "tdcn", "src.bvh")
