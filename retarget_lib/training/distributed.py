"""Data-parallel training over several processes (``torchrun``), one code path with a single
process.

``retarget train`` reads ``RANK``/``WORLD_SIZE``/``LOCAL_RANK`` (set by ``torchrun``;
:func:`from_environment`) and joins the process group (:func:`init_process_group`: NCCL on CUDA,
gloo on the CPU). With one process nothing here does anything: the single-process run is
bit-for-bit the one recorded before multi-process training existed.

How ``N`` processes reproduce one process at the same global batch ``B`` (``B % N == 0``):

* **Data.** Every rank seeds the global RNGs with the config's ``seed`` (as one process does) and
  draws the *whole* global batch of ``B`` samples — cheap index arithmetic — then keeps its shard
  (:meth:`Distributed.shard`, contiguous rows ``rank·B/N … (rank+1)·B/N``). The data stream is
  therefore the same at every world size, so a checkpoint (whose RNG state is that stream's)
  resumes at any world size, and the union of the shards is exactly the one-process batch.
* **Per-rank randomness.** Everything a step draws after its batch (dropout masks) comes from a
  generator seeded by ``(seed, rank, step)`` (:meth:`Distributed.rank_random`) and forked off the
  data stream, so ranks do not repeat each other's masks and the data stream stays shared.
* **Gradients.** Every loss is a mean over the local shard; :meth:`Distributed.average_gradients`
  all-reduces the gradients and divides by ``N`` before each optimiser step: the gradient of the
  mean over the global batch, which is what ``DistributedDataParallel`` computes. We do not wrap
  the modules in ``DistributedDataParallel`` itself: the TDCN step calls the generator through
  ``generate()`` twice (the A→B→A cycle) and freezes the discriminator during the generator update,
  which DDP's reducer (hooked on ``forward()``, a fixed set of used parameters) does not allow. The
  price is that the all-reduce does not overlap the backward pass (one collective per optimiser
  step; measured in ``benchmarks/scale-out.md``).
* **Batch statistics.** ``BatchNorm`` layers become :class:`GlobalBatchNorm`, whose training-mode
  mean and variance are all-reduced over the global batch (``torch.nn.SyncBatchNorm`` does this on
  GPUs only; this one also runs on gloo/CPU). Same state-dict keys, so checkpoints are portable.
* **Logging and checkpoints.** Losses are averaged over ranks before they are checked for
  NaN/inf (every rank stops together) and logged; rank 0 alone writes ``config.yaml``,
  ``losses.csv``, ``last.pt`` and ``final.pt``.

Where the N-process run is *not* exactly one process: a loss that is a mean over a data-dependent
subset of the batch — TDCN's discriminator term on the ``A ≠ B`` fakes (Eq. 21) — is averaged per
rank and then over ranks, which weights the fakes of a rank with fewer of them more (unbiased in
expectation). With ``data.same_fraction`` 0 or 1 every subset is the whole shard and the
equivalence is exact up to float summation order (``tests/test_distributed.py``).
"""

from __future__ import annotations

import contextlib
import os
from dataclasses import dataclass

import numpy as np
import torch
import torch.distributed as dist
from torch import nn

from ..errors import DeviceError

__all__ = [
    "Distributed",
    "SINGLE",
    "from_environment",
    "init_process_group",
    "shutdown",
    "GlobalBatchNorm",
    "prepare_module",
]


@dataclass(frozen=True)
class Distributed:
    """This process's place in a data-parallel run.

    Attributes:
        rank: 0 … ``world_size − 1`` (``RANK``).
        world_size: number of processes (``WORLD_SIZE``).
        local_rank: index on this node (``LOCAL_RANK``): the CUDA device it uses.
    """

    rank: int = 0
    world_size: int = 1
    local_rank: int = 0

    @property
    def enabled(self) -> bool:
        """More than one process."""
        return self.world_size > 1

    @property
    def is_main(self) -> bool:
        """Rank 0: the process that writes logs and checkpoints."""
        return self.rank == 0

    def shard(self, batch: int) -> slice:
        """This rank's rows of a global batch of ``batch`` samples.

        Raises:
            DeviceError: ``batch`` is not divisible by the world size.
        """
        if batch % self.world_size:
            raise DeviceError(
                f"train.batch = {batch} is not divisible by the {self.world_size} processes; "
                "choose a global batch that is a multiple of the number of processes"
            )
        size = batch // self.world_size
        return slice(self.rank * size, (self.rank + 1) * size)

    def rank_random(
        self, seed: int, step: int, device: torch.device
    ) -> contextlib.AbstractContextManager:
        """A context whose torch RNG is seeded by ``(seed, rank, step)`` and restored after it
        (nothing with a single process: its one stream is used as before)."""
        if not self.enabled:
            return contextlib.nullcontext()
        return _seeded_fork(
            int(np.random.SeedSequence([seed, self.rank, step]).generate_state(1)[0]), device
        )

    def average_gradients(self, *modules: nn.Module) -> None:
        """All-reduce the gradients of ``modules`` and divide by the world size (in place)."""
        if not self.enabled:
            return
        grads = [p.grad for m in modules for p in m.parameters() if p.grad is not None]
        if not grads:
            return
        flat = torch.cat([g.reshape(-1) for g in grads])
        dist.all_reduce(flat)
        flat /= self.world_size
        offset = 0
        for g in grads:
            g.copy_(flat[offset : offset + g.numel()].view_as(g))
            offset += g.numel()

    def mean(self, values: dict[str, float]) -> dict[str, float]:
        """``values`` averaged over the ranks (same keys on every rank)."""
        if not self.enabled:
            return values
        t = torch.tensor(list(values.values()), dtype=torch.float64)
        dist.all_reduce(t)
        return dict(zip(values, (t / self.world_size).tolist(), strict=False))

    def barrier(self) -> None:
        """Wait for every rank (nothing with one process)."""
        if self.enabled:
            dist.barrier()


