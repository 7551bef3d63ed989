#!/usr/bin/python3
"""Charts and a one-page report from tools/bench.py results.

    tools/report.py --bench out/bench [--stress out/stress] --out docs/report

Per scene: relMSE against render time (log-log, one line per method and
device), relMSE against spp, efficiency 1 / (relMSE x time) as bars; the
talk's timing table next to ours; crops of every method at equal spp and at
(about) equal time with per-pixel relative-error heat maps; for the stress
scenes, every method's relMSE at equal time with the failing methods marked
and the fireflies (pixels beyond 10 robust sigma) counted.
"""
import argparse
import json
import math
import subprocess
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
TALK = {  # slide 52: Core 2 Duo 2.4 GHz, one core, seconds
    "HT unbiased": ("ht", [5.1, 7.3, 10.0, 20.4]),
    "HT biased": ("ht-biased", [2.3, 3.2, 4.8, 9.9]),
    "HT+Vis biased": ("ht-vis-biased", [2.8, 3.7, 5.3, 10.3]),
    "WIS": ("wis", [6.4, 6.7, 7.8, 11.3]),
    "Two-stage": ("tsis", [0.8, 1.8, 5.8, 19.3]),
}
TALK_SPP = [4, 16, 64, 256]


def read_exr(htrender, path, tmp):
    pfm = tmp / (Path(path).stem + ".pfm")
    subprocess.run([htrender, "export", str(path), "--out", str(pfm)], check=True)
    data = pfm.read_bytes()
    head = data.split(b"\n", 3)
    w, h = map(int, head[1].split())
    img = np.frombuffer(head[3], dtype="<f4").reshape(h, w, 3)[::-1]
    pfm.unlink()
    return img


def lum(img):
    return 0.2126 * img[..., 0] + 0.7152 * img[..., 1] + 0.0722 * img[..., 2]


def tonemap(img):
    x = np.clip(img, 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)


def fireflies(test, ref):
    d = lum(test) - lum(ref)
    sigma = 1.4826 * np.median(np.abs(d - np.median(d))) + 1e-12
    return int(np.sum(np.abs(d) > 10.0 * sigma))


def interp_at_time(rows, t):
    """relMSE at time t by log-log interpolation over a method's spp points (None outside)."""
    pts = sorted((r["seconds"], r["relmse"]) for r in rows)
    for (t0, e0), (t1, e1) in zip(pts, pts[1:]):
        if t0 <= t <= t1 and t1 > t0:
            a = (math.log(t) - math.log(t0)) / (math.log(t1) - math.log(t0))
            return math.exp(math.log(e0) + a * (math.log(e1) - math.log(e0)))
    return None


def by_method(rows):
    out = {}
    for r in rows:
        out.setdefault(r["method"], []).append(r)
    for v in out.values():
        v.sort(key=lambda r: r["spp"])
    return out


def charts(scene, rows, outdir):
    methods = by_method(rows)
    fig, ax = plt.subplots(1, 3, figsize=(16, 4.6))
    for name, rs in methods.items():
        label = f"{name} ({rs[0]['device']})" if rs[0].get("device") else name
        ax[0].loglog([r["seconds"] for r in rs], [r["relmse"] for r in rs], "o-", label=label)
        ax[1].loglog([r["spp"] for r in rs], [r["relmse"] for r in rs], "o-", label=name)
    ax[0].set_xlabel("render time (s)")
    ax[0].set_ylabel("relMSE")
    ax[0].set_title(f"{scene}: error against time")
    ax[1].set_xlabel("samples per pixel")
    ax[1].set_ylabel("relMSE")
    ax[1].set_title("error against spp")
    names = list(methods)
    spps = sorted({r["spp"] for r in rows})
    width = 0.8 / max(1, len(spps))
    for k, spp in enumerate(spps):
        eff = []
        for n in names:
            r = next((r for r in methods[n] if r["spp"] == spp), None)
            eff.append(1.0 / (r["relmse"] * r["seconds"]) if r and r["relmse"] > 0 and r["seconds"] > 0 else 0.0)
        ax[2].bar(np.arange(len(names)) + k * width, eff, width, label=f"{spp} spp")
    ax[2].set_yscale("log")
    ax[2].set_xticks(np.arange(len(names)) + 0.4 - width / 2)
    ax[2].set_xticklabels(names, rotation=40, ha="right")
    ax[2].set_title("efficiency 1 / (relMSE x time)")
    ax[2].legend(fontsize=7)
    ax[0].legend(fontsize=7)
    for a in ax[:2]:
        a.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    path = outdir / f"{scene}-charts.png"
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path.name


