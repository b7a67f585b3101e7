"""The method registry: every retargeting method by name, in one place.

The command line (``retarget retarget --method NAME``), the evaluation tables, the benchmarks and
the notebooks all find methods here. **Adding a method** = one module in this folder with a
``load(checkpoint) -> retarget`` function, and one line in :data:`REGISTRY` below. A learned
method's default checkpoint is not written here but in ``data_manifest.yaml`` (the entry with
``method: NAME`` and ``default: true``).

A method's ``retarget`` function takes the canonical-22 source motion and the target — a
:class:`~retarget_lib.core.skeleton.Skeleton`, or for a method that ``needs_mesh`` a
:class:`~retarget_lib.core.character.Character` — and returns the motion on the target.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass

from ..core.motion import Motion
from ..data.manifest import default_checkpoint
from . import contact, copy, copy_rest, nkn, tdcn

__all__ = ["Method", "REGISTRY", "get_method", "method_names"]

#: ``retarget(source, target, **options) -> Motion``
Retarget = Callable[..., Motion]


@dataclass(frozen=True)
class Method:
    """A retargeting method of the registry.

    Attributes:
        name: the ``--method`` name.
        summary: one line for ``retarget retarget --help``.
        load: ``load(checkpoint, device) -> retarget`` (a manifest id or a path; a ``--device``
            name, ``None`` = CPU); methods without a checkpoint run in NumPy and take ``None`` for
            both.
        needs_checkpoint: a learned method (``--checkpoint``, default from the manifest).
        needs_mesh: the target must be a skinned ``Character`` (a shape file or a named
            character), not only a skeleton.
    """

    name: str
    summary: str
    load: Callable[..., Retarget]
    needs_checkpoint: bool = False
    needs_mesh: bool = False

    def default_checkpoint(self) -> str | None:
        """Manifest id of the checkpoint used when none is given (``None``: no default shipped,
        or the method needs none)."""
        return default_checkpoint(self.name) if self.needs_checkpoint else None

    def retargeter(
        self, checkpoint: str | os.PathLike | None = None, device: str | None = None
    ) -> Retarget:
        """The ready ``retarget`` function, its checkpoint loaded once.

        Args:
            checkpoint: a manifest id or a path; default :meth:`default_checkpoint`. Ignored by
                methods without a checkpoint.
            device: where a learned method's network runs (``auto``, ``cpu``, ``cuda``, ``mps``;
                default the CPU, :func:`~retarget_lib.devices.resolve_device`). Methods without a
                checkpoint run in NumPy and ignore it.

        Raises:
            ValueError: a learned method without a checkpoint.
        """
        if not self.needs_checkpoint:
            return self.load(None, None)
        checkpoint = checkpoint if checkpoint is not None else self.default_checkpoint()
        if checkpoint is None:
            raise ValueError(
                f"--method {self.name} needs --checkpoint (a `retarget train` output): no "
                f"{self.name} checkpoint is shipped yet"
            )
        return self.load(checkpoint, device)


#: every method, by name (the order of ``retarget retarget --help``)
REGISTRY: dict[str, Method] = {
    m.name: m
    for m in (
        Method("copy", "copy the local rotations, root scaled by the leg-length ratio", copy.load),
        Method(
            "copy-unscaled",
            "copy the local rotations and the root's displacements unscaled (the papers' copy row)",
            copy.load_unscaled,
        ),
        Method(
            "copy-rest",
            "copy the rotation deltas from each rig's retarget pose (its canonical T-pose)",
            copy_rest.load,
        ),
        Method("tdcn", "the TDCN generator (Kim et al. 2020)", tdcn.load, needs_checkpoint=True),
        Method(
            "nkn", "an NKN baseline generator of TDCN's Table 4", nkn.load, needs_checkpoint=True
        ),
        Method(
            "contact",
            "contact-aware RNN + encoder-space optimisation (Villegas et al. 2021)",
            contact.load,
            needs_checkpoint=True,
            needs_mesh=True,
        ),
    )
}


def method_names() -> list[str]:
    """The registered method names."""
    return list(REGISTRY)


def get_method(name: str) -> Method:
    """The registered method called ``name``.

    Raises:
        ValueError: unknown name (the known ones are listed).
    """
    if name not in REGISTRY:
        raise ValueError(f"unknown method {name!r}; choose from {', '.join(REGISTRY)}")
    return REGISTRY[name]
