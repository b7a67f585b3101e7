"""The Khronos glTF validator (npm ``gltf-validator``), run with Node on a written file.

Set-up (README, ``.ci/node-deps.sh``): ``npm install --prefix .venv/node
gltf-validator@2.0.0-dev.3.10``, i.e. into ``node/`` beside the active virtual environment
(``sys.prefix``); or point ``RETARGET_GLTF_VALIDATOR`` at the package folder
(``.../node_modules/gltf-validator``).
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

__all__ = ["GLTF_VALIDATOR_VERSION", "validator_path", "validator_missing", "validate_gltf"]

#: the version the set-up installs
GLTF_VALIDATOR_VERSION = "2.0.0-dev.3.10"

_SCRIPT = """
const validator = require(process.argv[1]);
const data = new Uint8Array(require('fs').readFileSync(process.argv[2]));
validator.validateBytes(data, {maxIssues: 200, uri: process.argv[2]})
  .then(r => process.stdout.write(JSON.stringify(r)))
  .catch(e => { console.error(String(e)); process.exit(1); });
"""


def validator_path() -> Path:
    """The ``gltf-validator`` package folder (it may not exist)."""
    env = os.environ.get("RETARGET_GLTF_VALIDATOR")
    return Path(env) if env else Path(sys.prefix) / "node" / "node_modules" / "gltf-validator"


def validator_missing() -> str | None:
    """Why the validator cannot run (Node or the package missing), or ``None`` when it can."""
    if shutil.which("node") is None:
        return "node is not installed (the Khronos glTF validator runs on Node.js)"
    if not (validator_path() / "package.json").is_file():
        return (
            f"gltf-validator is not installed at {validator_path()}; run "
            f"`npm install --prefix {Path(sys.prefix) / 'node'} "
            f"gltf-validator@{GLTF_VALIDATOR_VERSION}`"
        )
    return None


def validate_gltf(path: str | os.PathLike, timeout: float = 120.0) -> dict:
    """Validate a ``.glb`` (or self-contained ``.gltf``) file.

    Returns:
        the validator's report; ``report["issues"]["numErrors"]`` counts errors and
        ``report["issues"]["messages"]`` lists them (code, message, pointer, severity 0 = error).

    Raises:
        RuntimeError: the validator is missing (:func:`validator_missing` says why) or crashed.
    """
    reason = validator_missing()
    if reason:
        raise RuntimeError(reason)
    done = subprocess.run(
        ["node", "-e", _SCRIPT, str(validator_path()), str(path)],
        capture_output=True,
        text=True,
        timeout=timeout,
        check=False,
    )
    if done.returncode != 0:
        raise RuntimeError(f"gltf-validator failed on {path}: {done.stderr.strip()}")
    return json.loads(done.stdout)
