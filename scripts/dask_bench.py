#!/usr/bin/env python3
"""Rays per second of sahkd.dask.trace on a LocalCluster of 1 and of 2 workers.

    python scripts/dask_bench.py [MESH] [--rays 16000000] [--blocks 64] [--workers 1,2]
    python scripts/dask_bench.py MESH --scheduler tcp://host:8786   # a real cluster instead

Builds MESH's tree here (default ../shared/scenes/dragon.ply; skips, saying so, if absent),
makes the rays on the workers (each block from its own seed: origins on a sphere around the
mesh, aimed at random points of its bounding box) and keeps them there, then times
`sahkd.dask.trace` plus a reduction on the workers (hits and the sum of t per block), so that
what is timed is the tracing, not shipping rays or hits through this process. Each worker has
one Dask thread and RAYON_NUM_THREADS=1, so N workers use N cores. The first trace (which
scatters the tree and unpickles it on each worker) is timed apart; the rays/s are the median
of --repeat traces after it. Needs `pip install "sahkd[dask]"`.

With --scheduler the same code runs on the cluster at that address (`Client(address)`); the
workers there must have sahkd installed, and should be started with RAYON_NUM_THREADS equal
to their threads (e.g. `RAYON_NUM_THREADS=8 dask worker tcp://host:8786 --nthreads 8`).
"""

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np


def make_rays(block_id, n, lo, hi, seed):
    """n rays of block block_id: same rays for the same (seed, block) wherever it runs."""
    rng = np.random.default_rng([seed, block_id])
    centre, radius = (lo + hi) / 2, np.linalg.norm(hi - lo)
    d = rng.normal(size=(n, 3))
    origins = centre + radius * d / np.linalg.norm(d, axis=1, keepdims=True)
    targets = rng.uniform(lo, hi, (n, 3))
    return np.hstack([origins, targets - origins]).astype(np.float32)


def rays_on_workers(n_rays, blocks, lo, hi, seed):
    import dask.array as da

    base, extra = divmod(n_rays, blocks)
    rows = tuple(base + (i < extra) for i in range(blocks))
    return da.map_blocks(
        lambda block_id=None: make_rays(block_id[0], rows[block_id[0]], lo, hi, seed),
        chunks=(rows, (6,)), dtype=np.float32, meta=np.empty((0, 6), np.float32),
    )  # fmt: skip


def block_summary(t, prim):
    hit = prim >= 0
    return np.array([[hit.sum(), t[hit].astype(np.float64).sum()]])


def measure(client, tree, n_rays, blocks, repeat, lo, hi, seed):
    import dask.array as da
    import sahkd.dask
    from distributed import wait

    rays = client.persist(rays_on_workers(n_rays, blocks, lo, hi, seed))
    wait(rays)

    def once():
        start = time.perf_counter()
        hits = sahkd.dask.trace(tree, rays, client=client)
        per_block = da.map_blocks(
            block_summary, hits.t, hits.prim, chunks=((1,) * blocks, (2,)), new_axis=1,
            dtype=np.float64,
        )  # fmt: skip
        total = client.compute(per_block.sum(axis=0)).result()
        return time.perf_counter() - start, int(total[0]), total[1]

    first, hits, tsum = once()  # scatter + one unpickle per worker + trace
    times = [once()[0] for _ in range(repeat)]
    del rays
    return first, times, hits, tsum


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    root = Path(__file__).resolve().parents[1]
    ap.add_argument("mesh", nargs="?", default=str(root.parent / "shared" / "scenes" / "dragon.ply"))
    ap.add_argument("--rays", type=int, default=16_000_000)
    ap.add_argument("--blocks", type=int, default=64)
    ap.add_argument("--workers", default="1,2", help="worker counts of the LocalClusters")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--scheduler", help="address of a running scheduler (no LocalCluster)")
    args = ap.parse_args()

    if not os.path.exists(args.mesh):
        print(f"skipped: {args.mesh} not found (give a mesh path)")
        return 0
    try:
        from distributed import Client, LocalCluster
    except ImportError:
        print('skipped: dask.distributed is not installed (pip install "sahkd[dask]")')
        return 0
    import sahkd
    import sahkd.dask

    start = time.perf_counter()
    tree = sahkd.KdTree(*sahkd.dask.read_mesh(args.mesh))
    build = time.perf_counter() - start
    lo, hi = (np.asarray(b, np.float64) for b in tree.bounds)
    print(f"{args.mesh}: {len(tree)} triangles, built in {build:.2f} s; {args.rays} rays in "
          f"{args.blocks} blocks, median of {args.repeat}")  # fmt: skip

    configs = [("scheduler " + args.scheduler, None)] if args.scheduler else [
        (f"{n} worker{'s' * (n > 1)}", n) for n in map(int, args.workers.split(","))
    ]  # fmt: skip
    rates = {}
    for label, n in configs:
        if n is None:
            client, cluster = Client(args.scheduler), None
        else:
            cluster = LocalCluster(
                n_workers=n, threads_per_worker=1, processes=True, dashboard_address=None,
                env={"RAYON_NUM_THREADS": "1"},
            )  # fmt: skip
            client = Client(cluster)
        try:
            first, times, hits, tsum = measure(
                client, tree, args.rays, args.blocks, args.repeat, lo, hi, args.seed
            )
        finally:
            client.close()
            if cluster is not None:
                cluster.close()
        med = statistics.median(times)
        rates[n] = args.rays / med
        print(f"{label}: {args.rays / med / 1e6:.2f} Mrays/s (median {med:.2f} s, "
              f"min-max {min(times):.2f}-{max(times):.2f} s; first call {first:.2f} s); "
              f"{hits} hits, sum of t {tsum:.6g}")  # fmt: skip
    if 1 in rates and 2 in rates:
        print(f"2 workers / 1 worker: {rates[2] / rates[1]:.2f}x")
    return 0


if __name__ == "__main__":
    sys.exit(main())
