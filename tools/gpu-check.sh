#!/usr/bin/env bash
# The real-GPU check, one command for a machine with a GPU: builds htrender
# (unless $BUILD_DIR holds one), renders spheres.json at 1920x1080 and
# 16 spp with `mis`, the product methods (`ht-cut`, `ht-frontier`) and the seed's
# `ht-vis` on the first discrete GPU, side by side in one tools/bench.py run
# against a reference rendered on the same GPU, and writes the table (GPU
# ms, relMSE, efficiency against `mis`, the device's name) to
# docs/report/gpu/<device>.md with the run's results as <device>.json.
#
#   tools/gpu-check.sh
#   WIDTH=64 HEIGHT=32 SPP=4 REF_SPP=64 ANY_DEVICE=1 OUT=/tmp/g tools/gpu-check.sh   # lavapipe, small
#
# ANY_DEVICE=1 takes whatever `htrender info` picks for --device gpu (a CPU
# Vulkan device too); otherwise a machine without a discrete GPU is refused.
set -euo pipefail
cd "$(dirname "$0")/.."
WIDTH=${WIDTH:-1920}
HEIGHT=${HEIGHT:-1080}
SPP=${SPP:-16}
REF_SPP=${REF_SPP:-2048}
RUNS=${RUNS:-3}
METHODS=${METHODS:-mis,ht-cut,ht-frontier,ht-vis}
OUT=${OUT:-docs/report/gpu}
BUILD=${BUILD_DIR:-build}
# tools/bench.py needs numpy: the first Python that has it.
PY=${PYTHON:-}
for candidate in python3 /usr/bin/python3; do
  [ -n "$PY" ] && break
  "$candidate" -c 'import numpy' 2>/dev/null && PY=$candidate
done
[ -n "$PY" ] || { echo "gpu-check: no Python with numpy (tools/install-deps.sh installs python3-numpy)" >&2; exit 1; }
start=$SECONDS

[ -x "$BUILD/htrender" ] || BUILD_DIR="$BUILD" tools/build.sh
H="$BUILD/htrender"
info=$("$H" info)
line=$(printf '%s\n' "$info" | grep -E '^--device gpu( and --device auto)? use[s]? \[' || true)
if [ -z "$line" ]; then
  echo "gpu-check: no usable Vulkan device (htrender info)" >&2
  exit 1
fi
index=$(printf '%s\n' "$line" | sed -E 's/.*use[s]? \[([0-9]+)\].*/\1/')
type=$(printf '%s\n' "$info" | awk -v i="[$index]" '$1 == i {getline; print $2; exit}' | tr -d ,)
name=$(printf '%s\n' "$info" | awk -v i="[$index]" '$1 == i {$1 = ""; print substr($0, 2); exit}')
if [ "$type" != "discrete" ] && [ "${ANY_DEVICE:-0}" != 1 ]; then
  echo "gpu-check: the device --device gpu uses, [$index] $name, is $type, not a discrete GPU (ANY_DEVICE=1 takes it)" >&2
  exit 1
fi
echo "gpu-check: [$index] $name ($type), ${WIDTH}x${HEIGHT}, $SPP spp: $METHODS" >&2

work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
"$PY" tools/bench.py --htrender "$H" --scene data/scenes/spheres.json --device gpu --methods "$METHODS" \
  --spp "$SPP" --runs "$RUNS" --width "$WIDTH" --height "$HEIGHT" --ref-spp "$REF_SPP" --ref-device gpu \
  --extra "--gpu-index $index" --out "$work/bench"
mkdir -p "$OUT"
"$PY" tools/gpu_table.py --results "$work/bench/results.json" --out "$OUT"
echo "gpu-check: done in $((SECONDS - start)) s" >&2
