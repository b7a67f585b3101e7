"""``data_manifest.yaml``: what each data source is, where it comes from, and whether it checks out.

``retarget data list`` prints :func:`source_table`; ``retarget data verify`` runs :func:`verify`.
"""

from __future__ import annotations

import importlib.util
import os
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import yaml

from ..files import REPO_ROOT, DataError, cache_dir, sha256_file

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


@dataclass
class SourceStatus:
    """Result of checking one source."""

    id: str
    kind: str
    present: bool
    verified: bool | None  # None: nothing to verify / optional and absent
    detail: str
    optional: bool = False

    @property
    def state(self) -> str:
        """``ok``, ``present`` (nothing to verify), ``BAD``, ``absent (optional)`` or ``MISSING``."""
        if self.present:
            return "ok" if self.verified else "present" if self.verified is None else "BAD"
        return "absent (optional)" if self.optional else "MISSING"


def mixamo_local_dir() -> Path:
    """The reviewer's Mixamo folder: ``$RETARGET_MIXAMO`` or the manifest's ``path``."""
    return Path(os.environ.get("RETARGET_MIXAMO", REPO_ROOT / source("mixamo-local")["path"]))


def _check_cmu() -> SourceStatus:
    from .cmu import cmu_clip_path

    src = source("cmu-assimp")
    try:
        paths = {name: cmu_clip_path(name, fetch=False) for name in src["files"]}
    except DataError as e:
        return SourceStatus("cmu-assimp", src["kind"], False, None, str(e))
    bad = [n for n, p in paths.items() if sha256_file(p) != src["files"][n]["sha256"]]
    where = next(iter(paths.values())).parent
    if bad:
        return SourceStatus("cmu-assimp", src["kind"], True, False, f"checksum mismatch: {bad} in {where}")
    return SourceStatus("cmu-assimp", src["kind"], True, True, f"{len(paths)} clips in {where}")


def _check_mannequin() -> SourceStatus:
    src = source("mannequin-x")
    spec = importlib.util.find_spec("mannequin")
    if spec is None or not spec.submodule_search_locations:
        return SourceStatus("mannequin-x", src["kind"], False, None,
                            f"package not installed: {src['how_to_get']}")
    path = Path(list(spec.submodule_search_locations)[0]) / "assets" / "wooden.npz"
    if not path.exists():
        return SourceStatus("mannequin-x", src["kind"], False, None, f"{path} missing: {src['how_to_get']}")
    ok = sha256_file(path) == src["sha256"]
    return SourceStatus("mannequin-x", src["kind"], True, ok,
                        str(path) if ok else f"checksum mismatch for {path}")


def _check_synthetic() -> SourceStatus:
    from .synthetic import dataset_path, fingerprint_of

    src = source("synthetic")
    path = dataset_path()
    if not path.exists():
        return SourceStatus("synthetic", src["kind"], False, None, "not built: run `retarget data build`")
    expected = src.get("fingerprint")
    got = fingerprint_of(path)
    if expected is None:
        return SourceStatus("synthetic", src["kind"], True, None, f"built; fingerprint {got} (none recorded)")
    ok = got == expected
    return SourceStatus("synthetic", src["kind"], True, ok,
                        f"{path}" if ok else f"fingerprint {got} != manifest {expected}; "
                        "rebuild with `retarget data build --force`")


def _check_mixamo_local() -> SourceStatus:
    from .mixamo_local import scan_mixamo_folder

    src = source("mixamo-local")
    root = mixamo_local_dir()
    if not root.exists():
        return SourceStatus("mixamo-local", src["kind"], False, None,
                            f"optional; not present at {root} (set RETARGET_MIXAMO)")
    try:
        found = scan_mixamo_folder(root)
    except DataError as e:
        return SourceStatus("mixamo-local", src["kind"], True, False, str(e))
    n_motions = sum(len(c.motions) for c in found)
    return SourceStatus("mixamo-local", src["kind"], True, True,
                        f"{len(found)} characters, {n_motions} motions in {root}")


_CHECKS = {
    "synthetic": _check_synthetic,
    "cmu-assimp": _check_cmu,
    "mannequin-x": _check_mannequin,
    "mixamo-local": _check_mixamo_local,
}


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
    """

    id: str
    path: Path
    sha256: str
    config: str
    command: str
    losses: Path | None = None


def checkpoint(checkpoint_id: str, verify_checksum: bool = True) -> CheckpointEntry:
    """Look up a shipped checkpoint; check that it exists and matches its checksum.

    Raises:
        DataError: unknown id (the known ones are named), missing file or checksum mismatch (the
            message gives the command that re-creates it).
    """
    entries = load_manifest().get("checkpoints") or {}
    if checkpoint_id not in entries:
        raise DataError(f"unknown checkpoint {checkpoint_id!r}; known: {sorted(entries)}")
    e = entries[checkpoint_id]
    entry = CheckpointEntry(checkpoint_id, REPO_ROOT / e["path"], e["sha256"], e["config"], e["command"],
                            REPO_ROOT / e["losses"] if e.get("losses") else None)
    if not entry.path.exists():
        raise DataError(f"checkpoint {checkpoint_id} missing at {entry.path}; re-create it with: {entry.command}")
    if verify_checksum and sha256_file(entry.path) != entry.sha256:
        raise DataError(f"checkpoint {checkpoint_id} at {entry.path} does not match its sha256 in the "
                        f"manifest; re-create it with: {entry.command}")
    return entry


def check_checkpoints() -> list[SourceStatus]:
    """One status per shipped checkpoint."""
    out = []
    for cid in (load_manifest().get("checkpoints") or {}):
        try:
            e = checkpoint(cid)
            out.append(SourceStatus(f"checkpoint:{cid}", "checkpoint", True, True, str(e.path)))
        except DataError as err:
            out.append(SourceStatus(f"checkpoint:{cid}", "checkpoint", False, False, str(err)))
    return out


def check_sources() -> list[SourceStatus]:
    """Check every source listed in the manifest (those without a checker are reported as such)."""
    out = []
    for sid, src in load_manifest()["sources"].items():
        check = _CHECKS.get(sid)
        status = SourceStatus(sid, src["kind"], False, None, "no checker") if check is None else check()
        status.optional = bool(src.get("optional"))
        out.append(status)
    return out


def verify() -> list[SourceStatus]:
    """Check every source and checkpoint; raise :class:`DataError` listing each required one that
    fails."""
    statuses = check_sources() + check_checkpoints()
    problems = [s for s in statuses if not s.optional and s.state in ("BAD", "MISSING")]
    if problems:
        lines = "\n".join(f"  {s.id}: {s.detail}" for s in problems)
        raise DataError(f"data verification failed:\n{lines}")
    return statuses


def source_table() -> str:
    """A plain-text table of the sources and their status."""
    rows = [("id", "kind", "license", "status")]
    manifest = load_manifest()["sources"]
    for s in check_sources():
        rows.append((s.id, s.kind, str(manifest[s.id]["license"])[:38], f"{s.state}: {s.detail}"))
    widths = [max(len(r[i]) for r in rows) for i in range(3)]
    return "\n".join(f"{r[0]:<{widths[0]}}  {r[1]:<{widths[1]}}  {r[2]:<{widths[2]}}  {r[3]}" for r in rows)


def cache_summary() -> str:
    """Where the cache is."""
    return f"cache: {cache_dir()}"
