#!/usr/bin/env python3
"""Times sahkd's build from Python the way scripts/embree_build.py times Embree's: the whole
`sahkd.KdTree(vertices, faces, preset=NAME)` constructor on the indexed mesh, one warm-up build
and then K timed builds in one process, for the build-time table (scripts/build_table.py).

    python scripts/sahkd_build.py MESH [--preset NAME] [--repeat K]

The builds use every core the process may run on (the package's default thread count): run it
under `taskset -c 0` for one thread. Prints one JSON object: the median, min and max in ms,
and the last build's `stats` (its phases, nodes, references, SAH cost). Needs the sahkd
package (`crates/sahkd-python/test.sh`, or `maturin develop --release` there).
"""
import argparse
import json
import statistics
import time

import sahkd
from sahkd._sahkd import _read_mesh


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("mesh")
    p.add_argument("--preset", default="balanced")
    p.add_argument("--repeat", type=int, default=5)
    args = p.parse_args()
    vertices, faces = _read_mesh(args.mesh)

    def build():
        start = time.perf_counter()
        tree = sahkd.KdTree(vertices, faces, preset=args.preset)
        return (time.perf_counter() - start) * 1e3, tree

    build()
    times = []
    for _ in range(args.repeat):
        # The tree before is freed after this one's timed call returns, so at most two are held.
        ms, tree = build()
        times.append(ms)
    print(json.dumps(dict(median=statistics.median(times), min=min(times), max=max(times),
                          stats=tree.stats)))


if __name__ == "__main__":
    main()
