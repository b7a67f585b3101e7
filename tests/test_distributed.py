"""Multi-process training (retarget_lib.training.distributed): 2 gloo processes on the CPU give
the loss curve of one process at the same global batch, and a 2-process checkpoint resumes in one
process. Tiny widths, 4 steps, synthetic clips made here (no built dataset needed).

Tolerance: per-step losses agree to ``rtol = 1e-4`` (plus ``atol = 1e-7``). The two runs compute
the same mathematics in a different float32 summation order — each rank sums its half of the batch
(losses, batch-norm statistics, gradients) and the halves are then added (all-reduce), where one
process sums the batch in one pass — so they differ by rounding, which the Adam steps carry
forward. Measured (2026-12-01, this machine): step 0 identical in every logged digit (the log keeps
6 significant digits); later steps at most 6.5e-5 relative, on the quaternion regulariser Lr
(~1.4e-5 in value, i.e. 1e-9 absolute), every other term within 4e-6.

Spawning the processes (torch imports under load) makes this file slow: about 2 min on the busy
2-core machine, for about 30 s of CPU.
"""

import csv
import os
import socket
from pathlib import Path

import numpy as np
import pytest
import torch
import torch.multiprocessing as mp

from retarget_lib.config import load_config
from retarget_lib.core.rotations import quat_from_axis_angle
from retarget_lib.errors import DeviceError
from retarget_lib.training import distributed
from retarget_lib.training.loop import fit
from retarget_lib.training.tdcn import RetargetTraining
from retarget_lib.training.tdcn_data import TrainingClips

pytestmark = pytest.mark.slow

CONFIG = Path(__file__).resolve().parents[1] / "configs" / "tdcn_paper.yaml"
#: tiny widths; every pair A ≠ B (see the module docstring of distributed: the D fake term is then
#: a mean over the whole shard); no dropout (its masks are per rank by design)
OVERRIDES = [
    "model.channels=16",
    "model.disc_channels=8",
    "train.batch=4",
    "data.same_fraction=0.0",
    "model.dropout=0.0",
]
STEPS = 4
RTOL = 1e-4


def tiny_clips() -> TrainingClips:
    """3 characters x 2 clips of 100 frames: random smooth rotations, proportions scaled."""
    g = torch.Generator().manual_seed(0)
    frames, clips, chars = 100, 2, 3
    t = torch.linspace(0, 1, frames)[:, None, None]
    axis = torch.randn(clips, 1, 22, 3, generator=g)
    angle = 0.3 * torch.sin(2 * torch.pi * (t + torch.rand(clips, 1, 22, 1, generator=g)))
    rotations = quat_from_axis_angle(axis / axis.norm(dim=-1, keepdim=True) * angle).reshape(
        clips * frames, 22, 4
    )
    offsets = torch.randn(22, 3, generator=g) * 0.1 + torch.tensor([0.0, 0.1, 0.0])
    scale = torch.tensor([0.8, 1.0, 1.2])
    root = torch.stack(
        [
            torch.linspace(0, 1, clips * frames),
            torch.full((clips * frames,), 0.9),
            torch.zeros(clips * frames),
        ],
        -1,
    )
    return TrainingClips(
        ("a", "b", "c"),
        ("c0", "c1"),
        torch.tensor([0, frames, 2 * frames]),
        offsets * scale[:, None, None],
        rotations.expand(chars, -1, -1, -1).contiguous(),
        root * scale[:, None, None],
    )


def train(out: Path, steps: int, layout=distributed.SINGLE, resume: bool = False) -> None:
    torch.set_num_threads(1)
    config = load_config(
        CONFIG, OVERRIDES + [f"train.steps={steps}", "train.checkpoint_every=2"], "fast"
    )
    run = RetargetTraining(config, tiny_clips(), layout=layout)
    fit(
        run.task(),
        config,
        out,
        steps,
        checkpoint_every=2,
        resume=resume,
        progress=False,
        layout=layout,
    )


def _worker(rank: int, world: int, port: int, out: str, steps: int) -> None:
    os.environ.update(
        RANK=str(rank),
        WORLD_SIZE=str(world),
        LOCAL_RANK=str(rank),
        MASTER_ADDR="127.0.0.1",
        MASTER_PORT=str(port),
    )
    layout = distributed.from_environment()
    distributed.init_process_group(layout, torch.device("cpu"))
    try:
        train(Path(out), steps, layout)
    finally:
        distributed.shutdown()


def train_processes(out: Path, steps: int, world: int = 2) -> None:
    """The same run in ``world`` gloo processes (as ``torchrun`` would start them)."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    mp.start_processes(
        _worker, args=(world, port, str(out), steps), nprocs=world, start_method="spawn"
    )


def losses(run: Path) -> np.ndarray:
    with open(run / "losses.csv") as f:
        rows = list(csv.reader(f))
    return np.array([[float(v) for v in r[2:]] for r in rows[1:]])


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    root = tmp_path_factory.mktemp("ddp")
    train(root / "one", STEPS)
    train_processes(root / "two", STEPS)
    return root


def test_two_gloo_processes_match_one_process_at_the_same_global_batch(runs):
    one, two = losses(runs / "one"), losses(runs / "two")
    assert one.shape == two.shape == (STEPS, 9)
    np.testing.assert_allclose(two, one, rtol=RTOL, atol=1e-7)
    assert (runs / "two" / "final.pt").exists()


def test_a_two_process_checkpoint_resumes_in_one_process(runs, tmp_path):
    """Steps 0-1 in two processes, steps 2-3 resumed from its ``last.pt`` in one."""
    train_processes(tmp_path / "half", 2)
    train(tmp_path / "half", STEPS, resume=True)
    np.testing.assert_allclose(
        losses(tmp_path / "half"), losses(runs / "one"), rtol=RTOL, atol=1e-7
    )


def test_a_batch_that_does_not_split_over_the_processes_is_refused():
    with pytest.raises(DeviceError, match="not divisible by the 2 processes"):
        distributed.Distributed(rank=0, world_size=2).shard(5)
