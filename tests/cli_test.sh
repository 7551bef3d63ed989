#!/usr/bin/env bash
# End-to-end checks of the htrender command line: outputs, stats and errors.
set -uo pipefail
bin=$1
data=$2
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
failures=0
passes=0

ok() { passes=$((passes + 1)); }
fail() { echo "FAIL: $*"; failures=$((failures + 1)); }

# expect_error "<message part>" args...: non-zero exit, one line on stderr naming the problem
expect_error() {
  local want=$1
  shift
  "$bin" "$@" >"$tmp/out" 2>"$tmp/err"
  local rc=$?
  if [ $rc -eq 0 ]; then fail "exit 0 for: $*"; return; fi
  if ! grep -qF -- "$want" "$tmp/err"; then fail "'$want' not in: $(cat "$tmp/err") (for: $*)"; return; fi
  if [ "$(wc -l <"$tmp/err")" -gt 1 ]; then fail "more than one line for: $*: $(cat "$tmp/err")"; return; fi
  ok
}

"$bin" --help >"$tmp/help" 2>&1 && grep -q render "$tmp/help" && ok || fail "--help"
"$bin" render --help >"$tmp/help" 2>&1 && grep -q -- "--method" "$tmp/help" && ok || fail "render --help"
"$bin" methods >"$tmp/methods" && [ "$(wc -l <"$tmp/methods")" -ge 5 ] && ok || fail "methods"

for m in uniform cosine env brdf mis; do
  out="$tmp/furnace-$m.exr"
  if "$bin" render --scene "$data/scenes/furnace.json" --method $m --spp 2 --width 32 --height 16 \
      --device cpu --out "$out" --stats "$tmp/$m.json" -q; then
    [ -s "$out" ] && [ -s "${out%.exr}.png" ] && ok || fail "$m: outputs missing"
    /usr/bin/python3 - "$tmp/$m.json" "$m" <<'PY' && ok || fail "$m: stats"
import json, sys
s = json.load(open(sys.argv[1]))
assert s["method"] == sys.argv[2] and s["spp"] == 2 and s["width"] == 32, s
assert s["mean_samples_per_pixel"] == (4 if sys.argv[2] == "mis" else 2), s
assert all(k in s["seconds"] for k in ("parse", "environment", "render", "write")), s
assert s["device"]["type"] == "cpu"
PY
  else
    fail "render $m"
  fi
done

# auto falls back to the CPU and says so
"$bin" render --scene "$data/scenes/furnace.json" --spp 1 --width 8 --height 8 --out "$tmp/a.exr" 2>"$tmp/err" \
  && grep -q "cpu" "$tmp/err" && ok || fail "auto device"

expect_error 'unknown method "nope"' render --scene "$data/scenes/furnace.json" --method nope --out "$tmp/x.exr"
expect_error "gpu" render --scene "$data/scenes/furnace.json" --device gpu --out "$tmp/x.exr"
expect_error "does not exist" render --scene "$data/scenes/furnace.json" --out "$tmp/missing/dir/x.exr"
expect_error "cannot open scene file" render --scene "$tmp/none.json" --out "$tmp/x.exr"
expect_error "must end in .exr" render --scene "$data/scenes/furnace.json" --out "$tmp/x.png"
expect_error "--spp" render --scene "$data/scenes/furnace.json" --spp 0 --out "$tmp/x.exr"
expect_error "--width" render --scene "$data/scenes/furnace.json" --width 100000 --out "$tmp/x.exr"
expect_error "--bogus" render --bogus
mkdir -p "$tmp/ro" && chmod 555 "$tmp/ro"
if [ "$(id -u)" -ne 0 ]; then
  expect_error "not writable" render --scene "$data/scenes/furnace.json" --out "$tmp/ro/x.exr"
fi
printf '{"camera": {"position": [0,0,1],}\n' >"$tmp/bad.json"
expect_error "line 1, column" render --scene "$tmp/bad.json" --out "$tmp/x.exr"
printf 'not an exr' >"$tmp/fake.exr"
sed "s|../env/synthetic-constant.exr|$tmp/fake.exr|" "$data/scenes/furnace.json" >"$tmp/fake-env.json"
expect_error "fake.exr" render --scene "$tmp/fake-env.json" --out "$tmp/x.exr"

echo "$passes passed, $failures failed"
[ $failures -eq 0 ]
