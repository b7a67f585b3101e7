"""TDCN/NKN training (retarget_lib.training.tdcn): every Table 4 config, the training step, the
sampler (A = B fraction, balanced scaling, centring), `retarget train --resume`, NaN stop, and
load_generator → retargeting a 200-frame clip. Tiny widths and batches: the whole file runs in
seconds; real training lives in `retarget train`."""

import csv
import dataclasses
from pathlib import Path

import numpy as np
import pytest
import torch

from retarget_lib.cli import main
from retarget_lib.config import load_config
from retarget_lib.core.measures import nkn_height
from retarget_lib.core.quantities import leg_ratio
from retarget_lib.data.splits import tdcn_split
from retarget_lib.data.synthetic.dataset import load_synthetic
from retarget_lib.losses import NonFiniteLossError
from retarget_lib.methods.tdcn import load_generator, retarget_motion_with
from retarget_lib.models import PROFILE_WIDTHS, NKNGenerator, TDCNGenerator
from retarget_lib.training.loop import fit, load_checkpoint
from retarget_lib.training.tdcn import RetargetTraining
from retarget_lib.training.tdcn_data import WindowSampler, training_clips

pytestmark = pytest.mark.data  # trains on the synthetic dataset (`retarget data build`)

CONFIGS = Path(__file__).resolve().parents[1] / "configs"
ROWS = {
    "tdcn_baseline": "Baseline",
    "tdcn_baseline_dense": "Baseline-dense",
    "tdcn_baseline_dilated": "Baseline-dilated",
    "tdcn_baseline_height": "Baseline-height",
    "tdcn_paper": "ours",
    "tdcn_a1_dense": "A1",
    "tdcn_a2_unbalanced": "A2",
    "tdcn_a3_no_height": "A3",
    "tdcn_a4_disc81": "A4",
    "tdcn_a5_causal": "A5",
    "tdcn_ours_residual": "ours-residual",
}
#: configs that train a row's model another way (loss scale, data profile): stem -> the row's model
VARIANTS = {
    "tdcn_paper_code_scale": "ours",
    "tdcn_ours_mixamo_convention": "ours",
    "tdcn_ours_mixamo_convention_long": "ours",
    "tdcn_ours_mixamo_convention_code_losses": "ours",
    "tdcn_ours_mixamo_convention_code_losses_leg_root": "ours",
    "tdcn_ours_mixamo_convention_code": "ours",
    "tdcn_ours_mixamo_convention_root_residual": "ours",
    "tdcn_ours_root_residual": "ours",
    "tdcn_ours_residual_mixed": "ours-residual",
    **{
        f"{stem}_mixamo_convention": row
        for stem, row in ROWS.items()
        if stem not in ("tdcn_paper", "tdcn_ours_residual")
    },
}
#: the model keys of the NKN Baseline's root (docs/reproduction.md N1, N8)
# train.compile=false: these tiny runs test the training mechanics; the compiled GRU decoder is
# tested against the eager one in test_models.py (compiling it costs ~1 min of CPU per config)
TINY = ["model.channels=16", "model.disc_channels=16", "train.batch=4", "train.compile=false"]
TERMS = ["Lc", "Lt", "Lh", "La", "Lr", "Lo", "Ld", "total", "D"]
#: an NKN row also logs its root smoothness (the authors' code's term; weight 0 unless asked)
NKN_TERMS = [*TERMS[:-2], "Ls", *TERMS[-2:]]


def config(stem, *overrides, profile="fast"):
    return load_config(CONFIGS / f"{stem}.yaml", [*TINY, *overrides], profile=profile)


@pytest.fixture(autouse=True)
def _one_thread():
    """Tiny networks: one thread is faster and unaffected by other work on the machine."""
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(threads)


