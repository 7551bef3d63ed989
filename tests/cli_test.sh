#!/usr/bin/env bash
# End-to-end checks of the htrender command line: outputs, stats and errors.
# Usage: cli_test.sh HTRENDER DATA_DIR [WRITE_TEST_EXR [WRITE_TEST_HDR]]
# (write_test_exr and write_test_hdr, built with the tests, are looked for next to htrender by default)
set -uo pipefail
bin=$1
data=$(cd "$2" && pwd)
wexr=${3:-$(dirname "$bin")/write_test_exr}
whdr=${4:-$(dirname "$bin")/write_test_hdr}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
failures=0
passes=0
rc_last=0

ok() { passes=$((passes + 1)); }
fail() { echo "FAIL: $*"; failures=$((failures + 1)); }

# expect_error "<message part>" args...: non-zero exit, one line on stderr naming the problem.
# A crash (signal, sanitizer report) or an "internal error" is never the expected error.
expect_error() {
  local want=$1
  shift
  "$bin" "$@" >"$tmp/out" 2>"$tmp/err"
  local rc=$?
  rc_last=$rc
  if [ $rc -eq 0 ]; then fail "exit 0 for: $*"; return; fi
  if [ $rc -ge 126 ]; then fail "exit $rc (crash?) for: $*: $(head -c 2000 "$tmp/err")"; return; fi
  if grep -q "internal error" "$tmp/err"; then fail "internal error for: $*: $(cat "$tmp/err")"; return; fi
  if ! grep -qF -- "$want" "$tmp/err"; then fail "'$want' not in: $(cat "$tmp/err") (for: $*)"; return; fi
  if [ "$(wc -l <"$tmp/err")" -gt 1 ]; then fail "more than one line for: $*: $(cat "$tmp/err")"; return; fi
  ok
}

# expect_render_error "<message part>" scene.json [args...]: rendering the
# scene must stop with exit code 1 and one line naming the culprit and the problem.
expect_render_error() {
  local want=$1 scene=$2
  shift 2
  expect_error "$want" render --scene "$scene" --device cpu --spp 1 --out "$tmp/x.exr" "$@"
  [ $rc_last -eq 1 ] || fail "exit $rc_last, not 1, for $scene"
}

"$bin" --help >"$tmp/help" 2>&1 && grep -q render "$tmp/help" && ok || fail "--help"
"$bin" render --help >"$tmp/help" 2>&1 && grep -q -- "--method" "$tmp/help" && grep -q -- "--sampler" "$tmp/help" && ok ||
  fail "render --help"
expect_error "--sampler" render --scene "$data/scenes/furnace.json" --device cpu --sampler sobol --out "$tmp/s.exr"
"$bin" render --scene "$data/scenes/furnace.json" --method mis --spp 4 --width 16 --height 8 --device cpu \
  --sampler independent --out "$tmp/iid.exr" --stats "$tmp/iid.json" -q &&
  grep -q '"sampler": "independent"' "$tmp/iid.json" && ok || fail "--sampler independent in the stats"
expect_error "--frontier-colour-control" render --scene "$data/scenes/furnace.json" --device cpu \
  --frontier-colour-control maybe --out "$tmp/s.exr"
"$bin" render --scene "$data/scenes/furnace.json" --method ht-frontier --spp 4 --width 16 --height 8 --device cpu \
  --frontier-colour-control off --out "$tmp/cv.exr" --stats "$tmp/cv.json" -q &&
  grep -q '"frontier_colour_control": "off"' "$tmp/cv.json" && ok || fail "--frontier-colour-control off in the stats"
expect_error "--cut-nodes 5: -1 (by spp) or 12 to 512" render --scene "$data/scenes/furnace.json" --device cpu \
  --method ht-cut --cut-nodes 5 --out "$tmp/s.exr"
# The cut's size: 8 x spp within [192, 512] unless given.
for case in "16 -1 192" "32 -1 256" "48 -1 384" "64 -1 512" "64 100 100"; do
  read -r spp nodes want <<<"$case"
  "$bin" render --scene "$data/scenes/furnace.json" --method ht-cut --spp "$spp" --cut-nodes "$nodes" --width 4 \
    --height 2 --device cpu --out "$tmp/k.exr" --stats "$tmp/k.json" -q &&
    grep -q "\"cut_nodes\": $want," "$tmp/k.json" && ok || fail "--spp $spp --cut-nodes $nodes: not $want nodes in the stats"
done
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
assert s["device"]["type"] == "cpu" and s["sampler"] == "stratified"
PY
  else
    fail "render $m"
  fi
done

# auto says which device it picked
"$bin" render --scene "$data/scenes/furnace.json" --spp 1 --width 8 --height 8 --out "$tmp/a.exr" 2>"$tmp/err" \
  && grep -Eq "^device: (gpu|cpu reference)" "$tmp/err" && ok || fail "auto device: $(cat "$tmp/err")"

