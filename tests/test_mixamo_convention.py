"""The Mixamo-convention synthetic profile (retarget_lib/data/synthetic/mixamo_convention.py)."""

import csv
from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest
import torch

from retarget_lib.config import load_config
from retarget_lib.core.retarget_pose import rest_alignment, retarget_pose
from retarget_lib.core.rotations import quat_angle
from retarget_lib.core.skeleton import canonical22_skeleton
from retarget_lib.data.sources.real_characters import REAL_DIR, skeleton_proportions
from retarget_lib.data.splits import MotionId, ScenarioPair
from retarget_lib.data.synthetic import mixamo_convention as mc
from retarget_lib.data.synthetic.mixamo_convention import (
    N_CHARACTERS,
    RANGE_MARGIN,
    RANGE_SOURCES,
    REAL_RIG_RANGES,
    generate,
    mixamo_convention_names,
    mixamo_convention_spec,
    mixamo_convention_split,
)
from retarget_lib.data.synthetic.proportions import height_scale, unscaled_offsets
from retarget_lib.methods.copy import copy_rotations
from retarget_lib.training import contact as contact_training


def test_the_ranges_are_those_measured_on_the_real_rigs():
    with open(REAL_DIR / "proportions.csv") as f:
        rows = [r for r in csv.DictReader(f) if r["character"] in RANGE_SOURCES]
    assert len(rows) == len(RANGE_SOURCES)
    for key, (lo, hi) in REAL_RIG_RANGES.items():
        values = [float(r[key]) for r in rows]
        assert (lo, hi) == pytest.approx((min(values), max(values)), abs=1e-4), (
            key
        )  # the CSV keeps 4 decimals


@pytest.mark.parametrize("index", range(N_CHARACTERS))
def test_every_character_is_in_a_t_pose_with_real_proportions(index):
    """One T-pose convention (each retarget pose is the identity: copying rotations between them
    is the ground truth's rule), each bind with its own shape, proportions of the real rigs."""
    spec = mixamo_convention_spec(index)
    skeleton = canonical22_skeleton(unscaled_offsets(spec) * height_scale(spec))
    pose = torch.from_numpy(retarget_pose(skeleton))
    assert float(quat_angle(pose).max()) < 1e-9  # float64 rounding of an exact identity
    shape = (spec.arm_angle, spec.forearm_droop, spec.spine_curve, spec.toe_slope, spec.feet_out)
    assert all(abs(v) > 0 for v in shape) and spec.knee_bend == 0
    measured = skeleton_proportions(
        canonical22_skeleton(unscaled_offsets(spec) * height_scale(spec))
    )
    assert abs(measured["arm_angle_deg"] - spec.arm_angle) < 1e-6
    flat = replace(spec, arm_angle=0.0, arm_forward=0.0, spine_curve=0.0, feet_out=0.0)
    measured = skeleton_proportions(
        canonical22_skeleton(unscaled_offsets(flat) * height_scale(flat))
    )
    for key, (lo, hi) in REAL_RIG_RANGES.items():
        pad = RANGE_MARGIN * (hi - lo)
        assert lo - pad <= measured[key] <= hi + pad, key


def test_the_characters_differ_and_the_split_keeps_unseen_ones():
    specs = [mixamo_convention_spec(i) for i in range(N_CHARACTERS)]
    assert len({(s.height, s.thigh, s.upper_arm) for s in specs}) == N_CHARACTERS
    assert mixamo_convention_spec(3) == specs[3]  # deterministic
    split = mixamo_convention_split()
    assert set(split.train_characters).isdisjoint(split.test_characters)
    assert set(split.train_characters) | set(split.test_characters) == set(
        mixamo_convention_names()
    )


def test_each_character_performs_its_own_version_of_a_clip():
    data = generate(count=2, clip_ids=[("walk", 0), ("clap", 1)])
    a, b = data.characters["tp01"], data.characters["tp02"]
    for clip in ("walk_000", "clap_001"):
        own_a, own_b = data.clips[clip]["tp01"], data.clips[clip]["tp02"]
        assert own_a.num_frames == own_b.num_frames  # same seed, same timing
        assert own_a.skeleton.offsets == pytest.approx(a.skeleton.offsets)
        assert own_b.skeleton.offsets == pytest.approx(b.skeleton.offsets)
        # copying A's rotations onto B is close to B's own version (same rest) but not the same:
        # B's feet and hands are solved on B's body
        err = np.linalg.norm(
            copy_rotations(own_a, b.skeleton).global_positions() - own_b.global_positions(), axis=-1
        )
        assert 0.001 < err.mean() < 0.1 * b.skeleton.height(), clip
    walk = data.clips["walk_000"]["tp02"]
    feet = walk.global_positions()[
        :, [b.skeleton.index("LeftToeBase"), b.skeleton.index("RightToeBase")], 1
    ]
    assert (
        feet.min() > -0.01
    )  # planted on its own floor (1 cm: the toe joint's rest height above the sole)


