#!/usr/bin/env bash
# The bench and report tooling end to end on a tiny configuration, so that it
# keeps working: tools/bench.py (three methods, 1 and 4 spp, both samplers, 32x16, one run, a
# low-spp reference, on a copy of spheres.json with a small environment
# Nside), tools/scaling.py (one short sweep) and tools/report.py into a
# temporary folder; then checks that the outputs exist and are sane.
# Usage: bench_test.sh HTRENDER SOURCE_DIR
set -euo pipefail
htrender=$(realpath "$1")
src=$(realpath "$2")
py=/usr/bin/python3
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

$py - "$src/data/scenes/spheres.json" "$tmp/scene.json" <<'EOF'
import json, sys
from pathlib import Path
scene = json.loads(Path(sys.argv[1]).read_text())
env = scene["environment"]
env["file"] = str((Path(sys.argv[1]).parent / env["file"]).resolve())
env["nside"] = 64
Path(sys.argv[2]).write_text(json.dumps(scene))
EOF

$py "$src/tools/bench.py" --htrender "$htrender" --scene "$tmp/scene.json" --methods mis,ht-vis,ht-frontier --spp 1,4 \
  --samplers stratified,independent --runs 1 --width 32 --height 16 --ref-spp 256 --out "$tmp/bench" 2> "$tmp/bench.log" ||
  { cat "$tmp/bench.log"; exit 1; }
$py "$src/tools/scaling.py" --htrender "$htrender" --scene "$tmp/scene.json" --methods mis --sweeps spp,spheres \
  --spp 1,4 --width 16 --height 8 --spheres 1,20 --sphere-methods mis --sphere-devices cpu --sphere-size 16x8 \
  --out "$tmp/scaling" 2> "$tmp/scaling.log" ||
  { cat "$tmp/scaling.log"; exit 1; }
mkdir -p "$tmp/report" && echo keep > "$tmp/report/other.png"
$py "$src/tools/report.py" --htrender "$htrender" --bench "$tmp/bench" --stress "$tmp/bench" \
  --scaling "$tmp/scaling" --out "$tmp/report" 2> "$tmp/report.log" || { cat "$tmp/report.log"; exit 1; }

$py - "$tmp" <<'EOF'
import json, math, sys
from pathlib import Path
tmp = Path(sys.argv[1])
def check(cond, what):
    if not cond:
        sys.exit(f"bench_test: FAILED: {what}")
for f in ("bench/results.json", "bench/results.csv", "bench/results.md", "scaling/scaling.json",
          "scaling/scaling.csv", "report/README.md", "report/scene-charts.png", "report/scaling.png"):
    check((tmp / f).is_file() and (tmp / f).stat().st_size > 0, f"{f} exists")
res = json.loads((tmp / "bench/results.json").read_text())
rows = res["results"]
check(len(rows) == 12, f"12 result rows, got {len(rows)}")
check({(r["method"], r["sampler"], r["spp"]) for r in rows}
      == {(m, x, s) for m in ("mis", "ht-vis", "ht-frontier") for x in ("stratified", "independent") for s in (1, 4)},
      "rows")
check(len({r["file"] for r in rows}) == 12, "one EXR per point")
check(all(r["samples_per_pixel"] == r["spp"] for r in rows if r["method"] == "ht-frontier"),
      "ht-frontier draws exactly spp directions per pixel")
for r in rows:
    for k in ("rmse", "relmse", "seconds"):
        check(math.isfinite(r[k]) and r[k] >= 0, f"{r['method']} {r['spp']} spp: {k} = {r[k]} finite")
    check(r["rmse"] > 0, f"{r['method']} {r['spp']} spp: rmse > 0")
    check(isinstance(r["fireflies"], int) and 0 <= r["fireflies"] <= 32 * 16, "fireflies counted")
    check((tmp / "bench" / r["file"]).is_file(), f"{r['file']} kept")
mis = {r["spp"]: r["rmse"] for r in rows if r["method"] == "mis" and r["sampler"] == "stratified"}
check(mis[4] < mis[1], f"mis error falls from 1 to 4 spp ({mis[1]:.4f} -> {mis[4]:.4f})")
ref = next(iter(res["references"].values()))
check(math.isfinite(ref["residual_rmse"]) and ref["residual_rmse"] < mis[4], "reference residual below the 4 spp error")
sc = json.loads((tmp / "scaling/scaling.json").read_text())["results"]
check(len(sc) == 4 and all(r["seconds"] >= 0 and r["environment_trees"] >= 0 for r in sc), "scaling rows")
check([(r["sweep"], r["method"], r["x"]) for r in sc if r["sweep"] == "spheres"] ==
      [("spheres", "mis (cpu)", 1), ("spheres", "mis (cpu)", 20)], "sphere sweep rows")
check(all(len(r["seconds_runs"]) == (3 if r["sweep"] == "spheres" else 1) for r in sc),
      "three renders per sphere sweep point, one elsewhere")
md = (tmp / "report/README.md").read_text()
check("| spheres | mis (cpu) |" in md, "sphere sweep table")
for s in ("## scene", "slide 52", "Stress scenes", "## Scaling", "ht-vis", "Efficiency against `mis` at 4 spp",
          "`ht-frontier` against `mis`", "Stratified against independent"):
    check(s in md, f"report mentions {s!r}")
check(sum(f.stat().st_size for f in (tmp / "report").iterdir()) < 2_000_000, "report is small")
check(not list((tmp / "report").glob("*.exr")), "no EXRs in the report")
check((tmp / "report/other.png").read_text() == "keep\n", "the report leaves files it did not write")
print("bench_test: ok")
EOF
