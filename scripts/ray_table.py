#!/usr/bin/env python3
"""The ray-throughput table of BENCHMARKS.md: sahkd (Rust batch calls and the Python package)
against Embree 4 on the very same rays, every ray type, 1 and 2 threads, in one run.

    cargo build --release -p sahkd --example trace_throughput
    crates/sahkd-python/test.sh            # or any venv with the sahkd package installed
    pip install embreex                    # into the same venv
    VENV/bin/python scripts/ray_table.py [--repeat 3] [--threads 1,2] [--out DIR] [--single] [CASE ...]

A CASE is MESH:CAMERA with MESH a name in ../shared/scenes (or $SAHKD_SCENES) and CAMERA one of
trace_throughput's (near: 0.75 diagonals in front, front: 2 diagonals, auto: the render's
camera, inside the building for Sponza). Default: dragon and bunny from near and front, and
sponza_dabrovic from inside. For each case the example builds the default tree, makes the
primary rays and the shadow, AO and bounce rays of their hits, times them, and dumps them
(`--dump`); scripts/embree_throughput.py --sahkd then times Embree and sahkd's Python calls on
the dumped rays. Prints one markdown table (Mrays/s medians with min-max, ratios of medians)
and the load average before and after each case. `--single` also times the single-ray calls
(`--walk single`: the walk of the 8-wide nodes, one ray at a time) on the same rays in the
same run, in two more columns.
"""

import argparse
import os
import re
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
DEFAULT_CASES = ["dragon:near", "dragon:front", "bunny:near", "bunny:front", "sponza_dabrovic:auto"]

RUST = re.compile(
    r"^\s*(\w+) \((closest|any)\):\s+(\d+) rays,\s+([0-9.]+)% hit, (\d+) thread\(s\),\s+([0-9.]+) Mrays/s "
    r"median \(([0-9.]+)-([0-9.]+)\), ([0-9.]+) nodes, ([0-9.]+) leaves, ([0-9.]+) triangles"
)
EMBREE = re.compile(
    r"^\s*(\w+) \((closest|any)\):\s+(\d+) rays,.* (\d+) process\(es\),\s+([0-9.]+) Mrays/s median "
    r"\(([0-9.]+)-([0-9.]+)\), agree with sahkd on (\d+) of (\d+)"
)
PYTHON = re.compile(
    r"^\s*sahkd Python, (\d+) thread\(s\):\s+([0-9.]+) Mrays/s median \(([0-9.]+)-([0-9.]+)\), "
    r"same answer as the example on (\d+) of (\d+)"
)


def load():
    with open("/proc/loadavg") as f:
        return " ".join(f.read().split()[:3])


def run(cmd):
    print("$ " + " ".join(cmd), file=sys.stderr, flush=True)
    done = subprocess.run(cmd, capture_output=True, text=True)
    if done.returncode != 0:
        sys.exit(f"{cmd[0]} failed ({done.returncode}):\n{done.stdout}{done.stderr}")
    print(done.stdout, file=sys.stderr, flush=True)
    return done.stdout


def case(mesh, camera, args):
    scenes = os.environ.get("SAHKD_SCENES", os.path.join(ROOT, "..", "shared", "scenes"))
    dump = os.path.join(args.out, f"{mesh}-{camera}")
    before = load()
    rust = run([
        args.example, os.path.join(scenes, f"{mesh}.ply"), "--camera", camera, "--threads",
        args.threads, "--repeat", str(args.repeat), "--dump", dump,
    ])
    single = run([
        args.example, os.path.join(scenes, f"{mesh}.ply"), "--camera", camera, "--threads",
        args.threads, "--repeat", str(args.repeat), "--walk", "single", "--no-count",
    ]) if args.single else ""
    other = run([
        sys.executable, os.path.join(HERE, "embree_throughput.py"), dump, "--threads", args.threads,
        "--repeat", str(args.repeat), "--sahkd",
    ])
    rows = {}
    for line in rust.splitlines():
        m = RUST.match(line)
        if m:
            key = (m.group(1), int(m.group(5)))
            rows[key] = dict(
                rays=int(m.group(3)), hit=float(m.group(4)), rust=tuple(map(float, m.group(6, 7, 8))),
                nodes=float(m.group(9)), tris=float(m.group(11)),
            )
    for line in single.splitlines():
        m = RUST.match(line)
        if m:
            rows[(m.group(1), int(m.group(5)))]["single"] = tuple(map(float, m.group(6, 7, 8)))
    current = None
    for line in other.splitlines():
        m = EMBREE.match(line)
        if m:
            current = (m.group(1), int(m.group(4)))
            rows[current]["embree"] = tuple(map(float, m.group(5, 6, 7)))
            rows[current]["agree"] = (int(m.group(8)), int(m.group(9)))
            continue
        m = PYTHON.match(line)
        if m and current:
            rows[current]["python"] = tuple(map(float, m.group(2, 3, 4)))
            rows[current]["same"] = (int(m.group(5)), int(m.group(6)))
    return rows, before, load()


def spread(r):
    return f"{r[0]:.2f} ({r[1]:.2f}-{r[2]:.2f})"


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("cases", nargs="*", default=DEFAULT_CASES)
    p.add_argument("--repeat", type=int, default=3)
    p.add_argument("--threads", default="1,2")
    p.add_argument("--out", default=os.path.join(ROOT, "target", "rays"))
    p.add_argument("--single", action="store_true", help="also time the single-ray calls")
    p.add_argument("--example", default=os.path.join(ROOT, "target", "release", "examples", "trace_throughput"))
    args = p.parse_args()
    if not os.path.exists(args.example):
        sys.exit(f"{args.example} not found: cargo build --release -p sahkd --example trace_throughput")
    extra = " sahkd single | single / Embree |" if args.single else ""
    print("| mesh | camera | rays | threads | sahkd Rust | sahkd Python | Embree | Rust / Embree | Python / Rust |"
          + extra + " nodes / triangles per ray |")
    print("|---" * (10 + 2 * args.single) + "|")
    notes = []
    for spec in args.cases:
        mesh, _, camera = spec.partition(":")
        rows, before, after = case(mesh, camera or "near", args)
        for (name, threads), r in rows.items():
            ratio = r["rust"][0] / r["embree"][0] if "embree" in r else float("nan")
            door = r["python"][0] / r["rust"][0] if "python" in r else float("nan")
            single = ""
            if args.single:
                w = r.get("single", (0, 0, 0))
                single = f" {spread(w)} | {w[0] / r['embree'][0] if 'embree' in r else float('nan'):.2f} |"
            print(
                f"| {mesh} | {camera} | {name} {r['rays']:,} ({r['hit']:.0f} % hit) | {threads} | {spread(r['rust'])} "
                f"| {spread(r.get('python', (0, 0, 0)))} | {spread(r.get('embree', (0, 0, 0)))} | {ratio:.2f} | {door:.2f} |"
                + single + f" {r['nodes']:.1f} / {r['tris']:.2f} |",
                flush=True,
            )
            if "agree" in r and r["agree"][0] != r["agree"][1]:
                notes.append(f"{mesh} {camera} {name}: Embree agrees with sahkd on {r['agree'][0]:,} of {r['agree'][1]:,} rays")
            if "same" in r and r["same"][0] != r["same"][1]:
                notes.append(f"{mesh} {camera} {name}: Python differs from the example on {r['same'][1] - r['same'][0]:,} rays")
        notes.append(f"{mesh} {camera}: load average {before} before, {after} after")
    print()
    for n in notes:
        print(f"- {n}")


if __name__ == "__main__":
    main()
