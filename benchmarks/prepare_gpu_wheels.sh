#!/usr/bin/env bash
# Download the wheels that benchmarks/gpu_check.sh needs on the lent GPU machine, which reaches no
# package registry. Run it HERE (a machine with pip access), then carry the folder with the check:
#
#   bash benchmarks/prepare_gpu_wheels.sh            # -> .whl/ (git-ignored), prints the list and sizes
#   bash benchmarks/prepare_gpu_wheels.sh DIR        # another folder
#
# Target: the GPU image of this workplace (x86-64, Python 3.12, torch 2.11+cu130, transformers,
# numpy, scipy, scikit-image, opencv-python-headless, pandas, pyyaml, jinja2, rich, requests,
# huggingface-hub, ... already there: /work/.library/device/KINDS.md). Only what that image lacks
# travels, one version of each, so nothing installed into /tmp/site shadows the image's torch or
# numpy. Versions are the ones the project's CPU environment runs (checked together here).
#
# Left out on purpose (each is reported by the check, not silently lost):
#   pulp            16 MB of CBC solver binaries; Snakemake needs it only for its ILP scheduler and
#                   the check runs `snakemake --scheduler greedy`.
#   imageio-ffmpeg  68 MB (an ffmpeg binary); over the 64 MiB limit with pycolmap. The check writes
#                   the demo's mp4s with OpenCV's MPEG-4 encoder instead (benchmarks/gpu_check_shim/).
#   plyfile         only the test suite's interoperability check uses it.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
DEST="${1:-.whl}"
PY="${PYTHON:-$( [ -x .venv/bin/python ] && echo .venv/bin/python || echo python3)}"   # the project venv where there is one
# What the GPU image lacks, pinned. Roots: snakemake (+ closure), pycolmap (SfM), gsplat (CUDA
# rasterizer, pure Python: its CUDA sources are in the wheel and compile on first use),
# diffusers (LTX-Video), jsonschema (anigs' config validation).
WHEELS=(
  # the video prior
  diffusers==0.42.1 importlib-metadata==10.2.0
  # the CUDA rasterizer
  gsplat==1.5.3
  # structure from motion (cp312 manylinux, 38 MB: the largest)
  pycolmap==4.2.1
  # the workflow engine and what it needs beyond the image
  snakemake==9.27.1
  snakemake-interface-common==1.23.0 snakemake-interface-executor-plugins==9.4.0
  snakemake-interface-logger-plugins==2.1.0 snakemake-interface-report-plugins==1.3.0
  snakemake-interface-scheduler-plugins==2.0.2 snakemake-interface-storage-plugins==4.4.1
  argparse-dataclass==2.0.0 conda-inject==1.3.2 configargparse==1.9.0 docutils==0.22.4 dpath==2.2.0
  fastjsonschema==2.22.3 gitdb==4.0.12 gitpython==3.2.1 humanfriendly==10.0 immutables==0.21
  jupyter-core==5.9.1 nbformat==5.11.1 platformdirs==4.14.8 smart-open==7.7.1 smmap==5.0.3
  tenacity==9.2.1 throttler==1.2.3 traitlets==5.16.1 yte==1.9.4
  sqlmodel==0.0.37 sqlalchemy==2.0.58 greenlet==3.5.6 pydantic==2.14.4 pydantic-core==2.50.5
  annotated-types==0.8.0 typing-inspection==0.4.5
  # config validation (anigs and snakemake)
  jsonschema==4.26.0 jsonschema-specifications==2025.9.1 referencing==0.37.0 rpds-py==2026.9.1
)
# published as a source distribution only: built here into a pure-Python wheel
SDIST_ONLY=(connection-pool==0.0.3)

mkdir -p "$DEST"
if ! git check-ignore -q "$DEST/x.whl" 2>/dev/null; then
  echo "[gpu-wheels] warning: $DEST is not git-ignored: it would travel as untracked files" >&2
fi
PLAT=(--platform manylinux_2_28_x86_64 --platform manylinux_2_27_x86_64 --platform manylinux_2_24_x86_64
      --platform manylinux_2_17_x86_64 --platform manylinux2014_x86_64 --platform manylinux_2_5_x86_64
      --platform manylinux1_x86_64)
"$PY" -m pip download -q --disable-pip-version-check --no-deps --only-binary=:all: --python-version 3.12 \
  --implementation cp --abi cp312 --abi abi3 --abi none "${PLAT[@]}" -d "$DEST" "${WHEELS[@]}"
"$PY" -m pip wheel -q --disable-pip-version-check --no-deps --no-binary=:all: -w "$DEST" "${SDIST_ONLY[@]}"

# one version of each: two versions of a package stop the whole install on the device
want=$(printf '%s\n' "${WHEELS[@]}" "${SDIST_ONLY[@]}" | sed 's/==.*//' | tr '_.' '--' | tr 'A-Z' 'a-z' | sort)
have=$(ls "$DEST"/*.whl | xargs -n1 basename | cut -d- -f1 | tr '_.' '--' | tr 'A-Z' 'a-z' | sort)
extra=$(comm -13 <(echo "$want") <(echo "$have") || true)
missing=$(comm -23 <(echo "$want") <(echo "$have") || true)
dupes=$(echo "$have" | uniq -d)
if [ -n "$extra$missing$dupes" ]; then
  echo "[gpu-wheels] $DEST does not hold exactly the list: extra [$extra] missing [$missing] twice [$dupes];" \
       "empty the folder and run again" >&2
  exit 1
fi

echo "[gpu-wheels] $(ls "$DEST"/*.whl | wc -l) wheels in $DEST:"
ls -l "$DEST"/*.whl | awk '{printf "  %8.2f MB  %s\n", $5 / 1e6, $9}' | sort -k3
whl=$(du -cb "$DEST"/*.whl | tail -1 | cut -f1)
repo=$(git ls-files -z --cached --others --exclude-standard | xargs -0 du -cb 2>/dev/null | awk '/total$/ {s += $1} END {print s + 0}')
total=$((whl + repo))
limit=$((64 * 1024 * 1024))
printf '[gpu-wheels] wheels %.1f MiB + working tree %.1f MiB = %.1f MiB of the 64 MiB that travel\n' \
  "$(echo "$whl / 1048576" | bc -l)" "$(echo "$repo / 1048576" | bc -l)" "$(echo "$total / 1048576" | bc -l)"
if [ "$total" -gt "$limit" ]; then
  echo "[gpu-wheels] over the 64 MiB limit: the call would be refused" >&2
  exit 1
fi
echo "[gpu-wheels] carry: $DEST   (device side: bash benchmarks/gpu_check.sh installs them into /tmp/site)"
