#!/usr/bin/python3
"""Error against time for every method, measured side by side in one run.

Renders scene x device x method x spp with `htrender render`, times each
render (the fastest of --runs: other load on the machine only ever adds time;
one uncounted warm-up render per scene and device first; the runs go in
rounds, every point once per round, so that a slow spell of the machine
touches every method alike and the ratios between methods hold), and measures its
error against a converged reference: RMSE, relative MSE and mean absolute
relative error (`htrender compare`), each the mean over the timed runs, which
use seeds 1, 2, ...; and the fireflies (of the first run) (pixels whose luminance error exceeds 10 robust sigma of the
image's error, see `fireflies`). Writes results.csv, results.json (with the
machine, devices, build, settings and skipped points) and results.md into
--out, and keeps one EXR per point there (the first timed run).

Methods: every method of `htrender methods` except oracle, which is slow and
only rendered with --oracle, at --oracle-spp (its 16 spp is the variance
floor the others are compared with).

Samplers: --samplers stratified,independent renders every point with each
per-pixel sampler (`htrender render --sampler`); rows carry the sampler.

Devices: --device cpu,gpu renders every point on each device in the same
run. A method a device does not render (the command refuses it) is skipped
there with a note. Wall time (`seconds.render`) is the compared time; where
the device reports it, the GPU time (`seconds.gpu`, timestamp queries) is
recorded next to it.

The reference is the mean of two independent renders (different seeds) by an
unbiased method at high spp on the CPU with the stratified sampler, cached under --out keyed by scene
content, resolution, method, spp and htrender version. Its own residual error
is estimated from the difference of its two halves and reported.
"""
import argparse
import csv
import hashlib
import io
import json
import os
import platform
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
FIREFLY_SIGMAS = 10.0


class RenderRefused(Exception):
    pass


def replace_atomically(path, write):
    """Calls write(tmp) for a temporary next to `path`, then renames it over
    `path`: an interrupted run leaves the previous file, never half a file."""
    path = Path(path)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=path.suffix)
    os.close(fd)
    try:
        write(tmp)
        os.chmod(tmp, 0o644)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def csv_text(cols, rows):
    """The rows as CSV with a header; missing or None cells empty."""
    with io.StringIO() as f:
        w = csv.writer(f, lineterminator="\n")
        w.writerow(cols)
        for r in rows:
            w.writerow(["" if r.get(c) is None else r[c] for c in cols])
        return f.getvalue()


def write_atomic(path, data):
    """Text or bytes to `path`, through a temporary."""
    def write(tmp):
        with open(tmp, "wb") as f:
            f.write(data.encode() if isinstance(data, str) else data)
            f.flush()
            os.fsync(f.fileno())
    replace_atomically(path, write)


def save_figure(fig, path, **kwargs):
    """fig.savefig to `path`, through a temporary."""
    replace_atomically(path, lambda tmp: fig.savefig(tmp, **kwargs))


def run(cmd):
    res = subprocess.run([str(c) for c in cmd], capture_output=True, text=True)
    if res.returncode != 0:
        sys.exit(f"bench: command failed: {' '.join(map(str, cmd))}\n{res.stderr.strip()}")
    return res.stdout


# --- images: one place for reading EXRs and counting fireflies (report.py uses these too) ---

def read_exr(htrender, path, tmpdir=None):
    """An EXR as a float32 array (height, width, 3), top row first, via `htrender export` (PFM)."""
    import numpy as np
    with tempfile.TemporaryDirectory(dir=tmpdir) as tmp:
        pfm = Path(tmp) / "image.pfm"
        subprocess.run([str(htrender), "export", str(path), "--out", str(pfm)], check=True,
                       stdout=subprocess.DEVNULL)
        data = pfm.read_bytes()
    head = data.split(b"\n", 3)
    w, h = map(int, head[1].split())
    scale = float(head[2])
    dtype = "<f4" if scale < 0 else ">f4"
    return np.frombuffer(head[3], dtype=dtype).reshape(h, w, 3)[::-1].astype(np.float32)


