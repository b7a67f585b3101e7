"""Is every data source and shipped checkpoint present and intact? (``retarget data list`` prints
:func:`source_table`, ``retarget data verify`` runs :func:`verify`.)

Besides the manifest's checksums, :func:`verify` reads every ``.npz`` in the cache (the built
dataset and derived caches such as ``contact_training/``) in full, so a truncated, empty or
bit-flipped file (the zip CRC) is named, and sweeps the temporary files of killed writes.
"""

from __future__ import annotations

import importlib.util
import zipfile
from dataclasses import dataclass
from functools import partial
from pathlib import Path

import numpy as np

from ..errors import RetargetInputError
from ..files import DataError, cache_dir, sha256_file, sweep_stale_temps
from .manifest import checkpoint, load_manifest, mixamo_local_dir, source
from .sources import real_characters, real_motions
from .sources.cmu import cmu_clip_path
from .sources.mixamo_local import read_splits_file, scan_mixamo_folder
from .sources.model_viewer import SOURCE_ID as MODEL_VIEWER
from .sources.model_viewer import model_viewer_path
from .synthetic.dataset import dataset_path, fingerprint_of


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
        """``ok``, ``present`` (nothing to verify), ``BAD``, ``absent (optional)`` or
        ``MISSING``."""
        if self.present:
            return "ok" if self.verified else "present" if self.verified is None else "BAD"
        return "absent (optional)" if self.optional else "MISSING"


def _check_cmu() -> SourceStatus:
    src = source("cmu-assimp")
    try:
        paths = {name: cmu_clip_path(name, fetch=False) for name in src["files"]}
    except DataError as e:
        return SourceStatus("cmu-assimp", src["kind"], False, None, str(e))
    bad = [n for n, p in paths.items() if sha256_file(p) != src["files"][n]["sha256"]]
    where = next(iter(paths.values())).parent
    if bad:
        return SourceStatus(
            "cmu-assimp", src["kind"], True, False, f"checksum mismatch: {bad} in {where}"
        )
    return SourceStatus("cmu-assimp", src["kind"], True, True, f"{len(paths)} clips in {where}")


def _check_mannequin() -> SourceStatus:
    src = source("mannequin-x")
    spec = importlib.util.find_spec("mannequin")
    if spec is None or not spec.submodule_search_locations:
        return SourceStatus(
            "mannequin-x", src["kind"], False, None, f"package not installed: {src['how_to_get']}"
        )
    path = Path(list(spec.submodule_search_locations)[0]) / "assets" / "wooden.npz"
    if not path.exists():
        return SourceStatus(
            "mannequin-x", src["kind"], False, None, f"{path} missing: {src['how_to_get']}"
        )
    ok = sha256_file(path) == src["sha256"]
    return SourceStatus(
        "mannequin-x", src["kind"], True, ok, str(path) if ok else f"checksum mismatch for {path}"
    )


def _check_repository_files(module) -> SourceStatus:
    """A source shipped in the repository (``module``: its ``SOURCE_ID`` and ``check()``)."""
    src = source(module.SOURCE_ID)
    ok, detail = module.check()
    return SourceStatus(module.SOURCE_ID, src["kind"], ok or "missing" not in detail, ok, detail)


def _check_model_viewer() -> SourceStatus:
    src = source(MODEL_VIEWER)
    try:
        return SourceStatus(
            MODEL_VIEWER, src["kind"], True, True, str(model_viewer_path(fetch=False))
        )
    except DataError as e:
        present = "checksum" in str(e)
        return SourceStatus(MODEL_VIEWER, src["kind"], present, False if present else None, str(e))