def test_paper_settings_and_every_table4_row_config():
    paper = load_config(CONFIGS / "tdcn_paper.yaml", profile="paper")
    assert paper["model"]["channels"] == 1024 and paper["model"]["dropout"] == 0.1
    assert (
        paper["train"]["batch"] == 128
        and paper["train"]["lr"] == 1e-4
        and paper["train"]["betas"] == [0.5, 0.999]
    )
    assert paper["data"] == {
        "window": 81,
        "same_fraction": 0.5,
        "scale_range": [0.5, 1.5],
        "scale_targets": True,
        "mirror": False,
        "random_yaw": False,
        "rest_jitter_deg": 0.0,
        "source": "synthetic",
    }
    assert {
        k: paper["loss"][k]
        for k in ("lambda_t", "lambda_h", "lambda_a", "lambda_r", "lambda_o", "lambda_g")
    } == {
        "lambda_t": 10,
        "lambda_h": 10,
        "lambda_a": 1,
        "lambda_r": 0.1,
        "lambda_o": 1,
        "lambda_g": 5,
    }
    assert sorted(p.stem for p in CONFIGS.glob("tdcn_*.yaml")) == sorted({**ROWS, **VARIANTS})
    for stem, row in {**ROWS, **VARIANTS}.items():
        fast = load_config(CONFIGS / f"{stem}.yaml", profile="fast")
        assert fast["model"]["row"] == row and (stem in VARIANTS or fast["name"] == row)
        kind = "nkn" if row.startswith("Baseline") else "tdcn"
        assert fast["model"]["channels"] == PROFILE_WIDTHS["fast"][kind]
        assert (
            load_config(CONFIGS / f"{stem}.yaml", profile="paper")["model"]["channels"]
            == PROFILE_WIDTHS["paper"][kind]
        )
        run = RetargetTraining(config(stem))
        assert isinstance(run.generator, NKNGenerator if kind == "nkn" else TDCNGenerator)
        assert run.generator.config["row"] == row
        assert run.gan == ("sigmoid_ce" if kind == "nkn" else "lsgan")
    assert config("tdcn_a3_no_height")["loss"]["lambda_h"] == 0
    for stem in (
        s for s in VARIANTS if s.endswith("_mixamo_convention")
    ):  # each row as the papers train it
        mc, own = (
            config(stem),
            config(stem.removesuffix("_mixamo_convention").replace("tdcn_ours", "tdcn_paper")),
        )
        assert (
            mc["data"].pop("source") == "mixamo-convention"
            and own["data"].pop("source") == "synthetic"
        )
        assert (mc["loss"].pop("reduction"), mc["loss"].pop("standardize")) == ("frame_sum", True)
        if stem.startswith("tdcn_baseline"):  # and the root's steps in Lc/La (N1)
            assert mc["loss"].pop("root_term") == "velocity"
        assert (mc["data"], mc["loss"], mc["model"]) == (
            own["data"],
            {k: v for k, v in own["loss"].items() if k not in ("reduction", "standardize")},
            own["model"],
        )
    # the 10k-step row: the Mixamo-convention "ours" trained five times longer, nothing else changed
    long, short = (
        load_config(CONFIGS / f"{s}.yaml", profile="fast")
        for s in ("tdcn_ours_mixamo_convention_long", "tdcn_ours_mixamo_convention")
    )
    assert (long["train"].pop("steps"), short["train"].pop("steps")) == (10000, 2000)
    assert {k: v for k, v in long.items() if k not in ("name", "config_path")} == {
        k: v for k, v in short.items() if k not in ("name", "config_path")
    }
    assert config("tdcn_a2_unbalanced")["data"]["scale_range"] is None
    assert RetargetTraining(config("tdcn_a4_disc81")).discriminator.receptive_field == 81


def test_config_contradicting_its_row_is_refused():
    with pytest.raises(ValueError, match="lambda_h must be 0"):
        RetargetTraining(config("tdcn_a3_no_height", "loss.lambda_h=10"))
    with pytest.raises(ValueError, match="scale_range must be null"):
        RetargetTraining(config("tdcn_a2_unbalanced", "data.scale_range=[0.5, 1.5]"))
    with pytest.raises(ValueError, match="lambda_h must be > 0"):
        RetargetTraining(config("tdcn_baseline_height", "loss.lambda_h=0"))
    with pytest.raises(ValueError, match="lambda_s must be 0"):  # TDCN has no root steps
        RetargetTraining(config("tdcn_paper", "loss.lambda_s=0.01"))


