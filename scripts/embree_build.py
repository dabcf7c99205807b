#!/usr/bin/env python3
"""Times Embree 4's BVH build (embreex, its default build quality) on a triangle mesh, beside
`sahkd build --json`, for the build-time comparison in BENCHMARKS.md.

    python scripts/embree_build.py MESH [--repeat K]

The mesh is loaded as embreex users load one: `trimesh.load` (vertices and faces, the faces
indexing the shared vertices), handed to Embree as an indexed triangle mesh, not a soup.
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
    """Vertices (V, 3) float32 and faces (F, 3) int32, as trimesh reads them (unprocessed:
    the file's own vertices, none merged or dropped)."""
    import trimesh

    mesh = trimesh.load(path, force="mesh", process=False)
    vertices = np.ascontiguousarray(mesh.vertices, dtype=np.float32)
    faces = np.ascontiguousarray(mesh.faces, dtype=np.int32)
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