expect_error 'unknown method "nope"' render --scene "$data/scenes/furnace.json" --method nope --out "$tmp/x.exr"
expect_error "conflicts with --device cpu" render --scene "$data/scenes/furnace.json" --device cpu --gpu-index 0 \
  --out "$tmp/x.exr"
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
expect_error "fake.exr: not an OpenEXR file" render --scene "$tmp/fake-env.json" --out "$tmp/x.exr"

# ---------------------------------------------------------------------------
# Bad data through the whole command line.
for helper in "$wexr" "$whdr"; do
  if [ ! -x "$helper" ]; then
    echo "FAIL: $helper is missing (it is built with the tests)"
    exit 1
  fi
done
wexr() { "$wexr" "$@" || fail "write_test_exr $*"; }
whdr() { "$whdr" "$@" || fail "write_test_hdr $*"; }

# write_scene <env file> <scene.json> [more environment keys]: a small valid
# scene (16x8 pixels, Nside 4) lit by the given map.
write_scene() {
  cat >"$2" <<EOF
{
  "camera": { "position": [0, 0, 6], "look_at": [0, 0, 0], "fov": 35 },
  "image": { "width": 16, "height": 8 },
  "environment": { "file": "$1", "nside": 4 ${3:-} },
  "materials": { "grey": { "type": "lambert", "albedo": 0.5 } },
  "spheres": [ { "center": [0, 0, 0], "radius": 1, "material": "grey" } ],
  "planes": [ { "point": [0, -1, 0], "normal": [0, 1, 0], "material": "grey" } ]
}
EOF
}

# edit_scene <from> <to> <scene.json>: that scene under a constant map, with
# one literal change.
edit_scene() {
  write_scene "$data/env/synthetic-constant.exr" "$3"
  python3 - "$1" "$2" "$3" <<'PY' || fail "edit_scene $1"
import sys
old, new, path = sys.argv[1:]
text = open(path).read()
assert old in text, old
open(path, "w").write(text.replace(old, new, 1))
PY
}

# The scene itself is sound: with a good map it renders.
write_scene "$data/env/synthetic-constant.exr" "$tmp/good.json"
"$bin" render --scene "$tmp/good.json" --spp 1 --out "$tmp/good.exr" -q && ok || fail "the base scene does not render"

# Environment files.
write_scene "$tmp/missing.exr" "$tmp/e-missing.json"
expect_render_error "cannot open $tmp/missing.exr: No such file or directory" "$tmp/e-missing.json"
mkdir -p "$tmp/dir-env.exr"
write_scene "$tmp/dir-env.exr" "$tmp/e-dir.json"
expect_render_error "cannot open $tmp/dir-env.exr: is a directory" "$tmp/e-dir.json"
: >"$tmp/empty.exr"
write_scene "$tmp/empty.exr" "$tmp/e-empty.json"
expect_render_error "$tmp/empty.exr: not an OpenEXR file" "$tmp/e-empty.json"
printf 'P6\n8 4\n255\n' >"$tmp/ppm.exr"
write_scene "$tmp/ppm.exr" "$tmp/e-ppm.json"
expect_render_error "$tmp/ppm.exr: not an OpenEXR file" "$tmp/e-ppm.json"
size=$(stat -c %s "$data/env/studio.exr")
for cut in 6 300 1000 $((size / 2)) $((size - 1)); do
  head -c "$cut" "$data/env/studio.exr" >"$tmp/cut$cut.exr"
  write_scene "$tmp/cut$cut.exr" "$tmp/e-cut$cut.json"
  expect_render_error "$tmp/cut$cut.exr: " "$tmp/e-cut$cut.json"
  grep -q "truncated" "$tmp/err" && ok || fail "cut at $cut bytes: not called truncated: $(cat "$tmp/err")"
done
# Radiance .hdr maps. The same map as EXR and as .hdr, run-length coded or
# flat: `uniform` draws the same directions whatever the map, and its
# estimate is linear in the texels with non-negative weights, so each pixel
# differs by at most the RGBE rounding, a 256th of the texels' brightest
# channel, bounded here by the sum of the EXR render's channels / 256.
whdr --in "$data/env/sunrise.exr" --out "$tmp/sunrise.hdr"
whdr --in "$data/env/sunrise.exr" --out "$tmp/sunrise-flat.hdr" --flat
[ "$(stat -c %s "$tmp/sunrise.hdr")" -lt "$(stat -c %s "$tmp/sunrise-flat.hdr")" ] && ok ||
  fail "the run-length .hdr is not smaller than the flat one"