@pytest.mark.parametrize("stem", ["tdcn_paper", "tdcn_baseline_height"])
def test_training_steps_are_finite_and_update_both_networks(stem):
    run = RetargetTraining(config(stem))
    before = {
        name: [p.detach().clone() for p in m.parameters()]
        for name, m in (("G", run.generator), ("D", run.discriminator))
    }
    for i in range(2):
        log = run.step(i)
        assert list(log) == (NKN_TERMS if stem.startswith("tdcn_baseline") else TERMS)
        assert all(np.isfinite(v) for v in log.values()), log
    for name, m in (("G", run.generator), ("D", run.discriminator)):
        unchanged = [
            i
            for i, (a, b) in enumerate(zip(before[name], m.parameters(), strict=False))
            if torch.equal(a, b)
        ]
        assert not unchanged, f"{name} parameters {unchanged} did not change"
        assert all(p.requires_grad for p in m.parameters())


def test_sampler_pairs_scales_and_centring():
    clips = training_clips()
    split = tdcn_split()
    assert clips.characters == split.train_characters and len(clips.clip_names) == len(
        split.train_motions
    )
    sampler = WindowSampler(clips, window=81)
    b = sampler.sample(2000, torch.Generator().manual_seed(0))
    assert b.rotations.shape == b.real_rotations.shape == (2000, 81, 22, 4)
    assert abs(b.same_character.float().mean().item() - 0.5) < 0.04
    assert torch.equal(b.same_character, b.source == b.target)
    for s in (b.scale_source, b.scale_target):
        assert s.min() >= 0.5 and s.max() <= 1.5 and s.std() > 0.25  # ~U[0.5, 1.5] (std 0.289)
    assert torch.equal(
        b.scale_target[b.same_character], b.scale_source[b.same_character]
    )  # copied: exact
    assert torch.allclose(
        nkn_height(b.offsets_source), nkn_height(clips.offsets[b.source]) * b.scale_source
    )  # H scales with s
    # one elementwise product of the same two values (correctly rounded on any CPU): exact
    assert torch.equal(b.offsets_target[b.same_character], b.offsets_source[b.same_character])
    for r in (
        b.root_positions,
        b.real_root_positions,
    ):  # centre frame above the origin, height kept
        # centred: x - x is exactly 0
        assert torch.equal(r[:, 40, [0, 2]], torch.zeros(2000, 2)) and (r[:, 40, 1] > 0.2).all()
    unbalanced = WindowSampler(clips, window=81, scale_range=None).sample(500)
    assert torch.equal(unbalanced.scale_source, torch.ones(500))
    assert torch.equal(unbalanced.scale_target, torch.ones(500))
    assert torch.equal(
        unbalanced.offsets_source, clips.offsets[unbalanced.source]
    )  # x * 1.0: exact