def lum(img):
    return 0.2126 * img[..., 0] + 0.7152 * img[..., 1] + 0.0722 * img[..., 2]


def fireflies(test, ref, sigmas=FIREFLY_SIGMAS):
    """Pixels whose luminance error against the reference exceeds `sigmas` robust standard deviations
    (1.4826 x median absolute deviation) of the image's error. The deviation is taken over the pixels
    whose error is not exactly 0 (those that show the environment directly are exact for every
    method) and floored at 1e-4 of the reference's mean luminance, so that a nearly exact image does
    not count its rounding."""
    import numpy as np
    d = lum(test).astype(np.float64) - lum(ref).astype(np.float64)
    nz = d[d != 0.0]
    sigma = 1.4826 * float(np.median(np.abs(nz - np.median(nz)))) if nz.size else 0.0
    sigma = max(sigma, 1e-4 * float(np.mean(np.abs(lum(ref)))), 1e-12)
    return int(np.sum(np.abs(d) > sigmas * sigma))


# --- rendering ---

def render(args, scene, method, spp, seed, out, device="cpu", extra=()):
    stats = Path(out).with_suffix(".json")
    cmd = [args.htrender, "render", "--scene", scene, "--method", method, "--spp", str(spp), "--seed", str(seed),
           "--device", device, "--out", str(out), "--stats", str(stats), "-q", *extra]
    if args.width:
        cmd += ["--width", str(args.width)]
    if args.height:
        cmd += ["--height", str(args.height)]
    res = subprocess.run([str(c) for c in cmd], capture_output=True, text=True)
    if res.returncode != 0:
        msg = res.stderr.strip().splitlines()[-1] if res.stderr.strip() else f"exit status {res.returncode}"
        if device != "cpu":
            raise RenderRefused(msg)
        sys.exit(f"bench: command failed: {' '.join(map(str, cmd))}\n{res.stderr.strip()}")
    return json.loads(stats.read_text())


def timed_run(args, scene, device, ref, pt, k, out):
    """Timed run k of a point (seed 1 + k) into `out`, with its error against ref."""
    stats = render(args, scene, pt["method"], pt["spp"], 1 + k, out, device, pt["extra"])
    pt["errs"].append(compare(args, ref, out))
    pt["times"].append(stats["seconds"]["render"])
    if stats["seconds"].get("gpu") is not None:
        pt["gpu_times"].append(stats["seconds"]["gpu"])
    pt["stats"] = stats
    if args.max_seconds > 0 and pt["times"][-1] > args.max_seconds / 2:
        pt["done"] = True  # a long render: one timed run is enough


def compare(args, ref, test):
    return json.loads(run([args.htrender, "compare", "--ref", str(ref), "--test", str(test)]))


def average_exr(args, a, b, out):
    run([args.htrender, "average", "--out", str(out), str(a), str(b)])


