#!/usr/bin/python3
"""Error against time for every method, measured side by side in one run.

Renders scene x method x spp with `htrender render`, times each render
(median of --runs after one warm-up run that is not counted), and measures
its error against a converged reference: RMSE, relative MSE and mean absolute
relative error (`htrender compare`). Writes results.csv, results.json (with
the machine, device, build and settings) and results.md into --out.

The reference is the mean of two independent renders (different seeds) by an
unbiased method at high spp, cached under --out keyed by scene content,
resolution, method, spp and htrender version. Its own residual RMSE is
estimated from the difference of its two halves and reported.
"""
import argparse
import hashlib
import json
import os
import platform
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def run(cmd):
    res = subprocess.run(cmd, capture_output=True, text=True)
    if res.returncode != 0:
        sys.exit(f"bench: command failed: {' '.join(map(str, cmd))}\n{res.stderr.strip()}")
    return res.stdout


def render(args, scene, method, spp, seed, out, extra=()):
    stats = out.with_suffix(".json")
    cmd = [args.htrender, "render", "--scene", scene, "--method", method, "--spp", str(spp), "--seed", str(seed),
           "--device", args.device, "--out", str(out), "--stats", str(stats), "-q", *extra]
    if args.width:
        cmd += ["--width", str(args.width)]
    if args.height:
        cmd += ["--height", str(args.height)]
    run(cmd)
    return json.loads(stats.read_text())


def compare(args, ref, test):
    return json.loads(run([args.htrender, "compare", "--ref", str(ref), "--test", str(test)]))


def average_exr(args, a, b, out):
    run([args.htrender, "average", "--out", str(out), str(a), str(b)])


