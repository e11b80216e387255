#!/usr/bin/env bash
# The GPU check: one prepared script for a machine with one CUDA GPU (H100-class), about 8 minutes.
#
#   bash benchmarks/prepare_gpu_wheels.sh          # HERE, once: the missing packages as wheels in .whl/
#   bash benchmarks/gpu_check.sh                   # THERE (carry .whl): install, compile, measure, table
#
# Parts, most valuable first; each has its own time limit, and a failure in one does not stop the
# others (the table says FAILED and why). Estimated times on one H100 with 16 cores in brackets.
#   install   the carried wheels into /tmp/site (no registry there)                         [15 s]
#   env       GPU, driver, versions                                                         [5 s]
#   gsplat    gsplat's CUDA extension compiled on first use (TORCH_CUDA_ARCH_LIST=9.0,
#             MAX_JOBS=#cores), timed; meanwhile the CPU kernel is built and the demo capture
#             and a tiny random LTX-Video stack are written (untimed preparation)             [120-300 s]
#   static    the static fit on CUDA (gsplat): the demo's capture and settings, 1000 steps   [40 s]
#   agree     gsplat against the CPU kernel on that fitted model: images >= 40 dB PSNR,
#             gradients cosine >= 0.99 and relative L2 error <= 0.1 per parameter            [15 s]
#   static_cpu  the same fit on the machine's CPU for 300 steps: step time, PSNR at 100/200/300 [40 s]
#   ltx       the LTX-Video prior (tiny random weights) in bf16 on CUDA: refine + SDS        [30 s]
#   update    one round's model update on CUDA (120 steps, 30k Gaussians, 8 views), 10 on CPU [40 s]
#   demo      the whole demo workflow with device=cuda (snakemake, all cores)               [150-250 s]
#   gpu_tests the test suite's gpu-marked tests (if time is left)                          [30 s]
#
# Without a CUDA device (CI, the development machines) every CUDA part is reported as skipped and
# the script exits 0 in seconds. ANIGS_GPU_CHECK_DEVICE=cpu rehearses every part on the CPU at
# small sizes (the demo part with config/test.yaml), to prove the code paths without a GPU.
#
# Environment: ANIGS_GPU_CHECK_DEVICE (auto | cpu), ANIGS_GPU_CHECK_BUDGET_S (total seconds,
# default 550), ANIGS_GPU_CHECK_WHEELS (default .whl), ANIGS_GPU_CHECK_WORK (default
# /tmp/anigs-gpu-check), PYTHON (default python3), OUT (where the table, JSON and logs are copied).
# The mp4s of the demo are written with OpenCV's mp4v encoder when imageio-ffmpeg is missing
# (its 68 MB wheel does not travel): benchmarks/gpu_check_shim/sitecustomize.py.
set -uo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
ROOT=$PWD
T_START=$(date +%s)
BUDGET=${ANIGS_GPU_CHECK_BUDGET_S:-550}
WORK=${ANIGS_GPU_CHECK_WORK:-/tmp/anigs-gpu-check}
WHEELS=${ANIGS_GPU_CHECK_WHEELS:-.whl}
SITE=${ANIGS_GPU_CHECK_SITE:-/tmp/site}
PY=${PYTHON:-python3}
REQ=${ANIGS_GPU_CHECK_DEVICE:-auto}
NCPU=$(nproc 2>/dev/null || echo 4)
RESERVE=15   # seconds kept for the table and the copy to $OUT

rm -rf "$WORK"
mkdir -p "$WORK/logs" "$WORK/res" "$WORK/bin"
STATUS=$WORK/status.tsv
: > "$STATUS"
exec > >(tee -a "$WORK/logs/check.log") 2>&1