def test_an_evaluation_authors_only_the_versions_it_needs_with_the_cached_values(
    monkeypatch, tmp_path
):
    # two characters stand in for the profile's fourteen (the lazy path builds every character)
    build = mc._characters
    monkeypatch.setattr(mc, "_characters", lambda count=2: build(min(count, 2)))
    monkeypatch.setattr(mc, "data_path", lambda: tmp_path / "mixamo_convention.npz")
    pairs = [
        ScenarioPair("tp02", "tp02", MotionId("walk", 0)),
        ScenarioPair("tp01", "tp01", MotionId("clap", 1)),
        ScenarioPair("tp02", "tp02", MotionId("walk", 0)),
    ]
    wanted = [("walk_000", "tp02"), ("clap_001", "tp01")]
    mc.load_mixamo_convention.cache_clear()
    try:
        authored = mc.mixamo_convention_versions(pairs)  # nothing cached: authored now
        assert not (tmp_path / "mixamo_convention.npz").exists()  # and not cached
        assert {c: list(v) for c, v in authored.clips.items()} == {
            "walk_000": ["tp02"],
            "clap_001": ["tp01"],
        }
        assert list(authored.characters) == ["tp01", "tp02"]
        mc.save(generate(count=2, clip_ids=[("walk", 0), ("clap", 1)]), mc.data_path())
        cached = mc.mixamo_convention_versions(pairs)  # now read from the built profile
        assert set(cached.clips["walk_000"]) == {"tp01", "tp02"}
        for clip, name in wanted:
            a, b = authored.clips[clip][name], cached.clips[clip][name]
            # exactly equal: both went through the cache's float32 storage
            np.testing.assert_array_equal(a.rotations, b.rotations)
            np.testing.assert_array_equal(a.root_positions, b.root_positions)
            np.testing.assert_array_equal(a.meta["foot_contacts"], b.meta["foot_contacts"])
            np.testing.assert_array_equal(a.skeleton.offsets, b.skeleton.offsets)
            assert a.name == b.name == clip and a.meta["performer"] == name
        for name in ("tp01", "tp02"):
            np.testing.assert_array_equal(
                authored.characters[name].rest_vertices, cached.characters[name].rest_vertices
            )
            assert authored.characters[name].style == cached.characters[name].style
    finally:
        mc.load_mixamo_convention.cache_clear()


def test_contact_training_takes_the_profile_on_its_own_bodies(monkeypatch, tmp_path):
    # a two-character, two-clip profile in place of the cached one: each train clip is performed by
    # one train character in turn on its own body, seeds from held_out_seed on are left out, and
    # the targets are the split's train characters
    monkeypatch.setenv("RETARGET_CACHE", str(tmp_path / "cache"))
    tiny = generate(2, [("walk", 0), ("walk", 9)])
    names = tuple(tiny.characters)
    split = SimpleNamespace(
        train_characters=names, train_motions=(MotionId("walk", 0), MotionId("walk", 9))
    )
    monkeypatch.setattr(contact_training, "load_mixamo_convention", lambda: tiny)
    monkeypatch.setattr(contact_training, "mixamo_convention_split", lambda: split)
    monkeypatch.setattr(contact_training, "mixamo_convention_path", lambda: tmp_path / "mc.npz")
    monkeypatch.setattr(contact_training, "fingerprint_of", lambda path: "0" * 64)
    config = load_config("configs/contact_residual_mixed.yaml", ["data.source=mixamo-convention"])
    assert config["data"]["held_out_seed"] == 8
    clips, targets = contact_training.training_clips(config)
    assert sorted(targets) == sorted(names)
    assert [(c.name, c.character.name) for c in clips] == [("walk_000", names[0])]
    assert clips[0].motion is tiny.clips["walk_000"][names[0]]


def test_between_the_t_pose_binds_copy_rest_is_copy():
    """Mixamo's own rule (it copies local rotations between its T-pose binds): the rest alignment
    of every pair of the profile's characters is the identity, so copy-rest copies."""
    skeletons = [
        canonical22_skeleton(unscaled_offsets(s) * height_scale(s))
        for s in map(mixamo_convention_spec, range(N_CHARACTERS))
    ]
    for a in skeletons[:4]:
        for b in skeletons:
            c = torch.from_numpy(rest_alignment(a, b))
            assert float(quat_angle(c).max()) < 1e-9  # float64 rounding of an exact identity
