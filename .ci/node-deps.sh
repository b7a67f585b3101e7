#!/usr/bin/env bash
# The Khronos glTF validator (npm gltf-validator) for the tests that check every written GLB.
# Installed into node/ beside the virtual environment (retarget_lib/io/gltf_validator.py looks there).
set -euo pipefail
VENV="${1:-.venv}"
VERSION=2.0.0-dev.3.10
if ! command -v npm >/dev/null; then
  echo "node-deps: npm not found; install Node.js (Debian: apt-get install nodejs npm) for the glTF validator" >&2
  exit 0
fi
if [ -f "$VENV/node/node_modules/gltf-validator/package.json" ] && \
   grep -q "\"version\": \"$VERSION\"" "$VENV/node/node_modules/gltf-validator/package.json"; then exit 0; fi
npm install --silent --no-audit --no-fund --prefix "$VENV/node" "gltf-validator@$VERSION"
