#!/usr/bin/env python3
"""The real-GPU check's table: from a tools/bench.py run on one GPU, writes
<out>/<device>.md (GPU ms, relMSE and efficiency 1 / (relMSE x GPU time)
against `mis` at the same spp, per method) and <out>/<device>.json (the
run's results, which tools/report.py's "A real GPU" section reads).

    tools/gpu_table.py --results out/bench/results.json --out docs/report/gpu
"""
import argparse
import json
import re
import shutil
import sys
from pathlib import Path


def slug(name):
    return re.sub(r"[^a-z0-9]+", "-", name.lower()).strip("-") or "gpu"


def table(data):
    rows = [r for r in data["results"] if r.get("device", "cpu") != "cpu"]
    if not rows:
        raise SystemExit("gpu_table: the run has no GPU rows")
    names = sorted({r["device_name"] for r in rows})
    if len(names) != 1:
        raise SystemExit(f"gpu_table: the run has rows of several devices: {', '.join(names)}")
    mis = {r["spp"]: r for r in rows if r["method"] == "mis"}
    r0 = rows[0]
    ref = next(iter(data["references"].values()), {})
    md = [f"# {r0['device_name']}", "",
          f"{r0['device_name']} ({r0.get('device_driver', '')}): spheres.json at {data['width']}x{data['height']}, "
          f"the fastest of {data.get('gpu_runs') or data['runs']} timed runs per point after a warm-up, the methods "
          f"side by side in one run of tools/bench.py (tools/gpu-check.sh). Reference: {ref.get('method', '?')} at "
          f"{ref.get('spp', '?')} spp on the same device, residual relMSE about {ref.get('residual_relmse', 0):.1e}. "
          "GPU ms: the timestamp queries around the dispatches. Efficiency: 1 / (relMSE x GPU time) against "
          "`mis`'s at the same spp.", "",
          "| method | spp | GPU ms | wall ms | relMSE | efficiency vs mis |", "|---|---|---|---|---|---|"]
    for r in rows:
        g = r.get("gpu_seconds")
        base = mis.get(r["spp"])
        eff = "-"
        if g and base and base.get("gpu_seconds") and r["relmse"] > 0:
            eff = f"{(base['relmse'] * base['gpu_seconds']) / (r['relmse'] * g):.3g}x"
        md.append(f"| {r['method']} | {r['spp']} | {f'{1e3 * g:.2f}' if g is not None else '-'} | "
                  f"{1e3 * r['seconds']:.1f} | {r['relmse']:.3e} | {eff} |")
    return r0["device_name"], "\n".join(md) + "\n"


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--results", required=True, help="results.json of tools/bench.py")
    p.add_argument("--out", required=True, help="folder for <device>.md and <device>.json")
    args = p.parse_args()
    data = json.loads(Path(args.results).read_text())
    name, md = table(data)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / f"{slug(name)}.md").write_text(md)
    shutil.copyfile(args.results, out / f"{slug(name)}.json")
    sys.stdout.write(md)
    print(f"gpu_table: wrote {out / (slug(name) + '.md')} and {out / (slug(name) + '.json')}", file=sys.stderr)


if __name__ == "__main__":
    main()
