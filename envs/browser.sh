#!/usr/bin/env bash
# Headless browser for the browser tests (viewer, study page): Debian's chromium and
# chromium-driver, and Selenium from PyPI into the project's virtual environment.
# Nothing downloads a browser or driver of its own (Selenium is given /usr/bin/chromedriver).
#   bash envs/browser.sh [VENV]     (default ./.venv)
# Needs root for apt-get; without it (or without apt-get) it says so and exits 0, and the
# browser tests skip with that reason.
set -uo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
VENV="${1:-${ANIGS_VENV:-.venv}}"
CONSTRAINTS="${ANIGS_CONSTRAINTS:-envs/constraints.txt}"

if ! command -v chromium >/dev/null 2>&1 || ! command -v chromedriver >/dev/null 2>&1; then
  if [ "$(id -u)" = "0" ] && command -v apt-get >/dev/null 2>&1; then
    echo "[anigs] installing chromium and chromium-driver (apt)"
    export DEBIAN_FRONTEND=noninteractive
    apt-get update -qq >/dev/null 2>&1 || echo "[anigs] apt-get update failed" >&2
    apt-get install -y -qq chromium chromium-driver >/dev/null 2>&1 \
      || echo "[anigs] could not install chromium/chromium-driver: the browser tests will be skipped" >&2
  else
    echo "[anigs] chromium/chromium-driver missing and not root with apt-get: the browser tests will be skipped" >&2
  fi
fi
if [ -x "$VENV/bin/python" ] && ! "$VENV/bin/python" -c "import selenium" >/dev/null 2>&1; then
  "$VENV/bin/python" -m pip install -q "selenium>=4.20" -c "$CONSTRAINTS" \
    || echo "[anigs] could not install selenium: the browser tests will be skipped" >&2
fi
exit 0
