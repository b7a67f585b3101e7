"""``data_manifest.yaml``: what each data source and shipped checkpoint is and where it comes from.

Whether they are present and intact: :mod:`retarget_lib.data.status`.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import yaml

from ..files import REPO_ROOT, DataError, sha256_file

MANIFEST_PATH = REPO_ROOT / "data_manifest.yaml"


@lru_cache(maxsize=1)
def load_manifest(path: str | None = None) -> dict:
    """The parsed manifest (cached). Raises :class:`DataError` if it is missing or malformed."""
    p = Path(path) if path else MANIFEST_PATH
    if not p.exists():
        raise DataError(f"data manifest not found at {p}")
    with open(p) as f:
        data = yaml.safe_load(f)
    if not isinstance(data, dict) or "sources" not in data:
        raise DataError(f"{p}: expected a mapping with a 'sources' key")
    for sid, src in data["sources"].items():
        for key in ("kind", "origin", "license"):
            if key not in src:
                raise DataError(f"{p}: source {sid!r} lacks {key!r}")
    return data


def source(source_id: str) -> dict:
    """One source's manifest entry (raises :class:`DataError` naming the known ids)."""
    sources = load_manifest()["sources"]
    if source_id not in sources:
        raise DataError(f"unknown data source {source_id!r}; known: {sorted(sources)}")
    return sources[source_id]


def mixamo_local_dir() -> Path:
    """The reviewer's Mixamo folder: ``$RETARGET_MIXAMO`` or the manifest's ``path``."""
    return Path(os.environ.get("RETARGET_MIXAMO", REPO_ROOT / source("mixamo-local")["path"]))


@dataclass
class CheckpointEntry:
    """A trained model the notebooks load (``checkpoints:`` in the manifest).

    Attributes:
        id: manifest key, e.g. ``"tdcn-ours-fast"``.
        path: absolute path of the ``.pt`` file.
        sha256: expected checksum.
        config: the experiment config it was trained with (repo-relative).
        command: the exact command that produced it.
        losses: absolute path of its per-step training log (CSV), when shipped.
        method: the registry method that loads it (``retarget_lib.methods``), e.g. ``"tdcn"``.
        default: it is that method's default checkpoint (``retarget retarget --method NAME``
            without ``--checkpoint``).
        table: the paper table it fills a row of: ``"tdcn"`` (Kim et al. 2020, Table 4) or
            ``"contact"`` (Villegas et al. 2021, Table 3).
        row: that row's name, e.g. ``"ours"``, ``"A3"``, ``"Efull"``.
    """

    id: str
    path: Path
    sha256: str
    config: str
    command: str
    losses: Path | None = None
    method: str | None = None
    default: bool = False
    table: str | None = None
    row: str | None = None


def _entry(checkpoint_id: str, e: dict) -> CheckpointEntry:
    return CheckpointEntry(
        checkpoint_id,
        REPO_ROOT / e["path"],
        e["sha256"],
        e["config"],
        e["command"],
        REPO_ROOT / e["losses"] if e.get("losses") else None,
        e.get("method"),
        bool(e.get("default", False)),
        e.get("table"),
        e.get("row"),
    )


def checkpoint_entries() -> dict[str, CheckpointEntry]:
    """Every shipped checkpoint's entry, in manifest order (files not checked)."""
    return {cid: _entry(cid, e) for cid, e in (load_manifest().get("checkpoints") or {}).items()}


def checkpoint(checkpoint_id: str, verify_checksum: bool = True) -> CheckpointEntry:
    """Look up a shipped checkpoint; check that it exists and matches its checksum.

    Raises:
        DataError: unknown id (the known ones are named), missing file or checksum mismatch (the
            message gives the command that re-creates it).
    """
    entries = checkpoint_entries()
    if checkpoint_id not in entries:
        raise DataError(f"unknown checkpoint {checkpoint_id!r}; known: {sorted(entries)}")
    entry = entries[checkpoint_id]
    if not entry.path.exists():
        raise DataError(
            f"checkpoint {checkpoint_id} missing at {entry.path}; re-create it with: "
            f"{entry.command}"
        )
    if verify_checksum and sha256_file(entry.path) != entry.sha256:
        raise DataError(
            f"checkpoint {checkpoint_id} at {entry.path} does not match its sha256 in the "
            f"manifest; re-create it with: {entry.command}"
        )
    return entry


def default_checkpoint(method: str) -> str | None:
    """Id of ``method``'s default checkpoint (the entry with ``method: <method>`` and
    ``default: true``), or ``None`` if none is shipped.

    Raises:
        DataError: the manifest marks several defaults for ``method``.
    """
    ids = [e.id for e in checkpoint_entries().values() if e.method == method and e.default]
    if len(ids) > 1:
        raise DataError(
            f"data_manifest.yaml marks several default checkpoints for method {method!r}: {ids}"
        )
    return ids[0] if ids else None


def table_checkpoints(table: str) -> dict[str, CheckpointEntry]:
    """The shipped checkpoints of one paper table, by row name (``table:`` and ``row:`` in the
    manifest), in manifest order."""
    return {
        e.row: e for e in checkpoint_entries().values() if e.table == table and e.row is not None
    }