def test_rest_jitter_gives_other_rest_poses_performing_by_the_ground_truths_rule():
    """A re-rested character performs the window as the ground truth would (the rotation deltas
    from the retarget pose): a turn beyond the tolerance is compensated, one within it is shape."""
    from retarget_lib.core.skeleton import canonical22_skeleton
    from retarget_lib.core.transfer import transfer_rotations

    clips = training_clips()
    plain = WindowSampler(clips, window=81).sample(64, torch.Generator().manual_seed(5))
    jittered = WindowSampler(clips, window=81, rest_jitter_deg=30.0).sample(
        64, torch.Generator().manual_seed(5)
    )
    assert torch.equal(plain.source, jittered.source) and torch.equal(plain.target, jittered.target)
    moved = (jittered.offsets_source - plain.offsets_source).norm(dim=-1).amax(-1) > 1e-4
    assert 0.25 < moved.float().mean() < 0.75  # about half the sources
    for k in range(8):  # each sample against the per-skeleton float64 transfer
        src = canonical22_skeleton(plain.offsets_source[k].double().numpy())
        dst = canonical22_skeleton(jittered.offsets_source[k].double().numpy())
        want = transfer_rotations(plain.rotations[k].double().numpy(), src, dst)
        got = jittered.rotations[k].double().numpy()
        # float32 windows against float64: rounding only
        np.testing.assert_allclose(np.abs((want * got).sum(-1)), 1.0, atol=1e-5)
        if not moved[k]:  # an identity alignment: float32 products with 1, rounding only
            assert torch.allclose(plain.rotations[k], jittered.rotations[k], atol=1e-6)
    # bone lengths and heights are kept; A = B: one rest pose (same code, same values: exact)
    assert torch.allclose(nkn_height(jittered.offsets_source), nkn_height(plain.offsets_source))
    assert torch.equal(
        jittered.offsets_target[jittered.same_character],
        jittered.offsets_source[jittered.same_character],
    )


def read_log(path):
    with open(path) as f:
        return list(csv.reader(f))


def test_cli_train_resume_matches_a_straight_run(tmp_path, capsys):
    args = [
        "train",
        "--config",
        str(CONFIGS / "tdcn_paper.yaml"),
        *TINY,
        "train.checkpoint_every=2",
    ]
    assert main([*args, "train.steps=3", "--out", str(tmp_path / "a")]) == 0
    assert load_checkpoint(tmp_path / "a" / "last.pt")["step"] == 3
    assert main([*args, "train.steps=6", "--out", str(tmp_path / "a"), "--resume"]) == 0
    assert main([*args, "train.steps=6", "--out", str(tmp_path / "b")]) == 0
    assert f"checkpoint: {tmp_path / 'b' / 'final.pt'}" in capsys.readouterr().out
    resumed, straight = (load_checkpoint(tmp_path / d / "final.pt") for d in "ab")
    assert resumed["step"] == straight["step"] == 6
    for net in ("generator", "discriminator"):
        for k, v in straight["modules"][net].items():
            assert torch.equal(resumed["modules"][net][k], v), (
                net,
                k,
            )  # same code, one process, state reloaded: exact
    log_a, log_b = read_log(tmp_path / "a" / "losses.csv"), read_log(tmp_path / "b" / "losses.csv")
    assert log_a[0] == log_b[0] == ["step", "seconds", *TERMS]
    assert [r[2:] for r in log_a[1:]] == [r[2:] for r in log_b[1:]] and len(log_a) == 7


def test_nan_in_the_data_stops_training_naming_the_term(tmp_path):
    clips = training_clips()
    poisoned = dataclasses.replace(
        clips, root_positions=torch.full_like(clips.root_positions, float("nan"))
    )
    cfg = config("tdcn_paper")
    run = RetargetTraining(cfg, clips=poisoned)
    with pytest.raises(NonFiniteLossError, match="'Lc' is not finite"):
        fit(run.task(), cfg, tmp_path, steps=3, progress=False)
    assert not (tmp_path / "final.pt").exists()


