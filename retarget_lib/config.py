"""Experiment configs: YAML files that are small deltas over a base, with profiles and overrides.

A config file may name a ``base:`` (path relative to itself); its keys are deep-merged over the
base's. A ``profiles:`` mapping holds per-profile deltas (``fast`` for CI and laptops, ``paper`` for
the papers' sizes) applied after the merge. Command-line ``key=value`` overrides (dotted keys,
values parsed as YAML) come last. The seed lives in the config like everything else.

Which value wins, from strongest to weakest: an override; the file's own ``profiles:`` entry; a
key the file sets itself; the base's ``profiles:`` entry; the base's own key. So a file with
``base: tdcn_paper.yaml`` and ``model: {channels: 64}`` trains 64 channels in every profile
(the base's ``fast`` profile sets 256 only for files that do not say), and a file that wants a
value per profile says so in its own ``profiles:``.

Config files and override values are read as untrusted YAML
(:func:`~retarget_lib.files.read_yaml`: 1 MiB, nesting 32, aliases expanding to at most 100,000
values, no key twice), and sizes and the training memory they imply are bounded by the schema.

The merged config is checked against :mod:`retarget_lib.config_schema` before anything runs:
unknown keys, wrong types and invalid values (in the file or an override) raise
:class:`ConfigError` naming the file or override, the key and what is allowed.

Example::

    # configs/tdcn_a3_no_height.yaml  (ablation A3: ours without Lh)
    base: tdcn_paper.yaml
    name: A3
    model: {row: A3}
    loss: {lambda_h: 0.0}
"""

from __future__ import annotations

import copy
import os
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import yaml

from .config_schema import check_value, memory_problem, validate
from .errors import RetargetInputError, short_repr
from .files import load_yaml, read_yaml

PROFILES = ("fast", "paper")


def active_profile(profile: str | None = None) -> str:
    """``profile``, else ``$RETARGET_PROFILE``, else ``"fast"``: the one place the library reads the
    environment variable.

    Raises:
        ConfigError: a name that is not one of :data:`PROFILES`.
    """
    chosen = profile or os.environ.get("RETARGET_PROFILE", "fast")
    if chosen not in PROFILES:
        raise ConfigError(f"unknown profile {chosen!r}; choose from {PROFILES}")
    return chosen


class ConfigError(RetargetInputError):
    """A config file or override is malformed (the message names the file or key)."""


def deep_merge(base: dict, delta: dict) -> dict:
    """``base`` with ``delta`` merged in recursively (mappings merge, everything else replaces)."""
    out = copy.deepcopy(base)
    for k, v in delta.items():
        if isinstance(v, dict) and isinstance(out.get(k), dict):
            out[k] = deep_merge(out[k], v)
        else:
            out[k] = copy.deepcopy(v)
    return out


def _without_keys_of(delta: Any, own: dict) -> Any:
    """``delta`` (a base's profile delta) without every key that ``own`` (the file's own keys) sets,
    so the file's own values win over the base's profiles."""
    if not isinstance(delta, dict):
        return delta
    out = {}
    for k, v in delta.items():
        if k not in own:
            out[k] = v
        elif isinstance(v, dict) and isinstance(own[k], dict):
            out[k] = _without_keys_of(v, own[k])
    return out


def _read(path: Path, seen: tuple[Path, ...] = ()) -> dict:
    path = path.resolve()
    if path in seen:
        raise ConfigError(f"config base cycle: {' -> '.join(str(p) for p in seen + (path,))}")
    if not path.is_file():
        raise ConfigError(
            f"{path}: config file not found" if not path.exists() else f"{path}: not a file"
        )
    data = read_yaml(path, "config file", ConfigError)
    if not isinstance(data, dict):
        raise ConfigError(f"{path}: a config must be a mapping")
    base = data.pop("base", None)
    if base is None:
        return data
    if not isinstance(base, str) or not base:
        raise ConfigError(f"{path}: base must be the name of a config file, got {short_repr(base)}")
    base_path = path.parent / base
    if (
        not base_path.is_file()
    ):  # named by the file that refers to it: the base is that file's value
        raise ConfigError(
            f"{path}: base {short_repr(base)} is "
            + (
                "not a file"
                if base_path.exists()
                else "no config file (a path relative to this one)"
            )
        )
    merged = _read(base_path, seen + (path,))
    profiles = _pop_profiles(merged, path.parent / base)
    own_profiles = _pop_profiles(data, path)
    out = deep_merge(merged, data)
    base_profiles = {name: _without_keys_of(delta, data) for name, delta in profiles.items()}
    out["profiles"] = deep_merge(base_profiles, own_profiles)
    return out