def reference(args, scene, outdir):
    text = Path(scene).read_bytes()
    version = run([args.htrender, "--version"]).strip()
    key = hashlib.sha256(b"|".join([text, str(args.width).encode(), str(args.height).encode(),
                                    args.ref_method.encode(), str(args.ref_spp).encode(),
                                    version.encode()])).hexdigest()[:16]
    ref = outdir / f"ref-{Path(scene).stem}-{key}.exr"
    meta = ref.with_suffix(".meta.json")
    if ref.exists() and meta.exists():
        return ref, json.loads(meta.read_text())
    print(f"bench: reference {ref.name}: {args.ref_method} at {args.ref_spp} spp (two halves)", file=sys.stderr)
    half = max(1, args.ref_spp // 2)
    a, b = outdir / f"{ref.stem}-a.exr", outdir / f"{ref.stem}-b.exr"
    sa = render(args, scene, args.ref_method, half, 1000001, a)
    render(args, scene, args.ref_method, half, 2000003, b)
    average_exr(args, a, b, ref)
    # Each half has error e, their difference sqrt(2) e, their mean e / sqrt(2).
    diff = compare(args, a, b)
    info = {"method": args.ref_method, "spp": 2 * half, "version": version, "key": key,
            "width": sa["width"], "height": sa["height"],
            "residual_rmse": diff["rmse"] / 2.0, "residual_relmse": diff["relmse"] / 4.0}
    meta.write_text(json.dumps(info, indent=2))
    for p in (a, b, a.with_suffix(".json"), b.with_suffix(".json"), a.with_suffix(".png"), b.with_suffix(".png")):
        p.unlink(missing_ok=True)
    return ref, info


def machine():
    cpu = "unknown"
    try:
        for line in open("/proc/cpuinfo"):
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return {"cpu": cpu, "cores": os.cpu_count(), "system": platform.platform()}


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--scene", action="append", help="scene JSON (repeatable); default data/scenes/spheres.json")
    p.add_argument("--methods", default="env,brdf,mis,ht,ht-vis,ht-biased,ht-vis-biased")
    p.add_argument("--spp", default="4,16,64,256")
    p.add_argument("--runs", type=int, default=3, help="timed runs per point (median); one warm-up run first")
    p.add_argument("--device", default="cpu")
    p.add_argument("--width", type=int, default=0)
    p.add_argument("--height", type=int, default=0)
    p.add_argument("--ref-method", default="mis")
    p.add_argument("--ref-spp", type=int, default=4096)
    p.add_argument("--extra", default="", help="extra render arguments, e.g. '--brdf-bounds table'")
    p.add_argument("--label", default="", help="suffix for method names in the results (with --extra)")
    p.add_argument("--htrender", default=str(ROOT / "build" / "htrender"))
    p.add_argument("--out", default=str(ROOT / "out" / "bench"))
    args = p.parse_args()

    outdir = Path(args.out)
    outdir.mkdir(parents=True, exist_ok=True)
    scenes = args.scene or [str(ROOT / "data" / "scenes" / "spheres.json")]
    methods = [m for m in args.methods.split(",") if m]
    spps = [int(s) for s in args.spp.split(",") if s]
    extra = args.extra.split()
    rows = []
    refs = {}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        for scene in scenes:
            ref, refinfo = reference(args, scene, outdir)
            refs[scene] = {"file": str(ref), **refinfo}
            for method in methods:
                for spp in spps:
                    img = outdir / f"{Path(scene).stem}-{method}{args.label}-{spp}.exr"
                    render(args, scene, method, spp, 1, tmp / "warmup.exr", extra)
                    times, gpu_times, stats = [], [], None
                    for k in range(args.runs):
                        stats = render(args, scene, method, spp, 1 + k, img if k == 0 else tmp / "run.exr", extra)
                        times.append(stats["seconds"]["render"])
                        if "gpu" in stats["seconds"]:
                            gpu_times.append(stats["seconds"]["gpu"])
                    err = compare(args, ref, img)
                    row = {"scene": Path(scene).stem, "method": method + args.label, "spp": spp,
                           "seconds": statistics.median(times), "seconds_runs": times,
                           "gpu_seconds": statistics.median(gpu_times) if gpu_times else None,
                           "device": stats["device"]["name"], "samples_per_pixel": stats["mean_samples_per_pixel"],
                           **err}
                    rows.append(row)
                    print(f"{row['scene']:>10} {row['method']:>14} {spp:>5} spp  {row['seconds']:8.3f} s  "
                          f"rmse {err['rmse']:.4f}  relmse {err['relmse']:.5f}", file=sys.stderr)

    build = {}
    cache = ROOT / "build" / "CMakeCache.txt"
    if cache.exists():
        for line in cache.read_text().splitlines():
            if line.startswith("CMAKE_BUILD_TYPE:"):
                build["type"] = line.split("=", 1)[1]
    result = {"machine": machine(), "build": build, "device": args.device, "runs": args.runs,
              "extra": args.extra, "references": refs, "results": rows}
    (outdir / "results.json").write_text(json.dumps(result, indent=2))
    cols = ["scene", "method", "spp", "seconds", "samples_per_pixel", "rmse", "relmse", "mean_abs_rel_error", "device"]
    with open(outdir / "results.csv", "w") as f:
        f.write(",".join(cols) + "\n")
        for r in rows:
            f.write(",".join(str(r[c]) for c in cols) + "\n")
    with open(outdir / "results.md", "w") as f:
        f.write(f"Machine: {result['machine']['cpu']}, {result['machine']['cores']} cores; device {args.device}; "
                f"median of {args.runs} runs after a warm-up.\n\n")
        for scene, info in refs.items():
            f.write(f"Reference for {Path(scene).name}: {info['method']} at {info['spp']} spp, "
                    f"residual RMSE about {info['residual_rmse']:.4f}.\n\n")
        f.write("| scene | method | spp | render s | samples/px | RMSE | relMSE | mean abs rel err |\n")
        f.write("|---|---|---|---|---|---|---|---|\n")
        for r in rows:
            f.write(f"| {r['scene']} | {r['method']} | {r['spp']} | {r['seconds']:.3f} | {r['samples_per_pixel']:.1f} "
                    f"| {r['rmse']:.4f} | {r['relmse']:.5f} | {r['mean_abs_rel_error']:.4f} |\n")
    print(f"bench: wrote {outdir}/results.{{csv,json,md}}", file=sys.stderr)


if __name__ == "__main__":
    main()
