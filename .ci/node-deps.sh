#!/usr/bin/env bash
# Node packages the tests use as independent checkers, installed into node/ beside the virtual
# environment: the Khronos glTF validator (npm gltf-validator; every written GLB is checked,
# retarget_lib/io/gltf_validator.py looks there) and FBX2glTF (npm fbx2gltf: a converter built on
# the Autodesk FBX SDK 2019.2, which tests/test_fbx.py uses to check that the SDK reads our FBX files).
set -euo pipefail
VENV="${1:-.venv}"
VERSION=2.0.0-dev.3.10
FBX2GLTF_VERSION=0.9.7
if ! command -v npm >/dev/null; then
  echo "node-deps: npm not found; install Node.js (Debian: apt-get install nodejs npm) for the glTF validator" >&2
  exit 0
fi
installed() {  # installed PACKAGE VERSION
  [ -f "$VENV/node/node_modules/$1/package.json" ] && grep -q "\"version\": \"$2\"" "$VENV/node/node_modules/$1/package.json"
}
installed gltf-validator "$VERSION" || \
  npm install --silent --no-audit --no-fund --prefix "$VENV/node" "gltf-validator@$VERSION"
if [ "$(uname -s)" = Linux ]; then
  installed fbx2gltf "$FBX2GLTF_VERSION" || \
    npm install --silent --no-audit --no-fund --prefix "$VENV/node" "fbx2gltf@$FBX2GLTF_VERSION"
  chmod +x "$VENV/node/node_modules/fbx2gltf/bin/Linux/FBX2glTF"  # the package ships it without the x bit
fi
