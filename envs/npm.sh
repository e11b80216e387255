#!/usr/bin/env bash
# Third-party splat tools for the tests, from the npm registry at pinned versions, into the
# git-ignored folder .node/ (node_modules there): splat-transform (PlayCanvas's converter, which
# SuperSplat uses to write its PLY and compressed PLY), Spark with three.js (a real WebGL splat
# renderer for the browser test), the PlayCanvas engine (its glTF reader) and Khronos's glTF validator.
#   bash envs/npm.sh
# Without node/npm it says so and exits 0: the tests that need them skip with that reason
# (with ANIGS_REQUIRE_BROWSER=1, as in CI, they fail instead). No install scripts run.
set -uo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
DEST=.node
if ! command -v node >/dev/null 2>&1 || ! command -v npm >/dev/null 2>&1; then
  echo "[anigs] node/npm missing: the tests with splat-transform, Spark, PlayCanvas and the glTF validator will be skipped" >&2
  exit 0
fi
mkdir -p "$DEST"
if ! cmp -s envs/npm/package.json "$DEST/package.json" || [ ! -d "$DEST/node_modules" ]; then
  cp envs/npm/package.json "$DEST/package.json"
  echo "[anigs] installing the npm test tools into $DEST (splat-transform, Spark, three.js, PlayCanvas, gltf-validator)"
  (cd "$DEST" && npm install --no-audit --no-fund --ignore-scripts --loglevel=error >/dev/null) \
    || echo "[anigs] npm install failed: the tests that need these tools will be skipped" >&2
fi
exit 0
