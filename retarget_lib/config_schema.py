"""The experiment config schema: every key ``retarget train`` reads, its type and allowed values.

:func:`validate` runs on the merged config (base chain, profile, overrides) before any work starts,
so a typo (``trian:``, ``stesp``, ``lambda_hh``) or a bad value (``steps: abc``, ``channels: -4``)
stops the command with a :class:`~retarget_lib.config.ConfigError` naming the key and what is
allowed, instead of being ignored by a training run. A config with ``method: contact`` follows
:data:`CONTACT`, every other one :data:`TDCN`. Keys meant for the model constructors are listed
in :mod:`retarget_lib.models` (TDCN/NKN) and :mod:`retarget_lib.training.contact`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Callable

__all__ = ["Rule", "TDCN", "CONTACT", "schema_for", "check_value", "validate"]


@dataclass(frozen=True)
class Rule:
    """What one key accepts.

    Attributes:
        allowed: the allowed values in words (used in the error message).
        ok: ``ok(value) -> bool``.
    """

    allowed: str
    ok: Callable[[Any], bool]


def _is_int(v: Any) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


def _is_num(v: Any) -> bool:
    return (isinstance(v, (int, float)) and not isinstance(v, bool)) and math.isfinite(v)


POS_INT = Rule("an integer > 0", lambda v: _is_int(v) and v > 0)
NONNEG_INT = Rule("an integer >= 0", lambda v: _is_int(v) and v >= 0)
POS_NUM = Rule("a finite number > 0", lambda v: _is_num(v) and v > 0)
NONNEG_NUM = Rule("a finite number >= 0", lambda v: _is_num(v) and v >= 0)
FRACTION = Rule("a number in [0, 1]", lambda v: _is_num(v) and 0 <= v <= 1)
DECAY_FROM = Rule("null (constant rate) or a number in [0, 1]",
                  lambda v: v is None or (_is_num(v) and 0 <= v <= 1))
DROPOUT = Rule("null or a number in [0, 1)", lambda v: v is None or (_is_num(v) and 0 <= v < 1))
BOOL = Rule("true or false", lambda v: isinstance(v, bool))
TEXT = Rule("a string", lambda v: isinstance(v, str) and bool(v))
BETAS = Rule("two numbers in [0, 1), e.g. [0.5, 0.999]",
             lambda v: isinstance(v, list) and len(v) == 2 and all(_is_num(b) and 0 <= b < 1 for b in v))
SCALE_RANGE = Rule("null or [low, high] with 0 < low <= high",
                   lambda v: v is None or (isinstance(v, list) and len(v) == 2 and all(_is_num(x) for x in v)
                                           and 0 < v[0] <= v[1]))
NAMES = Rule("a list of character names", lambda v: isinstance(v, list) and all(isinstance(n, str) for n in v))
INT_LIST = Rule("a list of integers > 0", lambda v: isinstance(v, list) and all(_is_int(x) and x > 0 for x in v))


def choice(*values: Any) -> Rule:
    """One of ``values``."""
    return Rule("one of " + ", ".join(repr(v) for v in values), lambda v: v in values)


def lazy_choice(describe: str, values: Callable[[], Any]) -> Rule:
    """One of ``values()`` (imported on first use: the tables live in modules that load torch)."""
    return Rule(f"one of {describe}", lambda v: v in values())


def _table4_rows():
    from .models import TABLE4_ROWS
    return TABLE4_ROWS


#: ``data.source`` values: the embedded synthetic split, a reviewer's Mixamo folder, or both
DATA_SOURCES = ("synthetic", "mixamo-local", "mixamo-local+synthetic")


def _data_sources():
    return DATA_SOURCES


def _table3_rows():
    from .losses.contact import TABLE3_ROWS
    return TABLE3_ROWS


_COMMON = {"name": TEXT, "seed": NONNEG_INT, "method": choice("tdcn", "contact"), "profile": choice("fast", "paper"),
           "config_path": TEXT}

#: ``method: tdcn`` (default): TDCN and NKN rows of Kim et al. 2020, Table 4
TDCN: dict[str, Any] = {
    **_COMMON,
    "model": {"row": lazy_choice("the Table 4 rows (retarget_lib.models.TABLE4_ROWS)", _table4_rows),
              "kind": choice("tdcn", "nkn"), "variant": TEXT, "profile": choice("fast", "paper"),
              "channels": POS_INT, "disc_channels": POS_INT, "disc_receptive_field": choice(31, 81),
              "dropout": DROPOUT, "normalize_inputs": BOOL, "height_loss": BOOL, "dilations": INT_LIST,
              "kernel": POS_INT, "slope": NONNEG_NUM, "head_hidden": POS_INT, "skip_projection": BOOL,
              "num_layers": POS_INT, "disc_norm": TEXT, "causal": BOOL, "dense": BOOL, "residual": BOOL,
              "normalize_root": BOOL, "backbone": TEXT, "data": TEXT, "loss": TEXT},
    "data": {"window": POS_INT, "same_fraction": FRACTION, "scale_range": SCALE_RANGE, "scale_targets": BOOL,
             "mirror": BOOL, "random_yaw": BOOL,
             "rest_jitter_deg": Rule("a number of degrees in [0, 180]", lambda v: _is_num(v) and 0 <= v <= 180),
             "source": lazy_choice("synthetic, mixamo-local ($RETARGET_MIXAMO) or mixamo-local+synthetic",
                                   _data_sources)},
    "loss": {"gan": choice("lsgan", "sigmoid_ce"), "twist_alpha_deg": NONNEG_NUM, "twist_exclude_root": BOOL,
             **{f"lambda_{k}": NONNEG_NUM for k in "ctharogd"}},
    "train": {"steps": POS_INT, "batch": POS_INT, "lr": POS_NUM, "betas": BETAS, "checkpoint_every": POS_INT,
              "decay_from": DECAY_FROM, "compile": BOOL},
}

#: ``method: contact``: the contact-aware rows of Villegas et al. 2021, Table 3
CONTACT: dict[str, Any] = {
    **_COMMON,
    "model": {"hidden": POS_INT, "layers": POS_INT, "geometry": POS_INT, "dropout": DROPOUT, "residual": BOOL},
    "energy": {"row": lazy_choice("the Table 3 rows (retarget_lib.losses.contact.TABLE3_ROWS)", _table3_rows),
               "lambda_j2j": NONNEG_NUM, "beta_int": NONNEG_NUM, "gamma_foot": NONNEG_NUM, "rho": NONNEG_NUM,
               "omega": NONNEG_NUM, "length_unit": POS_NUM},
    "data": {"window": POS_INT, "held_out_seed": NONNEG_INT, "train_characters": NAMES,
             "source": lazy_choice("synthetic, mixamo-local ($RETARGET_MIXAMO) or mixamo-local+synthetic",
                                   _data_sources)},
    "train": {"steps": POS_INT, "epochs": POS_INT, "batch": POS_INT, "lr": POS_NUM, "betas": BETAS,
              "lr_decay": Rule("a number in (0, 1]", lambda v: _is_num(v) and 0 < v <= 1),
              "checkpoint_every": POS_INT, "compile": BOOL},
    "eso": {"iterations": NONNEG_INT, "lr": POS_NUM, "reach": POS_NUM, "blend": FRACTION},
}


def schema_for(config: dict) -> dict[str, Any]:
    """:data:`CONTACT` for ``method: contact``, else :data:`TDCN`."""
    return CONTACT if config.get("method") == "contact" else TDCN


def _problem(schema: dict, keys: list[str], value: Any) -> str | None:
    """What is wrong with ``value`` at the dotted ``keys`` (``None``: nothing)."""
    node: Any = schema
    for i, k in enumerate(keys):
        where = ".".join(keys[:i])
        if not isinstance(node, dict):
            return f"{'.'.join(keys[:i])!r} is not a section"
        if k not in node:
            return (f"unknown key {'.'.join(keys[: i + 1])!r}; allowed {'in ' + repr(where) if where else 'at the top'}: "
                    f"{', '.join(sorted(node))}")
        node = node[k]
    if isinstance(node, dict):
        if not isinstance(value, dict):
            return f"{'.'.join(keys)!r} must be a section (a mapping of {', '.join(sorted(node))})"
        for k, v in value.items():
            found = _problem(schema, keys + [str(k)], v)
            if found:
                return found
        return None
    if not node.ok(value):
        return f"{'.'.join(keys)} = {value!r} is invalid: must be {node.allowed}"
    return None


def check_value(config: dict, keys: list[str], value: Any) -> str | None:
    """The problem with setting the dotted ``keys`` of ``config`` to ``value``, or ``None``."""
    return _problem(schema_for(config), keys, value)


def validate(config: dict) -> str | None:
    """The first problem of a merged config (unknown key, wrong type, invalid value), or ``None``."""
    schema = schema_for(config)
    for k, v in config.items():
        found = _problem(schema, [str(k)], v)
        if found:
            return found
    return None
