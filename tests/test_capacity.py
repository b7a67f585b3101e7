"""Capacity checks (retarget_lib.evaluation.capacity): the tiny training set, its cases, and a
verdict that a model which has learnt the set passes and one that has not fails."""

import numpy as np
import torch
from skeletons import make_skeleton

from retarget_lib.cli import main
from retarget_lib.config import load_config
from retarget_lib.core.motion import Motion
from retarget_lib.core.rotations import quat_from_axis_angle
from retarget_lib.evaluation.capacity import (
    CONTACT_COPY,
    PROTOCOL_COPY,
    EnergyAtTruth,
    capacity_cases,
    capacity_check,
    contact_capacity_cases,
    contact_capacity_check,
    contact_energy_at_truth,
)
from retarget_lib.methods.contact import model_from_config
from retarget_lib.methods.registry import get_method
from retarget_lib.training.tdcn_data import stack_clips


def _clips():
    """Three characters performing two clips (130 frames: two short chunks; 40 frames: one)."""
    rng = np.random.default_rng(0)
    skeletons = {
        "tall": make_skeleton(1.9),
        "short": make_skeleton(1.5, leg_frac=0.45),
        "apose": make_skeleton(1.7, arm_deg=45.0),
    }
    clips = []
    for k, frames in enumerate((130, 40)):
        versions = {}
        for name, skeleton in skeletons.items():
            axis = rng.normal(size=(frames, 22, 3))
            angle = 0.3 * np.sin(np.linspace(0, 3, frames))[:, None] * rng.uniform(0.5, 1, 22)
            unit = axis / np.linalg.norm(axis, axis=-1, keepdims=True)
            rot = quat_from_axis_angle(torch.from_numpy(unit * angle[..., None])).numpy()
            root = np.cumsum(np.full((frames, 3), [0.01, 0.0, 0.02]), 0) + [0, 0.9, 0]
            versions[name] = Motion(skeleton, rot, root, 30.0, name=f"clip_{k}")
        clips.append((versions["tall"], versions))
    return stack_clips(skeletons, clips)


def test_subset_keeps_the_first_clips_of_the_first_characters():
    clips = _clips()
    small = clips.subset(clips=1, characters=2)
    assert small.characters == ("tall", "short") and small.clip_names == ("clip_0",)
    assert small.rotations.shape[:2] == (2, 130) and small.offsets.shape[0] == 2
    again = small.motion(1, 0)
    np.testing.assert_array_equal(again.rotations, clips.motion(1, 0).rotations)
    assert clips.subset(None, None).rotations.shape == clips.rotations.shape


def test_cases_are_every_ordered_pair_with_the_identity_pairs_marked():
    cases = capacity_cases(_clips())
    assert len(cases) == 2 * 3 * 3
    same = [c for c in cases if c.scenario == 0]
    assert len(same) == 6 and all(c.source_name == c.target_name for c in same)


def _oracle(cases):
    """A model that has learnt the set: the truth of whichever case and chunk it is given."""

    def retarget(source, target):
        for c in cases:
            if c.target is not target:
                continue
            r, n = c.source.rotations, source.num_frames
            for s in range(len(r) - n + 1):
                if np.array_equal(r[s], source.rotations[0]) and np.array_equal(
                    r[s + n - 1], source.rotations[-1]
                ):
                    return c.truth.slice(s, s + n)
        raise AssertionError("not a case of the set")

    return retarget


def test_a_model_that_learnt_the_set_passes_and_the_copy_row_itself_fails():
    cases = capacity_cases(_clips())
    learnt = capacity_check(_oracle(cases), cases)
    assert learnt.model_short == 0.0 and learnt.identity_pct == 0.0
    assert learnt.copy_short > 0 and learnt.passed  # the characters differ: copying is not exact
    copy = capacity_check(get_method(PROTOCOL_COPY).retargeter(), cases)
    # a model no better than the copy row fails (strictly below is asked), however exact its
    # identity (copying a clip onto its own performer is exact)
    assert copy.model_short == copy.copy_short and copy.identity_pct < 1e-9 and not copy.passed
    assert "FAIL" in copy.summary() and "PASS" in learnt.summary()


