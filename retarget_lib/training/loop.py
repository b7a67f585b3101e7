"""The training loop every model shares: seeded, logged to CSV, checkpointed atomically, resumable,
and stopped with a clear message on NaN/inf.

A method supplies a :class:`TrainTask` — its modules, optimisers and a ``step(batch_index)`` that
returns a dict of float losses — and :func:`fit` does the rest::

    run_dir/config.yaml      the merged config
    run_dir/losses.csv       one row per step: step, seconds, every loss term
    run_dir/last.pt          the latest checkpoint (atomic; ``--resume`` continues from it)
    run_dir/final.pt         written when training completes

Under ``torchrun`` every process runs :func:`fit` with its
:class:`~retarget_lib.training.distributed.Distributed` layout: the losses logged are the means
over the processes, and rank 0 alone writes the files above
(:mod:`retarget_lib.training.distributed`).
"""

from __future__ import annotations

import csv
import math
import random
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch
from tqdm.auto import tqdm

from ..config import dump_config
from ..data.checkpoints import load_state, save_state
from ..files import atomic_write
from ..losses import NonFiniteLossError
from .distributed import SINGLE, Distributed


def learning_rate(lr: float, index: int, steps: int, decay_from: float | None) -> float:
    """Adam's learning rate at step ``index`` of ``steps``: constant, or constant up to the fraction
    ``decay_from`` of the run and then linear towards 0 (the GAN schedule of CycleGAN, Zhu et al.
    2017, Sec. 7: same Adam betas (0.5, 0.999) as both trainers here). A function of the step
    alone, so a resumed run continues the same schedule.

    Args:
        lr: the base rate (``train.lr``).
        index: 0-based step.
        steps: the run's total steps (``train.steps``).
        decay_from: ``None``: ``lr`` at every step (the TDCN paper's constant rate), else a
            fraction in [0, 1].

    Returns:
        the rate; the last step of a decayed run uses ``lr / (decayed steps)``, never 0.
    """
    if decay_from is None:
        return lr
    start = int(round(float(decay_from) * steps))
    if index < start:
        return lr
    return lr * (steps - index) / max(steps - start, 1)


def seed_everything(seed: int) -> None:
    """Seed Python's ``random``, NumPy's global RNG and torch (CPU) with ``seed``."""
    random.seed(seed)
    np.random.seed(seed)
    torch.manual_seed(seed)


@dataclass
class TrainTask:
    """What :func:`fit` trains.

    Attributes:
        modules: name -> module (their ``state_dict`` is checkpointed).
        optimizers: name -> optimiser (checkpointed too).
        step: ``step(i) -> {term: float}``; does one optimisation step and returns its losses.
        extra_state: name -> object with ``state_dict``/``load_state_dict`` (e.g. a normaliser).
    """

    modules: dict[str, torch.nn.Module]
    optimizers: dict[str, torch.optim.Optimizer]
    step: Callable[[int], dict[str, float]]
    extra_state: dict = field(default_factory=dict)


def _rng_state() -> dict:
    """The three global RNG states as tensors and plain values (they load with ``weights_only``)."""
    name, keys, pos, has_gauss, cached = np.random.get_state()
    return {
        "torch": torch.get_rng_state(),
        "numpy": (
            name,
            torch.from_numpy(keys.astype(np.int64)),
            int(pos),
            int(has_gauss),
            float(cached),
        ),
        "python": random.getstate(),
    }


def _set_rng_state(state: dict) -> None:
    torch.set_rng_state(state["torch"])
    name, keys, pos, has_gauss, cached = state["numpy"]
    np.random.set_state(
        (name, np.asarray(keys, dtype=np.int64).astype(np.uint32), pos, has_gauss, cached)
    )
    random.setstate(state["python"])


def save_checkpoint(path: str | Path, task: TrainTask, step: int, config: dict) -> Path:
    """Write modules, optimisers, RNG states, step and config to ``path`` atomically."""
    state = {
        "step": step,
        "config": config,
        "modules": {k: m.state_dict() for k, m in task.modules.items()},
        "optimizers": {k: o.state_dict() for k, o in task.optimizers.items()},
        "extra": {k: e.state_dict() for k, e in task.extra_state.items()},
        "rng": _rng_state(),
    }
    return save_state(state, path)


