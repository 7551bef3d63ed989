#!/usr/bin/python3
"""How render and setup times scale, measured side by side in one run.

    tools/scaling.py --out out/scaling [--quick]

Four sweeps over a scene (default data/scenes/spheres.json), each point the
median of --runs renders:

  spp     render time against samples per pixel, per method;
  nside   render time and environment setup against the environment's
          HEALPix Nside (64..512; temporary scene copies with the map's
          absolute path);
  size    render time against image size (pixels);
  tree    the environment stage split into load / resample / trees for the
          scene's 1024x512 map and for a generated 8192x4096 map
          (`make_env sky-sun`), at each --tree-nside, rendered at 1x1 so the
          render itself costs nothing;
  spheres render time against the number of spheres of a sphere field
          (tools/sphere_field.py under sunrise.exr), per method and device
          (--sphere-methods, --sphere-devices).

Writes scaling.csv (one row per point: sweep, method, x, seconds, ...) and
scaling.json (settings, machine and the same rows) into --out.
"""
import argparse
import json
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench import csv_text, machine, write_atomic  # noqa: E402
from sphere_field import field_scene  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent


def ints(s):
    return [int(x) for x in s.split(",") if x]


def render(args, scene, method, spp, width, height, tmp, seed=1, device=None):
    out = tmp / "render.exr"
    stats = tmp / "render.json"
    cmd = [args.htrender, "render", "--scene", str(scene), "--method", method, "--spp", str(spp), "--seed", str(seed),
           "--device", device or args.device, "--width", str(width), "--height", str(height), "--out", str(out),
           "--stats", str(stats), "-q"]
    res = subprocess.run([str(c) for c in cmd], capture_output=True, text=True)
    if res.returncode != 0:
        sys.exit(f"scaling: command failed: {' '.join(map(str, cmd))}\n{res.stderr.strip()}")
    return json.loads(stats.read_text())


def point(args, sweep, scene, method, x, spp, width, height, tmp, runs=None, device=None, label=None):
    all_stats = [render(args, scene, method, spp, width, height, tmp, seed=1 + k, device=device)
                 for k in range(runs or args.runs)]
    med = lambda key: statistics.median(s["seconds"].get(key, 0.0) or 0.0 for s in all_stats)  # noqa: E731
    row = {"sweep": sweep, "method": label or method, "x": x, "spp": spp, "width": width, "height": height,
           "nside": all_stats[0]["environment"]["nside"], "seconds": med("render"),
           "seconds_runs": [s["seconds"]["render"] for s in all_stats],
           "environment": med("environment"), "environment_load": med("environment_load"),
           "environment_resample": med("environment_resample"), "environment_trees": med("environment_trees"),
           "prepare": med("prepare"), "samples_per_pixel": all_stats[0]["mean_samples_per_pixel"]}
    print(f"scaling: {sweep:>7} {row['method']:>20} x={x:<9} render {row['seconds']:8.3f} s  env {row['environment']:.3f} s "
          f"(load {row['environment_load']:.3f}, resample {row['environment_resample']:.3f}, "
          f"trees {row['environment_trees']:.4f})", file=sys.stderr)
    return row


