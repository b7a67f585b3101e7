"""The synthetic character family (retarget_lib.data.synthetic.characters)."""

import math

import numpy as np
import pytest
import torch
import trimesh

from retarget_lib.core.character import Character
from retarget_lib.core.skeleton import CANONICAL22, CANONICAL22_PARENTS, J
from retarget_lib.data.synthetic.characters import (
    CHARACTER_NAMES,
    CHARACTER_SPECS,
    all_characters,
    build_character,
    make_character,
    random_character,
)
from retarget_lib.data.synthetic.proportions import REFERENCE_OFFSETS, CharacterSpec


@pytest.fixture(scope="module")
def chars() -> list[Character]:
    return all_characters()


def _segment_distance(p, a, b):
    ab = b - a
    t = np.clip((p - a) @ ab / (ab @ ab), 0.0, 1.0)
    return float(np.linalg.norm(p - a - t * ab))


def _arm_angle(c: Character) -> float:
    """Degrees below horizontal of the left upper arm."""
    d = c.skeleton.offsets[J["LeftForeArm"]]
    return math.degrees(math.atan2(-d[1], math.hypot(d[0], d[2])))


def test_named_family(chars):
    assert len(CHARACTER_NAMES) >= 16 and len(set(CHARACTER_NAMES)) == len(CHARACTER_NAMES)
    assert [c.name for c in chars] == list(CHARACTER_NAMES)
    assert all(c.skeleton.is_canonical22() for c in chars)


def test_heights_span_the_range(chars):
    heights = np.array([c.height for c in chars])
    assert heights.min() >= 1.2 and heights.max() <= 2.1
    assert heights.max() - heights.min() >= 0.7
    spec_heights = np.array([s.height for s in CHARACTER_SPECS])
    np.testing.assert_allclose(heights, spec_heights, atol=1e-9)


def test_length_factors_against_reference(chars):
    ref = np.linalg.norm(REFERENCE_OFFSETS[1:], axis=1)
    ratios = []
    for c in chars:
        ratio = np.linalg.norm(c.skeleton.offsets[1:], axis=1) / (c.style["scale"] * ref)
        assert ratio.min() >= 0.6 - 1e-9 and ratio.max() <= 1.5 + 1e-9, c.name
        ratios.append(ratio)
    ratios = np.array(ratios)
    assert ratios.min() < 0.75 and ratios.max() > 1.35  # the family really varies proportions


def test_meshes_are_single_closed_bodies(chars):
    for c in chars:
        assert 1000 <= c.num_vertices <= 5000, c.name
        mesh = trimesh.Trimesh(c.rest_vertices, c.faces, process=False)
        assert mesh.is_watertight and mesh.is_winding_consistent, c.name
        assert len(mesh.split(only_watertight=False)) == 1, c.name
        assert mesh.volume > 0, c.name  # outward-facing triangles
        assert mesh.area_faces.min() > 1e-9, c.name
        assert len(np.unique(c.faces)) == c.num_vertices, c.name


def test_torsos_are_smooth_not_terraced(chars):
    """Neighbouring torso triangles meet at small angles: no stair-step terraces.

    The torsos are lofts of ellipses a few hundred triangles wide, so two neighbours differ by a
    few degrees (median ~7 deg after decimation); the terraces once left by the marching-cubes
    clamp doubled that on the bulky bodies (median 11-20 deg, half of the pairs above 20 deg).
    """
    for c in chars:
        mesh = trimesh.Trimesh(c.rest_vertices, c.faces, process=False)
        owner = c.weights.argmax(1)
        torso = np.isin(owner[c.faces], [J[n] for n in ("Spine", "Spine1", "Spine2")]).all(1)
        pairs = torso[mesh.face_adjacency[:, 0]] & torso[mesh.face_adjacency[:, 1]]
        angles = np.degrees(mesh.face_adjacency_angles[pairs])
        assert np.median(angles) < 9.0 and (angles > 20).mean() < 0.15, (c.name, np.median(angles))