#: a single-process run
SINGLE = Distributed()


@contextlib.contextmanager
def _seeded_fork(seed: int, device: torch.device):
    devices = [device] if device.type == "cuda" else []
    with torch.random.fork_rng(devices=devices):
        torch.manual_seed(seed)
        yield


def from_environment() -> Distributed:
    """The layout ``torchrun`` (or any launcher setting ``RANK``, ``WORLD_SIZE``, ``LOCAL_RANK``)
    gives this process; :data:`SINGLE` without those variables.

    Raises:
        DeviceError: inconsistent values.
    """
    try:
        world = int(os.environ.get("WORLD_SIZE", "1"))
        rank = int(os.environ.get("RANK", "0"))
        local = int(os.environ.get("LOCAL_RANK", str(rank)))
    except ValueError:
        raise DeviceError(
            "RANK, WORLD_SIZE and LOCAL_RANK must be integers (set by torchrun)"
        ) from None
    if world < 1 or not 0 <= rank < world or local < 0:
        raise DeviceError(
            f"RANK={rank} WORLD_SIZE={world} LOCAL_RANK={local}: need 0 <= RANK < WORLD_SIZE"
        )
    return Distributed(rank, world, local)


def init_process_group(layout: Distributed, device: torch.device) -> None:
    """Join the process group of ``layout`` (``env://``: ``MASTER_ADDR``/``MASTER_PORT``, as set by
    ``torchrun``) with NCCL on CUDA, gloo otherwise. Nothing for one process or if already
    joined."""
    if not layout.enabled or dist.is_initialized():
        return
    if device.type == "cuda":
        torch.cuda.set_device(device)
    dist.init_process_group(
        "nccl" if device.type == "cuda" else "gloo", rank=layout.rank, world_size=layout.world_size
    )


def shutdown() -> None:
    """Leave the process group (if this process joined one)."""
    if dist.is_initialized():
        dist.destroy_process_group()


class GlobalBatchNorm(nn.BatchNorm1d):
    """``BatchNorm1d`` whose training statistics are those of the global batch across all ranks
    (two all-reduces: the mean, then the centred sum of squares; both differentiable). Outside a
    multi-process group, or in eval mode, it is exactly ``BatchNorm1d``."""

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        if not (self.training and dist.is_initialized() and dist.get_world_size() > 1):
            return super().forward(x)
        # only in a multi-process group: torch.distributed.nn is not importable on every torch build
        # (it needs the distributed package compiled in), and a single process never reaches here
        from torch.distributed.nn.functional import all_reduce

        dtype, x = x.dtype, x.float()  # statistics in float32 (under bfloat16 autocast too)
        dims = [d for d in range(x.dim()) if d != 1]
        view = [1, -1] + [1] * (x.dim() - 2)
        stats = all_reduce(torch.cat([x.sum(dims), x.new_tensor([x.numel() // x.shape[1]])]))
        count = stats[-1]
        mean = stats[:-1] / count
        centred = x - mean.view(view)
        var = all_reduce((centred * centred).sum(dims)) / count
        if self.track_running_stats:
            with torch.no_grad():
                self.num_batches_tracked += 1
                m = (
                    self.momentum
                    if self.momentum is not None
                    else 1.0 / float(self.num_batches_tracked)
                )
                self.running_mean.mul_(1 - m).add_(mean.detach(), alpha=m)
                self.running_var.mul_(1 - m).add_(
                    var.detach() * count / (count - 1).clamp_min(1), alpha=m
                )
        out = centred / torch.sqrt(var.view(view) + self.eps)
        out = out * self.weight.view(view) + self.bias.view(view) if self.affine else out
        return out.to(dtype)


def _global_batchnorm(module: nn.Module) -> nn.Module:
    """``module`` with every ``BatchNorm1d`` replaced by a :class:`GlobalBatchNorm` holding the
    same parameters and buffers."""
    for name, child in module.named_children():
        if type(child) is nn.BatchNorm1d:
            new = GlobalBatchNorm(
                child.num_features,
                child.eps,
                child.momentum,
                child.affine,
                child.track_running_stats,
            )
            new.load_state_dict(child.state_dict())
            setattr(module, name, new)
        else:
            _global_batchnorm(child)
    return module


def prepare_module(module: nn.Module, device: torch.device, layout: Distributed) -> nn.Module:
    """Move ``module`` to ``device``; in a multi-process run also switch its batch norms to
    :class:`GlobalBatchNorm` and broadcast rank 0's weights (in place; returns ``module``)."""
    if layout.enabled:
        _global_batchnorm(module)
    module.to(device)
    if layout.enabled:
        for t in list(module.parameters()) + list(module.buffers()):
            dist.broadcast(t.data, 0)
    return module