for map in "$data/env/sunrise.exr" "$tmp/sunrise.hdr" "$tmp/sunrise-flat.hdr"; do
  name=$(basename "$map")
  sed "s|../env/sunrise.exr|$map|" "$data/scenes/spheres.json" >"$tmp/hdr-$name.json"
  "$bin" render --scene "$tmp/hdr-$name.json" --method uniform --device cpu --spp 4 --width 64 --height 32 -q \
    --out "$tmp/hdr-$name-out.exr" --stats "$tmp/hdr-$name-out.json" || fail "render with $name"
  "$bin" export "$tmp/hdr-$name-out.exr" --out "$tmp/hdr-$name-out.pfm" || fail "export $name"
done
grep -qF "\"file\": \"$tmp/sunrise.hdr\"" "$tmp/hdr-sunrise.hdr-out.json" && ok || fail ".hdr not in the stats"
# Its memory estimate counts the file and the decoder's copy while it is read.
python3 - "$tmp/hdr-sunrise.hdr-out.json" "$(stat -c %s "$tmp/sunrise.hdr")" <<'PY' && ok || fail ".hdr decoding not in the memory estimate"
import json, sys
parts = json.load(open(sys.argv[1]))["memory"]["parts"]
assert parts["decoding the input map (while read)"] == int(sys.argv[2]) + 1024 * 512 * 12, parts
PY
"$bin" compare --ref "$tmp/hdr-sunrise.hdr-out.exr" --test "$tmp/hdr-sunrise-flat.hdr-out.exr" >"$tmp/cmp.json" &&
  python3 -c 'import json,sys; e=json.load(open(sys.argv[1])); assert e["rmse"] == 0.0, e' "$tmp/cmp.json" &&
  ok || fail "run-length and flat .hdr render differently: $(cat "$tmp/cmp.json")"
/usr/bin/python3 - "$tmp/hdr-sunrise.exr-out.pfm" "$tmp/hdr-sunrise.hdr-out.pfm" <<'PY' && ok || fail ".hdr and EXR renders differ beyond the RGBE rounding"
import sys
import numpy as np
def pfm(path):
    data = open(path, "rb").read()
    head = data.split(b"\n", 3)
    w, h = map(int, head[1].split())
    return np.frombuffer(head[3], dtype="<f4").reshape(h, w, 3).astype(np.float64)
exr, hdr = pfm(sys.argv[1]), pfm(sys.argv[2])
bound = exr.sum(axis=2, keepdims=True) / 256 + 1e-5 * exr.max()
assert exr.mean() > 0.01, exr.mean()
assert np.all(np.abs(hdr - exr) <= bound), np.abs(hdr - exr).max()
# The means agree far closer than the per-pixel bound: rounding to nearest.
assert abs(hdr.mean() - exr.mean()) <= exr.mean() / 256, (hdr.mean(), exr.mean())
PY
# Bad .hdr files: one line naming the file and what is wrong.
hdr_error() {
  local want=$1 file=$2
  write_scene "$file" "$tmp/e-hdr.json"
  expect_render_error "$file: $want" "$tmp/e-hdr.json"
}
: >"$tmp/empty.hdr"
hdr_error "empty file" "$tmp/empty.hdr"
header_end=$(grep -abo '+X 1024' "$tmp/sunrise.hdr" | head -1 | cut -d: -f1)
head -c $((header_end + 8)) "$tmp/sunrise.hdr" >"$tmp/cut-header.hdr"
hdr_error "truncated Radiance .hdr file" "$tmp/cut-header.hdr"
head -c $(($(stat -c %s "$tmp/sunrise.hdr") / 2)) "$tmp/sunrise.hdr" >"$tmp/cut-half.hdr"
hdr_error "truncated Radiance .hdr file (the scanlines end early, in row" "$tmp/cut-half.hdr"
printf '#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n-Y 2 +X 8\n' >"$tmp/no-blank.hdr"
hdr_error "truncated or corrupt Radiance header (no blank line ends it" "$tmp/no-blank.hdr"
printf 'RADIANCE\n\n-Y 2 +X 8\n' >"$tmp/no-sig.hdr"
hdr_error "not a Radiance .hdr file (no #? signature)" "$tmp/no-sig.hdr"
printf '#?RADIANCE\n\n-Y 2 +X 0\n' >"$tmp/w0.hdr"
hdr_error "empty image (0x2)" "$tmp/w0.hdr"
printf '#?RADIANCE\n\n-Y 32768 +X 32768\n' >"$tmp/huge.hdr"
hdr_error "image too large (32768x32768" "$tmp/huge.hdr"
printf '#?RADIANCE\n\n-Y 16000 +X 16000\n\002\002' >"$tmp/big.hdr"
hdr_error "truncated Radiance .hdr file (2 bytes of scanlines cannot hold 16000x16000 pixels)" "$tmp/big.hdr"
whdr --in "$data/env/synthetic-constant.exr" --out "$tmp/flipped.hdr" --resolution "+Y 32 +X 64"
hdr_error "unsupported Radiance orientation \"+Y 32 +X 64\"" "$tmp/flipped.hdr"
whdr --in "$data/env/synthetic-constant.exr" --out "$tmp/xyze.hdr" --header FORMAT=32-bit_rle_xyze
hdr_error "unsupported Radiance pixel format" "$tmp/xyze.hdr"