def reference(args, scene, outdir):
    text = Path(scene).read_bytes()
    version = run([args.htrender, "--version"]).strip()
    sampler = ["--sampler", "stratified"]  # the reference's own noise falls fastest with it
    parts = [text, str(args.width).encode(), str(args.height).encode(), args.ref_method.encode(),
             str(args.ref_spp).encode(), version.encode(), " ".join(sampler).encode()]
    if args.ref_device != "cpu":  # the CPU's references keep their keys
        parts += [args.ref_device.encode(), args.extra.encode()]
    key = hashlib.sha256(b"|".join(parts)).hexdigest()[:16]
    ref = outdir / f"ref-{Path(scene).stem}-{key}.exr"
    meta = ref.with_suffix(".meta.json")
    if ref.exists() and meta.exists():
        return ref, json.loads(meta.read_text())
    print(f"bench: reference {ref.name}: {args.ref_method} at {args.ref_spp} spp (two halves)", file=sys.stderr)
    half = max(1, args.ref_spp // 2)
    a, b = outdir / f"{ref.stem}-a.exr", outdir / f"{ref.stem}-b.exr"
    device = args.ref_device
    extra = sampler + (args.extra.split() if device != "cpu" else [])
    try:
        sa = render(args, scene, args.ref_method, half, 1000001, a, device, extra)
        render(args, scene, args.ref_method, half, 2000003, b, device, extra)
    except RenderRefused as e:
        sys.exit(f"bench: the reference on {device}: {e}")
    average_exr(args, a, b, ref)
    # Each half has error e, their difference sqrt(2) e, their mean e / sqrt(2).
    diff = compare(args, a, b)
    info = {"method": args.ref_method, "spp": 2 * half, "sampler": "stratified", "device": device,
            "version": version, "key": key,
            "width": sa["width"], "height": sa["height"],
            "residual_rmse": diff["rmse"] / 2.0, "residual_relmse": diff["relmse"] / 4.0}
    write_atomic(meta, json.dumps(info, indent=2))
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


def all_methods(htrender):
    names = []
    for line in run([htrender, "methods"]).splitlines()[1:]:  # after the header
        if line.strip() and not line.startswith(" "):
            names.append(line.split()[0])
    return names


def image_name(scene, method, device, spp, sampler="stratified"):
    tail = "" if sampler == "stratified" else f"-{sampler}"
    return f"{Path(scene).stem}-{method}-{device}-{spp}{tail}.exr"


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--scene", action="append", help="scene JSON (repeatable); default data/scenes/spheres.json")
    p.add_argument("--methods", default="all", help="comma-separated, or 'all' (every method but oracle)")
    p.add_argument("--oracle", action="store_true", help="also render oracle (at --oracle-spp only)")
    p.add_argument("--oracle-spp", default="16", help="spp list for oracle (default 16)")
    p.add_argument("--spp", default="4,16,64,256")
    p.add_argument("--runs", type=int, default=3, help="timed runs per point (the fastest counts)")
    p.add_argument("--warmup", type=int, default=1, help="uncounted renders per scene and device")
    p.add_argument("--device", default="cpu", help="comma-separated devices, e.g. cpu,gpu")
    p.add_argument("--gpu-spp", default="", help="spp list on devices other than cpu (default: --spp)")
    p.add_argument("--gpu-runs", type=int, default=0, help="timed runs on devices other than cpu (default: --runs)")
    p.add_argument("--max-seconds", type=float, default=0.0,
                   help="skip a method's larger spp on a device when its render would take longer (predicted "
                        "linearly from the previous spp), and time a render longer than half of it once (0: never)")
    p.add_argument("--width", type=int, default=0)
    p.add_argument("--height", type=int, default=0)
    p.add_argument("--ref-method", default="mis")
    p.add_argument("--ref-spp", type=int, default=4096)
    p.add_argument("--ref-device", default="cpu",
                   help="device of the reference's renders (a GPU's with --extra, e.g. its --gpu-index)")
    p.add_argument("--samplers", default="stratified",
                   help="comma-separated per-pixel samplers (htrender render --sampler); every point is rendered "
                        "with each, side by side")
    p.add_argument("--extra", default="", help="extra render arguments, e.g. '--brdf-bounds table'")
    p.add_argument("--label", default="", help="suffix for method names in the results (with --extra)")
    p.add_argument("--htrender", default=str(ROOT / "build" / "htrender"))
    p.add_argument("--out", default=str(ROOT / "out" / "bench"))
    args = p.parse_args()

    outdir = Path(args.out)
    outdir.mkdir(parents=True, exist_ok=True)
    scenes = [str(Path(s).resolve()) for s in (args.scene or [ROOT / "data" / "scenes" / "spheres.json"])]
    known = all_methods(args.htrender)
    if args.methods == "all":
        methods = [m for m in known if m != "oracle"]
    else:
        methods = [m for m in args.methods.split(",") if m]
        unknown = [m for m in methods if m not in known]
        if unknown:
            sys.exit(f"bench: unknown method(s) {', '.join(unknown)} (htrender methods: {', '.join(known)})")
    if args.oracle and "oracle" not in methods:
        methods.append("oracle")
    spps = [int(s) for s in args.spp.split(",") if s]
    oracle_spps = [int(s) for s in args.oracle_spp.split(",") if s]
    devices = [d for d in args.device.split(",") if d]
    extra = args.extra.split()
    samplers = [x for x in args.samplers.split(",") if x]
    rows, skipped = [], []
    refs = {}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        for scene in scenes:
            ref, refinfo = reference(args, scene, outdir)
            refs[scene] = {"file": ref.name, **refinfo}
            ref_img = read_exr(args.htrender, ref, tmp)
            for device in devices:
                on_cpu = device == "cpu"
                runs = args.runs if on_cpu or not args.gpu_runs else args.gpu_runs
                dev_spps = spps if on_cpu or not args.gpu_spp else [int(s) for s in args.gpu_spp.split(",") if s]
                for w in range(args.warmup):  # file caches, driver start-up; never counted
                    try:
                        render(args, scene, "mis", min(dev_spps), 1, tmp / "warmup.exr", device, extra)
                    except RenderRefused:
                        pass
                # Round 0 renders the points in order (method, sampler, spp), predicting
                # each point's time from the method's last one; every further round renders
                # each point once more, so that a point's timed runs spread over the whole
                # bench and a slow spell of the machine touches every method alike.
                points = []
                for method in methods:
                    name = method + args.label
                    point_spps = oracle_spps if method == "oracle" else dev_spps
                    last = None  # (spp, seconds) of the previous point
                    for sampler, spp in ((x, spp) for x in samplers for spp in point_spps):
                        if spp == point_spps[0]:
                            last = None
                        predicted = last[1] * spp / last[0] if last else 0.0
                        if args.max_seconds > 0 and predicted > args.max_seconds:
                            skipped.append({"scene": Path(scene).stem, "device": device, "method": name, "spp": spp,
                                            "reason": f"about {predicted:.0f} s per render > --max-seconds "
                                                      f"{args.max_seconds:g}"})
                            print(f"bench: {device}: skipping {name} at {spp} spp (about {predicted:.0f} s)",
                                  file=sys.stderr)
                            continue
                        pt = {"method": method, "name": name, "sampler": sampler, "spp": spp,
                              "img": outdir / image_name(scene, name, device, spp, sampler),
                              "extra": [*extra, "--sampler", sampler],
                              "times": [], "gpu_times": [], "errs": [], "stats": None, "done": False}
                        try:
                            timed_run(args, scene, device, ref, pt, 0, pt["img"])
                        except RenderRefused as e:
                            skipped.append({"scene": Path(scene).stem, "device": device, "method": name,
                                            "reason": str(e)})
                            print(f"bench: {device}: skipping {name}: {e}", file=sys.stderr)
                            break
                        points.append(pt)
                        last = (spp, pt["times"][0])
                for k in range(1, runs):
                    print(f"bench: {Path(scene).stem} {device}: timed run {k + 1} of {runs} of every point",
                          file=sys.stderr)
                    for pt in points:
                        if pt["done"]:
                            continue
                        try:
                            timed_run(args, scene, device, ref, pt, k, tmp / "run.exr")
                        except RenderRefused:
                            pt["done"] = True
                for pt in points:
                    name, spp, run_errs, times, gpu_times = pt["name"], pt["spp"], pt["errs"], pt["times"], pt["gpu_times"]
                    # Error: the mean over the runs (seeds 1, 2, ...), which tames the seed-to-seed
                    # spread of relMSE where rare large samples dominate it.
                    err = {k: statistics.fmean(e[k] for e in run_errs) for k in run_errs[0]
                           if isinstance(run_errs[0][k], float)}
                    err["relmse_runs"] = [e["relmse"] for e in run_errs]
                    img = pt["img"]
                    ff = fireflies(read_exr(args.htrender, img, tmp), ref_img)
                    stats = pt["stats"]
                    sec = stats["seconds"]
                    row = {"scene": Path(scene).stem, "method": name, "device": device, "spp": spp,
                           "sampler": pt["sampler"],
                           "seconds": min(times), "seconds_runs": times,
                           "gpu_seconds": min(gpu_times) if gpu_times else None,
                           "setup_seconds": sec.get("environment", 0.0) + sec.get("prepare", 0.0)
                           + sec.get("device", 0.0) + sec.get("upload", 0.0),
                           "device_name": stats["device"]["name"],
                           "device_driver": stats["device"].get("driver", ""),
                           "gpu_work": stats["device"].get("work"),
                           "samples_per_pixel": stats["mean_samples_per_pixel"],
                           "fireflies": ff, "file": img.name, **err}
                    rows.append(row)
                    gpu = f" (gpu {row['gpu_seconds']:.3f} s)" if row["gpu_seconds"] is not None else ""
                    print(f"{row['scene']:>16} {device:>4} {name:>14} {pt['sampler'][:5]:>5} {spp:>5} spp  "
                          f"{row['seconds']:8.3f} s{gpu}  "
                          f"rmse {err['rmse']:.4f}  relmse {err['relmse']:.5f}  fireflies {ff}", file=sys.stderr)
                    Path(img).with_suffix(".json").unlink(missing_ok=True)

    build = {}
    cache = Path(args.htrender).resolve().parent / "CMakeCache.txt"
    if not cache.exists():
        cache = ROOT / "build" / "CMakeCache.txt"
    if cache.exists():
        for line in cache.read_text().splitlines():
            if line.startswith("CMAKE_BUILD_TYPE:"):
                build["type"] = line.split("=", 1)[1]
    build["version"] = run([args.htrender, "--version"]).strip()
    result = {"machine": machine(), "build": build, "devices": devices, "device": ",".join(devices),
              "runs": args.runs, "gpu_runs": args.gpu_runs or args.runs, "oracle_spp": oracle_spps, "warmup": args.warmup, "spp": spps, "width": args.width, "height": args.height,
              "samplers": samplers, "extra": args.extra, "firefly_sigmas": FIREFLY_SIGMAS, "references": refs, "results": rows,
              "skipped": skipped}
    write_atomic(outdir / "results.json", json.dumps(result, indent=2))
    cols = ["scene", "device", "method", "sampler", "spp", "seconds", "gpu_seconds", "setup_seconds", "samples_per_pixel",
            "rmse", "relmse", "mean_abs_rel_error", "luminance_relmse", "fireflies", "device_name"]
    write_atomic(outdir / "results.csv", csv_text(cols, rows))
    with io.StringIO() as f:
        f.write(f"Machine: {result['machine']['cpu']}, {result['machine']['cores']} cores; devices "
                f"{', '.join(devices)}; fastest of {args.runs} runs after a warm-up.\n\n")
        for scene, info in refs.items():
            f.write(f"Reference for {Path(scene).name}: {info['method']} at {info['spp']} spp, "
                    f"residual RMSE about {info['residual_rmse']:.4f}.\n\n")
        f.write("| scene | device | method | sampler | spp | render s | gpu s | samples/px | RMSE | relMSE "
                "| mean abs rel err | fireflies |\n|---|---|---|---|---|---|---|---|---|---|---|---|\n")
        for r in rows:
            g = f"{r['gpu_seconds']:.3f}" if r["gpu_seconds"] is not None else "-"
            f.write(f"| {r['scene']} | {r['device']} | {r['method']} | {r['sampler']} | {r['spp']} | {r['seconds']:.3f} | {g} "
                    f"| {r['samples_per_pixel']:.1f} | {r['rmse']:.4f} | {r['relmse']:.5f} "
                    f"| {r['mean_abs_rel_error']:.4f} | {r['fireflies']} |\n")
        if skipped:
            f.write("\nSkipped:\n\n")
            for s in skipped:
                f.write(f"- {s['scene']} {s['device']} {s['method']}"
                        f"{' at ' + str(s['spp']) + ' spp' if 'spp' in s else ''}: {s['reason']}\n")
        write_atomic(outdir / "results.md", f.getvalue())
    print(f"bench: wrote {outdir}/results.{{csv,json,md}}", file=sys.stderr)


if __name__ == "__main__":
    main()
