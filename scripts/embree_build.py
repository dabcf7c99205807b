#!/usr/bin/env python3
"""Times Embree 4's BVH build (embreex, its default build quality) on a triangle mesh, beside
`sahkd build --json`, for the build-time comparison in BENCHMARKS.md.

    python scripts/embree_build.py MESH [--repeat K]

The mesh is read by sahkd's own reader (the `sahkd` Python package: `maturin develop` in
crates/sahkd-python), so that Embree builds exactly the vertices and faces `sahkd build` does;
where that package is not installed, by `trimesh.load` (unprocessed: the same arrays for a
triangle PLY), saying so. It is handed to Embree as an indexed triangle mesh, not a soup.
Embree builds its BVH on the scene's first query; the timed region is that first query of one
ray on a fresh scene (a single ray costs microseconds). Embree uses every core the process may
run on: run it under `taskset -c 0` for one thread. Prints the median and the min-max of K
builds after one warm-up, in ms. Needs `pip install embreex trimesh numpy`.
"""
import argparse
import statistics
import time

import numpy as np


def load_indexed(path):
    """Vertices (V, 3) float32 and faces (F, 3) int32, as sahkd's reader reads them (the
    file's own vertices, none merged or dropped)."""
    try:
        from sahkd._sahkd import _read_mesh
    except ImportError:
        import sys

        import trimesh

        print("embree_build: the sahkd package is not installed; reading with trimesh", file=sys.stderr)
        mesh = trimesh.load(path, force="mesh", process=False)
        vertices, faces = mesh.vertices, mesh.faces
    else:
        vertices, faces = _read_mesh(path)
    vertices = np.ascontiguousarray(vertices, dtype=np.float32)
    faces = np.ascontiguousarray(faces, dtype=np.int32)
    return vertices, faces


def build_once(vertices, faces):
    from embreex import rtcore_scene
    from embreex.mesh_construction import TriangleMesh

    scene = rtcore_scene.EmbreeScene()
    TriangleMesh(scene=scene, vertices=vertices, indices=faces)
    one = np.zeros((1, 3), np.float32)
    start = time.perf_counter()
    scene.run(one, one + 1)
    return (time.perf_counter() - start) * 1e3


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("mesh")
    p.add_argument("--repeat", type=int, default=5)
    args = p.parse_args()
    vertices, faces = load_indexed(args.mesh)
    build_once(vertices, faces)
    times = [build_once(vertices, faces) for _ in range(args.repeat)]
    print(
        f"embree {args.mesh}: {len(faces)} triangles, {len(vertices)} vertices, build median "
        f"{statistics.median(times):.1f} ms (min {min(times):.1f}, max {max(times):.1f}, "
        f"{args.repeat} builds)"
    )


if __name__ == "__main__":
    main()
