#!/usr/bin/python3
"""Charts and a one-page report from tools/bench.py and tools/scaling.py results.

    tools/report.py --bench out/bench [--stress out/stress] [--scaling out/scaling] --out docs/report

Per scene: relMSE against render time (log-log, one line per method and
device), relMSE against spp, efficiency 1 / (relMSE x time) as bars; the
talk's timing table (slide 52) next to ours with biased / unbiased ratios and
the cost per sample; crops of every method at equal spp and at (about) equal
time with per-pixel relative-error heat maps; wall and GPU times of the
devices side by side. Every method's efficiency against mis at 16 spp, a
column per scene (spheres and the stress scenes). For the stress scenes, every method's relMSE at equal
time with the failing methods marked, and the fireflies (counted by bench.py,
see bench.fireflies). For the scaling sweeps, time against spp, Nside and
image size, and the environment stage split into load / resample / trees.

Writes README.md and PNG charts into --out (no EXRs).
"""
import argparse
import json
import math
import statistics
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench import lum, read_exr, save_figure, write_atomic  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
TALK = {  # slide 52: Core 2 Duo 2.4 GHz, one core, seconds
    "HT unbiased": ("ht", [5.1, 7.3, 10.0, 20.4]),
    "HT biased": ("ht-biased", [2.3, 3.2, 4.8, 9.9]),
    "HT+Vis biased": ("ht-vis-biased", [2.8, 3.7, 5.3, 10.3]),
    "WIS": ("wis", [6.4, 6.7, 7.8, 11.3]),
    "Two-stage": ("tsis", [0.8, 1.8, 5.8, 19.3]),
}
TALK_SPP = [4, 16, 64, 256]
FAIL_FACTOR = 10.0
DPI = 80


def tonemap(img):
    x = np.clip(img, 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)


def key(r):
    """A method's name in the report: the method, with its device unless cpu."""
    return r["method"] if r.get("device", "cpu") == "cpu" else f"{r['method']} ({r['device']})"


def by_key(rows):
    out = {}
    for r in rows:
        out.setdefault(key(r), []).append(r)
    for v in out.values():
        v.sort(key=lambda r: r["spp"])
    return out


def efficiency(r):
    return 1.0 / (r["relmse"] * r["seconds"]) if r["relmse"] > 0 and r["seconds"] > 0 else float("inf")


def interp_at_time(rows, t):
    """relMSE at time t: log-log interpolation over a method's spp points; outside them (or with one point),
    extrapolated from the nearest point as relMSE ~ 1 / time (exact for unbiased methods)."""
    pts = sorted((r["seconds"], r["relmse"]) for r in rows if r["seconds"] > 0 and r["relmse"] > 0)
    if not pts:
        return None
    for (t0, e0), (t1, e1) in zip(pts, pts[1:]):
        if t0 <= t <= t1 and t1 > t0:
            a = (math.log(t) - math.log(t0)) / (math.log(t1) - math.log(t0))
            return math.exp(math.log(e0) + a * (math.log(e1) - math.log(e0)))
    t0, e0 = min(pts, key=lambda p: abs(math.log(p[0] / t)))
    return e0 * t0 / t


def fmt_e(v):
    return "-" if v is None else f"{v:.2e}"


def charts(scene, rows, outdir):
    methods = by_key(rows)
    fig, ax = plt.subplots(1, 3, figsize=(16, 4.6))
    base = list(dict.fromkeys(r["method"] for r in rows))
    cmap = plt.get_cmap("tab20")
    for name, rs in methods.items():
        style = "s--" if rs[0].get("device", "cpu") != "cpu" else "o-"
        color = cmap(base.index(rs[0]["method"]) % 20)
        ax[0].loglog([r["seconds"] for r in rs], [r["relmse"] for r in rs], style, label=name, ms=4, color=color)
        ax[1].loglog([r["spp"] for r in rs], [r["relmse"] for r in rs], style, label=name, ms=4, color=color)
    ax[0].set_xlabel("render time (s, wall)")
    ax[0].set_ylabel("relMSE")
    ax[0].set_title(f"{scene}: error against time")
    ax[1].set_xlabel("samples per pixel")
    ax[1].set_ylabel("relMSE")
    ax[1].set_title("error against spp")
    names = [n for n in methods if methods[n][0].get("device", "cpu") == "cpu"]
    spps = sorted({r["spp"] for r in rows})
    width = 0.8 / max(1, len(spps))
    for k, spp in enumerate(spps):
        eff = []
        for n in names:
            r = next((r for r in methods[n] if r["spp"] == spp), None)
            eff.append(efficiency(r) if r and math.isfinite(efficiency(r)) else 0.0)
        ax[2].bar(np.arange(len(names)) + k * width, eff, width, label=f"{spp} spp")
    ax[2].set_yscale("log")
    ax[2].set_xticks(np.arange(len(names)) + 0.4 - width / 2)
    ax[2].set_xticklabels(names, rotation=40, ha="right")
    ax[2].set_title("efficiency 1 / (relMSE x time), cpu")
    ax[2].legend(fontsize=7)
    ax[0].legend(fontsize=6, ncol=2)
    for a in ax[:2]:
        a.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    path = outdir / f"{scene}-charts.png"
    save_figure(fig, path, dpi=DPI)
    plt.close(fig)
    return path.name


