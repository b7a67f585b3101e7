#!/usr/bin/env bash
# A real headless browser for the book's 3-D viewer test (tests/test_book_viewer.py, marked slow):
# Debian's chromium. Only CI installs it (about 300 MB with its libraries); `make` does not need it.
set -euo pipefail
command -v chromium >/dev/null && exit 0
if [ "$(id -u)" -ne 0 ]; then
  echo "browser-deps: no chromium; run: sudo apt-get install chromium" >&2
  exit 0
fi
apt-get update -qq
DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends chromium >/dev/null
