#!/usr/bin/env bash
# The command line's GPU side: `htrender info`; --device gpu on the machine's
# Vulkan device (lavapipe in CI) against --device cpu; and, with no Vulkan
# driver (VK_DRIVER_FILES pointing nowhere), the one-line error of
# --device gpu and the CPU fallback of --device auto.
# Usage: gpu_cli_test.sh HTRENDER DATA_DIR
set -uo pipefail
bin=$1
data=$(cd "$2" && pwd)
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
failures=0
passes=0

ok() { passes=$((passes + 1)); }
fail() { echo "FAIL: $*"; failures=$((failures + 1)); }

# expect_error "<message part>" command...: exit 1, one line on stderr holding the message.
expect_error() {
  local want=$1
  shift
  "$@" >"$tmp/out" 2>"$tmp/err"
  local rc=$?
  if [ $rc -ne 1 ]; then fail "exit $rc, not 1, for: $*: $(head -c 2000 "$tmp/err")"; return; fi
  if ! grep -qF -- "$want" "$tmp/err"; then fail "'$want' not in: $(cat "$tmp/err") (for: $*)"; return; fi
  if [ "$(wc -l <"$tmp/err")" -ne 1 ]; then fail "not one line for: $*: $(cat "$tmp/err")"; return; fi
  ok
}

furnace="$data/scenes/furnace.json"
loud=(--scene "$furnace" --spp 4 --width 24 --height 12)
small=("${loud[@]}" -q)

# info: every device with type, driver and API version, and which one is used.
if "$bin" info >"$tmp/info" 2>&1; then
  grep -q "type .*, driver .*, Vulkan [0-9]" "$tmp/info" && grep -q "usable: yes" "$tmp/info" \
    && grep -Eq "^--device gpu (and --device auto use|uses) \[" "$tmp/info" && ok || fail "info: $(cat "$tmp/info")"
else
  fail "info exits $?: $(cat "$tmp/info")"
fi

# --device gpu: every baseline method, stats of a GPU run, the same image as
# the CPU reference (in fp64, the variant that draws the CPU's samples).
for m in uniform cosine env brdf mis; do
  if VK_INSTANCE_LAYERS=VK_LAYER_KHRONOS_validation "$bin" render "${small[@]}" --method $m --device gpu \
      --gpu-precision fp64 --out "$tmp/g-$m.exr" --stats "$tmp/g-$m.json" >"$tmp/log" 2>&1; then
    grep -qi "validation" "$tmp/log" && fail "$m: validation layer output: $(head -c 2000 "$tmp/log")" || ok
    /usr/bin/python3 - "$tmp/g-$m.json" "$m" <<'PY' && ok || fail "$m: gpu stats"
