"""Config deltas and overrides; the shared training loop: CSV log, atomic checkpoints, exact resume,
clear stop on NaN."""

import csv

import numpy as np
import pytest
import torch

from retarget_lib.config import ConfigError, load_config
from retarget_lib.files import load_yaml
from retarget_lib.training.loop import NonFiniteLossError, TrainTask, fit, load_checkpoint


def write(path, text):
    path.write_text(text)
    return path


def test_config_delta_profile_and_overrides(tmp_path):
    write(
        tmp_path / "base.yaml",
        "seed: 1\nmodel: {channels: 1024, dropout: 0.1}\n"
        "train: {steps: 1000, batch: 128}\nprofiles: {fast: {model: {channels: 64}}}\n",
    )
    write(tmp_path / "a3.yaml", "base: base.yaml\nname: A3\nloss: {lambda_h: 0.0}\n")
    cfg = load_config(tmp_path / "a3.yaml", ["train.steps=20"], profile="fast")
    assert cfg["model"] == {"channels": 64, "dropout": 0.1}
    assert cfg["loss"] == {"lambda_h": 0.0} and cfg["train"] == {"steps": 20, "batch": 128}
    assert load_config(tmp_path / "a3.yaml", profile="paper")["model"]["channels"] == 1024
    with pytest.raises(ConfigError, match="unknown key 'train.stpes'"):
        load_config(tmp_path / "a3.yaml", ["train.stpes=3"])
    with pytest.raises(ConfigError, match="key.sub=value"):
        load_config(tmp_path / "a3.yaml", ["train.steps"])
    # a key the schema allows is set even where no file of the chain names it (a section too)
    cfg = load_config(tmp_path / "a3.yaml", ["loss.gan_weight=0.001", "data.window=60"])
    assert cfg["loss"] == {"lambda_h": 0.0, "gan_weight": 0.001} and cfg["data"] == {"window": 60}
    with pytest.raises(ConfigError, match="unknown key 'loss.gan_wieght'"):
        load_config(tmp_path / "a3.yaml", ["loss.gan_wieght=0.001"])
    write(tmp_path / "noseed.yaml", "model: {channels: 3}\n")
    with pytest.raises(ConfigError, match="seed"):
        load_config(tmp_path / "noseed.yaml")
    write(tmp_path / "loop.yaml", "base: loop.yaml\nseed: 1\n")
    with pytest.raises(ConfigError, match="cycle"):
        load_config(tmp_path / "loop.yaml")


@pytest.mark.parametrize(
    "text, value",
    [("1e-3", 0.001), ("-2E+5", -200000.0), (".5e1", 5.0), ("1.0e-4", 1.0e-4), ("3", 3)],
)
def test_an_exponent_without_a_dot_is_a_number(text, value):
    """YAML 1.1 (PyYAML) reads ``1e-3`` as the string "1e-3"; a user typing ``lr: 1e-3`` means the
    number. Words that only look alike stay strings."""
    parsed = load_yaml(text, "test", ConfigError)
    assert parsed == value and type(parsed) is type(value)
    for word in ("1e", "e5", "1e-3x"):
        assert load_yaml(word, "test", ConfigError) == word


def test_a_learning_rate_override_in_exponent_form(tmp_path):
    write(tmp_path / "c.yaml", "seed: 1\ntrain: {lr: 1e-4}\n")
    assert load_config(tmp_path / "c.yaml")["train"]["lr"] == 1e-4
    assert load_config(tmp_path / "c.yaml", ["train.lr=1e-3"])["train"]["lr"] == 1e-3


def regression_task(stop_at=None, nan_at=None):
    """Linear regression on random minibatches drawn from the global torch RNG."""
    torch.manual_seed(123)
    model = torch.nn.Linear(3, 1)
    opt = torch.optim.Adam(model.parameters(), lr=0.05)
    w_true = torch.tensor([[1.0, -2.0, 0.5]])

    def step(i):
        if stop_at is not None and i == stop_at:
            raise KeyboardInterrupt
        x = torch.randn(16, 3)
        loss = ((model(x) - x @ w_true.T) ** 2).mean()
        if nan_at is not None and i == nan_at:
            loss = loss * float("nan")
        opt.zero_grad()
        loss.backward()
        opt.step()
        return {"mse": loss.item(), "scale": 1.0}

    return TrainTask({"model": model}, {"adam": opt}, step), model


def read_log(path):
    with open(path) as f:
        return list(csv.reader(f))


def test_interrupted_run_resumes_to_the_same_result(tmp_path):
    task, straight = regression_task()
    fit(task, {"seed": 7}, tmp_path / "a", steps=10, checkpoint_every=3, progress=False)
    task, _ = regression_task(stop_at=7)
    with pytest.raises(KeyboardInterrupt):
        fit(task, {"seed": 7}, tmp_path / "b", steps=10, checkpoint_every=3, progress=False)
    assert load_checkpoint(tmp_path / "b" / "last.pt")["step"] == 6
    task, resumed = regression_task()
    fit(
        task, {"seed": 7}, tmp_path / "b", steps=10, checkpoint_every=3, resume=True, progress=False
    )
    for a, b in zip(straight.parameters(), resumed.parameters(), strict=False):
        assert torch.equal(a, b)  # the same code in one process, state reloaded from binary: exact
    log_a, log_b = read_log(tmp_path / "a" / "losses.csv"), read_log(tmp_path / "b" / "losses.csv")
    assert [r[0] for r in log_b[1:]] == [str(i) for i in range(10)]
    np.testing.assert_array_equal([r[2] for r in log_a], [r[2] for r in log_b])
    assert (tmp_path / "b" / "final.pt").exists() and (tmp_path / "b" / "config.yaml").exists()


def test_nan_stops_with_a_clear_message(tmp_path):
    task, _ = regression_task(nan_at=4)
    with pytest.raises(NonFiniteLossError, match=r"\['mse'\].*step 4.*last.pt"):
        fit(task, {"seed": 0}, tmp_path / "n", steps=10, checkpoint_every=2, progress=False)
    assert not (tmp_path / "n" / "final.pt").exists()
    assert load_checkpoint(tmp_path / "n" / "last.pt")["step"] == 4
