"""--device / --amp (retarget_lib.devices): auto is the CPU on this machine, an accelerator that is
not there or mixed precision off CUDA is a DeviceError, and the CLI reports it in one line (exit 2)
before any work."""

from pathlib import Path

import pytest
import torch

from retarget_lib.cli import main
from retarget_lib.devices import autocast, module_device, resolve_device
from retarget_lib.errors import DeviceError, RetargetInputError

CONFIG = str(Path(__file__).resolve().parents[1] / "configs" / "tdcn_paper.yaml")


def test_auto_and_cpu_resolve_to_the_cpu_here():
    expected = "cuda" if torch.cuda.is_available() else "cpu"
    if not torch.cuda.is_available() and torch.backends.mps.is_available():
        expected = "mps"
    assert resolve_device("auto").type == expected == resolve_device(None).type
    assert resolve_device("cpu") == torch.device("cpu")
    assert module_device(torch.nn.Linear(2, 2)) == torch.device("cpu")


@pytest.mark.skipif(torch.cuda.is_available(), reason="this machine has CUDA")
def test_missing_accelerators_and_cpu_mixed_precision_are_refused():
    assert issubclass(DeviceError, RetargetInputError)
    with pytest.raises(DeviceError, match="no CUDA device"):
        resolve_device("cuda")
    with pytest.raises(DeviceError, match="choose from"):
        resolve_device("tpu")
    with pytest.raises(DeviceError, match="needs --device cuda"):
        autocast(torch.device("cpu"), True)
    with autocast(torch.device("cpu"), False):  # off: a no-op anywhere
        pass


@pytest.mark.skipif(torch.cuda.is_available(), reason="this machine has CUDA")
@pytest.mark.parametrize(
    "flags, message",
    [
        (["--device", "cuda"], "no CUDA device"),
        (["--device", "cpu", "--amp"], "needs --device cuda"),
    ],
)
def test_cli_train_refuses_an_unusable_device_in_one_line(flags, message, tmp_path, capsys):
    assert main(["train", "--config", CONFIG, "--out", str(tmp_path / "run"), *flags]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and message in err[0] and err[0].startswith("retarget train: error:")
    assert not (tmp_path / "run").exists()