wexr --out "$tmp/depth.exr" --channels Z
write_scene "$tmp/depth.exr" "$tmp/e-depth.json"
expect_render_error "$tmp/depth.exr: no colour channels" "$tmp/e-depth.json"

# NaN/Inf: the number of bad values and the first one in row order.
wexr --out "$tmp/nan.exr" --set 2,3,1,inf,1 --set 5,1,nan,1,1
write_scene "$tmp/nan.exr" "$tmp/e-nan.json"
expect_render_error "$tmp/nan.exr: 2 NaN/Inf texel value(s), first at pixel (5, 1)" "$tmp/e-nan.json"
# --repair-nonfinite renders instead, warns with the count, records it.
"$bin" render --scene "$tmp/e-nan.json" --repair-nonfinite --spp 1 --out "$tmp/repaired.exr" --stats "$tmp/repaired.json" 2>"$tmp/err" \
  && grep -q "set 2 NaN/Inf texel value(s) to 0" "$tmp/err" \
  && grep -q '"repaired_nonfinite_texels": 2' "$tmp/repaired.json" && ok \
  || fail "--repair-nonfinite: $(cat "$tmp/err")"
wexr --out "$tmp/nan-half.exr" --type half --tile 4 --set 0,2,1,1,nan
write_scene "$tmp/nan-half.exr" "$tmp/e-nan-half.json"
expect_render_error "$tmp/nan-half.exr: 1 NaN/Inf texel value(s), first at pixel (0, 2)" "$tmp/e-nan-half.json"
# 70000 does not fit in a half: the file holds +Inf, refused like any Inf.
wexr --out "$tmp/inf-half.exr" --type half --set 7,3,70000
write_scene "$tmp/inf-half.exr" "$tmp/e-inf-half.json"
expect_render_error "$tmp/inf-half.exr: 3 NaN/Inf texel value(s), first at pixel (7, 3)" "$tmp/e-inf-half.json"

# Negatives: a large one is refused; tiny ones (lossy compression) are
# clamped to 0 with one warning line that counts them.
wexr --out "$tmp/neg.exr" --set 3,2,-5,1,1
write_scene "$tmp/neg.exr" "$tmp/e-neg.json"
expect_render_error "$tmp/neg.exr: negative texel value -5 at pixel (3, 2)" "$tmp/e-neg.json"
wexr --out "$tmp/tiny-neg.exr" --set 1,1,-0.001,1,1 --set 6,2,1,1,-0.002
write_scene "$tmp/tiny-neg.exr" "$tmp/e-tiny-neg.json"
if "$bin" render --scene "$tmp/e-tiny-neg.json" --spp 2 --out "$tmp/tiny-neg-out.exr" 2>"$tmp/err"; then
  [ "$(grep -c '^warning:' "$tmp/err")" -eq 1 ] &&
    grep -qF "warning: $tmp/tiny-neg.exr: clamped 2 tiny negative texel value(s) to 0" "$tmp/err" &&
    ok || fail "tiny negatives: no single warning line with the count: $(cat "$tmp/err")"
  # Clamped means rendered exactly as if those values were 0.
  wexr --out "$tmp/tiny-zero.exr" --set 1,1,0,1,1 --set 6,2,1,1,0
  write_scene "$tmp/tiny-zero.exr" "$tmp/e-tiny-zero.json"
  "$bin" render --scene "$tmp/e-tiny-zero.json" --spp 2 --out "$tmp/tiny-zero-out.exr" -q || fail "render tiny-zero"
  "$bin" compare --ref "$tmp/tiny-zero-out.exr" --test "$tmp/tiny-neg-out.exr" >"$tmp/cmp.json" &&
    python3 -c 'import json,sys; e=json.load(open(sys.argv[1])); assert e["rmse"] == 0.0, e' "$tmp/cmp.json" &&
    ok || fail "tiny negatives not rendered as zeros: $(cat "$tmp/cmp.json")"
else
  fail "tiny negatives refused: $(cat "$tmp/err")"
fi

# Finite, but with the scene's scale so bright that the renderer would overflow.
wexr --out "$tmp/bright.exr" --fill 1 --set 4,1,1e15
write_scene "$tmp/bright.exr" "$tmp/e-bright.json" ', "scale": 1e9'
expect_render_error "$tmp/bright.exr: brightest texel 1e+15 times environment.scale 1e+09 = 1e+24 exceeds 1e+20" \
  "$tmp/e-bright.json"

