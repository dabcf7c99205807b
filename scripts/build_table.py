#!/usr/bin/env python3
"""The build-time table of BENCHMARKS.md and README: every build preset of sahkd beside
Embree 4's BVH build (embreex, its default quality) on the same meshes, 2 and 1 threads, in
one run.

    cargo build --release -p sahkd-cli
    VENV/bin/python scripts/build_table.py [--repeat 5] [--presets LIST] [--python] [--baseline OLD_SAHKD] [MESH ...]

MESH is a name in ../shared/scenes (or $SAHKD_SCENES); default bunny, sponza_dabrovic, dragon
and dragon_res2. Every preset is one warm-up build and `--repeat` timed builds of `sahkd build
--preset NAME --json` (`build_ms`, the median reported), one process per build; one thread
means `taskset -c 0` and `--threads 1`. `--python` times sahkd instead the way Embree is timed,
from Python in one process: the indexed mesh read once, one warm-up build, then `--repeat`
timed calls of the whole `sahkd.KdTree(vertices, faces, preset=NAME)` constructor
(scripts/sahkd_build.py; needs the sahkd package in the interpreter running this), the
package's default threads (all the process may run on, so one under `taskset -c 0`). `sweep` is
serial and is timed at one thread only. Embree is timed by scripts/embree_build.py in the same
run, from the indexed mesh (needs embreex, and sahkd's Python package or trimesh to read it,
in the interpreter running this), under `taskset -c 0` for one thread. `--embree3` adds Embree
3's build at medium quality (its default) and at high quality (spatial splits, the peer of the
`quality` preset's clipped splits), timed by scripts/embree3_build.cpp (compiled into target/
on first use; needs Debian's libembree-dev) on the same indexed mesh. `--baseline` adds the
serial sweep of another sahkd binary (one built at an older commit, say), to compare sweeps at
identical trees: its rows must give the same nodes, references and SAH cost; `--baseline-kt K`
times this binary's sweep again at the baseline's K_T for that comparison (these rows go
through the CLI). Prints one markdown table with medians and min-max, the ratio to Embree at
the same threads, the build's phases of the last 2-thread run, and the load average before
and after each mesh.
"""

import argparse
import json
import os
import re
import statistics
import struct
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
DEFAULT_MESHES = ["bunny", "sponza_dabrovic", "dragon", "dragon_res2"]
PRESETS = ["fast", "balanced", "quality", "paper", "sweep"]
SERIAL = {"sweep"}
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


def sahkd(binary, mesh, options, threads, repeat):
    """One warm-up and `repeat` timed builds, each a fresh `sahkd build` process."""
    cmd = pinned(threads) + [binary, "build", mesh, "--threads", str(threads), "--json", "--quiet"] \
        + list(options)
    run(cmd)
    reports = [json.loads(run(cmd)) for _ in range(repeat)]
    times = [r["build_ms"] for r in reports]
    return summary((statistics.median(times), min(times), max(times)), reports[-1])


def sahkd_python(mesh, preset, threads, repeat):
    """One warm-up and `repeat` timed builds in one Python process (scripts/sahkd_build.py)."""
    out = json.loads(run(pinned(threads) + [sys.executable, os.path.join(HERE, "sahkd_build.py"), mesh,
                                            "--preset", preset, "--repeat", str(repeat)]))
    return summary((out["median"], out["min"], out["max"]), out["stats"])


def summary(ms, last):
    return dict(
        ms=ms, sah=last["sah_cost"], nodes=last["nodes"], refs=last["references"],
        triangles=last["triangles"],
        phases={k: last.get(k, 0.0) for k in ("presort_ms", "binned_ms", "subtrees_ms", "layout_ms")},
    )


def embree(mesh, threads, repeat):
    out = run(pinned(threads) + [sys.executable, os.path.join(HERE, "embree_build.py"), mesh,
                                 "--repeat", str(repeat)])
    m = EMBREE.search(out)
    return tuple(map(float, m.groups()))


def embree3_binary():
    """scripts/embree3_build.cpp compiled into target/, again whenever the source is newer."""
    source = os.path.join(HERE, "embree3_build.cpp")
    binary = os.path.join(ROOT, "target", "embree3_build")
    if not os.path.exists(binary) or os.path.getmtime(binary) < os.path.getmtime(source):
        run(["c++", "-O2", "-std=c++17", source, "-lembree3", "-o", binary])
    return binary


def embree3(binary, mesh, quality, threads, repeat):
    """Embree 3's build of `mesh` at `quality`, from the indexed mesh embree_build.py loads."""
    sys.path.insert(0, HERE)
    from embree_build import load_indexed

    vertices, faces = load_indexed(mesh)
    with tempfile.NamedTemporaryFile(suffix=".bin") as f:
        f.write(struct.pack("<II", len(vertices), len(faces)))
        f.write(vertices.astype("<f4").tobytes())
        f.write(faces.astype("<u4").tobytes())
        f.flush()
        out = run(pinned(threads) + [binary, f.name, quality, str(threads), str(repeat)])
    return tuple(map(float, EMBREE.search(out).groups()))


def spread(t):
    return f"{t[0]:.0f} ({t[1]:.0f}-{t[2]:.0f})" if t[0] >= 100 else f"{t[0]:.1f} ({t[1]:.1f}-{t[2]:.1f})"


