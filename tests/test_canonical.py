"""Folding other joint sets onto the canonical 22 (``to_canonical22``: the rig conventions of
``io.rig_maps``, then ``core.canonical.fold_to_canonical22``), resampling and root
normalisation, on hand-made skeletons and the real ``cmu-assimp`` clips."""

import numpy as np
import pytest
import torch

from retarget_lib.core.canonical import fold_to_canonical22, unfold_from_canonical22
from retarget_lib.core.motion import Motion
from retarget_lib.core.rotations import (
    quat_conjugate,
    quat_from_axis_angle,
    quat_mul,
    quat_rotate,
    quat_to_matrix,
)
from retarget_lib.core.skeleton import CANONICAL22, CANONICAL22_PARENTS, JointSetError, Skeleton
from retarget_lib.data.sources.cmu import CMU_CLIPS, cmu_clip_path, load_cmu_clip
from retarget_lib.io import load_bvh
from retarget_lib.io.joint_maps import present_map, to_canonical22
from retarget_lib.io.rig_maps import strip_prefix


def mixamo_motion(seed=0, frames=40, twists=None, rename=None) -> Motion:
    """A Mixamo-style motion: ``mixamorig:`` names, three-finger chains, ``HeadTop_End`` and
    ``*Toe_End`` leaves, random offsets and rotations.

    Args:
        twists: ``{child: twist}``: insert a zero-offset joint ``twist`` between ``child`` and its
            parent (a rotating intermediate joint that the fold must absorb).
        rename: ``{name: new name}`` applied last.
    """
    twists = twists or {}
    spec = [
        ("Hips", None, (0, 1.0, 0)),
        ("Spine", "Hips", (0, 0.1, 0)),
        ("Spine1", "Spine", (0, 0.12, 0)),
        ("Spine2", "Spine1", (0, 0.12, 0)),
        ("Neck", "Spine2", (0, 0.15, 0)),
        ("Head", "Neck", (0, 0.1, 0.02)),
        ("HeadTop_End", "Head", (0, 0.18, 0)),
    ]
    for side, s in (("Left", 1), ("Right", -1)):
        spec += [
            (f"{side}Shoulder", "Spine2", (s * 0.06, 0.1, 0)),
            (f"{side}Arm", f"{side}Shoulder", (s * 0.12, 0, 0)),
            (f"{side}ForeArm", f"{side}Arm", (s * 0.27, 0, 0)),
            (f"{side}Hand", f"{side}ForeArm", (s * 0.25, 0, 0)),
        ]
        for finger, z in (("Thumb", 0.03), ("Index", 0.01), ("Middle", -0.01)):
            parent = f"{side}Hand"
            for k in range(1, 5):
                spec.append((f"{side}Hand{finger}{k}", parent, (s * 0.03, 0, z)))
                parent = f"{side}Hand{finger}{k}"
    for side, s in (("Left", 1), ("Right", -1)):
        spec += [
            (f"{side}UpLeg", "Hips", (s * 0.09, -0.06, 0)),
            (f"{side}Leg", f"{side}UpLeg", (0, -0.42, 0)),
            (f"{side}Foot", f"{side}Leg", (0, -0.4, 0)),
            (f"{side}ToeBase", f"{side}Foot", (0, -0.08, 0.12)),
            (f"{side}Toe_End", f"{side}ToeBase", (0, 0, 0.06)),
        ]
    rng = np.random.default_rng(seed)
    names, parents, offsets = [], [], []
    for name, parent, off in spec:
        if name in twists:
            names.append(twists[name])
            parents.append(names.index(parent))
            offsets.append(np.zeros(3))
            parent = twists[name]
        names.append(name)
        parents.append(-1 if parent is None else names.index(parent))
        offsets.append(np.array(off) + rng.normal(size=3) * 0.01)
    names = [(rename or {}).get(n, n) for n in names]
    sk = Skeleton([f"mixamorig:{n}" for n in names], parents, np.array(offsets))
    rot = quat_from_axis_angle(
        torch.from_numpy(rng.normal(size=(frames, len(names), 3)) * 0.7)
    ).numpy()
    return Motion(sk, rot, rng.normal(size=(frames, 3)), fps=30)


def kept_errors(source: Motion, folded: Motion) -> dict[str, np.ndarray]:
    """``{canonical name: (T,) world-position error in metres}`` for every kept source joint."""
    g, gc = source.global_positions(), folded.global_positions()
    cmap, _ = present_map(source.skeleton)
    return {CANONICAL22[c]: np.linalg.norm(g[:, s] - gc[:, c], axis=-1) for s, c in cmap.items()}


def same_rotation(q1, q2, tol):
    m1, m2 = (quat_to_matrix(torch.as_tensor(q)).numpy() for q in (q1, q2))
    return np.abs(m1 - m2).max() < tol


