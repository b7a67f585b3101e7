"""A character built of several meshes, each with its own skin, as Blender exports it to FBX
(issue 28: such a file fell apart, a detached giant head).

``tests/data/multi_mesh_blender.fbx`` (made by ``tests/data/make_multi_mesh_fbx.py`` with Blender's
own FBX exporter): the synthetic character ``gus``, decimated to a tenth, with its head, hands and
feet as separate meshes, each under its own object transform (a head in centimetres, hands moved
and turned, feet scaled unevenly), the mesh data compensated so that nothing moves, and an eye
parented to the head bone without a skin.
"""

from pathlib import Path

import numpy as np
import pytest
from scipy.spatial import cKDTree

from retarget_lib.cli import main
from retarget_lib.core.rig import Rig
from retarget_lib.data.sources.cmu import cmu_clip_path
from retarget_lib.data.synthetic.characters import make_character
from retarget_lib.io import fbx, load_bvh, save_bvh
from retarget_lib.io.fbx import fbx_missing, load_fbx_rig
from retarget_lib.io.gltf import load_gltf_motion, skin

pytestmark = [
    pytest.mark.tooling,
    pytest.mark.skipif(
        fbx_missing() is not None, reason=f"fbx extra not installed: {fbx_missing()}"
    ),
]
FILE = Path(__file__).parent / "data" / "multi_mesh_blender.fbx"
#: metres: the file's mesh is the character decimated to a tenth (vertices collapsed onto their
#: neighbours: at most 3.9 cm from a vertex of the full mesh, measured)
DECIMATION_M = 0.05


def _distance_to_character(vertices: np.ndarray) -> np.ndarray:
    """Each vertex's distance to the nearest vertex of the full-resolution character."""
    rig = Rig.from_character(make_character("gus"))
    return cKDTree(rig.rest_vertices).query(vertices)[0]


def test_every_mesh_is_bound_by_its_own_bind_matrices():
    rig = load_fbx_rig(FILE)
    gus = Rig.from_character(make_character("gus"))
    joints = rig.character().skeleton.rest_positions()  # canonical-22 order, as gus's
    assert np.abs(joints - gus.character().skeleton.rest_positions()).max() < 2e-3  # Blender: 1 mm
    assert _distance_to_character(rig.rest_vertices).max() < DECIMATION_M
    np.testing.assert_allclose(
        np.ptp(rig.rest_vertices, axis=0), np.ptp(gus.rest_vertices, axis=0), atol=0.01
    )  # one body as tall, wide and deep as the character (1 cm: decimation)


def test_the_shared_skin_alone_tears_the_body_apart(monkeypatch):
    """What assimp's glTF export keeps (one skin, each joint bound as in the first mesh) puts the
    head, hands and feet metres away: the check above fails without each mesh's own matrices."""
    monkeypatch.setattr(fbx, "_mesh_binds", lambda doc, binds: None)
    assert _distance_to_character(load_fbx_rig(FILE).rest_vertices).max() > 1.0


def test_a_mesh_parented_to_a_bone_moves_with_it(monkeypatch):
    """The eye (no skin, a child of the head bone) is part of the body, weighted wholly to the
    head; without it the reader had only the skinned meshes."""
    rig = load_fbx_rig(FILE)
    character = rig.character()
    head = character.skeleton.index("Head")
    on_head = character.weights[:, head] == 1.0
    monkeypatch.setattr(skin, "_rigid_nodes", lambda doc, tree: {})
    without = load_fbx_rig(FILE)
    extra = len(rig.rest_vertices) - len(without.rest_vertices)
    assert extra > 0 and on_head[len(without.rest_vertices) :].all()
    # the eye sits on the front of the head (the check above: on the character's surface)
    eye = rig.rest_vertices[len(without.rest_vertices) :]
    assert eye[:, 1].min() > character.skeleton.rest_positions()[head, 1] - 0.05


def test_a_retarget_onto_it_writes_one_body(tmp_path):
    out = tmp_path / "onto_multi_mesh.glb"
    source = tmp_path / "walk.bvh"
    save_bvh(load_bvh(cmu_clip_path("01_01.bvh")).slice(0, 60), source)
    assert (
        main(
            [
                "retarget",
                "--source",
                str(source),
                "--target",
                str(FILE),
                "--method",
                "copy",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    motion, rig = load_gltf_motion(out)
    assert motion.num_frames == 60
    assert _distance_to_character(rig.rest_vertices).max() < DECIMATION_M