@pytest.mark.parametrize("stem", ["tdcn_paper", "tdcn_baseline_height"])
def test_load_generator_round_trip_and_retarget_200_frames(tmp_path, stem):
    cfg = config(stem, "model.normalize_inputs=true", "train.steps=2")
    run = RetargetTraining(cfg)
    assert not run.generator.normalizer.is_identity
    final = fit(run.task(), cfg, tmp_path, steps=2, progress=False)
    generator, loaded_cfg = load_generator(final)
    assert loaded_cfg == cfg and not generator.training
    trained = run.generator.state_dict()
    assert all(torch.equal(v, trained[k]) for k, v in generator.state_dict().items())
    ds, split = load_synthetic(), tdcn_split()
    source = next(
        c.motion for c in ds.clips if c.family in split.test_families and c.motion.num_frames >= 200
    )
    target = ds.characters[split.test_characters[0]].skeleton
    clip = source.slice(0, 200)
    out = retarget_motion_with(generator, clip, target)
    assert out.num_frames == 200 and np.allclose(out.skeleton.offsets, target.offsets)
    assert np.isfinite(out.root_positions).all()
    np.testing.assert_allclose(np.linalg.norm(out.rotations, axis=-1), 1.0, atol=1e-5)
    # a clip moved by d on the floor comes out moved by leg_ratio * d, the ground truth's path
    # scale (not H's); float32 network, metres: 1e-4 m
    d = np.array([2.0, 0.0, -1.5])
    moved = retarget_motion_with(
        generator, clip.copy(root_positions=clip.root_positions + d), target
    )
    np.testing.assert_allclose(
        moved.root_positions - out.root_positions,
        np.broadcast_to(leg_ratio(clip.skeleton, target) * d, out.root_positions.shape),
        atol=1e-4,
    )
    if not isinstance(generator, TDCNGenerator):
        with pytest.raises(ValueError, match="TDCNGenerator"):
            retarget_motion_with(generator, clip, target, windowed=True)
        return
    # per-frame windows: same as one pass when the root does not travel, and any clip works
    still = clip.copy(root_positions=clip.root_positions * [0.0, 1.0, 0.0] + [0.3, 0.0, -0.2])
    a, b = (
        retarget_motion_with(generator, still, target, windowed=w, chunk=64) for w in (False, True)
    )
    np.testing.assert_allclose(b.rotations, a.rotations, atol=1e-5)
    np.testing.assert_allclose(b.root_positions, a.root_positions, atol=1e-5)
    windowed = retarget_motion_with(generator, clip, target, windowed=True)
    assert windowed.num_frames == 200 and np.isfinite(windowed.root_positions).all()


def test_cli_export_writes_a_slim_generator_that_loads(tmp_path, capsys):
    slim = tmp_path / "slim.pt"
    args = [
        "train",
        "--config",
        str(CONFIGS / "tdcn_paper.yaml"),
        *TINY,
        "train.steps=2",
        "train.checkpoint_every=2",
        "--out",
        str(tmp_path / "run"),
        "--export",
        str(slim),
    ]
    assert main(args) == 0
    assert "exported model" in capsys.readouterr().out
    full = tmp_path / "run" / "final.pt"
    assert slim.stat().st_size < full.stat().st_size
    g_full, _ = load_generator(full)
    g_slim, cfg = load_generator(slim)
    assert cfg["train"]["steps"] == 2
    stored = torch.load(slim, weights_only=True)["modules"]["generator"]
    assert {v.dtype for v in stored.values() if v.is_floating_point()} == {torch.float16}
    for a, b in zip(g_full.state_dict().values(), g_slim.state_dict().values(), strict=False):
        # the export stores float16; the loader gives float32 back
        assert b.dtype == a.dtype and torch.equal(
            b, a.half().to(a.dtype) if a.is_floating_point() else a
        )


def test_root_steps_and_a_capacity_subset():
    """``loss.root_term: velocity`` z-scores the root's per-frame steps (centimetres a frame), not
    its path (tens of centimetres); ``data.max_clips`` / ``max_characters`` cut the training set."""

    def cut(root_term):
        c = config("tdcn_baseline_mixamo_convention")
        c["data"].update(max_clips=2, max_characters=2)
        c["loss"]["root_term"] = root_term
        return RetargetTraining(c)

    path, steps = cut("position"), cut("velocity")
    clips = steps.sampler.clips
    assert len(clips.characters) == 2 and len(clips.clip_names) == 2
    # horizontal channels: a walk's steps spread a few cm (the 1 cm floor aside), its path metres
    assert float(steps.position_scale.r_std[[0, 2]].max()) < 0.1
    assert float(path.position_scale.r_std[[0, 2]].min()) > 0.2
    log = steps.step(0)
    assert all(np.isfinite(v) for v in log.values()), log