# ------------------------------------------------------------------------ hand-made skeletons
def test_mixamo_with_fingers_folds_exactly():
    m = mixamo_motion()
    assert m.skeleton.num_joints == 22 + 1 + 2 * 12 + 2  # HeadTop_End, 3x4 finger joints, Toe_End
    c = to_canonical22(m)
    assert c.skeleton.joint_names == CANONICAL22 and c.skeleton.parents == CANONICAL22_PARENTS
    assert c.num_frames == m.num_frames and c.fps == m.fps
    errors = kept_errors(m, c)
    assert len(errors) == 22 and max(e.max() for e in errors.values()) < 1e-6
    # nothing was folded in between kept joints, so the global rotations are the originals too
    src = [strip_prefix(n) for n in m.skeleton.joint_names]
    g, gc = m.fk().rotations, c.fk().rotations
    for k, name in enumerate(CANONICAL22):
        assert same_rotation(g[:, src.index(name)], gc[:, k], 1e-9), name


def test_zero_offset_rotating_intermediate_joints_fold_exactly():
    # twist joints between a kept joint and its only kept child: the child's distance from its
    # kept parent never changes, so the refitted parent rotation absorbs the twist exactly
    twists = {"Spine2": "Spine1Twist", "Head": "NeckTwist", "LeftFoot": "LeftLegTwist"}
    m = mixamo_motion(seed=1, twists=twists)
    twist_idx = [m.skeleton.index(f"mixamorig:{t}") for t in twists.values()]
    angles = 2 * np.arccos(np.clip(np.abs(m.rotations[:, twist_idx, 0]), 0, 1))
    assert angles.max() > 1.0  # they really rotate
    c = to_canonical22(m)
    errors = kept_errors(m, c)
    assert max(e.max() for e in errors.values()) < 1e-6, {k: e.max() for k, e in errors.items()}
    # the folded offset is the rest-pose sum along the removed chain
    for child, _twist in twists.items():
        i = m.skeleton.index(f"mixamorig:{child}")
        np.testing.assert_allclose(
            c.skeleton.offsets[CANONICAL22.index(child)], m.skeleton.offsets[i]
        )
    # the parent's new global rotation is the old one followed by a pure swing: the swing axis is
    # perpendicular to where the old rotation pointed the bone, i.e. the old twist is kept
    neck = CANONICAL22.index("Neck")
    old = torch.from_numpy(m.fk().rotations[:, m.skeleton.index("mixamorig:Neck")])
    swing = quat_mul(torch.from_numpy(c.fk().rotations[:, neck]), quat_conjugate(old))
    bone = quat_rotate(old, torch.from_numpy(c.skeleton.offsets[CANONICAL22.index("Head")]))
    assert (swing[:, 1:] * bone).sum(-1).abs().max() < 1e-9
    assert swing[:, 1:].norm(dim=-1).max() > 0.1  # a real swing, not the identity


def test_missing_joint_is_named():
    m = mixamo_motion(rename={"LeftFoot": "LeftAnkle"})
    with pytest.raises(JointSetError, match=r"clip.bvh: cannot map joints \['LeftFoot'\]"):
        to_canonical22(m, what="clip.bvh")


def test_a_22_joint_set_in_another_order_is_only_reordered():
    # the canonical 22 under SMPL-X names and in SMPL-X order: nothing is refitted, every number is
    # kept
    from retarget_lib.io.amass import SMPLX_BODY_NAMES, SMPLX_BODY_PARENTS, SMPLX_TO_CANONICAL

    m = mixamo_motion(seed=3)
    c = to_canonical22(m)
    order = list(SMPLX_TO_CANONICAL)  # canonical c is SMPL-X joint order[c]
    back = [order.index(j) for j in range(22)]
    smplx = Motion(
        Skeleton(SMPLX_BODY_NAMES, SMPLX_BODY_PARENTS, c.skeleton.offsets[back]),
        c.rotations[:, back],
        c.root_positions,
        c.fps,
    )
    again = to_canonical22(smplx)
    assert again.meta["folded_from"] == "smplx"
    np.testing.assert_array_equal(again.skeleton.offsets, c.skeleton.offsets)
    np.testing.assert_array_equal(again.rotations, c.rotations)


def test_an_index_map_missing_a_needed_joint_is_refused():
    m = mixamo_motion()
    found, _ = present_map(m.skeleton)
    hand = next(i for i, c in found.items() if CANONICAL22[c] == "LeftHand")
    with pytest.raises(JointSetError, match=r"lacks \['LeftHand'\], which cannot be inserted"):
        fold_to_canonical22(m, {i: c for i, c in found.items() if i != hand})


# --------------------------------------------------------------------------- real clips
@pytest.fixture(scope="module")
def folded():
    out = {}
    for name in CMU_CLIPS:
        m = load_bvh(cmu_clip_path(name))
        out[name] = (m, to_canonical22(m))
    return out