export PYTHONUNBUFFERED=1 PYTHONDONTWRITEBYTECODE=1
export TORCH_CUDA_ARCH_LIST=${TORCH_CUDA_ARCH_LIST:-9.0} MAX_JOBS=${MAX_JOBS:-$NCPU}
export TORCH_EXTENSIONS_DIR=${TORCH_EXTENSIONS_DIR:-/tmp/anigs-torch-ext}
export ANIGS_GPU_CHECK_MP4_SHIM=1 GIT_PYTHON_REFRESH=quiet  # GitPython without a git binary: no import error
export PYTHONPATH="$ROOT/benchmarks/gpu_check_shim:$ROOT${PYTHONPATH:+:$PYTHONPATH}"
# the workflow's rules call `anigs`; here it runs from the source tree (nothing is installed)
printf '#!/usr/bin/env bash\nexec %q -c "import sys; from anigs.cli import main; sys.exit(main())" "$@"\n' \
  "$(command -v "$PY")" > "$WORK/bin/anigs"
chmod +x "$WORK/bin/anigs"
# the interpreter's own bin folder (ninja, which torch's extension builder calls, lives there in a venv)
export PATH="$WORK/bin:$PATH:$(dirname "$(command -v "$PY")")"

elapsed() { echo $(( $(date +%s) - T_START )); }
record() {  # name status seconds note
  printf '%s\t%s\t%s\t%s\n' "$1" "$2" "$3" "${4//$'\t'/ }" >> "$STATUS"
  echo "[gpu-check] $(printf '%-10s %-8s %6ss' "$1" "$2" "$3") ${4:-}"
}
# run_part NAME LIMIT_S CMD...: runs CMD with a time limit (cut to the budget left), logs to logs/NAME.log
run_part() {
  local name=$1 limit=$2; shift 2
  local left=$(( BUDGET - $(elapsed) - RESERVE ))
  if (( left < 20 )); then record "$name" SKIPPED 0 "no time left in the ${BUDGET} s budget"; return 1; fi
  (( limit > left )) && limit=$left
  echo "[gpu-check] $name: started at +$(elapsed) s (limit ${limit} s)"
  local t0 rc dt
  t0=$(date +%s%N)
  echo "+ $*" > "$WORK/logs/$name.log"
  timeout -k 10 "$limit" "$@" >> "$WORK/logs/$name.log" 2>&1
  rc=$?
  dt=$(( ($(date +%s%N) - t0) / 100000000 ))
  dt="$(( dt / 10 )).$(( dt % 10 ))"
  if (( rc == 0 )); then
    record "$name" OK "$dt" ""
  elif (( rc == 124 || rc == 137 )); then
    record "$name" TIMEOUT "$dt" "stopped at its ${limit} s limit"
  else
    record "$name" FAILED "$dt" "exit $rc: $(grep -v '^\s*$' "$WORK/logs/$name.log" | tail -1 | cut -c1-200)"
  fi
  return $rc
}
skip() { record "$1" SKIPPED 0 "$2"; }
PARTS=("$PY" benchmarks/gpu_check_parts.py)