def phases(r):
    p = r["phases"]
    return (f"presort {p['presort_ms']:.0f}, top {p['binned_ms']:.0f}, subtrees {p['subtrees_ms']:.0f}, "
            f"layout {p['layout_ms']:.0f}")


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("meshes", nargs="*", default=DEFAULT_MESHES)
    p.add_argument("--repeat", type=int, default=5)
    p.add_argument("--presets", default=",".join(PRESETS), help="comma-separated preset names")
    p.add_argument("--sahkd", default=os.path.join(ROOT, "target", "release", "sahkd"))
    p.add_argument("--python", action="store_true",
                   help="time sahkd's Python constructor in one process, as Embree is timed, "
                        "instead of one CLI process per build")
    p.add_argument("--embree3", action="store_true",
                   help="add Embree 3's medium and high (spatial-split) builds")
    p.add_argument("--baseline", help="another sahkd binary whose serial sweep is timed beside")
    p.add_argument("--baseline-kt", type=float,
                   help="the baseline's default K_T, where it differs from this binary's: this "
                        "binary's sweep is timed again with --kt K, so that both build one tree")
    args = p.parse_args()
    scenes = os.environ.get("SAHKD_SCENES", os.path.join(ROOT, "..", "shared", "scenes"))
    print("| mesh | build | 2 threads ms, median (min-max) | / Embree | 1 thread ms | / Embree "
          "| SAH cost | nodes | references | phases at 2 threads, ms (top and subtrees: workers' time) |")
    print("|---|---|---:|---:|---:|---:|---:|---:|---:|---|")
    notes = []
    e3 = embree3_binary() if args.embree3 else None
    for name in args.meshes:
        mesh = os.path.join(scenes, f"{name}.ply")
        before = load()
        bvh = {t: embree(mesh, t, args.repeat) for t in (2, 1)}
        e3_rows = [(q, {t: embree3(e3, mesh, q, t, args.repeat) for t in (2, 1)})
                   for q in ("medium", "high")] if e3 else []
        rows = []
        for preset in args.presets.split(","):
            def timed_at(t):
                if args.python:
                    return sahkd_python(mesh, preset, t, args.repeat)
                return sahkd(args.sahkd, mesh, ["--preset", preset], t, args.repeat)
            timed = {t: timed_at(t) for t in ((1,) if preset in SERIAL else (2, 1))}
            rows.append((preset, timed))
        if args.baseline:
            for axes in ["longest", "all"]:
                options = ["--preset", "sweep", "--axes", axes]
                if args.baseline_kt is not None:
                    rows.append((f"sweep ({axes}, K_T {args.baseline_kt:g})",
                                 {1: sahkd(args.sahkd, mesh, options + ["--kt", str(args.baseline_kt)], 1,
                                           args.repeat)}))
                rows.append((f"sweep ({axes}), baseline binary",
                             {1: sahkd(args.baseline, mesh, ["--algorithm", "sweep", "--axes", axes], 1,
                                       args.repeat)}))
        triangles = rows[0][1][1]["triangles"]
        print(f"| {name} ({triangles:,}) | Embree 4 BVH | {spread(bvh[2])} | 1 | {spread(bvh[1])} | 1 "
              f"| (BVH) | | | |", flush=True)
        for quality, timed in e3_rows:
            print(f"| | Embree 3 BVH, {quality} quality | {spread(timed[2])} | {timed[2][0] / bvh[2][0]:.2f} "
                  f"| {spread(timed[1])} | {timed[1][0] / bvh[1][0]:.2f} | (BVH) | | | |", flush=True)
        for builder, timed in rows:
            two, one = timed.get(2), timed[1]
            cells = f"{spread(two['ms'])} | {two['ms'][0] / bvh[2][0]:.2f}" if two else "(serial) | "
            bold = "**" if builder == "balanced" else ""
            print(f"| | {bold}{builder}{bold} | {cells} | {spread(one['ms'])} | {one['ms'][0] / bvh[1][0]:.2f} "
                  f"| {one['sah']:.3f} | {one['nodes']:,} | {one['refs']:,} | {phases(two or one)} |", flush=True)
        high = dict(e3_rows).get("high")
        quality = dict(rows).get("quality")
        if high and quality:
            notes.append(f"{name}: quality / Embree 3 high quality = "
                         f"{quality[2]['ms'][0] / high[2][0]:.2f}x at 2 threads, "
                         f"{quality[1]['ms'][0] / high[1][0]:.2f}x at 1")
        if args.baseline:
            for axes in ["longest", "all"]:
                mine = f"sweep ({axes}, K_T {args.baseline_kt:g})" if args.baseline_kt is not None \
                    else "sweep"
                new = next(t[1] for b, t in rows if b == mine)
                old = next(t[1] for b, t in rows if b == f"sweep ({axes}), baseline binary")
                # The SAH cost is summed in each report's own order: equal to rounding.
                same = (new["nodes"], new["refs"]) == (old["nodes"], old["refs"]) and \
                    abs(new["sah"] - old["sah"]) <= 1e-7 * new["sah"]
                notes.append(f"{name} sweep ({axes}): baseline / this = {old['ms'][0] / new['ms'][0]:.2f}x, "
                             f"{'same' if same else 'DIFFERENT'} tree")
        notes.append(f"{name}: load average {before} before, {load()} after")
    with open("/proc/cpuinfo") as f:
        model = next((l.split(":", 1)[1].strip() for l in f if l.startswith("model name")), "?")
    print()
    print(f"- {model}, {os.cpu_count()} cores")
    for n in notes:
        print(f"- {n}")


if __name__ == "__main__":
    main()
