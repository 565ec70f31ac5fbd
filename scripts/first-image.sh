#!/usr/bin/env bash
# Where the first image of a new mesh spends its time (issue #23): each
# workload runs RUNS times (default 5) as a fresh cellray-render process,
# 1024x768 on all cores (the ~2M-tet DVR 1024x1024, as #23 asks), timed
# from before the process starts to after it exits; the run with the median
# wall time is kept, with its --stats phases. Writes docs/first_image.csv and
# the chart docs/first_image.png (matplotlib). The ~2M-tet mesh is
# component8 with each tet split at its centroid into four (2.43M tets,
# tests/tools/refine_tets.cpp; ../shared/data has no real mesh that large),
# written to a temporary directory first.
# Needs the shared data set ($CELLRAY_DATA_DIR, default ../shared/data) and
# a Release build in build/ (built here if missing). About two minutes.
set -euo pipefail
cd "$(dirname "$0")/.."
d=${CELLRAY_DATA_DIR:-../shared/data}
runs=${RUNS:-5}
for f in openfoam/component8_heat_608k.vtk openfoam/boxturb48_dns.vtk openfoam/flange_snappy_89k.vtu vtk-data/kiefer_dataset.vtu; do
  [ -f "$d/$f" ] || { echo "first-image.sh: $d/$f missing: set CELLRAY_DATA_DIR to the shared data set" >&2; exit 1; }
done
# CELLRAY_RENDER=path: time that binary instead (e.g. another build), and
# CELLRAY_REFINE_TETS=path the refine_tets of that build (default: the one
# beside it, ../tests/refine_tets, built in build/ if missing).
r=${CELLRAY_RENDER:-}
refine=${CELLRAY_REFINE_TETS:-}
if [ -z "$r" ]; then
  ./scripts/install-deps.sh
  cmake -S . -B build -DCMAKE_BUILD_TYPE=Release >/dev/null
  cmake --build build -j"$(nproc)" --target cellray-render
  r=./build/examples/cellray-render
fi
[ -n "$refine" ] || refine=$(dirname "$r")/../tests/refine_tets
if [ ! -x "$refine" ]; then
  [ -f build/CMakeCache.txt ] || cmake -S . -B build -DCMAKE_BUILD_TYPE=Release >/dev/null
  cmake --build build -j"$(nproc)" --target refine_tets
  refine=./build/tests/refine_tets
fi
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
"$refine" "$d/openfoam/component8_heat_608k.vtk" "$tmp/component8_x4.vtk"
# name | arguments
workloads=(
  "component8 iso|$d/openfoam/component8_heat_608k.vtk --array T --iso 423 --iso-opacity 1 --size 1024x768"
  "component8 DVR|$d/openfoam/component8_heat_608k.vtk --array T --mode dvr --size 1024x768"
  "c8 x4 (2.4M) DVR|$tmp/component8_x4.vtk --array T --mode dvr --size 1024x1024"
  "boxturb48 iso|$d/openfoam/boxturb48_dns.vtk --array enstrophy --iso 0.1 --iso-opacity 1 --size 1024x768"
  "boxturb48 DVR|$d/openfoam/boxturb48_dns.vtk --array enstrophy --mode dvr --size 1024x768"
  "flange .vtu iso|$d/openfoam/flange_snappy_89k.vtu --array T --size 1024x768"
  "flange .vtu DVR|$d/openfoam/flange_snappy_89k.vtu --array T --mode dvr --size 1024x768"
  "kiefer zlib .vtu iso|$d/vtk-data/kiefer_dataset.vtu --size 1024x768"
)
for w in "${workloads[@]}"; do
  name=${w%%|*}
  args=${w#*|}
  for ((i = 0; i < runs; ++i)); do
    # Wall time around the whole process: --stats counts from main(), not
    # the program's loading (shared libraries) before it.
    t0=$(date +%s%N)
    # shellcheck disable=SC2086
    js=$($r $args --stats -o "$tmp/out.png")
    t1=$(date +%s%N)
    printf '%s\t%s\t%s\n' "$name" "$(((t1 - t0) / 1000))" "$js" >>"$tmp/stats.tsv"
  done
done
/usr/bin/python3 - "$tmp/stats.tsv" "$(uname -n) $(nproc) cores" <<'PY'
import csv, json, statistics, sys
import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt
phases = ["startup_ms", "load_ms", "prepare_ms", "validate_ms", "build_ms", "neighbours_ms", "gradients_ms", "render_ms_first", "write_ms"]
runs = {}
for line in open(sys.argv[1]):
    name, wall_us, js = line.rstrip("\n").split("\t", 2)
    j = json.loads(js)
    j["wall_ms"] = int(wall_us) / 1000.0
    # Before main() and after the image: loading the program and its
    # shared libraries, exit.
    j["startup_ms"] = max(0.0, j["wall_ms"] - j["total_ms"])
    # Gradients computed beside the BVH build are inside build_ms's wall time.
    if j.get("gradients_beside_build"):
        j["gradients_ms"] = 0.0
    runs.setdefault(name, []).append(j)
rows = []
for name, rs in runs.items():
    rs.sort(key=lambda j: j["wall_ms"])
    j = rs[len(rs) // 2]
    rows.append((name, j))
with open("docs/first_image.csv", "w", newline="") as f:
    w = csv.writer(f)
    w.writerow(["workload", "cells"] + phases + ["other_ms", "wall_ms", "wall_ms_min", "wall_ms_max", "stats_total_ms"])
    for name, j in rows:
        other = j["wall_ms"] - sum(j[p] for p in phases)
        ts = [x["wall_ms"] for x in runs[name]]
        w.writerow([name, j["cells"]] + [round(j[p], 1) for p in phases] + [round(other, 1), round(j["wall_ms"], 1), round(min(ts), 1), round(max(ts), 1), round(j["total_ms"], 1)])
fig, ax = plt.subplots(figsize=(8, 4.6))
left = [0.0] * len(rows)
colors = plt.get_cmap("tab10").colors
for k, p in enumerate(phases + ["other"]):
    vals = [(j["wall_ms"] - sum(j[q] for q in phases)) if p == "other" else j[p] for _, j in rows]
    ax.barh([n for n, _ in rows], vals, left=left, color=colors[k % 10], label=p.replace("_ms", "").replace("render_first", "first frame"))
    left = [a + b for a, b in zip(left, vals)]
ax.invert_yaxis()
ax.set_xlabel("ms from process start to the image on disk (median of %d fresh runs)" % len(next(iter(runs.values()))))
ax.set_title("First image of a new mesh (1024x768; 2.4M tets 1024x1024), cellray-render --stats (%s)" % sys.argv[2], fontsize=9)
ax.legend(fontsize=7, ncol=10, loc="upper center", bbox_to_anchor=(0.5, -0.2), frameon=False, columnspacing=1.0)
fig.tight_layout()
fig.savefig("docs/first_image.png", dpi=110)
for name, j in rows:
    print("%-16s wall %7.1f ms  " % (name, j["wall_ms"]) + "  ".join("%s %.0f" % (p.replace("_ms", ""), j[p]) for p in phases))
PY