@pytest.mark.data
@pytest.mark.parametrize("name", ["01_01.bvh", "01_03.bvh"])
def test_cmu_fold_error_is_the_neck_length_change(folded, name):
    m, c = folded[name]
    errors = kept_errors(m, c)
    assert len(errors) == 22
    # LHipJoint/RHipJoint/shoulders do not rotate in these files and fingers are leaves: exact
    assert max(e.max() for k, e in errors.items() if k != "Head") < 1e-6
    # Neck1 is folded into Neck->Head: its bending changes that bone's length, which no rotation
    # can undo; the refitted Neck points the bone exactly at the head, so that is all the error.
    n = m.skeleton.joint_names
    g = m.global_positions()
    length = np.linalg.norm(g[:, n.index("Head")] - g[:, n.index("Neck")], axis=-1)
    rest = np.linalg.norm(c.skeleton.offsets[CANONICAL22.index("Head")])
    assert rest == pytest.approx(
        np.linalg.norm(m.skeleton.offsets[n.index("Neck1")] + m.skeleton.offsets[n.index("Head")])
    )
    np.testing.assert_allclose(errors["Head"], np.abs(length - rest), atol=1e-9, rtol=0)
    assert errors["Head"].max() < 0.025  # measured: 2.17 cm (01_01), 1.32 cm (01_03)


@pytest.mark.data
def test_biovision_fold_is_exact_with_spine2_inserted(folded):
    m, c = folded["Boxing_Toes.bvh"]
    errors = kept_errors(m, c)
    assert len(errors) == 21 and max(e.max() for e in errors.values()) < 1e-6
    n = m.skeleton.joint_names
    g, gc = m.global_positions(), c.global_positions()
    mid = 0.5 * (g[:, n.index("Chest")] + g[:, n.index("Neck")])
    np.testing.assert_allclose(gc[:, CANONICAL22.index("Spine2")], mid, atol=1e-6)


# ---------------------------------------------------------------- resampling, normalisation
@pytest.mark.data
def test_resample_120_to_30_keeps_duration_and_frames(folded):
    _, c = folded["01_01.bvh"]
    r = load_cmu_clip("01_01.bvh", fps=30, normalize=False)
    assert r.fps == 30 and abs(r.duration - c.duration) < 1 / 30
    # 120 / 30 = 4: every resampled frame is an original frame
    np.testing.assert_allclose(r.root_positions, c.root_positions[::4][: r.num_frames], atol=1e-12)
    assert same_rotation(r.rotations, c.rotations[::4][: r.num_frames], 1e-9)
    b = load_cmu_clip("Boxing_Toes.bvh", fps=30, normalize=False)
    assert abs(b.duration - folded["Boxing_Toes.bvh"][1].duration) < 1 / 30


@pytest.mark.data
@pytest.mark.parametrize("name", CMU_CLIPS)
def test_normalize_root_faces_z_at_the_origin(name):
    raw = load_cmu_clip(name, normalize=False)
    m = load_cmu_clip(name)
    assert m.skeleton.is_canonical22() and m.fps == 30 and m.meta["source"] == "cmu-assimp"
    pos = m.global_positions()
    np.testing.assert_allclose(m.root_positions[0, [0, 2]], 0, atol=1e-9)
    # the right->left hip axis points along +X, so forward (left x up) is +Z
    across = pos[0, CANONICAL22.index("LeftUpLeg")] - pos[0, CANONICAL22.index("RightUpLeg")]
    across[1] = 0
    np.testing.assert_allclose(across / np.linalg.norm(across), [1, 0, 0], atol=1e-9)
    # feet on the ground over the first second
    assert pos[:30, :, 1].min() == pytest.approx(0, abs=1e-9)

    # a rigid motion of the whole clip: horizontal root path lengths and heights above the lowest
    # joint are unchanged
    def path(r):
        return np.linalg.norm(np.diff(r[:, [0, 2]], axis=0), axis=-1)

    np.testing.assert_allclose(path(m.root_positions), path(raw.root_positions), atol=1e-9)
    raw_pos = raw.global_positions()
    np.testing.assert_allclose(
        pos[..., 1] - pos[..., 1].min(), raw_pos[..., 1] - raw_pos[..., 1].min(), atol=1e-9
    )


@pytest.mark.data
@pytest.mark.parametrize("name", ["01_01.bvh", "Boxing_Toes.bvh"])
def test_unfold_from_canonical22_restores_the_full_joint_set(name):
    """fold -> unfold on the real clips: the 22 kept joints land where the canonical motion puts
    them."""
    raw = load_bvh(cmu_clip_path(name)).slice(0, 200)
    folded = to_canonical22(raw)
    full = unfold_from_canonical22(folded, raw.skeleton, present_map(raw.skeleton)[0])
    assert full.skeleton.joint_names == raw.skeleton.joint_names
    pos = full.global_positions()
    kept = [
        raw.skeleton.joint_names.index(n)
        for n in (
            ("Hips", "LeftUpLeg", "LeftFoot", "RightHand", "Head")
            if name != "Boxing_Toes.bvh"
            else ("Hips", "LeftHip", "LeftAnkle", "RightWrist", "Head")
        )
    ]
    canon = folded.global_positions()
    cidx = [CANONICAL22.index(n) for n in ("Hips", "LeftUpLeg", "LeftFoot", "RightHand", "Head")]
    err = np.abs(pos[:, kept] - canon[:, cidx]).max()
    # exact: folding gives the inserted Biovision Spine2 an identity rotation, so merging it back
    # into the chest loses nothing
    assert err < 1e-9, err
