#!/usr/bin/env bash
# The style gate (run by `bash envs/setup.sh test` before the tests, so by CI): the Python linter
# (ruff, configured in pyproject.toml [tool.ruff]), the rule files' formatter (snakefmt,
# [tool.snakefmt]) and Snakemake's own linter. Any finding fails the gate; fix with
# `ruff check --fix . && snakefmt Snakefile workflow/`. (No Python formatter yet: pyproject.toml
# [tool.ruff] says why.)
set -euo pipefail
cd "$(dirname "$0")/.."
echo "[anigs] style gate: ruff check, snakefmt --check, snakemake --lint"
ruff check --no-cache .
snakefmt --check Snakefile workflow/ 2> /tmp/anigs-snakefmt.$$ || { cat /tmp/anigs-snakefmt.$$; rm -f /tmp/anigs-snakefmt.$$; exit 1; }
rm -f /tmp/anigs-snakefmt.$$
lint=$(snakemake --lint 2>&1) || { echo "$lint"; exit 1; }
case "$lint" in *"good condition"*) ;; *) echo "$lint"; exit 1 ;; esac
echo "[anigs] style gate passed"
