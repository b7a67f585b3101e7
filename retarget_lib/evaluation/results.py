"""Stored evaluation results: every table of both papers, computed once and kept with its
provenance.

The full tables (every row, every clip; the contact tables' ESO rows dominate, and each part's
seconds are in its provenance) are produced by one command, ``retarget evaluate --all --out
results`` (``make tables``), and kept in the repository's ``results/`` folder. Every per-case CSV
has a ``<name>.provenance.json`` beside it: the command, the commit, the date, the machine, the
profile, the sha256 of every checkpoint that produced a row, the library modules the computation
loaded with a fingerprint of their code (:func:`code_fingerprint`), and the CSV's own sha256.

The notebooks read these files (:func:`load_result`) and re-run a small live subset that they
compare with the stored numbers within a stated tolerance (:func:`compare_with_stored`). A stored
file is **stale** when a checkpoint it was computed from is no longer the manifest's, when a row of
the table has a checkpoint it does not cover, or when the library code behind it changed
(:func:`code_fingerprint`); :func:`load_result` returns the reasons and
:meth:`StoredResult.report` prints them loudly.
"""

from __future__ import annotations

import ast
import datetime as dt
import hashlib
import json
import os
import platform
import subprocess
import sys
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import pandas as pd

from ..data.manifest import CheckpointEntry, checkpoint_entries
from ..files import REPO_ROOT, DataError, atomic_write, sha256_file

#: where the repository keeps the stored results
RESULTS_DIR = REPO_ROOT / "results"
#: the one command that recomputes every stored result
RECOMPUTE_COMMAND = "make tables   (= retarget evaluate --all --out results)"
#: loaded modules that move files and names, not numbers: the command line, paths and checksums, the
#: manifest and checkpoint look-up (a checkpoint is pinned by its sha256 instead), the glTF and FBX
#: writers, the FBX and shape readers, their budgets and type checks (io/untrusted.py) (no stored
#: table reads an FBX or shape file), devices, and this module; a change to them does not make a
#: stored result stale. The glTF reader (io/gltf/) reads the real characters of the real table, the
#: rig conventions (io/rig_maps.py) name the CMU clips' joints, and io/amass.py orders
#: mannequin-x's: they count.
NOT_NUMERIC = (
    "retarget_lib/cli/__init__.py",
    "retarget_lib/cli/commands.py",
    "retarget_lib/cli/evaluate.py",
    "retarget_lib/cli/parser.py",
    "retarget_lib/files.py",
    "retarget_lib/errors.py",
    "retarget_lib/devices.py",
    "retarget_lib/data/manifest.py",
    "retarget_lib/data/checkpoints.py",
    "retarget_lib/io/gltf_write.py",
    "retarget_lib/io/fbx.py",
    "retarget_lib/io/fbx_write.py",
    "retarget_lib/io/shape.py",
    "retarget_lib/io/gltf_validator.py",
    "retarget_lib/io/untrusted.py",
    "retarget_lib/evaluation/results.py",
)
#: printed float precision of stored CSVs: 7 significant digits, 1e-7 relative, far below every
#: re-run tolerance (1e-3 relative at the tightest)
CSV_FLOAT_FORMAT = "%.7g"