# An all-black map is valid: exit 0 and an image exactly zero and finite
# everywhere (NaN or Inf would make the metrics null), with every method.
wexr --out "$tmp/black.exr" --width 32 --height 16 --fill 0
write_scene "$tmp/black.exr" "$tmp/e-black.json"
wexr --out "$tmp/zero-16x8.exr" --width 16 --height 8 --fill 0
for m in $("$bin" methods | awk 'NR > 1 {print $1}'); do
  if "$bin" render --scene "$tmp/e-black.json" --method "$m" --spp 2 --out "$tmp/black-$m.exr" -q 2>"$tmp/err"; then
    "$bin" compare --ref "$tmp/zero-16x8.exr" --test "$tmp/black-$m.exr" >"$tmp/cmp.json" &&
      python3 -c '
import json, sys
e = json.load(open(sys.argv[1]))
assert e["pixels"] == 128 and e["rmse"] == 0.0 and e["relmse"] == 0.0 and e["mean_abs_rel_error"] == 0.0, e
' "$tmp/cmp.json" && ok || fail "black map, $m: not exactly zero: $(cat "$tmp/cmp.json")"
  else
    fail "black map, $m: render failed: $(cat "$tmp/err")"
  fi
done

# Scene files: the message reaches the user on one line, names the file and
# the problem, and the exit code is 1.
printf '{\n  "camera": {"position": [0, 0, 6], "look_at": [0, 0, 0]},\n  "image": {"width": 16 "height": 8},\n' \
  >"$tmp/s-syntax.json"
expect_render_error "$tmp/s-syntax.json: JSON syntax error at line 3, column 32" "$tmp/s-syntax.json"
: >"$tmp/s-empty.json"
expect_render_error "$tmp/s-empty.json: JSON syntax error at line 1, column 1" "$tmp/s-empty.json"
expect_render_error "$tmp: cannot open scene file (is a directory)" "$tmp"
edit_scene '"radius": 1,' '"radius": 1, "colour": 3,' "$tmp/s-key.json"
expect_render_error "$tmp/s-key.json: spheres[0]: unknown key \"colour\"" "$tmp/s-key.json"
edit_scene '"fov": 35' '"fov": 35, "aperture": 2' "$tmp/s-key2.json"
expect_render_error "$tmp/s-key2.json: camera: unknown key \"aperture\"" "$tmp/s-key2.json"
edit_scene '"radius": 1,' '"radius": "1",' "$tmp/s-type.json"
expect_render_error "$tmp/s-type.json: spheres[0]: \"radius\" must be a number" "$tmp/s-type.json"
edit_scene '"width": 16,' '"width": 16.5,' "$tmp/s-type2.json"
expect_render_error "$tmp/s-type2.json: image: \"width\" must be an integer" "$tmp/s-type2.json"
edit_scene '"radius": 1,' '"radius": -1,' "$tmp/s-radius.json"
expect_render_error "$tmp/s-radius.json: spheres[0]: \"radius\" = -1 is out of range (0, 1000000]" "$tmp/s-radius.json"
edit_scene '"type": "lambert", "albedo": 0.5' '"type": "ggx", "alpha": 1.5, "f0": 0.04' "$tmp/s-alpha.json"
expect_render_error "$tmp/s-alpha.json: materials.grey: \"alpha\" = 1.5 is out of range (0, 1]" "$tmp/s-alpha.json"
edit_scene '"type": "lambert", "albedo": 0.5' '"type": "ggx", "alpha": 0.0001, "f0": 0.04' "$tmp/s-alpha2.json"
expect_render_error "$tmp/s-alpha2.json: materials.grey: \"alpha\" = 0.0001 is below 0.001" "$tmp/s-alpha2.json"
edit_scene '"albedo": 0.5' '"albedo": [0.5, 1.2, 0.5]' "$tmp/s-albedo.json"
expect_render_error "$tmp/s-albedo.json: materials.grey: \"albedo\" components must lie in [0, 1]" "$tmp/s-albedo.json"
edit_scene '"nside": 4' '"nside": 100' "$tmp/s-nside.json"
expect_render_error "$tmp/s-nside.json: environment: \"nside\" = 100 is not a power of two" "$tmp/s-nside.json"
edit_scene '"nside": 4' '"nside": 18446744073709551615' "$tmp/s-nside2.json"
expect_render_error "$tmp/s-nside2.json: environment: \"nside\" = 18446744073709551615 is out of range [1, 8192]" \
  "$tmp/s-nside2.json"
