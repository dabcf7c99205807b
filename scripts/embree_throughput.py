#!/usr/bin/env python3
"""Embree 4 (through embreex's single-ray loop) on the rays the trace_throughput example dumped.

    cargo run --release -p sahkd --example trace_throughput -- MESH --camera near --dump DIR
    python scripts/embree_throughput.py DIR [--threads 1,2] [--repeat 7] [--sahkd]

Reads the mesh, DIR/vertices.npy (float32 x y z rows) and DIR/faces.npy (int32 corner indices;
face i is sahkd's triangle i), and DIR/sets.txt (lines `NAME closest|any`), and per set DIR/NAME.npy
(rows ox oy oz dx dy dz t_min t_max; t_min is 0 in every set the example makes) and sahkd's
answers DIR/NAME_answers.npy. Embree's scene is made from the indexed mesh (vertices and
faces), the way embreex and trimesh users load it, not from a triangle soup, which costs
Embree 20-30 % of its ray rate. Traces each set with embreex's `EmbreeScene.run` (closest hit:
INTERSECT, any hit: OCCLUDED, t_max passed as `dists`), and prints the median and min-max
Mrays/s over --repeat traces, the share of rays that hit and on how many rays Embree and
sahkd agree (same triangle or both miss; both blocked or both free).

Only `scene.run` is inside the timed region: the ray arrays are split into contiguous
origins, directions and distances once, before timing (earlier versions of this script cut
and copied them inside it, and passed no distances, which embreex then allocates per call).

With --threads N the rays are split into N contiguous parts traced by N processes at once,
each with its own copy of the scene (embreex holds the GIL while it traces); the time of a
repeat is from the first process starting to the last one finishing. Needs numpy and embreex only.

With --sahkd, the same run also times sahkd's Python package on the same rays
(`KdTree.intersect` / `occluded` on a tree of the same vertices and faces built with the defaults and
`threads=N`, the arrays made once outside the timed region, so the door from Python is what is
measured against the Rust example's batch calls) and checks its answers against the dumped ones.
"""

import argparse
import multiprocessing as mp
import sys
import time

import numpy as np

QUERIES = {"closest": "INTERSECT", "any": "OCCLUDED"}


def make_scene(mesh):
    from embreex import rtcore_scene
    from embreex.mesh_construction import TriangleMesh

    vertices, faces = mesh
    scene = rtcore_scene.EmbreeScene()
    TriangleMesh(scene=scene, vertices=vertices, indices=faces)
    one = np.zeros((1, 3), np.float32)
    scene.run(one, one + 1)  # Embree builds its BVH on the first query
    return scene


def prepare(rays):
    """The arrays `scene.run` takes, made once outside the timed region."""
    return (
        np.ascontiguousarray(rays[:, 0:3]),
        np.ascontiguousarray(rays[:, 3:6]),
        np.ascontiguousarray(rays[:, 7]),
    )


def trace(scene, prepared, query):
    origins, directions, t_max = prepared
    # run() writes the distances it is given (tfar), so each trace gets a fresh copy; the copy
    # is a memcpy of 4 bytes a ray, the same as embreex's own allocation when none is given.
    # INTERSECT answers the primID per ray (-1 for a miss); OCCLUDED 0 for a blocked ray.
    return scene.run(origins, directions, dists=t_max.copy(), query=QUERIES[query])


def worker(mesh, rays, query, repeat, barrier, starts, times, index, threads):
    scene = make_scene(mesh)
    prepared = prepare(rays)
    for k in range(repeat):
        barrier.wait()
        starts[k * threads + index] = time.perf_counter()
        trace(scene, prepared, query)
        times[k * threads + index] = time.perf_counter()
        barrier.wait()


def run_parallel(mesh, rays, query, repeat, threads):
    """Mrays/s of each repeat with `threads` processes sharing the rays."""
    parts = np.array_split(rays, threads)
    barrier = mp.Barrier(threads + 1)
    starts = mp.Array("d", repeat * threads, lock=False)
    times = mp.Array("d", repeat * threads, lock=False)
    procs = [
        mp.Process(target=worker, args=(mesh, part, query, repeat, barrier, starts, times, i, threads))
        for i, part in enumerate(parts)
    ]
    for p in procs:
        p.start()
    rates = []
    for k in range(repeat):
        barrier.wait()
        barrier.wait()
        # From the first process starting to the last one finishing (each reads the clock
        # itself: a small set can be done before this process would have read it).
        start = min(starts[k * threads : (k + 1) * threads])
        end = max(times[k * threads : (k + 1) * threads])
        rates.append(len(rays) / (end - start) / 1e6)
    for p in procs:
        p.join()
    return rates


