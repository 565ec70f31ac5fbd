#!/usr/bin/env python3
"""Draws docs/accuracy_iso.png, docs/accuracy_dvr.png and
docs/accuracy_normals.png from the CSV that
bench_accuracy writes: speed (Mrays/s, log x) against image error versus the
reference renderer (RMSE in 8-bit units, log y), one point per configuration
(aggregated over meshes: geometric-mean speed, largest RMSE), the Pareto
front (nothing both faster and more accurate, with the ties below) joined and labelled, and
cellray-render's default marked. Usage: accuracy-chart.py CSV OUTDIR"""
import csv
import math
import sys
from collections import defaultdict

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

# RMSE below FLOOR (float rounding against double) counts, and is drawn, as
# FLOOR; speeds within NOISE of each other count as ties (frame-time noise).
FLOOR = 1e-3
NOISE = 1.05


def load(path):
    with open(path) as f:
        return list(csv.DictReader(f))


def aggregate(rows, mode):
    by = defaultdict(list)
    for r in rows:
        if r["mode"] == mode:
            by[r["config"]].append(r)
    pts = []
    for cfg, rs in by.items():
        speed = math.exp(sum(math.log(max(float(r["mrays_per_s"]), 1e-9)) for r in rs) / len(rs))
        err = max(float(r["rmse_8bit"]) for r in rs)
        miss = max(float(r["missed_pct"]) + float(r["spurious_pct"]) for r in rs)
        pts.append(dict(config=cfg, speed=speed, err=max(err, FLOOR), raw_err=err, miss=miss,
                        default=any(r["is_default"] == "1" for r in rs), meshes=len(rs), row=rs[0]))
    return pts


def pareto(pts):
    def dominates(q, p):
        return (q["err"] <= p["err"] and q["speed"] > p["speed"] * NOISE) or \
               (q["err"] < p["err"] and q["speed"] * NOISE >= p["speed"])
    front = [p for p in pts if not any(dominates(q, p) for q in pts if q is not p)]
    return sorted(front, key=lambda p: p["speed"])


def label(p, mode):
    r = p["row"]
    if mode == "iso":
        return f'{r["roots"]}, {r["normals"]}, {r["isa"]}, {r["traversal"]}'
    return f'{r["dvr_mode"]}, step d/{r["step_div"]}, G{r["group"]}, {"ESS" if r["ess"] == "1" else "no ESS"}, ' \
           f'{r["isa"]}, {r["traversal"]}'


def draw(pts, mode, out, meshes):
    fig, ax = plt.subplots(figsize=(9, 6), dpi=110)
    front = pareto(pts)
    fset = {p["config"] for p in front}
    colour = {"sse4": "#1b9e77", "avx2": "#d95f02", "avx512": "#7570b3"}
    for isa, c in colour.items():
        xs = [p["speed"] for p in pts if p["row"]["isa"] == isa and p["config"] not in fset]
        ys = [p["err"] for p in pts if p["row"]["isa"] == isa and p["config"] not in fset]
        ax.scatter(xs, ys, s=18, color=c, alpha=0.6, label=f"{isa}")
    ax.plot([p["speed"] for p in front], [p["err"] for p in front], "-o", color="black", ms=5, lw=1,
            label="Pareto front")
    for i, p in enumerate(front):
        ax.annotate(label(p, mode), (p["speed"], p["err"]), fontsize=6, xytext=(5, 8 - 12 * (i % 2)),
                    textcoords="offset points", color="#333333")
    for p in pts:
        if p["default"]:
            ax.scatter([p["speed"]], [p["err"]], s=140, facecolors="none", edgecolors="red", linewidths=2,
                       label="cellray-render default", zorder=5)
    ax.axhline(1.0, color="grey", ls="--", lw=0.8)
    ax.text(0.01, 1.05, "1/255 RMSE", fontsize=7, color="grey", transform=ax.get_yaxis_transform())
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("speed: Mrays/s (median frame, geometric mean over meshes)")
    ax.set_ylabel("error vs reference: RMSE, 8-bit units (worst mesh)")
    ax.set_title(f"{'Isosurfaces' if mode == 'iso' else 'DVR'}: speed vs accuracy ({meshes})", fontsize=10)
    ax.grid(True, which="both", lw=0.3, alpha=0.5)
    ax.legend(fontsize=7, loc="upper left")
    fig.savefig(out, bbox_inches="tight")
    print(f"wrote {out}")
    return front


def draw_normals(rows, out):
    """Isosurface normals against the exact field's: one point per mesh and method."""
    pts = [r for r in rows if r["mode"] == "normals"]
    if not pts:
        return
    fig, ax = plt.subplots(figsize=(6.4, 3.6), dpi=150)
    marks = {"flat": "s", "central": "^", "smooth": "o"}
    for mesh in sorted({r["mesh"] for r in pts}):
        rs = [r for r in pts if r["mesh"] == mesh]
        for r in rs:
            ax.scatter(float(r["mrays_per_s"]), float(r["rmse_8bit"]), marker=marks.get(r["normals"], "x"), s=36,
                       label=f'{mesh}: {r["normals"]}' + (" (default)" if r["is_default"] == "1" else ""))
    ax.set_xlabel("Mrays/s (median frame, all cores)")
    ax.set_ylabel("shading RMSE vs the exact sphere (8-bit)")
    ax.set_title("Isosurface normals: speed vs error against the field's true normals", fontsize=10)
    ax.grid(True, lw=0.3, alpha=0.5)
    ax.legend(fontsize=6, loc="center left", bbox_to_anchor=(1.01, 0.5))
    fig.savefig(out, bbox_inches="tight")
    print(f"wrote {out}")
    for r in pts:
        print(f'normals {r["mesh"]} {r["normals"]}: {float(r["mrays_per_s"]):.3f} Mrays/s, '
              f'RMSE {float(r["rmse_8bit"]):.2f}/255, max {float(r["max_8bit"]):.1f}')


def main():
    rows = load(sys.argv[1])
    outdir = sys.argv[2] if len(sys.argv) > 2 else "docs"
    draw_normals(rows, f"{outdir}/accuracy_normals.png")
    rows = [r for r in rows if r["mode"] != "normals"]
    meshes = ", ".join(sorted({r["mesh"] for r in rows}))
    for mode in ("iso", "dvr"):
        pts = aggregate(rows, mode)
        if not pts:
            continue
        front = draw(pts, mode, f"{outdir}/accuracy_{mode}.png", meshes)
        for p in front:
            print(f"  front: {p['config']}: {p['speed']:.3f} Mrays/s, RMSE {p['raw_err']:.4f}/255")
        d = [p for p in pts if p["default"]]
        for p in d:
            on = "on" if p["config"] in {f["config"] for f in front} else "NOT on"
            print(f"{mode} default {p['config']}: {p['speed']:.3f} Mrays/s, RMSE {p['raw_err']:.4f}/255, "
                  f"missed+spurious {p['miss']:.3f}% -> {on} the Pareto front")


if __name__ == "__main__":
    main()