edit_scene '"look_at": [0, 0, 0]' '"look_at": [0, 0, 6]' "$tmp/s-cam.json"
expect_render_error "$tmp/s-cam.json: camera: position and look_at coincide" "$tmp/s-cam.json"
edit_scene '"look_at": [0, 0, 0]' '"look_at": [0, 0, 0], "up": [0, 0, 2]' "$tmp/s-cam2.json"
expect_render_error "$tmp/s-cam2.json: camera: up must be non-zero and not parallel" "$tmp/s-cam2.json"
edit_scene '"look_at": [0, 0, 0]' '"look_at": [0, 0, 0], "up": [0, 0, 0]' "$tmp/s-cam3.json"
expect_render_error "$tmp/s-cam3.json: camera: up must be non-zero and not parallel" "$tmp/s-cam3.json"
edit_scene '"position": [0, 0, 6]' '"position": [0, 0, 1e30]' "$tmp/s-cam4.json"
expect_render_error "$tmp/s-cam4.json: camera: position and look_at too far apart" "$tmp/s-cam4.json"
edit_scene '"fov": 35' '"fov": 180' "$tmp/s-fov.json"
expect_render_error "$tmp/s-fov.json: camera: \"fov\" = 180 is out of range (0, 179]" "$tmp/s-fov.json"
edit_scene '"width": 16,' '"width": 0,' "$tmp/s-width.json"
expect_render_error "$tmp/s-width.json: image: \"width\" = 0 is out of range [1, 16384]" "$tmp/s-width.json"
edit_scene '"height": 8' '"height": -8' "$tmp/s-height.json"
expect_render_error "$tmp/s-height.json: image: \"height\" = -8 is out of range [1, 16384]" "$tmp/s-height.json"
edit_scene '"material": "grey" } ]' '"material": "gray" } ]' "$tmp/s-mat.json"
expect_render_error "$tmp/s-mat.json: spheres[0]: unknown material \"gray\"" "$tmp/s-mat.json"
write_scene "$data/env/synthetic-constant.exr" "$tmp/s-noenv.json"
python3 - "$tmp/s-noenv.json" <<'PY' || fail "s-noenv.json"
import json, sys
s = json.load(open(sys.argv[1]))
del s["environment"]
json.dump(s, open(sys.argv[1], "w"), indent=1)
PY
expect_render_error "$tmp/s-noenv.json: missing key \"environment\"" "$tmp/s-noenv.json"

# Outputs. Root passes access(2) for any directory, so a read-only directory
# is tried as an unprivileged user where possible, and /proc (where no file
# can be created) always. Some of these fail only after rendering: -q keeps
# the progress lines out of stderr.
furnace="$data/scenes/furnace.json"
small=(--scene "$furnace" --spp 1 --width 8 --height 4 -q)
expect_error "cannot write /proc/ht-$$.exr: No such file or directory" render "${small[@]}" --out "/proc/ht-$$.exr"
[ $rc_last -eq 1 ] || fail "/proc: exit $rc_last, not 1"
if [ "$(id -u)" -eq 0 ]; then
  ro=$(mktemp -d)
  chmod 555 "$ro"
  if command -v setpriv >/dev/null &&
      setpriv --reuid=65534 --regid=65534 --clear-groups "$bin" methods >/dev/null 2>&1; then
    setpriv --reuid=65534 --regid=65534 --clear-groups "$bin" render "${small[@]}" --out "$ro/x.exr" 2>"$tmp/err"
    rc=$?
    [ $rc -eq 1 ] && grep -qF "$ro: output directory is not writable" "$tmp/err" &&
      [ "$(wc -l <"$tmp/err")" -eq 1 ] && [ ! -e "$ro/x.exr" ] &&
      ok || fail "read-only directory (as nobody): exit $rc: $(cat "$tmp/err")"
  else
    echo "note: $bin cannot run as nobody here; read-only directories are checked through /proc only"
  fi
  rmdir "$ro"
fi
touch "$tmp/plain"
expect_error "$tmp/plain" render "${small[@]}" --out "$tmp/plain/x.exr"
mkdir -p "$tmp/out-dir.exr"
expect_error "cannot write $tmp/out-dir.exr: Is a directory" render "${small[@]}" --out "$tmp/out-dir.exr"
[ -d "$tmp/out-dir.exr" ] && ok || fail "the directory given as output was removed"
mkdir -p "$tmp/preview.png"
expect_error "cannot write $tmp/preview.png" render "${small[@]}" --out "$tmp/preview.exr"
expect_error "does not exist" render "${small[@]}" --out "$tmp/y.exr" --stats "$tmp/missing/s.json"
# A full disk: small images sit in buffers until the file is closed, and
# OpenEXR writes its offset table from a destructor; neither may fail silently,
# nor leave anything behind.
ln -s /dev/full "$tmp/full.exr"
expect_error "cannot write $tmp/full.exr: No space left on device" render "${small[@]}" --out "$tmp/full.exr"
ln -s /dev/full "$tmp/full-big.exr"
expect_error "cannot write $tmp/full-big.exr: No space left on device" render --scene "$furnace" --spp 1 \
  --width 512 --height 256 -q --out "$tmp/full-big.exr"