import json, sys
s = json.load(open(sys.argv[1]))
d = s["device"]
assert d["type"] == "gpu" and d["name"] and d["vulkan"] and d["shader"] == "baselines.fp64.spv", d
assert d["precision"] == "fp64", d
assert d["texel_views"] is True, d  # the scene's map fits its texel views
assert s["method"] == sys.argv[2] and s["mean_samples_per_pixel"] == (8 if sys.argv[2] == "mis" else 4), s
sec = s["seconds"]
assert all(k in sec for k in ("parse", "environment", "render", "write", "device", "upload", "gpu")), sec
assert sec["gpu"] is None or 0 <= sec["gpu"] <= sec["render"] + 1e-3, sec
w = d["work"]  # the tiles cover the image; each waited for at least once
tiles = -(-s["width"] // w["tile_width"]) * -(-s["height"] // w["tile_height"])
assert w["tiles"] == tiles and w["submissions"] >= tiles and w["restarts"] == 0 and w["batch_limit"] > 0, w
assert w["readback_seconds"] is None or 0 <= w["readback_seconds"] <= sec["render"], w
PY
    "$bin" render "${small[@]}" --method $m --device cpu --out "$tmp/c-$m.exr" \
      && "$bin" compare --ref "$tmp/c-$m.exr" --test "$tmp/g-$m.exr" >"$tmp/cmp" \
      && /usr/bin/python3 -c "import json,sys; e=json.load(open('$tmp/cmp')); sys.exit(0 if e['mean_abs_rel_error'] < 1e-5 else 1)" \
      && ok || fail "$m: gpu image differs from cpu: $(cat "$tmp/cmp")"
  else
    fail "render $m --device gpu: $(head -c 2000 "$tmp/log")"
  fi
done

# What --device auto picks agrees with `info`: a GPU, never a CPU Vulkan device.
"$bin" render "${loud[@]}" --out "$tmp/a.exr" --stats "$tmp/a.json" >/dev/null 2>"$tmp/err"
if grep -q "auto use \[" "$tmp/info"; then
  grep -q "^device: gpu " "$tmp/err" && ok || fail "auto should use the GPU: $(cat "$tmp/err")"
else
  grep -q "^device: cpu reference (" "$tmp/err" && ok || fail "auto should use the CPU: $(cat "$tmp/err")"
fi
if grep -q "auto: the CPU reference (faster than a CPU Vulkan device)" "$tmp/info"; then
  grep -q "^device: cpu reference (the only Vulkan device, .* runs on the CPU; --device gpu uses it)" "$tmp/err" \
    && ok || fail "auto with only a CPU Vulkan device: $(cat "$tmp/err")"
fi

# fp32 is the default variant; wis and tsis exist in fp64 only.
for mp in "mis baselines.fp32.spv" "ht-vis ht.fp32.spv" "tsis competitors.fp64.spv"; do
  set -- $mp
  "$bin" render "${small[@]}" --device gpu --method "$1" --out "$tmp/p.exr" --stats "$tmp/p.json" 2>"$tmp/err" \
    && /usr/bin/python3 -c "import json,sys; d=json.load(open('$tmp/p.json'))['device']; sys.exit(0 if d['shader'] == '$2' and d['precision'] == 'auto' else 1)" \
    && ok || fail "$1: default precision: $(cat "$tmp/p.json" "$tmp/err")"
done
expect_error "method tsis needs shaderFloat64 on the GPU" "$bin" render "${small[@]}" --device gpu --method tsis --gpu-precision fp32 --out "$tmp/x.exr"
expect_error "--gpu-index 99" "$bin" render "${small[@]}" --device gpu --gpu-index 99 --out "$tmp/x.exr"
expect_error "method oracle runs on the CPU reference only" "$bin" render "${small[@]}" --device gpu --method oracle --out "$tmp/x.exr"
"$bin" render "${loud[@]}" --method oracle --out "$tmp/oracle.exr" 2>"$tmp/err" \
  && grep -q "device: cpu reference (method oracle has no GPU version)" "$tmp/err" && ok || fail "auto, oracle: $(cat "$tmp/err")"

# SPIR-V missing next to the binary.
mkdir -p "$tmp/bin" && cp "$bin" "$tmp/bin/htrender"
expect_error "SPIR-V shader not found" "$tmp/bin/htrender" render "${small[@]}" --device gpu --out "$tmp/x.exr"

# No Vulkan driver.
nodriver=(env VK_DRIVER_FILES=/nonexistent/icd.json VK_ICD_FILENAMES=/nonexistent/icd.json)
expect_error "--device gpu: no Vulkan driver found" "${nodriver[@]}" "$bin" render "${small[@]}" --device gpu --out "$tmp/x.exr"
expect_error "no Vulkan driver found" "${nodriver[@]}" "$bin" info
if "${nodriver[@]}" "$bin" render --scene "$furnace" --spp 2 --width 16 --height 8 --out "$tmp/n.exr" \
    --stats "$tmp/n.json" 2>"$tmp/err"; then
  grep -q "^device: cpu reference (no Vulkan driver found" "$tmp/err" && ok || fail "auto without driver: $(cat "$tmp/err")"
  /usr/bin/python3 -c "import json,sys; s=json.load(open('$tmp/n.json')); sys.exit(0 if s['device']['type']=='cpu' and 'gpu' not in s['seconds'] else 1)" \
    && ok || fail "auto without driver: stats"
else
  fail "auto without driver exits non-zero: $(cat "$tmp/err")"
fi

echo "gpu_cli: $passes passed, $failures failed"
[ $failures -eq 0 ]