def sahkd_rates(mesh, rays, query, repeat, threads, theirs):
    """Mrays/s of sahkd's Python calls on `rays`, and on how many rays they agree with the
    example's answers (bit for bit: same t and triangle for closest hits)."""
    import sahkd

    tree = sahkd.KdTree(*mesh, threads=threads)
    origins, directions = np.ascontiguousarray(rays[:, 0:3]), np.ascontiguousarray(rays[:, 3:6])
    t_min, t_max = np.ascontiguousarray(rays[:, 6]), np.ascontiguousarray(rays[:, 7])
    call = tree.intersect if query == "closest" else tree.occluded
    answer = call(origins, directions, t_min, t_max)  # the first call makes the trace layout
    if query == "closest":
        agree = int(np.sum((answer.prim == theirs[:, 1].astype(np.int64)) & ((answer.t == theirs[:, 0]) | (answer.prim < 0))))
    else:
        agree = int(np.sum(answer == (theirs[:, 0] != 0)))
    rates = []
    for _ in range(repeat):
        start = time.perf_counter()
        call(origins, directions, t_min, t_max)
        rates.append(len(rays) / (time.perf_counter() - start) / 1e6)
    return rates, agree


def summary(rates):
    rates = sorted(rates)
    return f"{rates[len(rates) // 2]:6.2f} Mrays/s median ({rates[0]:.2f}-{rates[-1]:.2f})"


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("dir")
    p.add_argument("--threads", default="1,2", help="comma-separated process counts")
    p.add_argument("--repeat", type=int, default=7)
    p.add_argument("--sahkd", action="store_true", help="also time sahkd's Python calls on the same rays")
    args = p.parse_args(argv)
    try:
        threads = [int(t) for t in args.threads.split(",")]
    except ValueError:
        p.error(f"--threads: not a list of integers: {args.threads!r}")
    if min(threads) < 1 or args.repeat < 1:
        p.error("--threads and --repeat must be at least 1")
    try:
        import embreex
    except ImportError as e:
        sys.exit(f"embreex is not installed ({e}); pip install embreex numpy")

    try:
        mesh = (np.load(f"{args.dir}/vertices.npy"), np.load(f"{args.dir}/faces.npy"))
    except FileNotFoundError as e:
        sys.exit(f"{e.filename}: missing; dump the rays again with trace_throughput --dump (it writes the mesh)")
    with open(f"{args.dir}/sets.txt") as f:
        sets = [line.split() for line in f if line.strip()]
    scene = make_scene(mesh)
    print(
        f"embreex {getattr(embreex, '__version__', '')}: indexed mesh of {len(mesh[0])} vertices, "
        f"{len(mesh[1])} triangles, "
        f"{args.repeat} repeats"
    )
    for name, query in sets:
        rays = np.load(f"{args.dir}/{name}.npy")
        if len(rays) and np.any(rays[:, 6] != 0):
            sys.exit(f"{name}: rays with t_min != 0, which embreex's run cannot pass")
        theirs = np.load(f"{args.dir}/{name}_answers.npy")
        prepared = prepare(rays)
        answer = trace(scene, prepared, query)
        if query == "closest":
            found = answer >= 0
            agree = int(np.sum(answer == theirs[:, 1].astype(np.int64)))
        else:
            # embreex reports an occluded ray as 0 and a free one as -1.
            found = answer == 0
            agree = int(np.sum(found == (theirs[:, 0] != 0)))
        share = float(np.mean(found)) if len(rays) else 0.0
        for t in threads:
            if t == 1:
                rates = []
                for _ in range(args.repeat):
                    start = time.perf_counter()
                    trace(scene, prepared, query)
                    rates.append(len(rays) / (time.perf_counter() - start) / 1e6)
            else:
                rates = run_parallel(mesh, rays, query, args.repeat, t)
            print(
                f"{name:>7} ({query}): {len(rays):>8} rays, {100 * share:5.1f}% hit, {t} process(es), "
                f"{summary(rates)}, agree with sahkd on {agree} of {len(rays)}"
            )
            if args.sahkd:
                rates, same = sahkd_rates(mesh, rays, query, args.repeat, t, theirs)
                print(
                    f"{'':>7} sahkd Python, {t} thread(s): {summary(rates)}, "
                    f"same answer as the example on {same} of {len(rays)}"
                )


if __name__ == "__main__":
    main()