[ -c /dev/full ] && [ -L "$tmp/full.exr" ] && ok || fail "/dev/full or the link to it was replaced"

# Every output is written to a temporary next to it and renamed into place
# once all of them are complete; anything unwritable is refused before
# rendering (stderr then holds only the error: no progress line).
no_temporaries() { ! ls -A "$1" | grep -q '\.tmp\.' || fail "temporary files left in $1: $(ls -A "$1")"; }
"$bin" render "${small[@]}" --out "$tmp/keep.exr" || fail "render keep.exr"
keep=$(md5sum <"$tmp/keep.exr")
unchanged() { [ "$(md5sum <"$tmp/keep.exr")" = "$keep" ] && ok || fail "keep.exr was replaced: $*"; }
quiet_small=(--scene "$furnace" --spp 1 --width 8 --height 4 --device cpu)
expect_error "cannot write /dev/full: No space left on device" render "${small[@]}" --out "$tmp/df.exr" --stats /dev/full
[ ! -e "$tmp/df.exr" ] && [ ! -e "$tmp/df.png" ] && ok || fail "--stats /dev/full: the images were still written"
expect_error "cannot write /dev/full: No space left on device" export "$tmp/keep.exr" --out /dev/full
expect_error "cannot write $tmp/full.exr: No space left on device" export "$tmp/keep.exr" --out "$tmp/full.exr"
[ -L "$tmp/full.exr" ] && ok || fail "export replaced the link to /dev/full"
"$bin" export "$tmp/keep.exr" --out "$tmp/keep.pfm" && [ "$(head -c 11 "$tmp/keep.pfm")" = "$(printf 'PF\n8 4\n-1.0')" ] &&
  [ "$(stat -c %s "$tmp/keep.pfm")" -eq $((12 + 8 * 4 * 12)) ] && ok || fail "export to a file"
expect_error "--out and --stats name the same file $tmp/keep.exr" render "${quiet_small[@]}" --out "$tmp/keep.exr" \
  --stats "$tmp/keep.exr"
unchanged "--stats = --out"
mkdir -p "$tmp/sub"
expect_error "name the same file" render "${quiet_small[@]}" --out "$tmp/keep.exr" --stats "$tmp/sub/../keep.png"
unchanged "--stats = the PNG preview"
ln -sf "$tmp/keep.exr" "$tmp/link.json"
expect_error "name the same file" render "${quiet_small[@]}" --out "$tmp/keep.exr" --stats "$tmp/link.json"
unchanged "--stats links to --out"
mv "$tmp/keep.png" "$tmp/keep-preview.png" && mkdir "$tmp/keep.png"
expect_error "cannot write $tmp/keep.png: Is a directory" render "${quiet_small[@]}" --out "$tmp/keep.exr"
unchanged "the PNG preview is a directory"
rmdir "$tmp/keep.png"
mkdir -p "$tmp/stats-dir.json"
expect_error "cannot write $tmp/stats-dir.json: Is a directory" render "${quiet_small[@]}" --out "$tmp/keep.exr" \
  --stats "$tmp/stats-dir.json"
unchanged "the stats path is a directory"
expect_error "cannot write /proc/ht-$$.json: No such file or directory" render "${quiet_small[@]}" \
  --out "$tmp/keep.exr" --stats "/proc/ht-$$.json"
unchanged "the stats path cannot be created"
expect_error "$tmp/missing: output directory does not exist" export "$tmp/keep.exr" --out "$tmp/missing/x.pfm"
no_temporaries "$tmp"

# A signal between writing the temporaries and renaming them (the test hook
# holds there), and one while a large EXR is being written: the old file
# stays, nothing partial is left, the process dies of that signal.
/usr/bin/python3 - "$bin" "$furnace" "$tmp/sig" <<'PY' && ok || fail "signals"
import hashlib, os, signal, subprocess, sys, time
binary, scene, d = sys.argv[1:]
os.makedirs(d)
target = os.path.join(d, "img.exr")
base = [binary, "render", "--scene", scene, "--device", "cpu", "--spp", "1", "-q", "--out", target]
subprocess.run(base + ["--width", "8", "--height", "4"], check=True)
digest = lambda p: hashlib.md5(open(p, "rb").read()).hexdigest()
old = digest(target)
def temporaries():
    return [f for f in os.listdir(d) if ".tmp." in f]
for sig in (signal.SIGTERM, signal.SIGINT):
    env = dict(os.environ, HTRENDER_TEST_HOLD_BEFORE_RENAME="60")
    p = subprocess.Popen(base + ["--width", "64", "--height", "32", "--stats", os.path.join(d, "s.json")],
                         env=env, stderr=subprocess.PIPE, text=True)
    line = p.stderr.readline()
    assert line.startswith("holding "), line
    held = line.split(" ", 1)[1].strip()
    assert os.path.getsize(held) > 0, held
    p.send_signal(sig)
    assert p.wait(timeout=30) == -sig, (sig, p.returncode)
    assert digest(target) == old, "the old image was replaced"
    assert not temporaries(), temporaries()
    assert not os.path.exists(os.path.join(d, "s.json"))