def test_frame_feet_on_ground_facing_z(chars):
    for c in chars:
        pos = c.rest_joint_positions()
        assert abs(c.rest_vertices[:, 1].min()) < 1e-9, c.name
        assert pos[J["Head"], 1] > pos[J["Hips"], 1] > 0.4
        assert pos[J["LeftToeBase"], 2] > pos[J["LeftFoot"], 2]
        assert pos[J["LeftHand"], 0] > 0 > pos[J["RightHand"], 0]
        lo, hi = c.rest_vertices.min(0), c.rest_vertices.max(0)
        assert np.all(pos >= lo) and np.all(pos <= hi), c.name


def test_weights_are_top4_convex(chars):
    for c in chars:
        assert c.weights.shape == (c.num_vertices, 22)
        assert (c.weights >= 0).all()
        np.testing.assert_allclose(c.weights.sum(1), 1.0, atol=1e-9)
        assert (c.weights > 0).sum(1).max() <= 4


def test_weight_groups_sit_on_their_bones(chars):
    """Vertices with weight >= 0.5 (Villegas et al. 2021, Sec. 3.2) form each body part."""
    children = {j: [k for k, p in enumerate(CANONICAL22_PARENTS) if p == j] for j in range(22)}
    for c in chars:
        pos = c.rest_joint_positions()
        for j, name in enumerate(CANONICAL22):
            group = c.weights[:, j] >= 0.5
            assert group.sum() >= 5, (c.name, name)
            centroid = c.rest_vertices[group].mean(0)
            if children[j]:
                dist = min(_segment_distance(centroid, pos[j], pos[k]) for k in children[j])
                assert dist < 0.05 * c.height, (c.name, name, dist)
            else:  # head, hands, toes lie beyond their joint, which is still the nearest one
                assert np.linalg.norm(pos - centroid, axis=1).argmin() == j, (c.name, name)


def test_hands_are_solid_paddles(chars):
    for c in chars:
        pos = c.rest_joint_positions()
        hand = c.rest_vertices[c.weights[:, J["LeftHand"]] >= 0.5]
        along = pos[J["LeftHand"]] - pos[J["LeftForeArm"]]
        along /= np.linalg.norm(along)
        length = np.ptp(hand @ along)
        thickness = np.ptp(hand[:, 2]), np.ptp(hand[:, 1])
        assert length > 0.08 * c.style["scale"], c.name
        assert min(thickness) > 0.02 * c.style["scale"], c.name


def test_rest_poses_differ(chars):
    by_name = {c.name: c for c in chars}
    t_pose, a_pose = by_name["ada"], by_name["nova"]
    assert abs(_arm_angle(t_pose)) < 1.0
    assert 45.0 < _arm_angle(a_pose) < 55.0
    for c in chars:
        assert (c.style["rest_pose"] == "A-pose") == (_arm_angle(c) >= 15.0), c.name
    tags = {c.style["rest_pose"] for c in chars}
    assert tags == {"T-pose", "A-pose"}
    assert any(c.style["knee_bend_deg"] > 0 for c in chars)
    assert any(c.style["spine_curve_deg"] > 0 for c in chars) and any(
        c.style["spine_curve_deg"] < 0 for c in chars
    )


def test_skinny_and_bulky(chars):
    kinds = {k: [c for c in chars if c.body_type == k] for k in ("skinny", "average", "bulky")}
    assert len(kinds["skinny"]) >= 3 and len(kinds["bulky"]) >= 3
    girth = {c.name: trimesh.Trimesh(c.rest_vertices, c.faces).volume / c.height**3 for c in chars}
    assert max(girth[c.name] for c in kinds["skinny"]) < min(girth[c.name] for c in kinds["bulky"])


def test_identity_pose_skins_to_rest(chars):
    c = chars[0]
    rot = np.zeros((2, 22, 4))
    rot[..., 0] = 1.0
    root = np.repeat(c.skeleton.offsets[:1], 2, axis=0)
    np.testing.assert_allclose(
        c.skinned(rot, root), np.repeat(c.rest_vertices[None], 2, 0), atol=1e-12
    )
    out = c.skinned(torch.tensor(rot, dtype=torch.float32), torch.tensor(root, dtype=torch.float32))
    assert out.dtype == torch.float32 and out.shape == (2, c.num_vertices, 3)