def _check_synthetic() -> SourceStatus:
    src = source("synthetic")
    path = dataset_path()
    if not path.exists():
        return SourceStatus(
            "synthetic", src["kind"], False, None, "not built: run `retarget data build`"
        )
    expected = src.get("fingerprint")
    problem = _npz_problem(path)
    if problem:
        return SourceStatus(
            "synthetic",
            src["kind"],
            True,
            False,
            f"{problem}; rebuild with `retarget data build --force`",
        )
    got = fingerprint_of(path)
    if expected is None:
        return SourceStatus(
            "synthetic", src["kind"], True, None, f"built; fingerprint {got} (none recorded)"
        )
    ok = got == expected
    return SourceStatus(
        "synthetic",
        src["kind"],
        True,
        ok,
        f"{path}"
        if ok
        else f"fingerprint {got} != manifest {expected}; "
        "rebuild with `retarget data build --force`",
    )


def _check_mixamo_local() -> SourceStatus:
    src = source("mixamo-local")
    root = mixamo_local_dir()
    if not root.exists():
        return SourceStatus(
            "mixamo-local",
            src["kind"],
            False,
            None,
            f"optional; not present at {root} (set RETARGET_MIXAMO)",
        )
    try:
        found = scan_mixamo_folder(root)
        splits = read_splits_file(root, found)
    except (DataError, RetargetInputError) as e:
        return SourceStatus("mixamo-local", src["kind"], True, False, str(e))
    n_motions = sum(len(c.motions) for c in found)
    return SourceStatus(
        "mixamo-local",
        src["kind"],
        True,
        True,
        f"{len(found)} characters, {n_motions} motions in {root}"
        + (f" (split: {splits.path.name})" if splits is not None else ""),
    )


def _npz_problem(path: Path) -> str | None:
    """Why ``path`` is not a complete ``.npz`` (empty, truncated, a failed CRC), or ``None``."""
    if path.stat().st_size == 0:
        return f"{path}: empty file"
    try:
        with np.load(path, allow_pickle=False) as z:
            for key in z.files:
                z[key]
    except (zipfile.BadZipFile, EOFError, OSError, ValueError) as e:
        return f"{path}: truncated or corrupt ({e})"
    return None


def check_cache() -> SourceStatus:
    """Every ``.npz`` under the cache read in full (:func:`_npz_problem`); stale temporary files
    of killed writes removed."""
    root = cache_dir()
    files = sorted(root.rglob("*.npz"))
    for folder in {root, *(f.parent for f in files)}:
        sweep_stale_temps(folder)
    bad = [problem for f in files if (problem := _npz_problem(f))]
    if bad:
        return SourceStatus(
            "cache",
            "derived",
            True,
            False,
            f"{len(bad)} bad file(s), delete them and rerun: " + "; ".join(bad),
        )
    return SourceStatus(
        "cache", "derived", True, True, f"{len(files)} cached .npz files read in full under {root}"
    )


_CHECKS = {
    "synthetic": _check_synthetic,
    "cmu-assimp": _check_cmu,
    "mannequin-x": _check_mannequin,
    MODEL_VIEWER: _check_model_viewer,
    "mixamo-local": _check_mixamo_local,
    real_characters.SOURCE_ID: partial(_check_repository_files, real_characters),
    real_motions.SOURCE_ID: partial(_check_repository_files, real_motions),
}


def check_checkpoints() -> list[SourceStatus]:
    """One status per shipped checkpoint."""
    out = []
    for cid in load_manifest().get("checkpoints") or {}:
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
        status = (
            SourceStatus(sid, src["kind"], False, None, "no checker") if check is None else check()
        )
        status.optional = bool(src.get("optional"))
        out.append(status)
    return out


def verify() -> list[SourceStatus]:
    """Check every source and checkpoint; raise :class:`DataError` listing each required one that
    fails."""
    statuses = check_sources() + check_checkpoints() + [check_cache()]
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
    return "\n".join(
        f"{r[0]:<{widths[0]}}  {r[1]:<{widths[1]}}  {r[2]:<{widths[2]}}  {r[3]}" for r in rows
    )


def cache_summary() -> str:
    """Where the cache is."""
    return f"cache: {cache_dir()}"