def image_grid(scene, rows, ref_img, images, outdir, title, pick):
    methods = by_method(rows)
    chosen = [(n, pick(rs)) for n, rs in methods.items()]
    chosen = [(n, r) for n, r in chosen if r is not None and r["file"] in images]
    if not chosen:
        return None
    h, w = ref_img.shape[:2]
    y0, y1, x0, x1 = h // 4, 3 * h // 4, 0, w  # the band of objects
    fig, ax = plt.subplots(2, len(chosen), figsize=(2.6 * len(chosen), 3.4), squeeze=False)
    for k, (n, r) in enumerate(chosen):
        img = images[r["file"]]
        ax[0][k].imshow(tonemap(img[y0:y1, x0:x1]))
        ax[0][k].set_title(f"{n}\n{r['spp']} spp, {r['seconds']:.2f} s", fontsize=8)
        rel = np.abs(lum(img) - lum(ref_img)) / (np.abs(lum(ref_img)) + 1e-2)
        ax[1][k].imshow(rel[y0:y1, x0:x1], cmap="inferno", vmin=0.0, vmax=1.0)
        ax[1][k].set_title(f"relMSE {r['relmse']:.2e}", fontsize=8)
        for a in (ax[0][k], ax[1][k]):
            a.axis("off")
    fig.suptitle(f"{scene}: {title} (bottom: relative error, 0..1)", fontsize=10)
    fig.tight_layout()
    path = outdir / f"{scene}-{title.replace(' ', '-')}.png"
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path.name


def talk_table(rows):
    methods = by_method(rows)
    lines = ["| method | " + " | ".join(f"{s} spp ours / talk" for s in TALK_SPP) +
             " | ours per extra sample (ms) | talk per extra sample (ms) |",
             "|---|" + "---|" * (len(TALK_SPP) + 2)]
    ours_by = {}
    for label, (name, talk) in TALK.items():
        rs = {r["spp"]: r["seconds"] for r in methods.get(name, [])}
        ours_by[label] = rs
        cells = [f"{rs[s]:.2f} / {t}" if s in rs else f"- / {t}" for s, t in zip(TALK_SPP, talk)]
        ours_slope = f"{(rs[256] - rs[4]) / 252 * 1e3:.2f}" if 4 in rs and 256 in rs else "-"
        talk_slope = (talk[3] - talk[0]) / 252 * 1e3
        lines.append(f"| {label} | " + " | ".join(cells) + f" | {ours_slope} | {talk_slope:.1f} |")
    lines.append("")
    ratio = []
    for s_i, s in enumerate(TALK_SPP):
        u, b = ours_by["HT unbiased"].get(s), ours_by["HT biased"].get(s)
        talk_r = TALK["HT biased"][1][s_i] / TALK["HT unbiased"][1][s_i]
        ratio.append(f"{s} spp: ours {b / u:.2f}, talk {talk_r:.2f}" if u and b else f"{s} spp: talk {talk_r:.2f}")
    lines.append("Biased / unbiased time ratio: " + "; ".join(ratio) + ".")
    return "\n".join(lines)