# No hook: a real signal once the large EXR's temporary has started to
# fill. Should the render win the race and finish first, the new image must
# be whole; either way nothing partial may be left.
p = subprocess.Popen(base + ["--method", "uniform", "--width", "4096", "--height", "2048"], stderr=subprocess.PIPE)
deadline = time.time() + 300
while p.poll() is None and time.time() < deadline:
    if any(f.startswith(".img.exr.") and os.path.getsize(os.path.join(d, f)) > 0 for f in temporaries()):
        p.send_signal(signal.SIGTERM)
        break
    time.sleep(0.001)
rc = p.wait(timeout=300)
assert not temporaries(), temporaries()
if rc == -signal.SIGTERM:
    assert digest(target) == old, "the old image was replaced by a partial one"
else:
    assert rc == 0, rc
    r = subprocess.run([binary, "compare", "--ref", target, "--test", target], capture_output=True, text=True)
    assert r.returncode == 0 and '"pixels":8388608' in r.stdout, r
    print("note: the large render finished before the signal", file=sys.stderr)
PY

# Memory: the estimate is checked against --max-memory (default: 80% of the
# available memory) before anything large is allocated.
edit_scene '"nside": 4' '"nside": 8192' "$tmp/s-8192.json"
expect_render_error "not enough memory: this render needs about" "$tmp/s-8192.json" --method mis --max-memory 16G
grep -qE "needs about 2[0-9]\.[0-9] GiB .*more than the limit of 16\.0 GiB \(--max-memory\)" "$tmp/err" && ok ||
  fail "nside 8192: need and limit not named: $(cat "$tmp/err")"
expect_render_error "more than the limit of 512.0 MiB" "$tmp/s-8192.json" --method ht --max-memory 512M
expect_render_error '--max-memory: "lots" is not a size' "$tmp/s-8192.json" --max-memory lots
expect_render_error '--max-memory: "-1G" is not a size' "$tmp/s-8192.json" --max-memory=-1G
# A moderate case: the peak resident set measured by the process lies
# within a factor 1.5 of the estimate either way (recorded in the stats).
# Not under AddressSanitizer, whose shadow memory and quarantine add to the
# resident set and are no part of a render's needs.
edit_scene '"nside": 4' '"nside": 512' "$tmp/s-512.json"
for m in mis ht; do
  "$bin" render --scene "$tmp/s-512.json" --method $m --device cpu --spp 1 -q --out "$tmp/m.exr" \
    --stats "$tmp/m.json" --max-memory 2G && SANITIZED=${ASAN_OPTIONS:+1} /usr/bin/python3 - "$tmp/m.json" <<'PY' && ok || fail "memory estimate, $m"
import json, os, sys
m = json.load(open(sys.argv[1]))["memory"]
ratio = m["peak_rss_bytes"] / m["estimate_bytes"]
assert m["limit_bytes"] == 2 << 30, m
assert os.environ.get("SANITIZED") or 1 / 1.5 <= ratio <= 1.5, (ratio, m)
PY
done
expect_render_error "HT node geometry 80.0 MiB" "$tmp/s-512.json" --method ht --max-memory 100M

# Command-line values.
expect_error "--spp: Value -3 not in range" render --scene "$furnace" --spp -3 --out "$tmp/x.exr"
expect_error "--width: Value -5 not in range" render --scene "$furnace" --width -5 --out "$tmp/x.exr"
expect_error "--height: Value 0 not in range" render --scene "$furnace" --height 0 --out "$tmp/x.exr"
expect_error "--seed = abc" render --scene "$furnace" --seed abc --out "$tmp/x.exr"
expect_error "--seed = -1" render --scene "$furnace" --seed -1 --out "$tmp/x.exr"
expect_error "--exposure = bright" render --scene "$furnace" --exposure bright --out "$tmp/x.exr"
expect_error "--device" render --scene "$furnace" --device tpu --out "$tmp/x.exr"
expect_error "--gpu-index: Value -1 not in range 0 to 255" render --scene "$furnace" --gpu-index -1 --out "$tmp/x.exr"
expect_error "--ref" compare --test "$tmp/zero-16x8.exr"
expect_error "cannot open $tmp/none.exr" compare --ref "$tmp/none.exr" --test "$tmp/zero-16x8.exr"
expect_error "differs from the reference" compare --ref "$tmp/black.exr" --test "$tmp/zero-16x8.exr"

echo "cli: $passes passed, $failures failed"
[ $failures -eq 0 ]
