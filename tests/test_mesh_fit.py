"""A target mesh whose skeleton differs a little from the target's (real exports: 1-2.5 cm) is
rebound to the target's skeleton, with one warning line beyond 1 % of the height; beyond 5 % it is
refused as another character's (issue 24)."""

import warnings

import numpy as np
import pytest

from retarget_lib.cli import main
from retarget_lib.data.synthetic.characters import make_character
from retarget_lib.data.synthetic.motions import make_motion
from retarget_lib.errors import RetargetInputError, RetargetWarning
from retarget_lib.io import save_bvh
from retarget_lib.io.shape import save_shape_npz
from retarget_lib.methods.inputs import MESH_LIMIT, MESH_WARN, load_target, rebind_mesh


def _stretched(character, factor):
    """The character with every bone below the root ``factor`` times longer (its mesh unchanged)."""
    other = character.copy()
    other.skeleton.offsets[1:] *= factor
    return other


def _root_relative(skeleton):
    rest = skeleton.rest_positions()
    return rest - rest[0]


def test_rebinding_moves_each_vertex_with_its_joints():
    gus = make_character("gus")
    target = _stretched(gus, 1.03).skeleton
    target.offsets[0, 1] -= 0.9  # a BVH-like root placement: the mesh keeps its own
    bound = rebind_mesh(gus, target)
    moved = _root_relative(target) - _root_relative(gus.skeleton)
    np.testing.assert_allclose(
        bound.rest_vertices - gus.rest_vertices, gus.weights @ moved, atol=1e-12
    )  # same sums
    np.testing.assert_allclose(bound.skeleton.offsets[1:], target.offsets[1:])  # copied
    np.testing.assert_array_equal(bound.skeleton.offsets[0], gus.skeleton.offsets[0])  # copied
    # a vertex bound to one joint only moves exactly with it
    one = gus.copy()
    one.weights[0] = np.eye(22)[gus.skeleton.index("LeftHand")]
    np.testing.assert_allclose(
        rebind_mesh(one, target).rest_vertices[0] - gus.rest_vertices[0],
        moved[gus.skeleton.index("LeftHand")],
        atol=1e-12,
    )


@pytest.fixture()
def files(tmp_path):
    gus = make_character("gus")
    save_bvh(make_motion("walk", gus.skeleton, 0, 0.1), tmp_path / "gus.bvh")
    for name, factor in (("close", 1.002), ("real", 1.03), ("other", 1.10)):
        save_shape_npz(_stretched(gus, factor), tmp_path / f"{name}.npz")
    return tmp_path


@pytest.mark.parametrize("name,warns", [("close", False), ("real", True)])
def test_a_mesh_within_5_percent_is_rebound(files, name, warns):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        target = load_target(str(files / "gus.bvh"), files / f"{name}.npz")
    ours = [w for w in caught if issubclass(w.category, RetargetWarning)]
    assert len(ours) == int(warns)
    if warns:
        assert f"{name}.npz" in str(ours[0].message) and "rebound" in str(ours[0].message)
    np.testing.assert_allclose(
        _root_relative(target.character.skeleton), _root_relative(target.skeleton), atol=1e-9
    )  # sums of the same offsets (BVH text: 6 decimals of cm)
    assert MESH_WARN < MESH_LIMIT


def test_a_mesh_beyond_5_percent_is_refused(files):
    with pytest.raises(
        RetargetInputError, match=r"other\.npz: .*more than 5%: a mesh of another character"
    ):
        load_target(str(files / "gus.bvh"), files / "other.npz")


def test_the_command_prints_one_warning_line_and_runs(files, capsys):
    out = files / "o.bvh"
    assert (
        main(
            [
                "retarget",
                "--source",
                str(files / "gus.bvh"),
                "--target",
                str(files / "gus.bvh"),
                "--method",
                "contact",
                "--target-mesh",
                str(files / "real.npz"),
                "--out",
                str(out),
            ]
        )
        == 0
    )
    err = capsys.readouterr().err.strip().splitlines()
    assert (
        len(err) == 1 and err[0].startswith("retarget retarget: warning: ") and "real.npz" in err[0]
    ), err
    assert out.exists()
