#!/usr/bin/env bash
# Regenerates docs/report/ for the default settings (about 40 minutes on 2 cores):
#   1. tools/bench.py on data/scenes/spheres.json: every method at 4/16/64/256
#      spp on the cpu, and on the gpu (lavapipe here) every method the GPU path
#      has, at $GPU_SPP; each point with the stratified and the independent
#      sampler ($SAMPLERS);
#   2. the variance floor: oracle against ht-frontier, ht-cut, ht-vis, ht and mis at 16 spp, side by
#      side in one run (oracle is slow: 16 spp only);
#   3. tools/bench.py on every data/scenes/stress/*.json at one spp on the cpu
#      and lavapipe, the fastest of $STRESS_RUNS runs (the report carries each
#      method's relMSE to equal time on the cpu, and gives every method's
#      efficiency against mis on both);
#   4. tools/scaling.py: render time against spp, environment Nside and image
#      size; the environment stage split into load / resample / trees for a
#      1024x512 and a generated 8192x4096 map;
#   5. tools/report.py into docs/report/ (Markdown + PNG charts, no EXRs),
#      with the bench runs on real GPUs kept in docs/report/gpu/*.json
#      (tools/bench.py --device gpu --spp 16 --width 1920 --height 1080 on
#      such a machine; its results.json).
# The binaries are copied first, so a rebuild during the run does not disturb
# it. Intermediate results (EXRs, CSV, JSON, cached references) go to $OUT.
# Every setting below can be overridden from the environment, e.g.
#   WIDTH=480 HEIGHT=240 RUNS=5 tools/make-report.sh
set -euo pipefail
cd "$(dirname "$0")/.."

PY=/usr/bin/python3
BUILD=${BUILD:-build}
OUT=${OUT:-out/report-data}
REPORT=${REPORT:-docs/report}
WIDTH=${WIDTH:-200}              # spheres.json bench
HEIGHT=${HEIGHT:-100}
SPP=${SPP:-4,16,64,256}
SAMPLERS=${SAMPLERS:-stratified,independent}
RUNS=${RUNS:-4}                  # timed runs per point (the fastest counts)
DEVICES=${DEVICES:-cpu,gpu}
GPU_SPP=${GPU_SPP:-4,16,64}
GPU_RUNS=${GPU_RUNS:-$RUNS}      # the same on the gpu, so that their ratios compare like with like
REF_SPP=${REF_SPP:-2048}
MAX_SECONDS=${MAX_SECONDS:-60}   # skip a point predicted to take longer; time a long one once
FLOOR_WIDTH=${FLOOR_WIDTH:-200}  # oracle variance floor
FLOOR_HEIGHT=${FLOOR_HEIGHT:-100}
ORACLE_ORDER=${ORACLE_ORDER:-6}  # its table: Nside 2^6 = 64
STRESS_WIDTH=${STRESS_WIDTH:-80}
STRESS_HEIGHT=${STRESS_HEIGHT:-40}
STRESS_SPP=${STRESS_SPP:-16}
STRESS_REF_SPP=${STRESS_REF_SPP:-1024}
STRESS_RUNS=${STRESS_RUNS:-5}    # their renders take milliseconds: the fastest of several
SCALING_METHODS=${SCALING_METHODS:-mis,ht-vis,ht-frontier,ht-cut}

start=$(date +%s)
stamp() { echo "make-report: $1 ($(( $(date +%s) - start )) s)" >&2; }

bin="$OUT/bin"
rm -rf "$bin"
mkdir -p "$bin"
cp "$BUILD/htrender" "$BUILD/make_env" "$bin/"
mkdir -p "$bin/shaders"
cp "$BUILD"/shaders/*.spv "$bin/shaders/" 2>/dev/null || true
[ -f "$BUILD/CMakeCache.txt" ] && grep '^CMAKE_BUILD_TYPE:' "$BUILD/CMakeCache.txt" > "$bin/CMakeCache.txt"
H="$bin/htrender"

stamp "bench: spheres.json ${WIDTH}x${HEIGHT}, spp ${SPP} (gpu ${GPU_SPP}), devices ${DEVICES}"
$PY tools/bench.py --htrender "$H" --scene data/scenes/spheres.json --device "$DEVICES" \
  --spp "$SPP" --runs "$RUNS" --gpu-spp "$GPU_SPP" --gpu-runs "$GPU_RUNS" --width "$WIDTH" --height "$HEIGHT" \
  --samplers "$SAMPLERS" --ref-spp "$REF_SPP" --max-seconds "$MAX_SECONDS" --out "$OUT/bench"

stamp "variance floor: oracle at 16 spp, ${FLOOR_WIDTH}x${FLOOR_HEIGHT}"
$PY tools/bench.py --htrender "$H" --scene data/scenes/spheres.json --device cpu --methods ht-frontier,ht-cut,ht-vis,ht,mis \
  --oracle --oracle-spp 16 --spp 16 --runs 1 --width "$FLOOR_WIDTH" --height "$FLOOR_HEIGHT" \
  --extra "--oracle-order $ORACLE_ORDER" \
  --ref-spp "$REF_SPP" --out "$OUT/floor"

stamp "bench: stress scenes ${STRESS_WIDTH}x${STRESS_HEIGHT}, ${STRESS_SPP} spp"
stress=()
for s in data/scenes/stress/*.json; do stress+=(--scene "$s"); done
$PY tools/bench.py --htrender "$H" "${stress[@]}" --device "$DEVICES" --spp "$STRESS_SPP" --runs "$STRESS_RUNS" \
  --width "$STRESS_WIDTH" --height "$STRESS_HEIGHT" --ref-spp "$STRESS_REF_SPP" --out "$OUT/stress"

stamp "scaling"
$PY tools/scaling.py --htrender "$H" --make-env "$bin/make_env" --methods "$SCALING_METHODS" --out "$OUT/scaling"

stamp "report"
real_gpu=()
for f in docs/report/gpu/*.json; do [ -f "$f" ] && real_gpu+=(--real-gpu "$f"); done
$PY tools/report.py --htrender "$H" --bench "$OUT/bench" --floor "$OUT/floor" --stress "$OUT/stress" \
  --scaling "$OUT/scaling" "${real_gpu[@]}" --out "$REPORT"
stamp "done: $REPORT/README.md ($(du -sh "$REPORT" | cut -f1))"
