#!/usr/bin/env python3
"""Times Embree 4's BVH build (embreex, its default build quality) on a binary PLY triangle
mesh, beside `sahkd build --json`, for the build-time comparison in BENCHMARKS.md.

    python scripts/embree_build.py MESH.ply [--repeat K]

Embree builds its BVH on the scene's first query; the timed region is that first query of
one ray on a fresh scene (a single ray costs microseconds). Embree uses every core the
process may run on: run it under `taskset -c 0` for one thread. Prints the median and the
min-max of K builds after one warm-up, in ms.
"""
import argparse
import statistics
import time

import numpy as np


def read_ply(path):
    """Vertices (V, 3) float32 and faces (F, 3) int32 of a binary little-endian PLY with float x, y, z vertices
    and a `list uchar int` face property (the meshes of ../shared/scenes)."""
    with open(path, "rb") as f:
        header = []
        while True:
            line = f.readline().decode("ascii").strip()
            header.append(line)
            if line == "end_header":
                break
        counts = {w[1]: int(w[2]) for w in (l.split() for l in header) if w[0] == "element"}
        if "format binary_little_endian 1.0" not in header:
            raise SystemExit(f"{path}: not a binary little-endian PLY")
        vertices = np.frombuffer(f.read(counts["vertex"] * 12), "<f4").reshape(-1, 3)
        faces = np.frombuffer(f.read(counts["face"] * 13), np.dtype([("n", "u1"), ("i", "<i4", 3)]))
    if (faces["n"] != 3).any():
        raise SystemExit(f"{path}: faces that are not triangles")
    return vertices, np.ascontiguousarray(faces["i"])


def build_once(mesh):
    from embreex import rtcore_scene
    from embreex.mesh_construction import TriangleMesh

    scene = rtcore_scene.EmbreeScene()
    vertices, faces = mesh
    # The indexed mesh, as embreex and trimesh users load it, not a triangle soup.
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
    mesh = read_ply(args.mesh)
    build_once(mesh)
    times = [build_once(mesh) for _ in range(args.repeat)]
    print(
        f"embree {args.mesh}: {len(mesh[1])} triangles, build median {statistics.median(times):.1f} ms"
        f" (min {min(times):.1f}, max {max(times):.1f}, {args.repeat} builds)"
    )


if __name__ == "__main__":
    main()
