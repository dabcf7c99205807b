#!/usr/bin/env python3
"""The build-time table of BENCHMARKS.md: sahkd's builders against Embree 4's BVH
build on the same meshes, 1 and 2 threads, in one run.

    cargo build --release -p sahkd-cli
    VENV/bin/python scripts/build_table.py [--repeat 5] [--baseline OLD_SAHKD] [MESH ...]

MESH is a name in ../shared/scenes (or $SAHKD_SCENES); default bunny, dragon_res2 and dragon.
Every configuration is one warm-up build and `--repeat` timed builds of `sahkd build --json`
(`build_ms`); one thread means `taskset -c 0` and `--threads 1`. Embree is timed by
scripts/embree_build.py in the same run, from the indexed mesh (needs embreex and trimesh
in the interpreter running this),
under `taskset -c 0` for one thread. `--baseline` adds the serial sweep of another sahkd
binary (e.g. one built at an older commit), to compare sweeps at identical trees: its rows
must give the same nodes, references and SAH cost; `--baseline-kt 15` times this binary's sweep
again at the baseline's K_T for that comparison. Prints one markdown
table with medians and min-max, and the load average before and after each mesh.
"""

import argparse
import json
import os
import re
import statistics
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
DEFAULT_MESHES = ["bunny", "dragon_res2", "dragon"]
# (algorithm, axes, threads, bins); the first is the default build. Bins None is the
# builder's own default (256 for the hybrid, exact for the others); 0 is exact SAH.
CONFIGS = [
    ("hybrid", "longest", 2, None),
    ("hybrid", "longest", 2, 0),
    ("hybrid", "longest", 1, None),
    ("hybrid", "longest", 1, 0),
    ("sweep", "longest", 1, None),
    ("level", "longest", 2, None),
    ("hybrid", "all", 2, None),
    ("hybrid", "all", 2, 0),
    ("sweep", "all", 1, None),
    ("median", "longest", 2, None),
]
EMBREE = re.compile(r"build median ([0-9.]+) ms \(min ([0-9.]+), max ([0-9.]+)")


def load():
    with open("/proc/loadavg") as f:
        return " ".join(f.read().split()[:3])


def run(cmd):
    done = subprocess.run(cmd, capture_output=True, text=True)
    if done.returncode != 0:
        sys.exit(f"{' '.join(cmd)} failed ({done.returncode}):\n{done.stdout}{done.stderr}")
    return done.stdout


def pinned(threads):
    return ["taskset", "-c", "0"] if threads == 1 else []


def sahkd(binary, mesh, algorithm, axes, threads, repeat, bins=None, extra=()):
    cmd = pinned(threads) + [
        binary, "build", mesh, "--algorithm", algorithm, "--axes", axes,
        "--threads", str(threads), "--json", "--quiet",
    ] + ([] if bins is None else ["--bins", str(bins)]) + list(extra)
    run(cmd)
    reports = [json.loads(run(cmd)) for _ in range(repeat)]
    times = [r["build_ms"] for r in reports]
    last = reports[-1]
    return dict(
        ms=(statistics.median(times), min(times), max(times)),
        sah=last["sah_cost"], nodes=last["nodes"], refs=last["references"],
        bytes=last.get("peak_working_bytes_per_triangle"), bins=last.get("bins"),
        triangles=last["triangles"],
    )


def embree(mesh, threads, repeat):
    out = run(pinned(threads) + [sys.executable, os.path.join(HERE, "embree_build.py"), mesh,
                                 "--repeat", str(repeat)])
    m = EMBREE.search(out)
    return tuple(map(float, m.groups()))


def spread(t):
    return f"{t[0]:.0f} ({t[1]:.0f}-{t[2]:.0f})" if t[0] >= 100 else f"{t[0]:.1f} ({t[1]:.1f}-{t[2]:.1f})"


def working(b):
    return "-" if b is None else f"{b:.0f}"


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("meshes", nargs="*", default=DEFAULT_MESHES)
    p.add_argument("--repeat", type=int, default=5)
    p.add_argument("--sahkd", default=os.path.join(ROOT, "target", "release", "sahkd"))
    p.add_argument("--baseline", help="another sahkd binary whose serial sweep is timed beside")
    p.add_argument("--baseline-kt", type=float,
                   help="the baseline's default K_T, where it differs from this binary's: this "
                        "binary's sweep is timed again with --kt K, so that both build one tree")
    args = p.parse_args()
    scenes = os.environ.get("SAHKD_SCENES", os.path.join(ROOT, "..", "shared", "scenes"))
    print("| scene | builder (axes) | threads | build ms, median (min-max) | / Embree same threads "
          "| SAH cost | nodes | references | peak working B/tri |")
    print("|---|---|---:|---:|---:|---:|---:|---:|---:|")
    notes = []
    for name in args.meshes:
        mesh = os.path.join(scenes, f"{name}.ply")
        before = load()
        rows = []
        for a, x, t, bins in CONFIGS:
            r = sahkd(args.sahkd, mesh, a, x, t, args.repeat, bins)
            binned = f", {r['bins']} bins" if r["bins"] else ""
            rows.append((f"{a} ({x}{binned})", t, r))
        if args.baseline:
            for axes in ["longest", "all"]:
                if args.baseline_kt is not None:
                    rows.append((f"sweep ({axes}, K_T {args.baseline_kt:g})", 1,
                                 sahkd(args.sahkd, mesh, "sweep", axes, 1, args.repeat,
                                       extra=["--kt", str(args.baseline_kt)])))
                rows.append((f"sweep ({axes}), baseline binary", 1,
                             sahkd(args.baseline, mesh, "sweep", axes, 1, args.repeat)))
        bvh = {t: embree(mesh, t, args.repeat) for t in (2, 1)}
        label = f"{name} ({rows[0][2]['triangles']:,})"
        for i, (builder, threads, r) in enumerate(rows):
            bold = "**" if i == 0 else ""
            print(f"| {label if i == 0 else ''} | {bold}{builder}{bold} | {threads} | {spread(r['ms'])} "
                  f"| {r['ms'][0] / bvh[threads][0]:.2f} | {r['sah']:.3f} | {r['nodes']:,} | {r['refs']:,} "
                  f"| {working(r['bytes'])} |", flush=True)
        print(f"| | Embree 4 BVH | 2 / 1 | {spread(bvh[2])} / {spread(bvh[1])} | 1 | (BVH) | | | |", flush=True)
        if args.baseline:
            for axes in ["longest", "all"]:
                mine = f"sweep ({axes}, K_T {args.baseline_kt:g})" if args.baseline_kt is not None \
                    else f"sweep ({axes})"
                new = next(r for b, t, r in rows if b == mine)
                old = next(r for b, t, r in rows if b == f"sweep ({axes}), baseline binary")
                # The SAH cost is summed in each report's own order: equal to rounding (dragon_res2
                # at K_T 15: 1315.40989 both ways, 2.6e-8 apart).
                same = (new["nodes"], new["refs"]) == (old["nodes"], old["refs"]) and \
                    abs(new["sah"] - old["sah"]) <= 1e-7 * new["sah"]
                notes.append(f"{name} sweep ({axes}): baseline / this = {old['ms'][0] / new['ms'][0]:.2f}x, "
                             f"{'same' if same else 'DIFFERENT'} tree")
        notes.append(f"{name}: load average {before} before, {load()} after")
    print()
    for n in notes:
        print(f"- {n}")


if __name__ == "__main__":
    main()
