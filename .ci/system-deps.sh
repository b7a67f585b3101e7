#!/usr/bin/env bash
# Install the Debian packages the suite uses, if they are missing and we may (root).
# nodejs + npm: the Khronos glTF validator (.ci/node-deps.sh); libassimp5: FBX input (the [fbx] extra, 12.7 MB), so its tests run here.
set -euo pipefail
pkgs=(libegl1 libgl1 libgl1-mesa-dri libglx-mesa0 assimp-testmodels libassimp5)
# Node from any source will do (many machines have it outside Debian's packages): only when there is
# no npm at all do we ask Debian for it
command -v npm >/dev/null || pkgs+=(nodejs npm)
missing=()
for p in "${pkgs[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then exit 0; fi
if [ "$(id -u)" -ne 0 ]; then
  echo "system-deps: missing ${missing[*]}; run: sudo apt-get install ${missing[*]}" >&2
  exit 0
fi
echo "system-deps: installing ${missing[*]}"
apt-get update -qq
DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
