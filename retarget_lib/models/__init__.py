"""Retargeting networks: the TDCN generator and patch discriminator (Kim et al. 2020) and the NKN
baselines (Villegas et al. 2018), built from small config dicts.

>>> from retarget_lib.models import build_model
>>> gen, disc = build_model({"row": "A5", "profile": "fast"})      # causal TDCN, 256 channels

Model config keys (all optional; a ``"model"`` sub-dict is used if present):

=====================  ====================================================================
``row``                a Table 4 row name (:data:`TABLE4_ROWS`), expanded first; explicit
                       keys override it
``kind``               ``"tdcn"`` (default) or ``"nkn"``
``variant``            TDCN: ``"ours"`` (default), ``"dense"`` (A1), ``"disc81"`` (A4),
                       ``"causal"`` (A5). NKN: ``"baseline"`` (default), ``"dense"``,
                       ``"dilated"``, ``"height"``
``profile``            ``"fast"`` or ``"paper"``; default ``$RETARGET_PROFILE`` or ``"fast"``;
                       only picks default widths (:data:`PROFILE_WIDTHS`)
``channels``           generator width (TDCN channels / NKN hidden size)
``disc_channels``      discriminator width
``disc_receptive_field``  31 (default) or 81 (A4)
``dropout``            generator dropout (TDCN default 0.1, Sec. 5)
``normalize_inputs``   ``False`` (default, the paper) or ``True``: the training code fits the
                       generator's :class:`~retarget_lib.models.features.FeatureNormalizer`
``standardized_root``  TDCN paper form and NKN: the root head outputs z-scores (needs
                       ``normalize_inputs``; :class:`~retarget_lib.models.tdcn.TDCNGenerator`,
                       :class:`~retarget_lib.models.nkn.NKNGenerator`)
``height_loss``        NKN only; defaults to ``True`` for ``variant="height"``
``root_frame``         NKN only: ``"world"`` (default) or ``"facing"`` root offsets
``root_height``        NKN only: ``"step"`` (default, integrated) or ``"floor"`` (the root's height)
``root_residual``      TDCN paper form and NKN: ``True`` adds the root head's output (TDCN: the
                       root; NKN: its steps) to the source's, scaled by the leg ratio
                       (:class:`~retarget_lib.models.tdcn.TDCNGenerator`,
                       :class:`~retarget_lib.models.nkn.NKNGenerator`)
``positions_frame``    TDCN paper form: ``"world"`` (default, Eq. 1) or ``"root"``; NKN:
                       ``"world"`` or ``"facing"`` (:data:`~retarget_lib.models.features.
                       POSITION_FRAMES`; the authors' code, audit T5 / N4)
``dilations``, ``kernel``, ``slope``, ``head_hidden``, ``skip_projection``, ``num_layers``,
``disc_norm``, ``causal``, ``dense``  passed to the constructors
=====================  ====================================================================

A2 (unbalanced data) and A3 (no ``L_h``) use the same network as "ours"; their rows only carry
``data``/``loss`` notes for the training code.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, NamedTuple

from torch import nn

from ..config import active_profile
from ..config_schema import TABLE4_ROWS
from ..config_schema import TDCN as TDCN_SCHEMA
from .discriminator import PatchDiscriminator
from .features import FeatureNormalizer, discriminator_features, generator_features
from .nkn import NKNDiscriminator, NKNGenerator
from .tdcn import (
    DilatedStack,
    GeneratorOutput,
    TDCNGenerator,
    normalize_quaternions,
    quaternion_norm,
)

__all__ = [
    "build_model",
    "count_parameters",
    "ModelPair",
    "TABLE4_ROWS",
    "PROFILE_WIDTHS",
    "resolve_config",
    "TDCNGenerator",
    "PatchDiscriminator",
    "NKNGenerator",
    "NKNDiscriminator",
    "DilatedStack",
    "GeneratorOutput",
    "FeatureNormalizer",
    "generator_features",
    "discriminator_features",
    "normalize_quaternions",
    "quaternion_norm",
]

#: default widths per profile (paper: TDCN Sec. 3.2 "1024"; NKN hidden 512; released TDCN disc 256)
PROFILE_WIDTHS: dict[str, dict[str, int]] = {
    "fast": {"tdcn": 256, "nkn": 128, "disc": 128},
    "paper": {"tdcn": 1024, "nkn": 512, "disc": 256},
}

_TDCN_VARIANTS = {
    "ours": {},
    "dense": {"dense": True},
    "causal": {"causal": True},
    "disc81": {"disc_receptive_field": 81},
}
_NKN_VARIANTS = {
    "baseline": {"backbone": "gru"},
    "dense": {"backbone": "dense"},
    "dilated": {"backbone": "dilated"},
    "height": {"backbone": "gru", "normalize_root": True, "height_loss": True},
}
#: the keys a model config may have: the schema's (:data:`retarget_lib.config_schema.TDCN`)
_KNOWN = frozenset(TDCN_SCHEMA["model"])


class ModelPair(NamedTuple):
    """``(generator, discriminator)``; both carry the resolved config as ``.config``."""

    generator: nn.Module
    discriminator: nn.Module


def count_parameters(module: nn.Module, trainable_only: bool = True) -> int:
    """Number of (trainable) parameters of ``module``."""
    return sum(p.numel() for p in module.parameters() if p.requires_grad or not trainable_only)


def resolve_config(config: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """Expand ``row``/``variant``/``profile`` into explicit constructor settings.

    Args:
        config: a model config (see the module docstring) or an experiment config with a
            ``"model"`` entry.

    Returns:
        A new dict with ``kind``, ``variant``, ``profile``, ``channels``, ``disc_channels``,
        ``disc_receptive_field``, ``normalize_inputs`` and the variant's flags filled in.

    Raises:
        ValueError: unknown keys, kinds, variants, rows or profiles.
    """
    config = dict(config or {})
    if "model" in config and isinstance(config["model"], Mapping):
        config = dict(config["model"])
    unknown = set(config) - _KNOWN
    if unknown:
        raise ValueError(f"unknown model config keys {sorted(unknown)}; known: {sorted(_KNOWN)}")
    cfg: dict[str, Any] = {}
    if "row" in config:
        if config["row"] not in TABLE4_ROWS:
            raise ValueError(f"unknown Table 4 row {config['row']!r}; rows: {list(TABLE4_ROWS)}")
        cfg.update(TABLE4_ROWS[config["row"]])
    cfg.update(config)
    kind = cfg.setdefault("kind", "tdcn")
    variants = {"tdcn": _TDCN_VARIANTS, "nkn": _NKN_VARIANTS}.get(kind)
    if variants is None:
        raise ValueError(f"kind must be 'tdcn' or 'nkn', got {kind!r}")
    variant = cfg.setdefault("variant", "ours" if kind == "tdcn" else "baseline")
    if variant not in variants:
        raise ValueError(f"unknown {kind} variant {variant!r}; variants: {list(variants)}")
    for key, value in variants[variant].items():
        cfg.setdefault(key, value)
    profile = cfg.setdefault("profile", active_profile())
    if profile not in PROFILE_WIDTHS:
        raise ValueError(f"profile must be one of {list(PROFILE_WIDTHS)}, got {profile!r}")
    cfg.setdefault("channels", PROFILE_WIDTHS[profile][kind])
    cfg.setdefault("disc_channels", PROFILE_WIDTHS[profile]["disc"])
    cfg.setdefault("disc_receptive_field", 31)
    cfg.setdefault("normalize_inputs", False)
    if cfg.get("standardized_root") and not cfg["normalize_inputs"]:
        raise ValueError("standardized_root needs normalize_inputs: true (the root's mean and std)")
    return cfg


def build_model(config: Mapping[str, Any] | None = None) -> ModelPair:
    """Build a generator and its discriminator from a (small) config dict.

    Args:
        config: see the module docstring; e.g. ``{"kind": "tdcn", "variant": "causal"}`` or
            ``{"row": "Baseline-height", "profile": "paper"}``.

    Returns:
        :class:`ModelPair` ``(generator, discriminator)``, freshly initialised, in train mode.
        TDCN → (:class:`TDCNGenerator`, :class:`PatchDiscriminator`); NKN →
        (:class:`NKNGenerator`, :class:`NKNDiscriminator`).
    """
    cfg = resolve_config(config)
    pick = lambda *keys: {k: cfg[k] for k in keys if k in cfg}  # noqa: E731
    if cfg["kind"] == "tdcn":
        gen = TDCNGenerator(
            channels=cfg["channels"],
            **pick(
                "dropout",
                "dilations",
                "kernel",
                "causal",
                "dense",
                "slope",
                "head_hidden",
                "skip_projection",
                "residual",
                "standardized_root",
                "root_residual",
                "positions_frame",
            ),
        )
        disc = PatchDiscriminator(
            channels=cfg["disc_channels"],
            receptive_field=cfg["disc_receptive_field"],
            **({"norm": cfg["disc_norm"]} if "disc_norm" in cfg else {}),
            **pick("slope"),
        )
    else:
        gen = NKNGenerator(
            hidden=cfg["channels"],
            **pick(
                "backbone",
                "normalize_root",
                "root_frame",
                "root_height",
                "standardized_root",
                "root_residual",
                "positions_frame",
                "height_loss",
                "dropout",
                "dilations",
                "num_layers",
                "slope",
            ),
        )
        disc = NKNDiscriminator(**pick("slope"))
    gen.config = dict(cfg)
    disc.config = dict(cfg)
    return ModelPair(gen, disc)