def stress_section(stress_json, htrender, tmp, outdir):
    data = json.loads(Path(stress_json).read_text())
    rows = data["results"]
    scenes = sorted({r["scene"] for r in rows})
    out = ["## Stress scenes: where methods fail", "",
           "relMSE at equal time (log-log interpolation between spp points; `-` where a method's times do not "
           "reach the common budget), fireflies = pixels beyond 10 robust sigma of the error at the largest spp. "
           "**bold**: the best; *failing*: more than 10x the best relMSE.", ""]
    for scene in scenes:
        srows = [r for r in rows if r["scene"] == scene]
        methods = by_method(srows)
        t16 = sorted(r["seconds"] for r in srows if r["spp"] == 16)
        budget = t16[len(t16) // 2]
        ref_file = next(v["file"] for k, v in data["references"].items() if Path(k).stem == scene)
        ref_img = read_exr(htrender, ref_file, tmp)
        at = {n: interp_at_time(rs, budget) for n, rs in methods.items()}
        best = min((v for v in at.values() if v), default=None)
        out.append(f"### {scene} (budget {budget:.2f} s)")
        out.append("")
        out.append("| method | relMSE at budget | relMSE at 16 spp | fireflies |")
        out.append("|---|---|---|---|")
        for n, rs in methods.items():
            v = at[n]
            mark = "-" if v is None else (f"**{v:.2e}**" if v == best else
                                          (f"*{v:.2e} failing*" if best and v > 10 * best else f"{v:.2e}"))
            r16 = next((r for r in rs if r["spp"] == 16), None)
            last = rs[-1]
            ff = fireflies(read_exr(htrender, last["file"], tmp), ref_img) if Path(last["file"]).exists() else "-"
            out.append(f"| {n} | {mark} | {r16['relmse']:.2e} |" if r16 else f"| {n} | {mark} | - |")
            out[-1] += f" {ff} |"
        out.append("")
    return "\n".join(out)


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--bench", default=str(ROOT / "out" / "bench"), help="folder with results.json of tools/bench.py")
    p.add_argument("--stress", help="folder with results.json of a bench run over the stress scenes")
    p.add_argument("--htrender", default=str(ROOT / "build" / "htrender"))
    p.add_argument("--out", default=str(ROOT / "docs" / "report"))
    args = p.parse_args()
    outdir = Path(args.out)
    outdir.mkdir(parents=True, exist_ok=True)
    tmp = outdir / ".tmp"
    tmp.mkdir(exist_ok=True)

    bench = json.loads((Path(args.bench) / "results.json").read_text())
    rows = bench["results"]
    for r in rows:
        r["file"] = str(Path(args.bench) / f"{r['scene']}-{r['method']}-{r['spp']}.exr")
    md = ["# htrender: error against time", "",
          f"Machine: {bench['machine']['cpu']}, {bench['machine']['cores']} cores ({bench['machine']['system']}); "
          f"build {bench['build'].get('type', '?')}; device {bench['device']}; median of {bench['runs']} runs "
          f"after a warm-up. Regenerate with `tools/bench.py` then `tools/report.py`.", ""]
    for scene_path, info in bench["references"].items():
        scene = Path(scene_path).stem
        srows = [r for r in rows if r["scene"] == scene]
        md += [f"## {scene}", "",
               f"Reference: {info['method']} at {info['spp']} spp, {info['width']}x{info['height']}, residual RMSE "
               f"about {info['residual_rmse']:.4f} (relMSE {info['residual_relmse']:.1e}).", "",
               f"![charts]({charts(scene, srows, outdir)})", ""]
        ref_img = read_exr(args.htrender, info["file"], tmp)
        images = {r["file"]: read_exr(args.htrender, r["file"], tmp) for r in srows if Path(r["file"]).exists()}
        g = image_grid(scene, srows, ref_img, images, outdir, "equal spp", lambda rs: next(
            (r for r in rs if r["spp"] == 16), None))
        if g:
            md += [f"![equal spp]({g})", ""]
        t16 = sorted(r["seconds"] for r in srows if r["spp"] == 16)
        if t16:
            budget = t16[len(t16) // 2]
            g = image_grid(scene, srows, ref_img, images, outdir, "equal time",
                           lambda rs: min(rs, key=lambda r: abs(math.log(r["seconds"] / budget))))
            if g:
                md += [f"![equal time]({g}) (for each method, the spp whose time is closest to {budget:.2f} s)", ""]
        md += ["| method | spp | time s | samples/px | RMSE | relMSE | efficiency |", "|---|---|---|---|---|---|---|"]
        for r in srows:
            eff = 1.0 / (r["relmse"] * r["seconds"]) if r["relmse"] > 0 and r["seconds"] > 0 else float("inf")
            md.append(f"| {r['method']} | {r['spp']} | {r['seconds']:.3f} | {r['samples_per_pixel']:.1f} | "
                      f"{r['rmse']:.4f} | {r['relmse']:.2e} | {eff:.3g} |")
        md += ["", "### The talk's timing table (slide 52) next to ours", "",
               "Talk: Core 2 Duo 2.4 GHz, one core, its own scene. Ours: this machine, all cores, this scene; "
               "compare shapes and ratios, not absolute times.", "", talk_table(srows), ""]
    if args.stress:
        stress = json.loads((Path(args.stress) / "results.json").read_text())
        for r in stress["results"]:
            r["file"] = str(Path(args.stress) / f"{r['scene']}-{r['method']}-{r['spp']}.exr")
        (tmp / "stress.json").write_text(json.dumps(stress))
        md.append(stress_section(tmp / "stress.json", args.htrender, tmp, outdir))
    (outdir / "README.md").write_text("\n".join(md) + "\n")
    for f in tmp.iterdir():
        f.unlink()
    tmp.rmdir()
    print(f"report: wrote {outdir}/README.md", file=sys.stderr)


if __name__ == "__main__":
    main()