def _pop_profiles(config: dict, path: Path) -> dict:
    """``config``'s ``profiles:`` mapping, removed from it (``{}`` without one)."""
    profiles = config.pop("profiles", None) or {}
    if not isinstance(profiles, dict):
        raise ConfigError(f"{path}: 'profiles' must map profile names to config deltas")
    return profiles


def parse_override(item: str) -> tuple[list[str], Any]:
    """``"train.steps=200"`` → ``(["train", "steps"], 200)`` (the value is parsed as YAML)."""
    if "=" not in item:
        raise ConfigError(f"override {item!r} must look like key.sub=value")
    key, raw = item.split("=", 1)
    if not key or any(not part for part in key.split(".")):
        raise ConfigError(f"override {item!r} has an empty key")
    return key.split("."), load_yaml(raw, f"override {item!r}", ConfigError)


def set_key(config: dict, keys: list[str], value: Any) -> None:
    """Set ``config[k0][k1]... = value``, creating the sections on the way; the key must be one
    the config's schema allows (:func:`~retarget_lib.config_schema.check_value`, the typo guard),
    whether or not the file sets it."""
    problem = check_value(config, keys, value)
    if problem:
        raise ConfigError(problem)
    node = config
    for i, k in enumerate(keys[:-1]):
        node = node.setdefault(k, {})
        if not isinstance(node, dict):
            raise ConfigError(f"{'.'.join(keys[: i + 1])!r} is not a section")
    node[keys[-1]] = value


def load_config(
    path: str | os.PathLike, overrides: Iterable[str] = (), profile: str | None = None
) -> dict:
    """Read a config, apply its base chain, the profile and the overrides.

    Args:
        path: YAML file.
        overrides: ``key.sub=value`` strings.
        profile: ``"fast"`` or ``"paper"``; default ``$RETARGET_PROFILE`` or ``"fast"``.

    Returns:
        the merged config, with ``profile`` and ``config_path`` recorded in it.
    """
    profile = active_profile(profile)
    cfg = _read(Path(path))
    profiles = cfg.pop("profiles", {}) or {}
    if not isinstance(profiles, dict) or not all(
        isinstance(v, dict) for v in profiles.values() if v is not None
    ):
        raise ConfigError(f"{path}: 'profiles' must map profile names to config deltas")
    unknown = set(profiles) - set(PROFILES)
    if unknown:
        raise ConfigError(
            f"{path}: unknown profiles {sorted(unknown)}; allowed: {', '.join(PROFILES)}"
        )
    for merged in [cfg] + [deep_merge(cfg, delta or {}) for delta in profiles.values()]:
        problem = validate(merged) or memory_problem(merged)  # also every profile's values
        if problem:
            raise ConfigError(f"{path}: {problem}")
    cfg = deep_merge(cfg, profiles.get(profile, {}) or {})
    for item in overrides:
        keys, value = parse_override(item)
        try:
            set_key(cfg, keys, value)
        except ConfigError as e:
            raise ConfigError(f"override {item!r}: {e}") from None
    problem = memory_problem(cfg)
    if problem:
        raise ConfigError(f"{path} with {' '.join(overrides)}: {problem}")
    if "seed" not in cfg:
        raise ConfigError(f"{path}: every experiment config needs a 'seed'")
    cfg["profile"] = profile
    cfg["config_path"] = str(Path(path))
    return cfg


def dump_config(config: dict) -> str:
    """The config as YAML text (stored next to checkpoints)."""
    return yaml.safe_dump(config, sort_keys=False)
