"""Where tensors live: ``--device auto|cpu|cuda|mps`` and mixed precision.

Every command that runs a network (``retarget train``, ``evaluate``, ``retarget``, ESO inside the
contact method) takes ``--device``; :func:`resolve_device` turns the option into a
:class:`torch.device`. ``auto`` picks CUDA, then Apple's MPS, then the CPU — so on the laptop and
in CI it is the CPU, and the CPU path is the one the recorded numbers were measured on: data are
sampled on the CPU (the same RNG draws on every device) and moved to the device per step.

Mixed precision (:func:`autocast`) is CUDA-only and uses bfloat16, which has float32's exponent
range: no loss scaling is needed, so the optimiser code is the same with and without it.
"""

from __future__ import annotations

import contextlib

import torch

from .errors import DeviceError

__all__ = ["DEVICE_CHOICES", "resolve_device", "autocast", "module_device"]

#: what ``--device`` accepts
DEVICE_CHOICES: tuple[str, ...] = ("auto", "cpu", "cuda", "mps")


def _mps_available() -> bool:
    mps = getattr(torch.backends, "mps", None)
    return bool(mps is not None and mps.is_available())


def resolve_device(name: str | torch.device | None = "auto", local_rank: int = 0) -> torch.device:
    """The :class:`torch.device` of a ``--device`` option.

    Args:
        name: ``"auto"`` (CUDA, else MPS, else CPU), ``"cpu"``, ``"cuda"``, ``"mps"``, a
            ``torch.device``, or ``None`` (= ``"auto"``).
        local_rank: the CUDA device index of this process under ``torchrun`` (its ``LOCAL_RANK``).

    Returns:
        the device (``cuda:<local_rank>`` for CUDA).

    Raises:
        DeviceError: an unknown name, or an accelerator this machine does not have.
    """
    if isinstance(name, torch.device):
        name = name.type
    name = "auto" if name is None else str(name)
    if name not in DEVICE_CHOICES:
        raise DeviceError(f"--device {name!r}: choose from {', '.join(DEVICE_CHOICES)}")
    if name == "auto":
        name = "cuda" if torch.cuda.is_available() else "mps" if _mps_available() else "cpu"
    if name == "cuda":
        if not torch.cuda.is_available():
            raise DeviceError(
                "--device cuda: this torch build or machine has no CUDA device "
                f"(torch {torch.__version__}); use --device auto or cpu"
            )
        return torch.device("cuda", local_rank % torch.cuda.device_count())
    if name == "mps" and not _mps_available():
        raise DeviceError(
            "--device mps: Apple's Metal backend is not available here; use --device auto or cpu"
        )
    return torch.device(name)


def autocast(device: torch.device, enabled: bool) -> contextlib.AbstractContextManager:
    """``torch.autocast`` in bfloat16 on CUDA when ``enabled``; a no-op context otherwise.

    Raises:
        DeviceError: ``enabled`` on a device other than CUDA, or a GPU without bfloat16.
    """
    if not enabled:
        return contextlib.nullcontext()
    if device.type != "cuda":
        raise DeviceError(f"--amp (mixed precision) needs --device cuda, not {device.type}")
    if not torch.cuda.is_bf16_supported():
        raise DeviceError("--amp: this GPU has no bfloat16 support; train without --amp")
    return torch.autocast("cuda", dtype=torch.bfloat16)


def module_device(module: torch.nn.Module) -> torch.device:
    """The device of ``module``'s first parameter (CPU for a module without parameters)."""
    return next((p.device for p in module.parameters()), torch.device("cpu"))
