"""Model checkpoint files: what a reference points at, how a file is read, how it is written.

* A **reference** is a manifest id (``data_manifest.yaml``, ``checkpoints:``) or a path. An id
  always means the shipped file and is checked against its sha256 on every load — never a file of
  the same name in the working directory. A path to a shipped file is checked too.
* Files are **read** with ``torch.load(..., weights_only=True)``: tensors and plain Python values
  only (dict, list, tuple, str, int, float, bool, None), nothing in the file is executed. Tensors
  stored as float16 come back as float32.
* Exported, inference-only models may be **written** with their floating-point tensors as float16
  (:func:`save_state` with ``half=True``): half the bytes on disk and in the git history. The
  exporters do so only where that moves no reported number by more than 1e-3 relative (TDCN
  generators; docs/checkpoints.md). Training checkpoints (``last.pt``, ``final.pt``) keep
  float32, so a resumed run is exact.
* A file that is not a checkpoint (empty, truncated, text, bit-flipped so that it no longer
  unpickles) or holds no ``config``/``modules`` mappings, or model weights that are non-finite or
  beyond :data:`MAX_WEIGHT`, raises :class:`~retarget_lib.errors.CheckpointError` naming the file.
  Whether the weights fit the model is checked where the model is built.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import torch

from ..errors import CheckpointError
from ..files import atomic_write, readable_file
from .manifest import checkpoint, checkpoint_entries

__all__ = ["MAX_WEIGHT", "resolve_checkpoint", "load_state", "save_state"]

#: largest magnitude of a model weight or normaliser statistic accepted in a checkpoint. The
#: shipped models stay below 50 (batch-norm running variances); a flipped exponent bit in a
#: float16/float32 weight of order 1 gives 2**16 or more
MAX_WEIGHT = 1e4


def resolve_checkpoint(ref: str | os.PathLike) -> Path:
    """The file a checkpoint reference points at, checked.

    Args:
        ref: a manifest checkpoint id (a ``str``) or a path.

    Returns:
        the shipped file of an id (sha256 verified), else the path (verified as well if it is a
        shipped file).

    Raises:
        DataError: the id's file is missing or fails its checksum.
        CheckpointError: the reference is neither an id nor an existing file (the known ids are
            named).
        InputFileError: the path is a directory, unreadable or empty.
    """
    entries = checkpoint_entries()
    if isinstance(ref, str) and ref in entries:
        return checkpoint(ref).path
    path = Path(ref)
    if not path.exists():
        raise CheckpointError(
            f"checkpoint {str(ref)!r} is neither a shipped checkpoint id ({', '.join(entries)}) "
            "nor an existing file"
        )
    readable_file(path, "checkpoint file")
    for entry in entries.values():
        if entry.path.exists() and entry.path.samefile(path):
            return checkpoint(entry.id).path
    return path


def _map_tensors(value: Any, fn) -> Any:
    """``value`` with ``fn`` applied to every tensor inside dicts, lists and tuples (a state
    dict's ``_metadata`` is kept)."""
    if isinstance(value, torch.Tensor):
        return fn(value)
    if isinstance(value, dict):
        out = type(value)((k, _map_tensors(v, fn)) for k, v in value.items())
        if hasattr(value, "_metadata"):
            out._metadata = value._metadata  # type: ignore[attr-defined]  # an OrderedDict's attribute
        return out
    if isinstance(value, (list, tuple)):
        items = [_map_tensors(v, fn) for v in value]
        return type(value)(*items) if hasattr(value, "_fields") else type(value)(items)
    return value


def _upcast(t: torch.Tensor) -> torch.Tensor:
    return t.float() if t.dtype == torch.float16 else t


def _halve(t: torch.Tensor) -> torch.Tensor:
    return t.half() if t.is_floating_point() else t


def load_state(ref: str | os.PathLike) -> dict:
    """Read a checkpoint (:func:`resolve_checkpoint`) with ``weights_only=True``; float16
    tensors are returned as float32.

    Raises:
        CheckpointError: not a loadable checkpoint, no ``config``/``modules`` mappings, or
            module weights that are non-finite or beyond :data:`MAX_WEIGHT` (which one is named).
        DataError, InputFileError: as :func:`resolve_checkpoint`.
    """
    path = resolve_checkpoint(ref)
    try:
        state = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as e:  # weights_only: any failure means the bytes are not a checkpoint
        problem = str(e).strip().splitlines()[0][:200] if str(e).strip() else type(e).__name__
        raise CheckpointError(
            f"{path}: not a readable checkpoint (truncated, corrupt or not a torch file): {problem}"
        ) from None
    _validate(state, path)
    return _map_tensors(state, _upcast)


def _validate(state: Any, path: Path) -> None:
    """Raise :class:`CheckpointError` unless ``state`` holds ``config`` and ``modules`` mappings
    whose floating-point weights are finite and within :data:`MAX_WEIGHT`."""
    if (
        not isinstance(state, dict)
        or not isinstance(state.get("config"), dict)
        or not isinstance(state.get("modules"), dict)
    ):
        raise CheckpointError(
            f"{path}: not a checkpoint of `retarget train` (expected a mapping with 'config' and "
            "'modules')"
        )
    for module, weights in state["modules"].items():
        if not isinstance(weights, dict):
            raise CheckpointError(f"{path}: modules[{module!r}] is not a state dict")
        for name, t in weights.items():
            if not isinstance(t, torch.Tensor):
                raise CheckpointError(f"{path}: {module}.{name} is not a tensor")
            if t.is_floating_point() and t.numel():
                if not torch.isfinite(t).all():
                    raise CheckpointError(
                        f"{path}: {module}.{name} has NaN or inf weights (corrupt file)"
                    )
                if t.abs().max() > MAX_WEIGHT:
                    raise CheckpointError(
                        f"{path}: {module}.{name} has weights beyond the limit |w| <= "
                        f"{MAX_WEIGHT:g} (corrupt file?)"
                    )


def save_state(state: dict, path: str | os.PathLike, half: bool = False) -> Path:
    """Write ``state`` (tensors and plain Python values) to ``path`` atomically.

    Args:
        state: what to store; it must load with ``weights_only=True``.
        path: destination.
        half: store floating-point tensors as float16 (exported models).

    Returns:
        ``path``.
    """
    with atomic_write(path) as f:
        torch.save(_map_tensors(state, _halve) if half else state, f)
    return Path(path)