def test_cli_refuses_a_folder_that_is_not_a_capacity_run(tmp_path, capsys):
    assert main(["capacity", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "config.yaml" in err[0] and "Traceback" not in err[0]
    (tmp_path / "config.yaml").write_text("method: tdcn\nmodel: {row: ours}\ndata: {window: 81}\n")
    (tmp_path / "final.pt").write_bytes(b"")
    assert main(["capacity", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "max_clips" in err[0]


def test_the_contact_check_passes_a_network_that_learnt_its_clips_and_fails_the_copy_row():
    """The contact network's check on a real tiny set (the first training clip of two training
    characters, onto both): a model returning each case's ground truth passes; the copy row as the
    model fails (not strictly below itself), and a model that walks one centimetre off the truth in
    every frame misses identity by 1 cm / H, measured."""
    config = {
        "data": {"train_characters": ["ada", "dex"], "held_out_seed": 8, "max_clips": 1},
    }
    cases = contact_capacity_cases(config)
    assert [(c.source_character.name, c.target.name) for c in cases] == [
        ("ada", "ada"),
        ("ada", "dex"),
    ]
    assert np.array_equal(cases[0].truth.rotations, cases[0].source.rotations)  # identity's truth

    def truth_of(source, target):
        return next(c.truth for c in cases if c.target is target and c.source is source)

    learnt = contact_capacity_check(truth_of, cases)
    assert learnt.model_short == 0.0 and learnt.identity_pct == 0.0
    assert learnt.copy_short > 0 and learnt.passed and "PASS" in learnt.summary()
    copy = get_method(CONTACT_COPY).retargeter()
    as_copy = contact_capacity_check(lambda s, t: copy(s, t.skeleton), cases)
    assert as_copy.model_short == as_copy.copy_short and not as_copy.passed

    def off_by_a_centimetre(source, target):
        truth = truth_of(source, target)
        return truth.copy(root_positions=truth.root_positions + [0.01, 0.0, 0.0])

    shifted = contact_capacity_check(off_by_a_centimetre, cases)
    h = cases[0].target.skeleton.height()
    assert abs(shifted.identity_pct - 1.0 / h) < 1e-9  # every joint 1 cm off, in % of H (m)


def _tiny_contact_config(row: str) -> dict:
    """configs/capacity/contact_skeleton.yaml on one clip of one character, a small network."""
    overrides = ["data.train_characters=[ada]", "data.max_clips=1", f"energy.row={row}"]
    overrides += ["model.hidden=32", "model.geometry=16"]
    return load_config("configs/capacity/contact_skeleton.yaml", overrides, profile="fast")


def test_the_contact_energy_is_read_at_the_truth_of_a_clip_onto_its_own_performer():
    """Onto its own performer the truth is the source: Eweak and Eee are 0 there (to float32
    rounding of the rotation matrices, 1e-6 per entry), so Eskel+Efoot at the truth is below an
    untrained network's. Efull adds Eint, which the truth itself has (the synthetic clip's arms
    and legs pass into the mesh, as real clips do)."""
    config = _tiny_contact_config("Eskel+Efoot")
    torch.manual_seed(0)
    result = contact_energy_at_truth(config, model_from_config(config))
    assert result.windows == 6  # one clip onto its performer: 2 windows x 3 sampled frames
    assert result.truth["weak"] < 1e-6 and result.truth["ee"] < 1e-6
    assert result.network["weak"] > 1.0  # random rotations, rho = 1000 on squared entries
    assert result.truth_is_minimum and "no higher than the network" in result.summary()
    full = _tiny_contact_config("Efull")
    at_truth = contact_energy_at_truth(full, model_from_config(full))
    assert at_truth.truth["int"] > 0 and at_truth.truth["weak"] < 1e-6


def test_an_energy_lower_off_the_truth_is_reported():
    """The verdict follows the totals, and the line names every non-zero term."""
    terms = dict(weak=0.0, ee=0.0, foot=0.0, j2j=0.0, int=0.0)
    off = EnergyAtTruth(
        "Efull",
        4,
        {**terms, "weak": 3.0, "int": 1.0, "total": 4.0},
        {**terms, "int": 5.0, "total": 5.0},
    )
    assert not off.truth_is_minimum
    assert "minimum is not the truth" in off.summary() and "int 5" in off.summary()
    assert "weak 3, int 1" in off.summary()