def load_checkpoint(path: str | Path, task: TrainTask | None = None) -> dict:
    """Read a checkpoint (``weights_only``); with ``task``, restore its modules, optimisers, extra
    state and RNGs."""
    state = load_state(path)
    if task is not None:
        for k, m in task.modules.items():
            m.load_state_dict(state["modules"][k])
        for k, o in task.optimizers.items():
            o.load_state_dict(state["optimizers"][k])
        for k, e in task.extra_state.items():
            e.load_state_dict(state["extra"][k])
        _set_rng_state(state["rng"])
    return state


def _check_finite(losses: dict[str, float], step: int, run_dir: Path) -> None:
    bad = [k for k, v in losses.items() if not math.isfinite(v)]
    if bad:
        last = run_dir / "last.pt"
        where = f"; the last good checkpoint is {last}" if last.exists() else ""
        raise NonFiniteLossError(
            f"loss term(s) {bad} became non-finite at step {step}{where}. "
            "Lower the learning rate or check the input data for NaNs."
        )


def _truncate_log(path: Path, upto: int) -> None:
    """Keep the header and the rows with ``step < upto`` (a resumed run rewrites the rest)."""
    if not path.exists():
        return
    with open(path) as f:
        rows = list(csv.reader(f))
    keep = rows[:1] + [r for r in rows[1:] if r and int(r[0]) < upto]
    with atomic_write(path, "w") as f:
        csv.writer(f).writerows(keep)


def fit(
    task: TrainTask,
    config: dict,
    run_dir: str | Path,
    steps: int,
    checkpoint_every: int = 100,
    resume: bool = False,
    progress: bool = True,
    layout: Distributed = SINGLE,
) -> Path:
    """Run ``steps`` optimisation steps of ``task``; return the final checkpoint's path.

    Args:
        task: the :class:`TrainTask`.
        config: merged config (its ``seed`` seeds everything; it is stored in the checkpoints).
        run_dir: output folder.
        steps: total steps (a resumed run continues up to this number).
        checkpoint_every: steps between ``last.pt`` writes.
        resume: continue from ``run_dir/last.pt`` if it exists (modules, optimisers, RNGs, log).
        progress: show a tqdm progress bar (rank 0 only).
        layout: this process's place in a multi-process run (default: the only process). The task
            must shard its batches and average its gradients with the same layout.

    Raises:
        NonFiniteLossError: as soon as a loss is NaN/inf (nothing after it is saved).
    """
    run_dir = Path(run_dir)
    main = layout.is_main
    if main:
        run_dir.mkdir(parents=True, exist_ok=True)
        with atomic_write(run_dir / "config.yaml", "w") as f:
            f.write(dump_config(config))
    layout.barrier()
    seed_everything(int(config["seed"]))
    start = 0
    last = run_dir / "last.pt"
    log_path = run_dir / "losses.csv"
    if resume and last.exists():
        start = int(load_checkpoint(last, task)["step"])
        if main:
            _truncate_log(log_path, start)
    elif main and log_path.exists():
        log_path.unlink()
    layout.barrier()
    for m in task.modules.values():
        m.train()
    writer, fh, header = None, None, None
    t0 = time.perf_counter()
    bar = tqdm(
        range(start, steps),
        initial=start,
        total=steps,
        disable=not (progress and main),
        desc=config.get("name", "train"),
    )
    try:
        for i in bar:
            losses = layout.mean(task.step(i))
            _check_finite(losses, i, run_dir)
            if not main:
                continue
            if writer is None:
                header = ["step", "seconds"] + list(losses)
                new = not log_path.exists() or log_path.stat().st_size == 0
                fh = open(log_path, "a", newline="")
                writer = csv.writer(fh)
                if new:
                    writer.writerow(header)
            writer.writerow(
                [i, f"{time.perf_counter() - t0:.3f}"] + [f"{losses[k]:.6g}" for k in header[2:]]
            )
            if progress:
                bar.set_postfix({k: f"{v:.3g}" for k, v in list(losses.items())[:3]})
            if (i + 1) % checkpoint_every == 0 or i + 1 == steps:
                fh.flush()
                save_checkpoint(last, task, i + 1, config)
    finally:
        if fh is not None:
            fh.close()
    final = run_dir / "final.pt"
    if main:
        save_checkpoint(final, task, steps, config)
    layout.barrier()
    return final
