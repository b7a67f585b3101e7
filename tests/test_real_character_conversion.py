"""tools/real_characters.py: a mesh that assimp binds through the wrong bone is re-bound where its
node places it (the Quaternius goblin's face and cowboy's hat were drawn at the feet)."""

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest

_TOOL = Path(__file__).resolve().parents[1] / "tools" / "real_characters.py"
_spec = importlib.util.spec_from_file_location("real_characters_tool", _TOOL)
rc = importlib.util.module_from_spec(_spec)
sys.modules[_spec.name] = rc  # its dataclasses look their module up
_spec.loader.exec_module(rc)


def _translate(x, y, z):
    m = np.eye(4)
    m[:3, 3] = x, y, z
    return m


def _quad(n_vertices=4):
    return rc.Primitive(
        positions=np.random.default_rng(0).uniform(-0.05, 0.05, (n_vertices, 3)),
        faces=np.array([[0, 1, 2], [0, 2, 3]]),
        joints=np.zeros((n_vertices, 4), dtype=np.int64),
        weights=np.tile([1.0, 0.0, 0.0, 0.0], (n_vertices, 1)),
    )


def _doc(body_node, part_node):
    """Joints root (0, 0, 0) and head (0, 1.6, 0); a body mesh bound to the root and a small part
    whose node puts it at (0, 1.7, 0), both bound with the skin's matrices (the body's)."""
    nodes = [
        rc.Node("root", np.eye(4), [1]),
        rc.Node("head", _translate(0, 1.6, 0)),
        rc.Node("body", body_node, mesh=0, skin=0),
        rc.Node("part", part_node, mesh=1, skin=0),
    ]
    skin = rc.Skin([0, 1], np.stack([np.eye(4), np.linalg.inv(_translate(0, 1.6, 0))]))
    return rc.Doc(nodes, [[_quad()], [_quad()]], [skin], roots=[0, 2, 3])


def _skinned(doc, mesh):
    world = doc.world()
    skin = doc.skins[0]
    binds = np.stack([world[j] @ skin.ibm[k] for k, j in enumerate(skin.joints)])
    p = doc.meshes[mesh][0]
    blend = np.einsum("vk,vkab->vab", p.weights, binds[p.joints])
    return np.einsum("vab,vb->va", blend, np.c_[p.positions, np.ones(len(p.positions))])[:, :3]


def test_a_part_the_skin_draws_at_the_feet_is_bound_to_the_joint_where_its_node_puts_it():
    doc = _doc(np.eye(4), _translate(0, 1.7, 0))
    part = doc.meshes[1][0].positions.copy()
    assert _skinned(doc, 1)[:, 1].max() < 0.1  # at the feet before
    assert rc.rebind_misplaced_meshes(doc) == ["part -> head"]
    np.testing.assert_allclose(_skinned(doc, 1), part + [0, 1.7, 0], atol=1e-12)
    assert (doc.meshes[1][0].joints[:, 0] == 1).all()  # follows the head
    np.testing.assert_array_equal(doc.meshes[1][0].weights[:, 0], 1.0)
    assert (doc.meshes[0][0].joints == 0).all()  # the body, which agrees with its node, is kept


@pytest.mark.parametrize("body_y", [0.5, 1.7])
def test_nothing_moves_when_no_mesh_agrees_with_its_node(body_y):
    # vertices already in the skin's space (BCN_Epileptic.X): the node transforms mean nothing
    doc = _doc(_translate(0, body_y, 0), _translate(0, 1.7, 0))
    before = [m[0].positions.copy() for m in doc.meshes]
    assert rc.rebind_misplaced_meshes(doc) == []
    for m, b in zip(doc.meshes, before, strict=True):
        np.testing.assert_array_equal(m[0].positions, b)
