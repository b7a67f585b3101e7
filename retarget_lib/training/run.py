"""One training run from a config file: what ``retarget train`` and every sweep job execute.

:func:`train_config` loads the config (profile, overrides), places the run (``--device``,
``--amp``, the ``torchrun`` layout of :mod:`.distributed`), builds the TDCN/NKN
(:mod:`.tdcn`) or contact-aware (:mod:`.contact`) training, runs :func:`~.loop.fit` and, on
rank 0, exports the slim model. Under ``torchrun`` every process calls it with the same
arguments.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path
from typing import NamedTuple

from ..config import load_config
from ..devices import resolve_device
from . import distributed
from .contact import ContactTraining
from .contact import export_model as export_contact_model
from .loop import fit
from .tdcn import RetargetTraining, export_generator

__all__ = ["TrainResult", "train_config"]


class TrainResult(NamedTuple):
    """What a run wrote (rank 0's paths; the same on every rank).

    Attributes:
        final: ``<out>/final.pt``.
        exported: the slim model, or ``None`` without ``export``.
    """

    final: Path
    exported: Path | None


def train_config(
    config_path: str | os.PathLike,
    overrides: Sequence[str] = (),
    profile: str | None = None,
    out: str | os.PathLike | None = None,
    resume: bool = False,
    export: str | os.PathLike | None = None,
    device: str = "auto",
    amp: bool = False,
    progress: bool = False,
) -> TrainResult:
    """Train the row of ``config_path`` (see the module docstring).

    Args:
        config_path: experiment YAML (``configs/…``).
        overrides: ``key.sub=value`` overrides.
        profile: ``fast`` or ``paper`` (default ``$RETARGET_PROFILE`` or ``fast``).
        out: run folder (default ``runs/<config stem>``).
        resume: continue from ``<out>/last.pt`` if it exists (at any number of processes).
        export: also write the slim inference model here (rank 0).
        device: ``auto``, ``cpu``, ``cuda`` or ``mps``
            (:func:`~retarget_lib.devices.resolve_device`; under ``torchrun`` CUDA device
            ``LOCAL_RANK``).
        amp: bfloat16 autocast (CUDA only).
        progress: tqdm progress bar (rank 0).

    Returns:
        :class:`TrainResult`.

    Raises:
        ConfigError: a bad config or override.
        DeviceError: a device, ``--amp`` or process count this run cannot use.
        NonFiniteLossError: a loss became NaN/inf.
    """
    config = load_config(config_path, overrides, profile)
    out = Path(out or Path("runs") / Path(config_path).stem)
    layout = distributed.from_environment()
    place = resolve_device(device, layout.local_rank)
    distributed.init_process_group(layout, place)
    try:
        contact = config.get("method") == "contact"
        Training = ContactTraining if contact else RetargetTraining
        export_fn = export_contact_model if contact else export_generator
        run = Training(config, device=place, amp=amp, layout=layout)
        final = fit(
            run.task(),
            config,
            out,
            int(config["train"]["steps"]),
            checkpoint_every=int(config["train"]["checkpoint_every"]),
            resume=resume,
            progress=progress,
            layout=layout,
        )
        exported = (
            export_fn(final, export)
            if export and layout.is_main
            else (Path(export) if export else None)
        )
        layout.barrier()
    finally:
        distributed.shutdown()
    return TrainResult(final, exported)