def headline_chart(scene, rows, outdir):
    """Error against time of the product methods and `mis`, every device: the README's chart."""
    methods = by_key([r for r in rows if r["method"] in PRODUCT_METHODS + ("mis",)])
    if not methods:
        return None
    fig, ax = plt.subplots(figsize=(6.4, 3.6))
    colors = {"ht-frontier": "tab:red", "ht-cut": "tab:orange", "mis": "tab:blue", "ht-vis": "tab:gray"}
    for name, rs in sorted(methods.items()):
        device = rs[0].get("device", "cpu")
        label = f"{rs[0]['method']} ({'lavapipe' if device == 'gpu' else device})"
        ax.loglog([r["seconds"] for r in rs], [r["relmse"] for r in rs], "s--" if device != "cpu" else "o-",
                  label=label, ms=4, color=colors.get(rs[0]["method"], "black"))
        for r in rs:
            ax.annotate(str(r["spp"]), (r["seconds"], r["relmse"]), fontsize=6, xytext=(3, 3),
                        textcoords="offset points")
    ax.set_xlabel("render time (s, wall; points labelled with spp)")
    ax.set_ylabel("relMSE")
    ax.set_title(f"{scene}: error against time (lower left is better)", fontsize=10)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    path = outdir / f"{scene}-headline.png"
    save_figure(fig, path, dpi=DPI)
    plt.close(fig)
    return path.name


