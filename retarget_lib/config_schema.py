"""The experiment config schema: every key ``retarget train`` reads, its type and allowed values.

:func:`validate` runs on the merged config (base chain, profile, overrides) before any work starts,
so a typo (``trian:``, ``stesp``, ``lambda_hh``) or a bad value (``steps: abc``, ``channels: -4``)
stops the command with a :class:`~retarget_lib.config.ConfigError` naming the key and what is
allowed, instead of being ignored by a training run. A config with ``method: contact`` follows
:data:`CONTACT`, every other one :data:`TDCN`. Keys meant for the model constructors are listed
in :mod:`retarget_lib.models` (TDCN/NKN) and :mod:`retarget_lib.training.contact`.

Sizes are bounded (``SECURITY.md``): every width at most :data:`MAX_WIDTH` (4x the papers' 1024),
``train.batch`` at most :data:`MAX_BATCH` (16x the papers' 256), ``data.window`` at most
:data:`MAX_WINDOW` frames, ``train.steps`` at most :data:`MAX_STEPS`; and the memory a
combination implies (:func:`training_memory`) at most :data:`MAX_TRAINING_BYTES`, so a value such
as ``model.channels=200000`` or ``train.batch=1000000000`` is refused before any tensor exists.
Values shown in messages are cut short (:func:`~retarget_lib.errors.short_repr`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Any

from .errors import short_repr

__all__ = [
    "Rule",
    "TDCN",
    "CONTACT",
    "MAX_WIDTH",
    "MAX_BATCH",
    "MAX_WINDOW",
    "MAX_STEPS",
    "MAX_TRAINING_BYTES",
    "schema_for",
    "check_value",
    "validate",
    "training_memory",
    "memory_problem",
]

#: bounds of the sizes a config sets (module docstring)
MAX_WIDTH, MAX_BATCH, MAX_WINDOW, MAX_STEPS = 4096, 4096, 1000, 10_000_000
#: the training memory a config may imply (:func:`training_memory`): a large GPU node
MAX_TRAINING_BYTES = 64 * 2**30
#: the per-sample activation bytes of one width unit: float32 x an upper bound of the layers x
#: (forward + backward) of the generator and discriminator
_ACTIVATION_BYTES = 4 * 64


@dataclass(frozen=True)
class Rule:
    """What one key accepts.

    Attributes:
        allowed: the allowed values in words (used in the error message).
        ok: ``ok(value) -> bool``.
        listed: for a choice read late (:func:`lazy_choice`), ``listed()`` gives its values, which
            the error message then lists after ``allowed``.
    """

    allowed: str
    ok: Callable[[Any], bool]
    listed: Callable[[], Iterable[Any]] | None = None

    def words(self) -> str:
        """``allowed``, followed by the values of a late-read choice."""
        if self.listed is None:
            return self.allowed
        return f"{self.allowed}: {', '.join(map(str, self.listed()))}"


def _is_int(v: Any) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


def _is_num(v: Any) -> bool:
    return (_is_int(v) and abs(v) < 2**53) or (isinstance(v, float) and math.isfinite(v))


NONNEG_INT = Rule("an integer >= 0", lambda v: _is_int(v) and v >= 0)
POS_NUM = Rule("a finite number > 0", lambda v: _is_num(v) and v > 0)
NONNEG_NUM = Rule("a finite number >= 0", lambda v: _is_num(v) and v >= 0)
FRACTION = Rule("a number in [0, 1]", lambda v: _is_num(v) and 0 <= v <= 1)
#: ``train.decay_from`` of both trainers: where the linear tail to 0 starts, as a fraction of the
#: steps (:func:`~retarget_lib.training.loop.learning_rate`)
DECAY_FROM = Rule(
    "null (no linear tail) or a number in [0, 1]",
    lambda v: v is None or (_is_num(v) and 0 <= v <= 1),
)
DROPOUT = Rule("null or a number in [0, 1)", lambda v: v is None or (_is_num(v) and 0 <= v < 1))
BOOL = Rule("true or false", lambda v: isinstance(v, bool))
TEXT = Rule("a string", lambda v: isinstance(v, str) and bool(v))
BETAS = Rule(
    "two numbers in [0, 1), e.g. [0.5, 0.999]",
    lambda v: isinstance(v, list) and len(v) == 2 and all(_is_num(b) and 0 <= b < 1 for b in v),
)
SCALE_RANGE = Rule(
    "null or [low, high] with 0 < low <= high",
    lambda v: (
        v is None
        or (isinstance(v, list) and len(v) == 2 and all(_is_num(x) for x in v) and 0 < v[0] <= v[1])
    ),
)
NAMES = Rule(
    "a list of character names",
    lambda v: isinstance(v, list) and all(isinstance(n, str) for n in v),
)


def up_to(high: int) -> Rule:
    """An integer in ``[1, high]``."""
    return Rule(f"an integer > 0 and at most {high}", lambda v: _is_int(v) and 1 <= v <= high)


WIDTH, BATCH, WINDOW, STEPS = (
    up_to(MAX_WIDTH),
    up_to(MAX_BATCH),
    up_to(MAX_WINDOW),
    up_to(MAX_STEPS),
)
LAYERS = up_to(64)
ITERATIONS = Rule("an integer >= 0 and at most 100000", lambda v: _is_int(v) and 0 <= v <= 100_000)
DILATIONS = Rule(
    f"a list of at most 64 integers > 0 and at most {MAX_WINDOW}",
    lambda v: (
        isinstance(v, list) and len(v) <= 64 and all(_is_int(x) and 1 <= x <= MAX_WINDOW for x in v)
    ),
)


def choice(*values: Any) -> Rule:
    """One of ``values``."""
    return Rule("one of " + ", ".join(repr(v) for v in values), lambda v: v in values)


def lazy_choice(describe: str, values: Callable[[], Any]) -> Rule:
    """One of ``values()`` (imported on first use: the tables live in modules that load torch);
    the error message names ``describe`` and lists the values."""
    return Rule(f"one of {describe}", lambda v: v in values(), values)


#: TDCN Table 4 rows → model config deltas (A2/A3 change data/loss, not the network), the names
#: ``model.row`` takes; :func:`retarget_lib.models.resolve_config` expands them
TABLE4_ROWS: dict[str, dict[str, Any]] = {
    "Baseline": {"kind": "nkn", "variant": "baseline"},
    "Baseline-dense": {"kind": "nkn", "variant": "dense"},
    "Baseline-dilated": {"kind": "nkn", "variant": "dilated"},
    "Baseline-height": {"kind": "nkn", "variant": "height"},
    "ours": {"kind": "tdcn", "variant": "ours"},
    "A1": {"kind": "tdcn", "variant": "dense"},
    "A2": {"kind": "tdcn", "variant": "ours", "data": "unbalanced"},
    "A3": {"kind": "tdcn", "variant": "ours", "loss": "no_height"},
    "A4": {"kind": "tdcn", "variant": "disc81"},
    "A5": {"kind": "tdcn", "variant": "causal"},
    # not a row of the paper: "ours" with a residual output over copy
    # (TDCNGenerator.compose_residual)
    "ours-residual": {"kind": "tdcn", "variant": "ours", "residual": True},
}


#: ``data.source`` values: the embedded synthetic split (varied-rest profile), its Mixamo-convention
#: profile, both profiles, a reviewer's Mixamo folder, or that folder and the synthetic split
DATA_SOURCES = (
    "synthetic",
    "mixamo-convention",
    "synthetic+mixamo-convention",
    "mixamo-local",
    "mixamo-local+synthetic",
)

#: ``data.source`` values of the contact-aware method (no Mixamo-local-only mix with the
#: Mixamo-convention profile)
CONTACT_DATA_SOURCES = (
    "synthetic",
    "mixamo-local",
    "mixamo-local+synthetic",
    "mixamo-convention",
    "synthetic+mixamo-convention",
)


def _data_sources():
    return DATA_SOURCES


def _table3_rows():
    # read where a contact config is validated: a top import would make this bottom module (the
    # models import it) import the losses above it, and torch with them
    from .losses.contact import TABLE3_ROWS

    return TABLE3_ROWS


def _ee_scales():
    from .losses.contact import EE_SCALES  # read late, as _table3_rows

    return EE_SCALES


_COMMON = {
    "name": TEXT,
    "seed": NONNEG_INT,
    "method": choice("tdcn", "contact"),
    "profile": choice("fast", "paper"),
    "config_path": TEXT,
}

#: ``method: tdcn`` (default): TDCN and NKN rows of Kim et al. 2020, Table 4
TDCN: dict[str, Any] = {
    **_COMMON,
    "model": {
        "row": choice(*TABLE4_ROWS),
        "kind": choice("tdcn", "nkn"),
        "variant": TEXT,
        "profile": choice("fast", "paper"),
        "channels": WIDTH,
        "disc_channels": WIDTH,
        "disc_receptive_field": choice(31, 81),
        "dropout": DROPOUT,
        "normalize_inputs": BOOL,
        "height_loss": BOOL,
        "dilations": DILATIONS,
        "kernel": up_to(MAX_WINDOW),
        "slope": NONNEG_NUM,
        "head_hidden": WIDTH,
        "skip_projection": BOOL,
        "num_layers": LAYERS,
        "disc_norm": TEXT,
        "causal": BOOL,
        "dense": BOOL,
        "residual": BOOL,
        "standardized_root": BOOL,
        "normalize_root": BOOL,
        "root_frame": choice("world", "facing"),
        "root_height": choice("step", "floor"),
        "root_residual": BOOL,
        "positions_frame": choice("world", "facing", "root"),
        "backbone": TEXT,
        "data": TEXT,
        "loss": TEXT,
    },
    "data": {
        "window": WINDOW,
        "same_fraction": FRACTION,
        "scale_range": SCALE_RANGE,
        "scale_targets": BOOL,
        "mirror": BOOL,
        "random_yaw": BOOL,
        "rest_jitter_deg": Rule(
            "a number of degrees in [0, 180]", lambda v: _is_num(v) and 0 <= v <= 180
        ),
        "rest_arm_drop_deg": Rule(
            "a number of degrees in [0, 180]", lambda v: _is_num(v) and 0 <= v <= 180
        ),
        "max_clips": up_to(100_000),
        "max_characters": up_to(1_000),
        "source": lazy_choice(
            "the data sources (mixamo-local reads $RETARGET_MIXAMO)", _data_sources
        ),
    },
    "loss": {
        "gan": choice("lsgan", "sigmoid_ce"),
        "twist_alpha_deg": NONNEG_NUM,
        "twist_exclude_root": BOOL,
        "twist_measure": choice("angle", "about_bone"),
        "gan_weight": NONNEG_NUM,
        "reduction": choice("mean", "frame_sum"),
        "standardize": BOOL,
        "quaternion_weight": POS_NUM,
        "position_joints": choice("all", "end_effectors"),
        "root_scale": choice("height", "leg_length"),
        "root_term": choice("position", "velocity"),
        **{f"lambda_{k}": NONNEG_NUM for k in "ctharogds"},
    },
    "train": {
        "steps": STEPS,
        "batch": BATCH,
        "lr": POS_NUM,
        "betas": BETAS,
        "checkpoint_every": STEPS,
        "decay_from": DECAY_FROM,
        "compile": BOOL,
        "clip_grad_norm": POS_NUM,
    },
}

#: ``method: contact``: the contact-aware rows of Villegas et al. 2021, Table 3
CONTACT: dict[str, Any] = {
    **_COMMON,
    "model": {
        "hidden": WIDTH,
        "layers": LAYERS,
        "geometry": WIDTH,
        "dropout": DROPOUT,
        "residual": BOOL,
        "lower_body_from_base": BOOL,
        "root_residual": BOOL,
    },
    "energy": {
        "row": lazy_choice("the Table 3 rows", _table3_rows),
        "lambda_j2j": NONNEG_NUM,
        "beta_int": NONNEG_NUM,
        "gamma_foot": NONNEG_NUM,
        "rho": NONNEG_NUM,
        "omega": NONNEG_NUM,
        "length_unit": POS_NUM,
        "ee_scale": lazy_choice("the Eee scales", _ee_scales),
    },
    "data": {
        "window": WINDOW,
        "held_out_seed": NONNEG_INT,
        "max_clips": up_to(100_000),
        "train_characters": NAMES,
        "source": choice(*CONTACT_DATA_SOURCES),
    },
    "train": {
        "steps": STEPS,
        "epochs": STEPS,
        "batch": BATCH,
        "lr": POS_NUM,
        "betas": BETAS,
        "lr_decay": Rule("a number in (0, 1]", lambda v: _is_num(v) and 0 < v <= 1),
        "decay_from": DECAY_FROM,
        "checkpoint_every": STEPS,
        "compile": BOOL,
    },
    "eso": {
        "iterations": ITERATIONS,
        "lr": POS_NUM,
        "reach": POS_NUM,
        "blend": FRACTION,
        "rho": POS_NUM,
        "beta_int": POS_NUM,
    },
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
            return (
                f"unknown key {'.'.join(keys[: i + 1])!r}; allowed "
                f"{'in ' + repr(where) if where else 'at the top'}: "
                f"{', '.join(sorted(node))}"
            )
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
        return f"{'.'.join(keys)} = {short_repr(value)} is invalid: must be {node.words()}"
    return None


def check_value(config: dict, keys: list[str], value: Any) -> str | None:
    """The problem with setting the dotted ``keys`` of ``config`` to ``value``, or ``None``."""
    return _problem(schema_for(config), keys, value)


def validate(config: dict) -> str | None:
    """The first problem of a merged config (unknown key, wrong type, invalid value), or
    ``None``."""
    schema = schema_for(config)
    for k, v in config.items():
        found = _problem(schema, [str(k)], v)
        if found:
            return found
    return None


def training_memory(config: dict) -> int:
    """An upper estimate of the bytes one training step of ``config`` needs: activations
    ``batch x window x width x`` :data:`_ACTIVATION_BYTES` plus parameters, gradients and Adam's
    two moments ``16 x 64 x width^2`` (width: the widest of the model's sizes; a size the config
    leaves to the model's defaults counts as the paper's 1024)."""
    model, data, train = (
        config.get(k) if isinstance(config.get(k), dict) else {} for k in ("model", "data", "train")
    )
    sizes = [
        model.get(k) for k in ("channels", "disc_channels", "head_hidden", "hidden", "geometry")
    ]
    width = max([v for v in sizes if _is_int(v)] or [1024])
    batch, window = (v if _is_int(v) else 1 for v in (train.get("batch"), data.get("window")))
    return batch * window * width * _ACTIVATION_BYTES + 16 * 64 * width * width


def memory_problem(config: dict) -> str | None:
    """Why ``config`` would need more than :data:`MAX_TRAINING_BYTES` to train, or ``None``."""
    need = training_memory(config)
    if need <= MAX_TRAINING_BYTES:
        return None
    return (
        f"train.batch x data.window x the model's width would need about {need / 2**30:,.0f} GiB "
        "to train "
        f"(estimate), beyond the {MAX_TRAINING_BYTES / 2**30:.0f} GiB limit; make them smaller"
    )
