"""One definition each of a character's heights, its rest pose, its rest ground and its feet's rest
heights (retarget_lib.core.measures, Skeleton.rest_positions/height/leg_length), each pinned against
values worked out by hand on a small hand-built skeleton and mesh.

Tolerances: the hand values are decimals, which float64 does not hold exactly, and each measure adds
or subtracts at most about ten of them, so float64 results are within 1e-12 m of the decimal value;
the float32 tensor forms are within a relative 1e-6 (float32 keeps about 7 digits).
"""

import inspect

import numpy as np
import pytest
import torch

from retarget_lib.core.character import Character
from retarget_lib.core.measures import (
    HEAD_TOP_FACTOR,
    estimated_standing_height,
    foot_rest_heights,
    leg_length,
    mesh_ground,
    mesh_standing_height,
    nkn_height,
    rest_ground,
    skeleton_leg_length,
)
from retarget_lib.core.skeleton import J, canonical22_skeleton
from retarget_lib.geometry.contacts import detect_foot_contacts

#: float64 sums of a few decimals (see the module docstring)
EXACT = 1e-12


def _offsets() -> np.ndarray:
    """``(22, 3)`` a straight character, hips 1 m up. Spine chain 0.1 + 0.1 + 0.1 + 0.2 + 0.1 up
    (the Head joint at 1.6 m). Left leg: hip (0.09, -0.12, 0) (a 0.15 bone), thigh and shin 0.4
    down, toe (0, -0.06, 0.08) (a 0.1 bone): ankle at 0.08 m, toe at 0.02 m. Right leg: thigh
    0.42, shin 0.4, toe (0, -0.05, 0.08): ankle at 0.06 m, toe at 0.01 m (the lowest foot joint)."""
    off = np.zeros((22, 3))
    off[J["Hips"]] = (0.0, 1.0, 0.0)
    for name, up in (
        ("Spine", 0.1),
        ("Spine1", 0.1),
        ("Spine2", 0.1),
        ("Neck", 0.2),
        ("Head", 0.1),
    ):
        off[J[name]] = (0.0, up, 0.0)
    off[J["LeftUpLeg"]] = (0.09, -0.12, 0.0)
    off[J["LeftLeg"]] = (0.0, -0.4, 0.0)
    off[J["LeftFoot"]] = (0.0, -0.4, 0.0)
    off[J["LeftToeBase"]] = (0.0, -0.06, 0.08)
    off[J["RightUpLeg"]] = (-0.09, -0.12, 0.0)
    off[J["RightLeg"]] = (0.0, -0.42, 0.0)
    off[J["RightFoot"]] = (0.0, -0.4, 0.0)
    off[J["RightToeBase"]] = (0.0, -0.05, 0.08)
    for side, sx in (("Left", 1.0), ("Right", -1.0)):
        off[J[f"{side}Shoulder"]] = (sx * 0.05, 0.05, 0.0)
        off[J[f"{side}Arm"]] = (sx * 0.1, 0.0, 0.0)
        off[J[f"{side}ForeArm"]] = (sx * 0.3, 0.0, 0.0)
        off[J[f"{side}Hand"]] = (sx * 0.25, 0.0, 0.0)
    return off


#: ``(4, 3)`` a hand-built rest mesh: soles 5 mm below the floor, the crown at 1.75 m
MESH = np.array([[0.0, -0.005, 0.0], [0.1, 1.75, 0.0], [0.05, 0.9, 0.2], [-0.1, 0.3, -0.1]])


def test_the_rest_pose_is_the_offsets_summed_down_the_tree():
    rest = canonical22_skeleton(_offsets()).rest_positions()
    np.testing.assert_allclose(rest[J["Head"]], [0.0, 1.6, 0.0], atol=EXACT)
    np.testing.assert_allclose(rest[J["LeftFoot"]], [0.09, 0.08, 0.0], atol=EXACT)
    np.testing.assert_allclose(rest[J["RightToeBase"]], [-0.09, 0.01, 0.08], atol=EXACT)
    np.testing.assert_allclose(rest[J["LeftHand"]], [0.7, 1.35, 0.0], atol=EXACT)