# ---- install: the carried wheels ------------------------------------------------------------------
PYVER=$("$PY" -c 'import sys; print("%d.%d" % sys.version_info[:2])' 2>/dev/null || echo "?")
if ! ls "$WHEELS"/*.whl >/dev/null 2>&1; then
  skip install "no wheels in $WHEELS (bash benchmarks/prepare_gpu_wheels.sh makes them)"
elif [ "$PYVER" != 3.12 ]; then
  skip install "the wheels in $WHEELS are for CPython 3.12 (the GPU image); $PY is $PYVER"
else
  run_part install 120 "$PY" -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade \
    --target "$SITE" "$WHEELS"/*.whl
  export PYTHONPATH="$PYTHONPATH:$SITE" PATH="$PATH:$SITE/bin"
fi

# ---- env: which device ----------------------------------------------------------------------------
run_part env 90 "${PARTS[@]}" env "$WORK/res/env.json"
HAS_CUDA=$("$PY" -c "import torch; print(int(torch.cuda.is_available()))" 2>/dev/null || echo 0)
SMALL=()
if [ "$REQ" = cpu ]; then
  DEV=cpu; SMALL=(--small); NOCUDA="rehearsal on the CPU (ANIGS_GPU_CHECK_DEVICE=cpu)"
elif [ "$HAS_CUDA" = 1 ]; then
  DEV=cuda; NOCUDA=""
else
  DEV=""; NOCUDA="no CUDA device on this machine"
fi

if [ -z "$DEV" ]; then
  for p in gsplat static agree static_cpu ltx update demo gpu_tests; do skip "$p" "$NOCUDA"; done
else
  # ---- untimed preparation in the background: CPU kernel, demo capture, tiny LTX stack -------------
  ( timeout 300 "$PY" -c "import sys; from anigs.cli import main; sys.exit(main())" build-kernel \
      > "$WORK/logs/build_kernel.log" 2>&1; echo $? > "$WORK/build_kernel.rc"
    timeout 300 "$PY" benchmarks/gpu_check_parts.py capture "$WORK/res/capture.json" --dir "$WORK/capture" \
      "${SMALL[@]}" > "$WORK/logs/capture.log" 2>&1; echo $? > "$WORK/capture.rc" ) &
  PID_PREP=$!
  ( timeout 300 "$PY" -c "import sys; from anigs.refine.prior.ltx import save_tiny_random_stack as s; \
s(sys.argv[1])" "$WORK/ltx-tiny" > "$WORK/logs/ltx_stack.log" 2>&1; echo $? > "$WORK/ltx_stack.rc" ) &
  PID_LTX=$!

  # ---- gsplat: compile its CUDA extension (timed) -----------------------------------------------
  FAST=torch
  if [ "$DEV" = cuda ]; then
    if run_part gsplat 360 "$PY" -c "
import json, os, sys, time
cached = os.path.exists(os.path.join(os.environ['TORCH_EXTENSIONS_DIR'], 'gsplat_cuda', 'gsplat_cuda.so'))
t = time.time()
from gsplat.cuda._backend import _C
assert _C is not None, 'gsplat: no CUDA extension (see the messages above)'
r = {'seconds': time.time() - t, 'built_before': cached, 'arch': os.environ['TORCH_CUDA_ARCH_LIST'],
     'max_jobs': os.environ['MAX_JOBS']}
json.dump(r, open(sys.argv[1], 'w'))
print(r)" "$WORK/res/gsplat.json"; then
      FAST=gsplat
    fi
  else
    skip gsplat "$NOCUDA: gsplat needs CUDA (the torch backend stands in below)"
  fi
  wait "$PID_PREP"
  for prep in build_kernel capture; do
    [ "$(cat "$WORK/$prep.rc" 2>/dev/null)" = 0 ] || echo "[gpu-check] preparation $prep failed: $(tail -3 "$WORK/logs/$prep.log")"
  done
  if [ "$DEV" = cuda ]; then ITER=1000; CPU_ITER=300; STEPS=120; CPU_STEPS=10; EVERY=100; BACKEND=$FAST
  else ITER=60; CPU_ITER=30; STEPS=6; CPU_STEPS=3; EVERY=30; BACKEND=cpu; fi

  # ---- static fit on the device, then gsplat against the CPU kernel on the fitted model ------------
  run_part static 180 "${PARTS[@]}" static "$WORK/res/static.json" --dir "$WORK/capture" --device "$DEV" \
    --backend "$BACKEND" --iterations "$ITER" --eval-every "$EVERY" --ply "$WORK/fitted.ply"
  MODEL=$WORK/fitted.ply; [ -f "$MODEL" ] || MODEL=$WORK/capture/gt/gaussians.ply  # the ground truth if the fit failed
  run_part agree 120 "${PARTS[@]}" agree "$WORK/res/agree.json" --dir "$WORK/capture" --ply "$MODEL" --device "$DEV" \
    --png "$WORK/agree_view.png"
  run_part static_cpu 120 "${PARTS[@]}" static "$WORK/res/static_cpu.json" --dir "$WORK/capture" --device cpu \
    --backend cpu --iterations "$CPU_ITER" --eval-every "$EVERY"

  # ---- LTX-Video in bf16, one round's update ----------------------------------------------------
  wait "$PID_LTX"
  LTX_MODEL=$WORK/ltx-tiny; [ "$(cat "$WORK/ltx_stack.rc" 2>/dev/null)" = 0 ] || LTX_MODEL=$WORK/ltx-tiny-again
  run_part ltx 150 "${PARTS[@]}" ltx "$WORK/res/ltx.json" --device "$DEV" --model "$LTX_MODEL" "${SMALL[@]}"
  run_part update 150 bash -c 'set -e; "$0" benchmarks/gpu_check_parts.py update "$1/res/update.json" --device "$2" \
    --steps "$3" --backend "$5" "${@:6}"; "$0" benchmarks/gpu_check_parts.py update "$1/res/update_cpu.json" \
    --device cpu --steps "$4" "${@:6}"' "$PY" "$WORK" "$DEV" "$STEPS" "$CPU_STEPS" "$BACKEND" "${SMALL[@]}"

  # ---- the whole demo -----------------------------------------------------------------------------
  if [ "$DEV" = cuda ]; then DEMO_CFG=(); else DEMO_CFG=(--configfile config/test.yaml); fi
  if "$PY" -c "import snakemake" 2>/dev/null; then
    run_part demo 420 "$PY" -m snakemake --cores "$NCPU" --scheduler greedy --workflow-profile workflow/profiles/default \
      "${DEMO_CFG[@]}" --config device="$DEV" results="$WORK/demo-results" --nolock
  else
    skip demo "snakemake is not installed (carry the wheels: benchmarks/prepare_gpu_wheels.sh)"
  fi
  if [ "$DEV" = cuda ]; then
    run_part gpu_tests 90 "$PY" -m pytest -q -m gpu tests/refine/test_prior_ltx.py -p no:cacheprovider
  else
    skip gpu_tests "$NOCUDA"
  fi
fi

# ---- the table ----------------------------------------------------------------------------------
echo
"$PY" benchmarks/gpu_check_table.py "$WORK" | tee "$WORK/table.md" || { echo "(table failed; the raw status:)"; cat "$STATUS"; }
echo "[gpu-check] done in $(elapsed) s; logs and JSON in $WORK"
if [ -n "${OUT:-}" ] && [ -d "$OUT" ]; then
  cp "$WORK/table.md" "$OUT/" 2>/dev/null
  "$PY" -c "import json, pathlib, sys; w = pathlib.Path(sys.argv[1]); json.dump({p.stem: json.loads(p.read_text()) \
for p in sorted((w / 'res').glob('*.json'))}, open(sys.argv[2], 'w'), indent=1)" "$WORK" "$OUT/results.json" 2>/dev/null
  tar -czf "$OUT/logs.tar.gz" -C "$WORK" logs status.tsv \
    $(cd "$WORK" && ls -d demo-results/*/*/final/final.json demo-results/*/*/eval/metrics.json \
      demo-results/*/static/metrics.json demo-results/*/*/benchmarks demo-results/*/benchmarks 2>/dev/null) 2>/dev/null
  cp "$WORK/logs/check.log" "$OUT/check.log" 2>/dev/null
  [ -f "$WORK/agree_view.png" ] && cp "$WORK/agree_view.png" "$OUT/"
  f=$(find "$WORK/demo-results" -path '*final/slices*' -name '*_frame.png' 2>/dev/null | sort | head -1)
  [ -n "$f" ] && cp "$f" "$OUT/demo_final_frame.png"
  f=$(find "$WORK/demo-results" -path '*effects*' -name 'overview.png' 2>/dev/null | sort | head -1)
  [ -n "$f" ] && cp "$f" "$OUT/demo_effects_overview.png"
fi
exec >&- 2>&-   # the tee of the log sees the end and writes its last lines
sleep 1
exit 0
