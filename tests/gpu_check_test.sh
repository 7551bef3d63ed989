#!/usr/bin/env bash
# tools/gpu-check.sh on this machine's Vulkan device at a small size, so that
# the real-GPU check keeps working between the times a GPU is at hand.
# Usage: gpu_check_test.sh SOURCE_DIR BUILD_DIR
set -uo pipefail
src=$1
build=$2
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
failures=0
passes=0
ok() { passes=$((passes + 1)); }
fail() { echo "FAIL: $*"; failures=$((failures + 1)); }

# The device --device gpu uses, as tools/gpu-check.sh picks it.
info=$("$build/htrender" info 2>/dev/null)
index=$(printf '%s\n' "$info" | sed -nE 's/^--device gpu( and --device auto)? uses? \[([0-9]+)\].*/\2/p')
if [ -z "$index" ]; then
  echo "gpu_check: no usable Vulkan device here; skipped"
  exit 77
fi
type=$(printf '%s\n' "$info" | awk -v i="[$index]" '$1 == i {getline; print $2; exit}' | tr -d ,)
small=(env WIDTH=32 HEIGHT=16 SPP=4 REF_SPP=64 RUNS=1 BUILD_DIR="$build" OUT="$tmp/out")
if "${small[@]}" ANY_DEVICE=1 "$src/tools/gpu-check.sh" >"$tmp/log" 2>&1; then
  ok
  md=$(ls "$tmp"/out/*.md 2>/dev/null | head -1)
  json=${md%.md}.json
  [ -f "$md" ] && [ -f "$json" ] && ok || fail "no table or results in $tmp/out: $(ls "$tmp/out")"
  python3 - "$md" "$json" <<'PY' && ok || fail "the table: $(cat "$md")"
import json, re, sys
md, data = open(sys.argv[1]).read(), json.load(open(sys.argv[2]))
rows = {}
for line in md.splitlines():
    cells = [c.strip() for c in line.strip("|").split("|")]
    if len(cells) == 6 and cells[1] == "4":
        rows[cells[0]] = cells
assert set(rows) == {"mis", "ht-cut", "ht-frontier", "ht-vis"}, rows
for m, c in rows.items():
    assert float(c[2]) > 0 and float(c[4]) > 0, c          # GPU ms, relMSE
    assert re.fullmatch(r"[0-9.e+-]+x", c[5]), c           # efficiency against mis
assert rows["mis"][5] == "1x", rows["mis"]
name = data["results"][0]["device_name"]
assert md.startswith("# " + name), md[:80]
assert {r["method"] for r in data["results"]} == {"mis", "ht-cut", "ht-frontier", "ht-vis"}, data["results"]
PY
else
  fail "gpu-check.sh: $(tail -5 "$tmp/log")"
fi

# Without ANY_DEVICE, a device that is not a discrete GPU is refused in one line.
if [ "$type" != "discrete" ]; then
  if "${small[@]}" "$src/tools/gpu-check.sh" >"$tmp/log" 2>"$tmp/err"; then
    fail "gpu-check.sh took a $type device"
  else
    grep -q "is $type, not a discrete GPU" "$tmp/err" && [ "$(wc -l <"$tmp/err")" -eq 1 ] && ok ||
      fail "refusal: $(cat "$tmp/err")"
  fi
fi

echo "gpu_check: $passes passed, $failures failed"
[ $failures -eq 0 ]