def test_nkn_height_is_the_spine_chain_plus_the_left_leg():
    sk = canonical22_skeleton(_offsets())
    # 0.1 + 0.1 + 0.1 + 0.2 + 0.1 (root -> head) + 0.4 + 0.4 + 0.1 (left thigh, shin, toe bone)
    assert sk.height() == pytest.approx(1.5, abs=EXACT)
    assert (
        Character("hand", sk, MESH, np.zeros((0, 3)), np.full((4, 22), 1 / 22)).height
        == sk.height()
    )
    longer_right = _offsets()
    longer_right[J["RightLeg"], 1] = -0.6  # the right leg is not in H
    assert canonical22_skeleton(longer_right).height() == sk.height()
    batch = torch.as_tensor(np.stack([_offsets(), 2 * _offsets()]), dtype=torch.float32)
    torch.testing.assert_close(nkn_height(batch), torch.tensor([1.5, 3.0]), rtol=1e-6, atol=0.0)
    assert nkn_height(torch.as_tensor(_offsets())).item() == pytest.approx(sk.height(), abs=EXACT)


def test_nkn_height_of_tensors_is_differentiable():
    off = torch.tensor(_offsets(), requires_grad=True)
    nkn_height(off).backward()
    # d|s|/ds = s/|s| for each height bone, zero elsewhere
    np.testing.assert_allclose(off.grad[J["LeftToeBase"]].numpy(), [0.0, -0.6, 0.8], atol=EXACT)
    assert not off.grad[J["RightLeg"]].any() and not off.grad[J["Hips"]].any()


def test_leg_length_is_the_hips_above_the_lowest_foot_joint():
    sk = canonical22_skeleton(_offsets())
    # the right toe is the lowest
    assert skeleton_leg_length(sk) == pytest.approx(1.0 - 0.01, abs=EXACT)
    batch = torch.as_tensor(np.stack([_offsets(), 2 * _offsets()]), dtype=torch.float32)
    torch.testing.assert_close(leg_length(batch), torch.tensor([0.99, 1.98]), rtol=1e-6, atol=0.0)


def test_rest_ground_of_a_skeleton_on_the_floor_and_of_a_bvh_skeleton():
    sk = canonical22_skeleton(_offsets())
    assert rest_ground(sk) == 0.0  # every foot joint above y = 0
    np.testing.assert_allclose(foot_rest_heights(sk), [0.08, 0.06, 0.02, 0.01], atol=EXACT)
    bvh_like = _offsets()
    bvh_like[J["Hips"]] = 0.0  # root at the origin: the feet hang below y = 0
    bvh = canonical22_skeleton(bvh_like)
    assert rest_ground(bvh) == pytest.approx(0.01 - 1.0, abs=EXACT)  # the right toe is its sole
    np.testing.assert_allclose(foot_rest_heights(bvh), [0.07, 0.05, 0.01, 0.0], atol=EXACT)


def test_rest_ground_and_foot_rest_heights_of_a_mesh():
    sk = canonical22_skeleton(_offsets())
    assert mesh_ground(MESH) == -0.005 and isinstance(mesh_ground(MESH), float)
    assert rest_ground(sk, MESH) == -0.005
    np.testing.assert_allclose(
        foot_rest_heights(sk, MESH), [0.085, 0.065, 0.025, 0.015], atol=EXACT
    )
    assert rest_ground(sk, np.zeros((0, 3))) == rest_ground(sk)  # an empty mesh is no mesh


def test_estimated_standing_height_is_the_head_joint_plus_the_head_top():
    assert HEAD_TOP_FACTOR == 1.12
    assert estimated_standing_height(canonical22_skeleton(_offsets())) == pytest.approx(
        1.12 * 1.6, abs=EXACT
    )
    bvh_like = _offsets()
    bvh_like[J["Hips"]] = 0.0  # head at 0.6, ground at -0.99
    assert estimated_standing_height(canonical22_skeleton(bvh_like)) == pytest.approx(
        1.12 * 1.59, abs=EXACT
    )


def test_mesh_standing_height_is_the_meshs_vertical_extent():
    height = mesh_standing_height(MESH)
    assert height == pytest.approx(1.755, abs=EXACT) and isinstance(height, float)
    batch = torch.as_tensor(np.stack([MESH, 2 * MESH]), dtype=torch.float32)
    torch.testing.assert_close(
        mesh_standing_height(batch), torch.tensor([1.755, 3.51]), rtol=1e-6, atol=0.0
    )
    torch.testing.assert_close(
        mesh_ground(batch), torch.tensor([-0.005, -0.01]), rtol=1e-6, atol=0.0
    )
    np.testing.assert_allclose(
        mesh_standing_height(np.stack([MESH, 2 * MESH])), [1.755, 3.51], atol=EXACT
    )


def test_foot_contact_thresholds_take_the_height_from_the_caller():
    # no default height: every caller names the height it scales Sec. 3.4's thresholds with
    assert (
        inspect.signature(detect_foot_contacts).parameters["character_height"].default
        is inspect.Parameter.empty
    )
