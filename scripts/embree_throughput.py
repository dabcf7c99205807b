#!/usr/bin/env python3
"""Embree 4 (through embreex's single-ray loop) on the rays the trace_throughput example dumped.

    cargo run --release -p sahkd --example trace_throughput -- MESH --camera front --dump DIR
    python scripts/embree_throughput.py DIR [--threads N] [--repeat 7]

Reads DIR/triangles.npy, DIR/primary.npy and DIR/occlusion.npy (rows ox oy oz dx dy dz t_min
t_max), traces the primary rays (closest hit) and the occlusion rays (any hit) with embreex's
`EmbreeScene.run`, and prints the median and min-max Mrays/s over --repeat traces, the share
of rays that hit, and how many primary rays agree with sahkd's answers in
DIR/primary_hits.npy (same triangle, or both miss).

With --threads N the rays are split into N contiguous parts traced by N processes at once,
each with its own copy of the scene (embreex holds the GIL while it traces); the time of a
repeat is from a common start to the last process finishing. Needs numpy and embreex only.
"""

import argparse
import multiprocessing as mp
import sys
import time

import numpy as np


def make_scene(triangles):
    from embreex import rtcore_scene
    from embreex.mesh_construction import TriangleMesh

    scene = rtcore_scene.EmbreeScene()
    TriangleMesh(scene=scene, vertices=triangles)
    one = np.zeros((1, 3), np.float32)
    scene.run(one, one + 1)  # Embree builds its BVH on the first query
    return scene


def trace(scene, rays, query):
    origins = np.ascontiguousarray(rays[:, 0:3])
    directions = np.ascontiguousarray(rays[:, 3:6])
    # INTERSECT answers the primID per ray (-1 for a miss); OCCLUDED 0 for a blocked ray.
    return scene.run(origins, directions, query=query)


def worker(triangles, rays, query, repeat, barrier, times, index, threads):
    scene = make_scene(triangles)
    for k in range(repeat):
        barrier.wait()
        trace(scene, rays, query)
        times[k * threads + index] = time.perf_counter()
        barrier.wait()


def run_parallel(triangles, rays, query, repeat, threads):
    """Mrays/s of each repeat with `threads` processes sharing the rays."""
    parts = np.array_split(rays, threads)
    barrier = mp.Barrier(threads + 1)
    times = mp.Array("d", repeat * threads, lock=False)
    procs = [
        mp.Process(target=worker, args=(triangles, part, query, repeat, barrier, times, i, threads))
        for i, part in enumerate(parts)
    ]
    for p in procs:
        p.start()
    rates = []
    for k in range(repeat):
        barrier.wait()
        start = time.perf_counter()
        barrier.wait()
        end = max(times[k * threads : (k + 1) * threads])
        rates.append(len(rays) / (end - start) / 1e6)
    for p in procs:
        p.join()
    return rates


def summary(rates):
    rates = sorted(rates)
    return f"{rates[len(rates) // 2]:6.2f} Mrays/s median ({rates[0]:.2f}-{rates[-1]:.2f})"


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("dir")
    p.add_argument("--threads", type=int, default=1)
    p.add_argument("--repeat", type=int, default=7)
    args = p.parse_args(argv)
    if args.threads < 1 or args.repeat < 1:
        p.error("--threads and --repeat must be at least 1")
    try:
        import embreex
    except ImportError as e:
        sys.exit(f"embreex is not installed ({e}); pip install embreex numpy")

    triangles = np.load(f"{args.dir}/triangles.npy")
    primary = np.load(f"{args.dir}/primary.npy")
    occlusion = np.load(f"{args.dir}/occlusion.npy")
    sahkd_hits = np.load(f"{args.dir}/primary_hits.npy")

    scene = make_scene(triangles)
    prim = trace(scene, primary, "INTERSECT")
    sahkd_prim = sahkd_hits[:, 1].astype(np.int64)
    agree = int(np.sum(prim == sahkd_prim))
    blocked = trace(scene, occlusion, "OCCLUDED")
    # embreex reports an occluded ray as 0 and a free one as -1.
    blocked_share = float(np.mean(blocked == 0)) if len(occlusion) else 0.0
    print(
        f"embreex {getattr(embreex, '__version__', '')}: {len(triangles)} triangles, "
        f"{args.threads} process(es), {args.repeat} repeats"
    )
    for name, rays, query, share in [
        ("primary", primary, "INTERSECT", float(np.mean(prim >= 0))),
        ("occlusion", occlusion, "OCCLUDED", blocked_share),
    ]:
        if args.threads == 1:
            rates = []
            for _ in range(args.repeat):
                start = time.perf_counter()
                trace(scene, rays, query)
                rates.append(len(rays) / (time.perf_counter() - start) / 1e6)
        else:
            rates = run_parallel(triangles, rays, query, args.repeat, args.threads)
        print(f"{name:>9}: {len(rays):>8} rays, {100 * share:5.1f}% hit, {summary(rates)}")
    print(f"primary rays where Embree and sahkd name the same triangle (or both miss): {agree} of {len(primary)}")


if __name__ == "__main__":
    main()