def test_deterministic_and_cached_copies():
    spec = CHARACTER_SPECS[3]
    a, b = build_character(spec), build_character(spec)
    np.testing.assert_array_equal(
        a.rest_vertices, b.rest_vertices
    )  # the same code twice in one process: exact
    np.testing.assert_array_equal(a.faces, b.faces)
    np.testing.assert_array_equal(a.weights, b.weights)
    np.testing.assert_array_equal(a.skeleton.offsets, b.skeleton.offsets)
    c = make_character(spec.name)
    c.rest_vertices[:] = 0.0
    assert np.ptp(make_character(spec.name).rest_vertices[:, 1]) > 1.0


def test_random_characters():
    a, b, c = random_character(7), random_character(7), random_character(8)
    np.testing.assert_array_equal(
        a.rest_vertices, b.rest_vertices
    )  # copied (cached), not recomputed: exact
    assert a.name == "random-7" and a.height != c.height
    for x in (a, c):
        assert 1.2 <= x.height <= 2.1 and 1000 <= x.num_vertices <= 5000
        assert trimesh.Trimesh(x.rest_vertices, x.faces, process=False).is_watertight


def test_bad_names_and_factors():
    with pytest.raises(KeyError, match="ada"):
        make_character("nobody")
    with pytest.raises(ValueError, match="thigh"):
        build_character(CharacterSpec("odd", 1.5, thigh=1.8))


# ----------------------------------------------------------------------------- mannequin-x
@pytest.fixture(scope="module")
def mannequin():
    pytest.importorskip("mannequin", reason="mannequin-x is not installed")
    from retarget_lib.data.sources.mannequin import load_mannequin

    return load_mannequin()


def test_mannequin_layout(mannequin):
    c = mannequin
    assert c.name == "mannequin-x" and c.skeleton.is_canonical22()
    assert c.num_vertices == 24256 and c.faces.shape == (48396, 3)
    assert c.weights.shape == (24256, 22)
    np.testing.assert_allclose(c.weights.sum(1), 1.0, atol=1e-9)
    assert (c.weights >= 0).all()


def test_mannequin_frame_and_size(mannequin):
    c = mannequin
    pos = c.rest_joint_positions()
    lo, hi = c.rest_vertices.min(0), c.rest_vertices.max(0)
    assert np.all(pos > lo) and np.all(pos < hi)
    assert lo[1] == pytest.approx(0.0, abs=1e-9)  # soles on the ground
    assert 1.5 < hi[1] < 2.0  # a plausible adult, in metres
    assert 1.3 < c.height < 1.8
    assert pos[J["LeftToeBase"], 2] > pos[J["LeftFoot"], 2]  # faces +Z
    assert pos[J["LeftHand"], 0] > 0.5 > -0.5 > pos[J["RightHand"], 0]  # T-pose, left at +X
    # the hands' skin (fingers folded into the wrists) surrounds the wrist joints
    hand = c.rest_vertices[c.weights[:, J["LeftHand"]] >= 0.5]
    assert len(hand) > 1000 and hand[:, 0].min() < pos[J["LeftHand"], 0] + 0.02


def test_mannequin_identity_pose(mannequin):
    c = mannequin
    rot = np.zeros((1, 22, 4))
    rot[..., 0] = 1.0
    out = c.skinned(rot, c.skeleton.offsets[:1])
    np.testing.assert_allclose(out[0], c.rest_vertices, atol=1e-9)


def test_mannequin_checksum():
    pytest.importorskip("mannequin", reason="mannequin-x is not installed")
    from retarget_lib.data.sources.mannequin import MANNEQUIN_SHA256, mannequin_path
    from retarget_lib.files import sha256_file

    assert sha256_file(mannequin_path()) == MANNEQUIN_SHA256


def test_mannequin_missing_package_says_how_to_install(monkeypatch):
    import importlib.resources

    from retarget_lib.data.sources.mannequin import load_mannequin
    from retarget_lib.files import DataError

    def missing(name):
        raise ModuleNotFoundError(name)

    monkeypatch.setattr(importlib.resources, "files", missing)
    with pytest.raises(DataError, match="pip install mannequin-x"):
        load_mannequin()
