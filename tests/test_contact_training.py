"""Contact-aware training: one step lowers nothing to NaN, every term is logged, resume is exact,
the exported model retargets; the command line's contact method."""

import numpy as np
import pytest
import torch

from retarget_lib.cli import main
from retarget_lib.config import load_config
from retarget_lib.data.synthetic.characters import make_character
from retarget_lib.data.synthetic.motions import body_radii_from_mesh, make_motion
from retarget_lib.methods.contact import contact_clip, load_contact_model, retarget_with_network
from retarget_lib.training.contact import LOG_TERMS, ContactTraining, export_model
from retarget_lib.training.loop import fit, seed_everything


@pytest.fixture(scope="module")
def small():
    performer = make_character("ada")
    radii = body_radii_from_mesh(performer.skeleton, performer.rest_vertices, performer.weights)
    motion = make_motion("clap", performer.skeleton, 0, duration=3.0, body_radii=radii)
    clips = [contact_clip(motion, performer)]
    targets = {n: make_character(n) for n in ("dex", "fern")}
    config = load_config(
        "configs/contact_paper.yaml",
        [
            "model.hidden=32",
            "model.geometry=16",
            "train.batch=2",
            "train.steps=4",
            "train.epochs=2",
            "data.window=20",
            "train.checkpoint_every=2",
            "train.compile=false",
        ],
        profile="fast",
    )
    return clips, targets, config


def test_clip_has_detected_hand_contacts(small):
    clips, _, _ = small
    assert len(clips[0].self_contacts) > 0 and clips[0].foot_contacts.shape == (
        clips[0].motion.num_frames,
        4,
    )


def test_the_rate_follows_the_papers_epochs_and_the_optional_linear_tail(small):
    clips, targets, config = small  # 4 steps, 2 epochs, lr 1e-4, lr_decay 0.95 (App. B.1)
    paper = ContactTraining(
        {**config, "train": {**config["train"], "decay_from": None}}, clips, targets
    )
    assert [paper.rate(i) for i in range(4)] == pytest.approx([1e-4, 1e-4, 0.95e-4, 0.95e-4])
    assert config["train"]["decay_from"] == 0.5  # the fast profile's tail
    settled = ContactTraining(config, clips, targets)
    # steps 0-1 as the paper; steps 2, 3 of the second epoch scaled by 2/2 and 1/2 (never 0)
    assert [settled.rate(i) for i in range(4)] == pytest.approx([1e-4, 1e-4, 0.95e-4, 0.475e-4])
    settled.step(3)
    assert settled.optimizer.param_groups[0]["lr"] == pytest.approx(0.475e-4)


@pytest.mark.slow
def test_training_logs_every_term_and_resumes_exactly(small, tmp_path):
    clips, targets, config = small
    run = ContactTraining(config, clips, targets)
    losses = run.step(0)
    assert list(losses) == list(LOG_TERMS) and all(np.isfinite(v) for v in losses.values())
    assert losses["foot"] == 0.0  # App. B.1: Efoot is ramped in from 0 in the first epoch
    assert run.epoch(3) == 1

    full = fit(
        ContactTraining(config, clips, targets).task(),
        config,
        tmp_path / "full",
        4,
        2,
        progress=False,
    )
    part = tmp_path / "part"
    fit(ContactTraining(config, clips, targets).task(), config, part, 2, 2, progress=False)
    resumed = fit(
        ContactTraining(config, clips, targets).task(),
        config,
        part,
        4,
        2,
        resume=True,
        progress=False,
    )
    a, b = torch.load(full, weights_only=False), torch.load(resumed, weights_only=False)
    for k, v in a["modules"]["model"].items():
        torch.testing.assert_close(v, b["modules"]["model"][k])

    slim = export_model(full, tmp_path / "model.pt")
    stored = torch.load(slim, weights_only=True)["modules"]["model"]
    assert all(
        v.dtype == torch.float32 for v in stored.values() if v.is_floating_point()
    )  # see export_model
    model, cfg = load_contact_model(slim)
    out = retarget_with_network(model, clips[0].motion.slice(0, 10), targets["dex"])
    assert out.rotations.shape == (10, 22, 4) and out.skeleton is targets["dex"].skeleton
    np.testing.assert_allclose(np.linalg.norm(out.rotations, axis=-1), 1.0, atol=1e-5)


@pytest.mark.data
@pytest.mark.slow
def test_a_compiled_decoder_trains_like_the_eager_one(small):
    clips, targets, config = small
    # no dropout: compiled code draws its random masks from another stream than eager code
    config = {**config, "model": {**config["model"], "dropout": 0.0}}
    eager, compiled = (
        ContactTraining({**config, "train": {**config["train"], "compile": flag}}, clips, targets)
        for flag in (False, True)
    )
    for step in range(
        2
    ):  # the second step runs after one Adam update through the compiled backward
        seed_everything(step)  # both draw the same batch from the global RNGs
        a = eager.step(step)
        seed_everything(step)
        b = compiled.step(step)
        for term in LOG_TERMS:
            # fused kernels sum in another order: float32 rounding, amplified over 20 recurrent
            # frames
            assert b[term] == pytest.approx(a[term], rel=1e-3, abs=1e-6), (step, term)


def test_contact_method_on_the_command_line(tmp_path, capsys):
    from retarget_lib.data.sources.cmu import cmu_clip_path
    from retarget_lib.io import load_bvh, save_bvh

    short = tmp_path / "short.bvh"
    save_bvh(load_bvh(cmu_clip_path("01_03.bvh")).slice(0, 24), short)
    out = tmp_path / "contact.bvh"
    assert (
        main(
            [
                "retarget",
                "--source",
                str(short),
                "--target",
                "gus",
                "--method",
                "contact",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    result = load_bvh(out)
    # the method runs at 30 fps (7 frames: 6 over 5/30 s and the source's last at 23/120 s); the
    # output comes back at the source's 120 fps with every one of its 24 frames
    assert result.fps == pytest.approx(120.0) and result.num_frames == 24
    assert (
        main(
            [
                "retarget",
                "--source",
                str(short),
                "--target",
                str(cmu_clip_path("Boxing_Toes.bvh")),
                "--method",
                "contact",
                "--out",
                str(out),
            ]
        )
        == 2
    )
    assert "--target-mesh" in capsys.readouterr().err