def image_grid(scene, chosen, ref_img, images, outdir, title, crop=True):
    """chosen: [(name, row)]; top: tone-mapped crop, bottom: relative error |L - Lref| / (Lref + 0.01), 0..1."""
    chosen = [(n, r) for n, r in chosen if r is not None and r["file"] in images]
    if not chosen:
        return None
    h, w = ref_img.shape[:2]
    y0, y1 = (h // 4, 3 * h // 4) if crop else (0, h)
    cols = min(len(chosen), 7)
    nrow = (len(chosen) + cols - 1) // cols
    fig, ax = plt.subplots(2 * nrow, cols, figsize=(2.3 * cols, 2.0 * nrow * (y1 - y0) / w * 2.3 + 0.9 * nrow),
                           squeeze=False)
    for a in ax.flat:
        a.axis("off")
    ref_l = lum(ref_img)
    for k, (n, r) in enumerate(chosen):
        i, j = 2 * (k // cols), k % cols
        img = images[r["file"]]
        ax[i][j].imshow(tonemap(img[y0:y1]), interpolation="nearest")
        ax[i][j].set_title(f"{n}\n{r['spp']} spp, {r['seconds']:.2f} s", fontsize=7)
        rel = np.abs(lum(img) - ref_l) / (np.abs(ref_l) + 1e-2)
        ax[i + 1][j].imshow(rel[y0:y1], cmap="inferno", vmin=0.0, vmax=1.0, interpolation="nearest")
        ax[i + 1][j].set_title(f"relMSE {r['relmse']:.2e}", fontsize=7)
    fig.suptitle(f"{scene}: {title} (below each: relative error, black 0 .. yellow 1)", fontsize=9)
    fig.tight_layout()
    path = outdir / f"{scene}-{title.replace(' ', '-')}.png"
    save_figure(fig, path, dpi=DPI)
    plt.close(fig)
    return path.name


def talk_table(rows):
    methods = by_key([r for r in rows if r.get("device", "cpu") == "cpu"])
    lines = ["| method | " + " | ".join(f"{s} spp ours / talk (s)" for s in TALK_SPP) +
             " | ours ms per spp | ours ns per pixel-sample | talk ms per spp |",
             "|---|" + "---|" * (len(TALK_SPP) + 3)]
    ours_by = {}
    pixels = None
    for label, (name, talk) in TALK.items():
        rs = {r["spp"]: r["seconds"] for r in methods.get(name, [])}
        for r in methods.get(name, []):
            pixels = pixels or r.get("pixels")
        ours_by[label] = rs
        cells = [f"{rs[s]:.2f} / {t}" if s in rs else f"- / {t}" for s, t in zip(TALK_SPP, talk)]
        slope = (rs[256] - rs[4]) / 252 if 4 in rs and 256 in rs else None
        ours_slope = f"{slope * 1e3:.1f}" if slope is not None else "-"
        ours_ns = f"{slope / pixels * 1e9:.0f}" if slope is not None and pixels else "-"
        talk_slope = (talk[3] - talk[0]) / 252 * 1e3
        lines.append(f"| {label} (`{name}`) | " + " | ".join(cells) +
                     f" | {ours_slope} | {ours_ns} | {talk_slope:.1f} |")
    lines.append("")
    for num, den in (("HT biased", "HT unbiased"), ("HT+Vis biased", "HT unbiased"), ("HT+Vis biased", "HT biased")):
        parts = []
        for i, s in enumerate(TALK_SPP):
            u, b = ours_by[den].get(s), ours_by[num].get(s)
            tr = TALK[num][1][i] / TALK[den][1][i]
            parts.append(f"{s} spp: ours {b / u:.2f}, talk {tr:.2f}" if u and b else f"{s} spp: talk {tr:.2f}")
        lines.append(f"- {num} / {den} time: " + "; ".join(parts) + ".")
    lines.append("")
    lines.append("Each method's time relative to HT unbiased at the same spp (ours / talk):")
    lines.append("")
    lines.append("| method | " + " | ".join(f"{s} spp" for s in TALK_SPP) + " |")
    lines.append("|---|" + "---|" * len(TALK_SPP))
    for label, (name, talk) in TALK.items():
        cells = []
        for i, s in enumerate(TALK_SPP):
            u, o = ours_by["HT unbiased"].get(s), ours_by[label].get(s)
            tr = talk[i] / TALK["HT unbiased"][1][i]
            cells.append(f"{o / u:.2f} / {tr:.2f}" if u and o else f"- / {tr:.2f}")
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def devices_table(rows):
    """Wall and GPU time of every method on every device, side by side."""
    devices = sorted({r["device"] for r in rows}, key=lambda d: (d != "cpu", d))
    if len(devices) < 2 and all(r.get("gpu_seconds") is None for r in rows):
        return None
    spps = sorted({r["spp"] for r in rows})
    methods = []
    for r in rows:
        if r["method"] not in methods:
            methods.append(r["method"])
    head = ["method", "spp"] + [f"{d} wall s" for d in devices] + \
        [f"{d} timestamps s" for d in devices if d != "cpu"] + [f"{d} relMSE" for d in devices]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for m in methods:
        for s in spps:
            got = {r["device"]: r for r in rows if r["method"] == m and r["spp"] == s}
            if len(got) < 2:
                continue
            cells = [m, str(s)]
            cells += [f"{got[d]['seconds']:.3f}" if d in got else "-" for d in devices]
            cells += [f"{got[d]['gpu_seconds']:.3f}" if d in got and got[d].get("gpu_seconds") is not None else "-"
                      for d in devices if d != "cpu"]
            cells += [fmt_e(got[d]["relmse"]) if d in got else "-" for d in devices]
            lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) if len(lines) > 2 else None


PRODUCT_METHODS = ("ht-frontier", "ht-cut", "ht-vis")  # the fixed-count product methods and the seed's
FIXED_COUNT = ("ht-frontier", "ht-cut")  # the product methods peers are measured against


def findings(rows):
    """The headline sentences: efficiency of the product methods against mis, their variance against oracle."""
    cpu = [r for r in rows if r.get("device", "cpu") == "cpu"]
    get = lambda m, s: next((r for r in cpu if r["method"] == m and r["spp"] == s), None)  # noqa: E731
    out = []
    for m in PRODUCT_METHODS:
        effs = []
        for s in sorted({r["spp"] for r in cpu}):
            a, b = get(m, s), get("mis", s)
            if a and b and math.isfinite(efficiency(a)) and math.isfinite(efficiency(b)):
                effs.append((s, efficiency(a) / efficiency(b), b["relmse"] / a["relmse"], a["seconds"] / b["seconds"]))
        if effs:
            geo = math.exp(statistics.mean(math.log(e[1]) for e in effs))
            out.append(f"Efficiency (1 / (relMSE x time)) of `{m}` against `mis`: " +
                       ", ".join(f"{e[1]:.2f}x at {e[0]} spp (relMSE {1 / e[2]:.2f}x and time {e[3]:.2f}x mis's)"
                                 for e in effs) + f"; geometric mean {geo:.2f}x.")
    for m in PRODUCT_METHODS:
        a, o = get(m, 16), get("oracle", 16)
        if a and o:
            lum = ""
            if a.get("luminance_relmse") and o.get("luminance_relmse"):
                lum = f", {a['luminance_relmse'] / o['luminance_relmse']:.1f}x in luminance"
            out.append(f"At 16 spp `{m}` has {a['relmse'] / o['relmse']:.2f}x the relMSE of `oracle`{lum}, the "
                       f"brute-force product env x BRDF x visibility (relMSE {a['relmse']:.2e} against "
                       f"{o['relmse']:.2e}; render time {a['seconds']:.2f} s against {o['seconds']:.2f} s).")
    return " ".join(out)


def efficiency_table(rows, spp=16, device="cpu", timing=""):
    """Every method's efficiency against mis's at one spp (16, or the largest below it) on one device, a column
    per scene."""
    spps = {r["spp"] for r in rows if r.get("device", "cpu") == device}
    if spp not in spps:
        spp = max((s for s in spps if s < spp), default=min(spps, default=spp))
    on = [r for r in rows if r.get("device", "cpu") == device and r["spp"] == spp]
    scenes = list(dict.fromkeys(r["scene"] for r in on))
    methods = list(dict.fromkeys(r["method"] for r in on if r["method"] != "oracle"))
    cell = {(r["scene"], r["method"]): r for r in on}
    if not scenes or not any((s, "mis") in cell for s in scenes):
        return []
    name = "the cpu" if device == "cpu" else "lavapipe" if device == "gpu" else device
    md = [f"## Efficiency against `mis` at {spp} spp on {name}", "",
          f"1 / (relMSE x time) of each method divided by `mis`'s, both at {spp} spp on {name}, measured side by "
          f"side in one run per scene{timing}: above 1 is better than `mis` at equal time. **bold**: the best "
          "unbiased method of the scene.", "",
          "| method | " + " | ".join(scenes) + " |", "|---|" + "---|" * len(scenes)]
    ratio = {}
    for s in scenes:
        base = cell.get((s, "mis"))
        for m in methods:
            r = cell.get((s, m))
            if base and r and math.isfinite(efficiency(r)) and math.isfinite(efficiency(base)):
                ratio[s, m] = efficiency(r) / efficiency(base)
    best = {s: max((v for (sc, m), v in ratio.items() if sc == s and "biased" not in m), default=None)
            for s in scenes}
    for m in methods:
        cells = []
        for s in scenes:
            v = ratio.get((s, m))
            cells.append("-" if v is None else f"**{v:.2f}**" if v == best[s] else f"{v:.2f}")
        md.append(f"| {m} | " + " | ".join(cells) + " |")
    md.append("")
    md += peers_ahead(ratio, scenes, methods)
    return md


PEERS = ("mis-compensated", "ris", "restir", "restir-biased", "wis", "tsis")  # what users reach for, and the talk's


def peers_ahead(ratio, scenes, methods):
    """The scenes where a peer beats the better fixed-count product method at equal time (docs/competitors.md
    says why)."""
    ahead = []
    for s in scenes:
        mine = [(ratio[s, m], m) for m in FIXED_COUNT if (s, m) in ratio]
        if not mine:
            continue
        p, product = max(mine)
        for m in methods:
            v = ratio.get((s, m))
            if m in PEERS and v is not None and v > p:
                ahead.append(f"{s}: `{m}` {v:.2f}x against `{product}`'s {p:.2f}x")
    names = " or ".join(f"`{m}`" for m in FIXED_COUNT)
    if not ahead:
        return [f"No peer beats {names} at equal time in these scenes.", ""]
    return [f"Where a peer beats the better of {names} at equal time (why: docs/competitors.md): " +
            "; ".join(ahead) + ".", ""]


def real_gpu_section(data, source):
    """A bench run on a real GPU (kept in the repository: such a machine is not always at hand)."""
    rows = [r for r in data["results"] if r["device"] != "cpu" and r.get("sampler", "stratified") == "stratified"]
    if not rows:
        return []
    r0 = rows[0]
    mis = {r["spp"]: r for r in rows if r["method"] == "mis"}
    md = [f"## A real GPU: {r0['device_name']}", "",
          f"{r0['device_name']} ({r0.get('device_driver', '')}), spheres.json at {data['width']}x{data['height']}, "
          f"the fastest of {data.get('gpu_runs') or data['runs']} timed runs per point after a warm-up, every method "
          f"side by side in one run of tools/bench.py on a machine with {data['machine']['cores']} CPU cores "
          f"(`{source}`). GPU ms: the timestamp queries around the dispatches; read-back ms: around the copies of "
          "the pixels' results to the host; wall: the render call, which adds the tables' upload and each "
          "tile's submission. Efficiency: "
          "1 / (relMSE x GPU time) against `mis`'s at the same spp. Tiles: the render's tiles and queue "
          "submissions.", "",
          "| method | spp | GPU ms | read-back ms | wall ms | relMSE | efficiency vs mis | tiles / submissions |",
          "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        g = r.get("gpu_seconds")
        base = mis.get(r["spp"])
        work = r.get("gpu_work") or {}
        eff = "-"
        if g and base and base.get("gpu_seconds") and r["relmse"] > 0:
            eff = f"{(base['relmse'] * base['gpu_seconds']) / (r['relmse'] * g):.3g}"
        back = work.get("readback_seconds")
        cells = [r["method"], str(r["spp"]), f"{1e3 * g:.2f}" if g is not None else "-",
                 f"{1e3 * back:.2f}" if back is not None else "-", f"{1e3 * r['seconds']:.1f}", fmt_e(r["relmse"]),
                 eff, f"{work['tiles']} / {work['submissions']}" if "tiles" in work else "-"]
        md.append("| " + " | ".join(cells) + " |")
    md.append("")
    return md


def floor_section(data):
    """The product methods (and the others of the run) against oracle, the brute-force product, at equal spp."""
    rows = [r for r in data["results"] if r.get("device", "cpu") == "cpu"]
    md = ["## Variance floor: against the brute-force product", ""]
    for scene in dict.fromkeys(r["scene"] for r in rows):
        srows = [r for r in rows if r["scene"] == scene]
        info = next((v for k, v in data["references"].items() if Path(k).stem == scene), {})
        for spp in sorted({r["spp"] for r in srows}):
            o = next((r for r in srows if r["method"] == "oracle" and r["spp"] == spp), None)
            if not o:
                continue
            others = [r for r in srows if r["spp"] == spp and r["method"] != "oracle"]
            lum = all(r.get("luminance_relmse") is not None for r in [o, *others])
            md += [f"{scene} at {info.get('width')}x{info.get('height')}, {spp} spp, side by side in one run "
                   f"(`oracle`: env x BRDF x visibility tabulated per shading point at HEALPix "
                   f"`{data.get('extra') or '--oracle-order 5'}`, each sample's node then refined by point "
                   f"evaluations down to 3 levels below the environment's pixels; `mis` takes two directions per "
                   f"spp). Every method here samples by luminance, so colour noise stays in the RGB relMSE of even "
                   f"a perfect sampler: the luminance relMSE shows the sampling alone.", "",
                   "| method | relMSE | relMSE / oracle's | luminance relMSE | luminance / oracle's | time s "
                   "| time / oracle's |" if lum else
                   "| method | relMSE | relMSE / oracle's | time s | time / oracle's |",
                   "|---|---|---|---|---|---|---|" if lum else "|---|---|---|---|---|"]
            for r in [o, *others]:
                cells = [r["method"], f"{r['relmse']:.2e}", f"{r['relmse'] / o['relmse']:.2f}"]
                if lum:
                    cells += [f"{r['luminance_relmse']:.2e}", f"{r['luminance_relmse'] / o['luminance_relmse']:.1f}"]
                cells += [f"{r['seconds']:.2f}", f"{r['seconds'] / o['seconds']:.3f}"]
                md.append("| " + " | ".join(cells) + " |")
            for m in PRODUCT_METHODS:
                a = next((r for r in others if r["method"] == m), None)
                if not a:
                    continue
                lum_text = (f"; in luminance {a['luminance_relmse'] / o['luminance_relmse']:.1f}x "
                            f"({a['luminance_relmse']:.2e} against {o['luminance_relmse']:.2e})" if lum else "")
                md += ["", f"**At {spp} spp `{m}` has {a['relmse'] / o['relmse']:.2f}x the relMSE of `oracle` "
                       f"({a['relmse']:.2e} against {o['relmse']:.2e}){lum_text}, in {a['seconds'] / o['seconds']:.3f}x "
                       f"its render time.**"]
            md.append("")
    return md


def scene_section(scene, info, srows, bench_dir, htrender, tmp, outdir, skipped):
    md = [f"## {scene}", "",
          f"Reference: {info['method']} at {info['spp']} spp, {info['width']}x{info['height']}, residual RMSE "
          f"about {info['residual_rmse']:.4f} (relMSE {info['residual_relmse']:.1e}).", ""]
    f = findings(srows)
    if f:
        md += [f"**{f}**", ""]
    headline = headline_chart(scene, srows, outdir)
    if headline:
        md += [f"![error against time of the product methods and mis]({headline})", ""]
    md += [f"![charts]({charts(scene, srows, outdir)})", ""]
    ref_img = read_exr(htrender, bench_dir / info["file"], tmp)
    images = {r["file"]: read_exr(htrender, bench_dir / r["file"], tmp) for r in srows
              if (bench_dir / r["file"]).exists()}
    cpu = by_key([r for r in srows if r.get("device", "cpu") == "cpu"])
    spps = sorted({r["spp"] for r in srows})
    eq_spp = 16 if 16 in spps else spps[len(spps) // 2]
    g = image_grid(scene, [(n, next((r for r in rs if r["spp"] == eq_spp), None)) for n, rs in cpu.items()],
                   ref_img, images, outdir, "equal spp")
    if g:
        md += [f"![equal spp]({g})", "", f"Every method at {eq_spp} spp (cpu).", ""]
    times = sorted(r["seconds"] for r in srows if r["spp"] == eq_spp and r.get("device", "cpu") == "cpu")
    if times:
        budget = statistics.median(times)
        chosen = [(n, min(rs, key=lambda r: abs(math.log(r["seconds"] / budget)))) for n, rs in cpu.items()
                  if n != "oracle"]
        g = image_grid(scene, chosen, ref_img, images, outdir, "equal time")
        if g:
            md += [f"![equal time]({g})", "",
                   f"Equal time: for each method the spp whose render time is closest to {budget:.2f} s (the median "
                   f"time at {eq_spp} spp).", ""]
    md += ["| method | device | spp | wall s | gpu s | samples/px | RMSE | relMSE | efficiency | fireflies |",
           "|---|---|---|---|---|---|---|---|---|---|"]
    for r in srows:
        g = f"{r['gpu_seconds']:.3f}" if r.get("gpu_seconds") is not None else "-"
        md.append(f"| {r['method']} | {r['device']} | {r['spp']} | {r['seconds']:.3f} | {g} | "
                  f"{r['samples_per_pixel']:.1f} | {r['rmse']:.4f} | {r['relmse']:.2e} | {efficiency(r):.3g} | "
                  f"{r.get('fireflies', '-')} |")
    md.append("")
    sk = [s for s in skipped if s["scene"] == scene]
    if sk:
        md.append("Not measured: " + "; ".join(
            f"{s['method']} on {s['device']}" + (f" at {s['spp']} spp" if "spp" in s else "") + f" ({s['reason']})"
            for s in sk) + ".")
        md.append("")
    dt = devices_table(srows)
    if dt:
        md += ["### Devices side by side", "",
               "Wall time is what the comparison uses; the GPU time comes from timestamp queries around the "
               "dispatches (on lavapipe the \"GPU\" is the same CPU).", "", dt, ""]
    md += ["### The talk's timing table (slide 52) next to ours", "",
           "Talk: Core 2 Duo 2.4 GHz, one core, its own scene and resolution. Ours: this machine, every core, "
           f"this scene at {info['width']}x{info['height']}, cpu. Compare the shapes and the ratios, not the "
           "absolute times. Cost per sample: the slope between 4 and 256 spp.", "", talk_table(srows), ""]
    return md


def stress_section(data, outdir):
    rows = [r for r in data["results"] if r.get("device", "cpu") == "cpu"]  # lavapipe's: the efficiency table
    scenes = sorted({r["scene"] for r in rows})
    spps = sorted({r["spp"] for r in rows})
    md = ["## Stress scenes: where methods fail", "",
          "relMSE at equal time: each method's relMSE carried to the scene's time budget (the median render time "
          f"of all methods at {spps[len(spps) // 2]} spp) by log-log interpolation between its spp points, or as "
          "relMSE x time / budget where it has one point (exact for unbiased methods). **bold**: the best; "
          f"**FAIL**: more than {FAIL_FACTOR:g}x the best unbiased method (the `-biased` ones can win at a low "
          f"budget without converging). Below: fireflies, pixels whose error exceeds "
          f"{data.get('firefly_sigmas', 10):g} robust sigma of the image's error, at the largest spp.", ""]
    methods = []
    for r in rows:
        if key(r) not in methods:
            methods.append(key(r))
    at, ff, budgets = {}, {}, {}
    for scene in scenes:
        srows = [r for r in rows if r["scene"] == scene]
        mid = spps[len(spps) // 2]
        budgets[scene] = statistics.median(r["seconds"] for r in srows if r["spp"] == mid)
        for n, rs in by_key(srows).items():
            at[scene, n] = interp_at_time(rs, budgets[scene])
            ff[scene, n] = rs[-1].get("fireflies")
    head = "| method | " + " | ".join(scenes) + " | scenes failed |"
    md += [head, "|---|" + "---|" * (len(scenes) + 1)]
    best = {s: min((v for (sc, _), v in at.items() if sc == s and v), default=None) for s in scenes}
    # Failing is measured against the best consistent method: a biased one can win at low spp without converging.
    best_u = {s: min((v for (sc, n), v in at.items() if sc == s and v and "biased" not in n), default=None)
              for s in scenes}
    failures = {}
    for n in methods:
        cells, nfail = [], 0
        for s in scenes:
            v = at.get((s, n))
            if v is None:
                cells.append("-")
            elif v == best[s]:
                cells.append(f"**{v:.2e}**")
            elif best_u[s] and v > FAIL_FACTOR * best_u[s]:
                cells.append(f"{v:.2e} **FAIL**")
                nfail += 1
                failures.setdefault(s, []).append(n)
            else:
                cells.append(f"{v:.2e}")
        md.append(f"| {n} | " + " | ".join(cells) + f" | {nfail} |")
    md.append("| *budget (s)* | " + " | ".join(f"{budgets[s]:.3f}" for s in scenes) + " | |")
    md += ["", "Fireflies:", "", head.replace(" scenes failed |", ""), "|---|" + "---|" * len(scenes)]
    for n in methods:
        md.append(f"| {n} | " + " | ".join(str(ff.get((s, n), "-")) if ff.get((s, n)) is not None else "-"
                                           for s in scenes) + " |")
    md.append("")
    if failures:
        md.append("Failing: " + "; ".join(f"{s}: {', '.join(ns)}" for s, ns in failures.items()) + ".")
        md.append("")
    sk = data.get("skipped", [])
    if sk:
        md.append("Not measured: " + "; ".join(
            f"{s['scene']} {s['method']} on {s['device']} ({s['reason']})" for s in sk) + ".")
        md.append("")
    return md


def scaling_section(data, outdir):
    rows = data["results"]
    md = ["## Scaling", "",
          f"`tools/scaling.py` on {data['scene']}, device {data['device']}, median of {data['runs']} run(s); the "
          f"spp and Nside sweeps at {data['width']}x{data['height']}, the Nside and size sweeps at "
          f"{data['sweep_spp']} spp. Render time is the render stage alone (wall); setup is reported apart. The "
          f"sphere sweep renders a field of N spheres on a plane (`tools/sphere_field.py`) on each device named "
          f"after its method (gpu: the Vulkan path on the machine's device), median of "
          f"{data.get('sphere_runs', data['runs'])} run(s).", ""]
    sweeps = [s for s in ("spp", "nside", "size", "spheres") if any(r["sweep"] == s for r in rows)]
    if sweeps:
        fig, ax = plt.subplots(1, len(sweeps), figsize=(5.2 * len(sweeps), 4.0), squeeze=False)
        labels = {"spp": "samples per pixel", "nside": "environment Nside", "size": "image pixels",
                  "spheres": "spheres (sphere field, 128x64)"}
        for a, s in zip(ax[0], sweeps):
            srows = [r for r in rows if r["sweep"] == s]
            for m in dict.fromkeys(r["method"] for r in srows):
                mr = sorted((r for r in srows if r["method"] == m), key=lambda r: r["x"])
                a.loglog([r["x"] for r in mr], [r["seconds"] for r in mr], "o-", label=m, ms=4)
            if s == "nside":
                mr = sorted((r for r in srows if r["method"] == srows[0]["method"]), key=lambda r: r["x"])
                a.loglog([r["x"] for r in mr], [r["environment"] for r in mr], "k:", label="environment setup")
            a.set_xlabel(labels[s])
            a.set_ylabel("seconds")
            a.set_title(f"time against {labels[s]}")
            a.grid(True, which="both", alpha=0.3)
            a.legend(fontsize=7)
        fig.tight_layout()
        save_figure(fig, outdir / "scaling.png", dpi=DPI)
        plt.close(fig)
        md += ["![scaling](scaling.png)", ""]
        for s in sweeps:
            srows = [r for r in rows if r["sweep"] == s]
            xs = sorted({r["x"] for r in srows})
            ms = list(dict.fromkeys(r["method"] for r in srows))
            md += [f"| {s} | " + " | ".join(ms) + (" | environment s |" if s == "nside" else " |"),
                   "|---|" + "---|" * (len(ms) + (1 if s == "nside" else 0))]
            for x in xs:
                cells = []
                for m in ms:
                    r = next((r for r in srows if r["x"] == x and r["method"] == m), None)
                    cells.append(f"{r['seconds']:.3f}" if r else "-")
                env = ""
                if s == "nside":
                    env = f" {statistics.median(r['environment'] for r in srows if r['x'] == x):.3f} |"
                xl = f"{x} ({next(r for r in srows if r['x'] == x)['width']}x" \
                     f"{next(r for r in srows if r['x'] == x)['height']})" if s == "size" else str(x)
                md.append(f"| {xl} | " + " | ".join(cells) + " |" + env)
            md.append("")
            # Growth between the extreme points: time ratio against x ratio (1.0 = linear).
            for m in ms:
                if s == "spheres":
                    mr = {r["x"]: r["seconds"] for r in srows if r["method"] == m}
                    if 16 in mr and max(mr) > 16 and mr[16] > 0:
                        md.append(f"- {m}: {mr[max(mr)] / mr[16]:.1f}x the time from 16 to {max(mr)} spheres "
                                  f"({mr[16]:.3f} s to {mr[max(mr)]:.3f} s).")
                    continue
                mr = sorted((r for r in srows if r["method"] == m), key=lambda r: r["x"])
                if len(mr) >= 2 and mr[0]["seconds"] > 0 and mr[-1]["x"] > mr[0]["x"]:
                    k = math.log(mr[-1]["seconds"] / mr[0]["seconds"]) / math.log(mr[-1]["x"] / mr[0]["x"])
                    md.append(f"- {m}: time grows as {s}^{k:.2f} from {mr[0]['x']} to {mr[-1]['x']} "
                              f"({mr[0]['seconds']:.3f} s to {mr[-1]['seconds']:.3f} s).")
            md.append("")
    tree = [r for r in rows if r["sweep"] == "tree"]
    if tree:
        md += ["### Environment setup: load / resample / trees", "",
               "The environment stage of `htrender render --stats` (`seconds.environment_load`, "
               "`environment_resample`, `environment_trees`): reading and checking the equirectangular EXR, "
               "resampling it into HEALPix (16 points per pixel), building the max/avg tree of its luminance. "
               "Maps generated by `make_env sky-sun`.", "",
               "| map | Nside | load s | resample s | trees s | environment total s |", "|---|---|---|---|---|---|"]
        for r in tree:
            md.append(f"| {r.get('map', '?')} | {r['nside']} | {r['environment_load']:.3f} | "
                      f"{r['environment_resample']:.3f} | {r['environment_trees']:.4f} | {r['environment']:.3f} |")
        md.append("")
    return md


def slope(rs):
    """Least-squares slope of log relMSE against log spp."""
    pts = [(math.log(r["spp"]), math.log(r["relmse"])) for r in rs if r["relmse"] > 0]
    if len(pts) < 2:
        return float("nan")
    mx = sum(x for x, _ in pts) / len(pts)
    my = sum(y for _, y in pts) / len(pts)
    return sum((x - mx) * (y - my) for x, y in pts) / sum((x - mx) ** 2 for x, _ in pts)


def sampler_section(rows):
    """Stratified against independent sample points, per method, from the same bench run."""
    cpu = [r for r in rows if r.get("device", "cpu") == "cpu"]
    if not any(r.get("sampler", "stratified") == "independent" for r in cpu):
        return []
    md = ["## Stratified against independent sample points", "",
          "Every method rendered with `--sampler stratified` (the default: one Owen-scrambled Sobol' (0,2)-sequence "
          "per decision) and with `--sampler independent` (i.i.d. points through the same warps), side by side in "
          "the bench run above. relMSE per spp; the slope is the least-squares fit of log relMSE against log spp "
          "(-1: plain Monte Carlo); the efficiency ratio is 1 / (relMSE x time), stratified over independent. The "
          "baselines that are not product samplers (uniform, cosine, brdf, env) are dominated by rare sun hits, "
          "whose relMSE varies from seed to seed more than the samplers differ.", ""]
    for scene in dict.fromkeys(r["scene"] for r in cpu):
        srows = [r for r in cpu if r["scene"] == scene]
        spps = sorted({r["spp"] for r in srows})
        md += [f"### {scene}", "",
               "| method | sampler | " + " | ".join(f"relMSE {s}" for s in spps) + " | slope | "
               + " | ".join(f"eff. ratio {s}" for s in spps) + " |",
               "|---|---|" + "---|" * (2 * len(spps) + 1)]
        for m in dict.fromkeys(r["method"] for r in srows):
            got = {(r.get("sampler", "stratified"), r["spp"]): r for r in srows if r["method"] == m}
            for smp in ("stratified", "independent"):
                rs = [got[(smp, s)] for s in spps if (smp, s) in got]
                if not rs:
                    continue
                rel = [fmt_e(got[(smp, s)]["relmse"]) if (smp, s) in got else "-" for s in spps]
                ratios = []
                for s in spps:
                    a, b = got.get(("stratified", s)), got.get(("independent", s))
                    ok = smp == "stratified" and a and b and efficiency(b) > 0
                    ratios.append(f"{efficiency(a) / efficiency(b):.2f}x" if ok else "")
                md.append(f"| {m} | {smp} | " + " | ".join(rel) + f" | {slope(rs):.2f} | " + " | ".join(ratios) + " |")
        md.append("")
    return md


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--bench", default=str(ROOT / "out" / "bench"), help="folder with results.json of tools/bench.py")
    p.add_argument("--stress", help="folder with results.json of a bench run over the stress scenes")
    p.add_argument("--scaling", help="folder with scaling.json of tools/scaling.py")
    p.add_argument("--floor", help="folder with results.json of a bench run with oracle (the variance floor)")
    p.add_argument("--real-gpu", action="append", default=[],
                   help="results.json of a bench run on a real GPU (repeatable)")
    p.add_argument("--command", default="tools/make-report.sh", help="the command named as the way to regenerate")
    p.add_argument("--htrender", default=str(ROOT / "build" / "htrender"))
    p.add_argument("--out", default=str(ROOT / "docs" / "report"))
    args = p.parse_args()
    outdir = Path(args.out)
    outdir.mkdir(parents=True, exist_ok=True)
    tmp = outdir / ".tmp"
    tmp.mkdir(exist_ok=True)

    bench_dir = Path(args.bench)
    bench = json.loads((bench_dir / "results.json").read_text())
    # The report's methods use the default sampler; the other one has its own section.
    rows = [r for r in bench["results"] if r.get("sampler", "stratified") == "stratified"]
    # The charts an earlier report wrote for these scenes (a method or grid
    # may be gone); other files in --out stay.
    for scene in {r["scene"] for r in rows}:
        for old in outdir.glob(f"{scene}-*.png"):
            old.unlink()
    (outdir / "scaling.png").unlink(missing_ok=True)
    for r in rows:
        info = next((v for k, v in bench["references"].items() if Path(k).stem == r["scene"]), {})
        r["pixels"] = info.get("width", 0) * info.get("height", 0)
    md = ["# htrender: error against time", "",
          f"Machine: {bench['machine']['cpu']}, {bench['machine']['cores']} cores ({bench['machine']['system']}); "
          f"build {bench['build'].get('type', '?')} {bench['build'].get('version', '')}; devices "
          f"{', '.join(bench.get('devices', [bench.get('device', 'cpu')]))}; the fastest of {bench['runs']} timed "
          f"run(s) per point on the cpu, {bench.get('gpu_runs', bench['runs'])} on other devices, after a warm-up, "
          f"the runs in rounds that render every point once. Every compared number comes from one run of the tools, methods side by side. "
          f"Regenerate with `{args.command}`.", ""]
    for scene_path, info in bench["references"].items():
        scene = Path(scene_path).stem
        srows = [r for r in rows if r["scene"] == scene]
        md += scene_section(scene, info, srows, bench_dir, args.htrender, tmp, outdir, bench.get("skipped", []))
    stress = json.loads((Path(args.stress) / "results.json").read_text()) if args.stress else None
    def timing(key):
        if not stress:
            return ""
        runs, stress_runs = bench.get(key) or bench["runs"], stress.get(key) or stress["runs"]
        return f" (times the fastest of {runs} runs on spheres.json, of {stress_runs} on the stress scenes)"
    md += efficiency_table(rows + (stress["results"] if stress else []), timing=timing("runs"))
    md += efficiency_table(rows + (stress["results"] if stress else []), device="gpu", timing=timing("gpu_runs"))
    md += sampler_section(bench["results"])
    if args.floor:
        md += floor_section(json.loads((Path(args.floor) / "results.json").read_text()))
    if stress:
        md += stress_section(stress, outdir)
    for f in args.real_gpu:
        path = Path(f).resolve()
        md += real_gpu_section(json.loads(path.read_text()), path.relative_to(ROOT) if path.is_relative_to(ROOT) else path)
    if args.scaling:
        md += scaling_section(json.loads((Path(args.scaling) / "scaling.json").read_text()), outdir)
    write_atomic(outdir / "README.md", "\n".join(md) + "\n")
    for f in tmp.iterdir():
        f.unlink()
    tmp.rmdir()
    print(f"report: wrote {outdir}/README.md", file=sys.stderr)


if __name__ == "__main__":
    main()