def _source_without_docstrings(path: Path) -> str:
    """A module's syntax tree as text, docstrings and comments left out (so prose edits do not make
    results stale)."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    for node in ast.walk(tree):
        body = getattr(node, "body", None)
        if (
            isinstance(body, list)
            and body
            and isinstance(body[0], ast.Expr)
            and isinstance(body[0].value, ast.Constant)
            and isinstance(body[0].value.value, str)
        ):
            body[0] = ast.Pass()
    return ast.dump(tree, annotate_fields=False)


def loaded_library_files() -> list[str]:
    """The library's modules this process has imported (paths relative to the repository, sorted),
    but for those in :data:`NOT_NUMERIC`: after an evaluation, the code that computed its
    numbers."""
    lib = REPO_ROOT / "retarget_lib"
    files = set()
    for module in list(sys.modules.values()):
        path = getattr(module, "__file__", None)
        if path and Path(path).resolve().is_relative_to(lib):
            files.add(Path(path).resolve().relative_to(REPO_ROOT).as_posix())
    return sorted(files - set(NOT_NUMERIC))


def code_fingerprint(files: Sequence[str]) -> str:
    """sha256 over the code (not the docstrings or comments) of the given library files (paths
    relative to the repository); a file that no longer exists counts as changed."""
    h = hashlib.sha256()
    for rel in sorted(files):
        path = REPO_ROOT / rel
        h.update(rel.encode() + b"\0")
        h.update(
            (_source_without_docstrings(path) if path.exists() else "<missing>").encode() + b"\0"
        )
    return h.hexdigest()


def _git_commit(code_files: Sequence[str]) -> str:
    """The checkout's commit, ``+dirty`` when the code that computed the numbers (``code_files``),
    the configs, the checkpoints or the manifest differ from it; ``unknown`` outside git."""
    try:
        head = subprocess.run(
            ["git", "rev-parse", "HEAD"], cwd=REPO_ROOT, capture_output=True, text=True, check=True
        ).stdout.strip()
        dirty = subprocess.run(
            [
                "git",
                "status",
                "--porcelain",
                "--untracked-files=no",
                "--",
                *code_files,
                "configs",
                "checkpoints",
                "data_manifest.yaml",
            ],
            cwd=REPO_ROOT,
            capture_output=True,
            text=True,
            check=True,
        ).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"
    return head + ("+dirty" if dirty else "")


def git_changed(path: str, commit: str) -> bool:
    """Whether ``path`` differs from its version at ``commit`` (False when git cannot tell)."""
    try:
        return (
            subprocess.run(
                ["git", "diff", "--quiet", commit.removesuffix("+dirty"), "--", path],
                cwd=REPO_ROOT,
                capture_output=True,
            ).returncode
            == 1
        )
    except OSError:
        return False


def machine_description() -> str:
    """CPU model, core count and OS of this machine (no host name, no path)."""
    model = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                model = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return f"{model}, {os.cpu_count()} cores, {platform.system()} {platform.machine()}"


@dataclass
class StoredResult:
    """One stored per-case table and what it was computed from.

    Attributes:
        name: file stem in ``results/``, e.g. ``"table4_cases"``.
        frame: the per-case rows.
        provenance: the parsed ``<name>.provenance.json``.
        stale: why the file no longer matches the checkpoints or code (empty when it does).
    """

    name: str
    frame: pd.DataFrame
    provenance: dict
    stale: list[str] = field(default_factory=list)

    def report(self) -> str:
        """One paragraph: where the numbers come from, and a loud warning when they are stale."""
        p = self.provenance
        text = (
            f"stored {self.name}: {len(self.frame)} rows, computed {p['date']} at commit "
            f"{p['commit'][:12]} "
            f"on {p['machine']} ({p['seconds']:.0f} s; `{p['command']}`)"
        )
        if self.stale:
            text += (
                "\n"
                + "!" * 78
                + "\nSTALE: these stored numbers no longer match this checkout:\n"
                + "\n".join(f"  - {why}" for why in self.stale)
                + f"\nRe-compute them with `{RECOMPUTE_COMMAND}`; the live re-run below checks a "
                "subset.\n" + "!" * 78
            )
        return text


def write_result(
    frame: pd.DataFrame,
    out_dir: str | Path,
    name: str,
    *,
    command: str,
    checkpoints: Mapping[str, CheckpointEntry | Path | str],
    profile: str,
    seconds: float,
) -> Path:
    """Write ``<name>.csv`` and ``<name>.provenance.json`` into ``out_dir`` (atomically).

    Args:
        frame: per-case rows.
        out_dir: destination folder (``results/`` for the repository's copy).
        name: file stem.
        command: the command that computed them.
        checkpoints: row name -> the checkpoint that produced it: a manifest entry, or the path of
            another checkpoint (e.g. a ``retarget sweep`` run), recorded by its sha256.
        profile: the evaluation profile.
        seconds: wall-clock seconds the computation took.

    Returns:
        the CSV's path.
    """
    out = Path(out_dir)
    csv_path = out / f"{name}.csv"
    with atomic_write(csv_path, "w") as f:
        frame.to_csv(f, index=False, float_format=CSV_FLOAT_FORMAT)
    rows = {}
    for row, ck in checkpoints.items():
        if isinstance(ck, CheckpointEntry):
            rows[row] = {"id": ck.id, "sha256": ck.sha256}
        else:
            rows[row] = {"id": Path(ck).name, "sha256": sha256_file(ck)}
    code_files = loaded_library_files()
    provenance = {
        "name": name,
        "command": command,
        "commit": _git_commit(code_files),
        "date": dt.datetime.now(dt.UTC).isoformat(timespec="seconds"),
        "machine": machine_description(),
        "profile": profile,
        "seconds": round(seconds, 1),
        "checkpoints": rows,
        "code": code_fingerprint(code_files),
        "code_files": code_files,
        "sha256": sha256_file(csv_path),
    }
    with atomic_write(out / f"{name}.provenance.json", "w") as f:
        json.dump(provenance, f, indent=1)
        f.write("\n")
    return csv_path


def staleness(provenance: Mapping, rows: Mapping[str, CheckpointEntry] | None = None) -> list[str]:
    """Why a stored result no longer matches this checkout (empty: it does).

    Args:
        provenance: a parsed ``<name>.provenance.json``.
        rows: the table's current row -> checkpoint (e.g. ``table_checkpoints("tdcn")``); a row
            here that the file does not cover is a reason. Default: only the recorded rows are
            checked.
    """
    current = checkpoint_entries()
    reasons = []
    for row, ck in provenance["checkpoints"].items():
        entry = current.get(ck["id"])
        if entry is None:
            reasons.append(f"row {row!r}: checkpoint {ck['id']} is not in data_manifest.yaml")
        elif entry.sha256 != ck["sha256"]:
            reasons.append(
                f"row {row!r}: checkpoint {ck['id']} was retrained (sha256 {ck['sha256'][:12]} "
                f"stored, {entry.sha256[:12]} in the manifest)"
            )
    for row, entry in (rows or {}).items():
        if row not in provenance["checkpoints"]:
            reasons.append(f"row {row!r} (checkpoint {entry.id}) has no stored numbers")
    if provenance["code"] != code_fingerprint(provenance["code_files"]):
        changed = [
            f
            for f in provenance["code_files"]
            if not (REPO_ROOT / f).exists() or git_changed(f, provenance["commit"])
        ]
        reasons.append(
            f"the library code that computed them changed since commit {provenance['commit'][:12]}"
            + (f" ({', '.join(changed[:6])}{' …' if len(changed) > 6 else ''})" if changed else "")
        )
    return reasons


def load_result(
    name: str,
    rows: Mapping[str, CheckpointEntry] | None = None,
    results_dir: str | Path = RESULTS_DIR,
) -> StoredResult:
    """Read ``<name>.csv`` and its provenance from ``results_dir``, check the CSV's sha256 and say
    whether it is stale (:func:`staleness`).

    Raises:
        DataError: the file or its provenance is missing, or the CSV does not match its recorded
            sha256 (edited by hand); the message gives the command that recomputes it.
    """
    folder = Path(results_dir)
    csv_path, prov_path = folder / f"{name}.csv", folder / f"{name}.provenance.json"
    for p in (csv_path, prov_path):
        if not p.exists():
            raise DataError(f"stored result {p} is missing; compute it with: {RECOMPUTE_COMMAND}")
    provenance = json.loads(prov_path.read_text())
    if sha256_file(csv_path) != provenance["sha256"]:
        raise DataError(
            f"{csv_path} does not match the sha256 in {prov_path.name} (edited by hand?); "
            f"recompute it with: {RECOMPUTE_COMMAND}"
        )
    return StoredResult(name, pd.read_csv(csv_path), provenance, staleness(provenance, rows))


def compare_with_stored(
    now: pd.DataFrame,
    stored: pd.DataFrame,
    keys: Sequence[str],
    metrics: Iterable[str],
    tolerance: Callable[[str, str, float], float],
) -> pd.DataFrame:
    """Put live numbers beside the stored ones, case by case.

    Args:
        now, stored: per-case frames sharing ``keys`` (the first key is the method/row name) and
            ``metrics`` columns.
        keys: the columns that identify a case, method first.
        metrics: the columns compared.
        tolerance: ``(method, metric, stored value) -> largest accepted |now - stored|``.

    Returns:
        One row per (case, metric): the keys, ``metric``, ``stored``, ``now``, ``abs diff``,
        ``tolerance`` and ``reproduces`` (within it, or both NaN).

    Raises:
        ValueError: a live case has no stored counterpart.
    """
    keys = list(keys)
    both = now.merge(stored, on=keys, how="left", suffixes=(" now", " stored"), indicator=True)
    if (both["_merge"] != "both").any():
        missing = both.loc[both["_merge"] != "both", keys].to_dict("records")
        raise ValueError(f"live cases without stored numbers: {missing[:3]}")
    out = pd.concat(
        [
            pd.DataFrame(
                {
                    **{k: both[k] for k in keys},
                    "metric": m,
                    "stored": both[f"{m} stored"],
                    "now": both[f"{m} now"],
                }
            )
            for m in metrics
        ],
        ignore_index=True,
    )
    out["abs diff"] = (out["now"] - out["stored"]).abs()
    out["tolerance"] = [
        tolerance(r, m, v)
        for r, m, v in zip(out[keys[0]], out["metric"], out["stored"], strict=False)
    ]
    out["reproduces"] = (out["abs diff"] <= out["tolerance"]) | (
        out["now"].isna() & out["stored"].isna()
    )
    return out