def scene_copy(scene, tmp, name, env_file=None, nside=None):
    """The scene with an absolute environment path (and optionally another map or Nside)."""
    data = json.loads(Path(scene).read_text())
    env = data["environment"]
    env["file"] = str(Path(env_file).resolve()) if env_file else str((Path(scene).parent / env["file"]).resolve())
    if nside:
        env["nside"] = nside
    path = tmp / f"{name}.json"
    path.write_text(json.dumps(data, indent=2))
    return path


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--scene", default=str(ROOT / "data" / "scenes" / "spheres.json"))
    p.add_argument("--methods", default="mis,ht,ht-vis", help="methods of the spp, nside and size sweeps")
    p.add_argument("--spp", default="1,4,16,64,256", help="the spp sweep")
    p.add_argument("--nside", default="64,128,256,512", help="the Nside sweep")
    p.add_argument("--sizes", default="60x30,120x60,240x120,480x240", help="the image size sweep")
    p.add_argument("--width", type=int, default=120, help="image width of the spp and nside sweeps")
    p.add_argument("--height", type=int, default=60)
    p.add_argument("--sweep-spp", type=int, default=16, help="spp of the nside and size sweeps")
    p.add_argument("--tree-nside", default="256,512", help="Nsides of the tree-build sweep")
    p.add_argument("--big-map", default="8192x4096", help="size of the generated map of the tree-build sweep")
    p.add_argument("--spheres", default="1,16,128,1024,8192", help="the sphere-count sweep")
    p.add_argument("--sphere-methods", default="mis,ht-vis,ht-frontier,ht-cut")
    p.add_argument("--sphere-devices", default="cpu,gpu")
    p.add_argument("--sphere-size", default="128x64", help="image size of the sphere-count sweep")
    p.add_argument("--sphere-runs", type=int, default=3,
                   help="renders per point of the sphere-count sweep, whose renders are short")
    p.add_argument("--sweeps", default="spp,nside,size,tree,spheres")
    p.add_argument("--runs", type=int, default=1)
    p.add_argument("--device", default="cpu")
    p.add_argument("--htrender", default=str(ROOT / "build" / "htrender"))
    p.add_argument("--make-env", default=str(ROOT / "build" / "make_env"))
    p.add_argument("--out", default=str(ROOT / "out" / "scaling"))
    args = p.parse_args()
    outdir = Path(args.out)
    outdir.mkdir(parents=True, exist_ok=True)
    methods = [m for m in args.methods.split(",") if m]
    sweeps = set(args.sweeps.split(","))
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        base = scene_copy(args.scene, tmp, "scene")
        if "spp" in sweeps:
            for m in methods:
                for spp in ints(args.spp):
                    rows.append(point(args, "spp", base, m, spp, spp, args.width, args.height, tmp))
        if "nside" in sweeps:
            for n in ints(args.nside):
                sc = scene_copy(args.scene, tmp, f"nside{n}", nside=n)
                for m in methods:
                    rows.append(point(args, "nside", sc, m, n, args.sweep_spp, args.width, args.height, tmp))
        if "size" in sweeps:
            for size in args.sizes.split(","):
                w, h = map(int, size.split("x"))
                for m in methods:
                    rows.append(point(args, "size", base, m, w * h, args.sweep_spp, w, h, tmp))
        if "tree" in sweeps:
            small = tmp / "map-1024x512.exr"
            bw, bh = map(int, args.big_map.split("x"))
            big = tmp / f"map-{bw}x{bh}.exr"
            for path, (w, h) in ((small, (1024, 512)), (big, (bw, bh))):
                subprocess.run([args.make_env, "sky-sun", "--sky", "0.4", "0.6", "1.0", "--ground", "0.1",
                                "--sun-radiance", "20000", "--sun-radius-deg", "1", "--theta", "50", "--phi", "120",
                                "--width", str(w), "--height", str(h), "--out", str(path)], check=True,
                               stdout=subprocess.DEVNULL)
            for label, path in (("1024x512", small), (f"{bw}x{bh}", big)):
                for n in ints(args.tree_nside):
                    sc = scene_copy(args.scene, tmp, f"tree-{label}-{n}", env_file=path, nside=n)
                    row = point(args, "tree", sc, "uniform", n, 1, 1, 1, tmp, runs=max(1, args.runs))
                    row["map"] = label
                    rows.append(row)

        sphere_runs = max(args.runs, args.sphere_runs)
        if "spheres" in sweeps:
            w, h = map(int, args.sphere_size.split("x"))
            env = str((ROOT / "data" / "env" / "sunrise.exr").resolve())
            for n in ints(args.spheres):
                sc = tmp / f"field-{n}.json"
                sc.write_text(json.dumps(field_scene(n, env, width=w, height=h)))
                for device in [d for d in args.sphere_devices.split(",") if d]:
                    for m in [m for m in args.sphere_methods.split(",") if m]:
                        rows.append(point(args, "spheres", sc, m, n, args.sweep_spp, w, h, tmp, device=device,
                                          label=f"{m} ({device})", runs=sphere_runs))

    result = {"machine": machine(), "device": args.device, "runs": args.runs,
              "sphere_runs": sphere_runs, "scene": Path(args.scene).name,
              "width": args.width, "height": args.height, "sweep_spp": args.sweep_spp, "results": rows}
    write_atomic(outdir / "scaling.json", json.dumps(result, indent=2))
    cols = ["sweep", "method", "x", "map", "spp", "width", "height", "nside", "seconds", "environment",
            "environment_load", "environment_resample", "environment_trees", "prepare", "samples_per_pixel"]
    write_atomic(outdir / "scaling.csv", csv_text(cols, rows))
    print(f"scaling: wrote {outdir}/scaling.{{csv,json}}", file=sys.stderr)


if __name__ == "__main__":
    main()
