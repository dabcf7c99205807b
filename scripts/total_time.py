#!/usr/bin/env python3
"""A user's total time, build plus one million rays, for each build preset (and variants of
the default), through the Python package, in one run: the table that chooses `balanced`.

    cargo build --release -p sahkd --example trace_throughput
    crates/sahkd-python/test.sh            # or any venv with the sahkd package installed
    VENV/bin/python scripts/total_time.py [--repeat 3] [--rays 1000000] [CASE ...]

A CASE is MESH:CAMERA as in scripts/ray_table.py; default bunny and dragon from near and
sponza_dabrovic from inside. The example dumps each case's mesh and ray sets (primary rays of a
1024 x 1024 picture; from their hits shadow, AO and bounce rays); the mixed set is `--rays` rays,
a quarter from each set taken at an even stride (a set with fewer rays is repeated). Each
candidate is timed as a user runs it, `sahkd.KdTree(V, F, ...)` and then `intersect` on the
primary and bounce quarters and `occluded` on the shadow and AO quarters, every core, `--repeat`
times (the median total is reported, with its build and ray parts from that run). Prints one
markdown table per case and the sum over the cases, each candidate's total against the
`balanced` preset's, and the load average before and after.
"""

import argparse
import os
import statistics
import subprocess
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
DEFAULT_CASES = ["bunny:near", "sponza_dabrovic:auto", "dragon:near"]
# The presets, then the default with one option changed: the settings `balanced` is chosen from.
CANDIDATES = {
    "fast": dict(preset="fast"),
    "balanced": dict(preset="balanced"),
    "quality": dict(preset="quality"),
    "balanced + clip on": dict(preset="balanced", clip=True),
    "balanced + clip on + K_T 45": dict(preset="balanced", clip=True, traversal=45.0),
    "balanced + 16 bins": dict(preset="balanced", bins=16),
    "balanced + 64 bins": dict(preset="balanced", bins=64),
    "balanced + all axes": dict(preset="balanced", axes="all"),
    "balanced + K_T 45": dict(preset="balanced", traversal=45.0),
    "balanced + K_T 90": dict(preset="balanced", traversal=90.0),
}


def load():
    with open("/proc/loadavg") as f:
        return " ".join(f.read().split()[:3])


def mixed(dump, total):
    """The four quarters of the mixed set: (query, origins, directions, t_min, t_max)."""
    quarters = []
    with open(os.path.join(dump, "sets.txt")) as f:
        sets = [line.split() for line in f if line.strip()]
    for name, query in sets:
        rays = np.load(os.path.join(dump, f"{name}.npy"))
        want = total // len(sets)
        stride = max(1, len(rays) // want)
        rays = np.resize(rays[::stride], (want, rays.shape[1]))
        rays = np.ascontiguousarray(rays, dtype=np.float32)
        quarters.append((query, rays[:, 0:3], rays[:, 3:6], rays[:, 6], rays[:, 7]))
    return quarters


def timed(sahkd, vertices, faces, options, quarters):
    start = time.perf_counter()
    tree = sahkd.KdTree(vertices, faces, **options)
    built = time.perf_counter()
    for query, origins, directions, t_min, t_max in quarters:
        if query == "closest":
            tree.intersect(origins, directions, t_min, t_max)
        else:
            tree.occluded(origins, directions, t_min, t_max)
    done = time.perf_counter()
    return (built - start) * 1e3, (done - built) * 1e3


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("cases", nargs="*", default=DEFAULT_CASES)
    p.add_argument("--repeat", type=int, default=3)
    p.add_argument("--rays", type=int, default=1_000_000)
    p.add_argument("--candidates", help="comma-separated names, default all: " + ", ".join(CANDIDATES))
    p.add_argument("--out", default=os.path.join(ROOT, "target", "total-time"))
    p.add_argument("--example", default=os.path.join(ROOT, "target", "release", "examples", "trace_throughput"))
    args = p.parse_args()
    import sahkd

    names = args.candidates.split(",") if args.candidates else list(CANDIDATES)
    unknown = [n for n in names if n not in CANDIDATES]
    if unknown:
        sys.exit(f"unknown candidates {unknown}; known: {', '.join(CANDIDATES)}")
    scenes = os.environ.get("SAHKD_SCENES", os.path.join(ROOT, "..", "shared", "scenes"))
    sums = {n: 0.0 for n in names}
    notes = []
    for case in args.cases:
        mesh, camera = case.split(":")
        dump = os.path.join(args.out, f"{mesh}-{camera}")
        if not os.path.exists(os.path.join(dump, "sets.txt")):
            subprocess.run([args.example, os.path.join(scenes, f"{mesh}.ply"), "--camera", camera,
                            "--threads", "1", "--repeat", "1", "--no-count", "--dump", dump],
                           check=True, capture_output=True)
        vertices = np.load(os.path.join(dump, "vertices.npy"))
        faces = np.load(os.path.join(dump, "faces.npy"))
        quarters = mixed(dump, args.rays)
        before = load()
        rows = {}
        for name in names:
            timed(sahkd, vertices, faces, CANDIDATES[name], quarters)  # warm-up
            runs = sorted((timed(sahkd, vertices, faces, CANDIDATES[name], quarters)
                           for _ in range(args.repeat)), key=sum)
            rows[name] = runs[len(runs) // 2]
            sums[name] += sum(rows[name])
        base = sum(rows["balanced"]) if "balanced" in rows else None
        print(f"\n{mesh} ({len(faces):,} triangles), {camera} camera, {args.rays:,} mixed rays, "
              f"every core, median of {args.repeat}\n")
        print("| build | build ms | rays ms | total ms | / balanced |")
        print("|---|---:|---:|---:|---:|")
        for name in names:
            b, r = rows[name]
            ratio = f"{(b + r) / base:.2f}" if base else "-"
            print(f"| {name} | {b:.0f} | {r:.0f} | {b + r:.0f} | {ratio} |", flush=True)
        notes.append(f"{case}: load average {before} before, {load()} after")
    base = sums.get("balanced")
    print(f"\nSum over {', '.join(args.cases)}\n")
    print("| build | total ms | / balanced |")
    print("|---|---:|---:|")
    for name in names:
        ratio = f"{sums[name] / base:.2f}" if base else "-"
        print(f"| {name} | {sums[name]:.0f} | {ratio} |")
    with open("/proc/cpuinfo") as f:
        model = next((l.split(":", 1)[1].strip() for l in f if l.startswith("model name")), "?")
    print(f"\n- {model}, {os.cpu_count()} cores")
    for n in notes:
        print(f"- {n}")


if __name__ == "__main__":
    main()
