"""Times Open3D's RaycastingScene and trimesh.proximity on the points query_throughput dumped,
and compares their answers with sahkd's.

    cargo run --release -p sahkd --example query_throughput -- MESH --dump DIR
    python scripts/query_compare.py DIR [--threads 2] [--trimesh-points 200]

Open3D (`pip install open3d`; it needs libusb-1.0-0) gets the indexed mesh as its users hand it
over (`RaycastingScene.add_triangles(vertices, faces)`) and every point; trimesh (with scipy)
the same mesh and only the first --trimesh-points points, it being slow.
Rates are points per second of the median of three runs (trimesh: one). Agreement: the
largest difference of distances, and the share of points more than 1e-4 of the diagonal
from the surface whose inside/outside answers differ from sahkd's.
"""

import argparse
import statistics
import time
from pathlib import Path

import numpy as np


def timed(f, repeat):
    times, out = [], None
    for _ in range(repeat):
        start = time.perf_counter()
        out = f()
        times.append(time.perf_counter() - start)
    return statistics.median(times), out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("dump")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--trimesh-points", type=int, default=200)
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    d = Path(args.dump)
    tri = np.load(d / "triangles.npy")
    points = np.load(d / "points.npy")
    distance = np.load(d / "distance.npy")
    signed = np.load(d / "signed.npy")
    inside = np.load(d / "inside.npy") > 0.5
    vertices = np.load(d / "vertices.npy")
    faces = np.load(d / "faces.npy").astype(np.uint32)
    diag = np.linalg.norm(vertices.max(0) - vertices.min(0))
    away = np.abs(distance) > 1e-4 * diag
    n = len(points)
    print(f"{len(tri)} triangles, {n} points, {args.threads} threads")
    try:
        import open3d as o3d

        scene = o3d.t.geometry.RaycastingScene()
        scene.add_triangles(o3d.core.Tensor(vertices), o3d.core.Tensor(faces))
        q = o3d.core.Tensor(points)
        nt = args.threads
        s, out = timed(lambda: scene.compute_closest_points(q, nthreads=nt), args.repeat)
        o3d_d = np.linalg.norm(out["points"].numpy().astype(np.float64) - points, axis=1)
        print(f"open3d {o3d.__version__} closest points   {n / s / 1e6:.4f} Mpoints/s; "
              f"max |distance - sahkd| {np.abs(o3d_d - distance).max():.3g}")
        s, sd = timed(lambda: scene.compute_signed_distance(q, nthreads=nt).numpy(), args.repeat)
        differ = ((sd < 0) != (signed < 0))[away].mean()
        print(f"open3d {o3d.__version__} signed distance  {n / s / 1e6:.4f} Mpoints/s; "
              f"sign differs from sahkd on {100 * differ:.3f} % of points off the surface")
        s, occ = timed(lambda: scene.compute_occupancy(q, nthreads=nt).numpy(), args.repeat)
        differ = ((occ > 0.5) != inside)[away].mean()
        print(f"open3d {o3d.__version__} occupancy        {n / s / 1e6:.4f} Mpoints/s; "
              f"differs from sahkd on {100 * differ:.3f} % of points off the surface")
    except ImportError as e:
        print(f"open3d not available: {e}")
    if args.trimesh_points <= 0:
        return
    try:
        import trimesh

        mesh = trimesh.Trimesh(vertices=vertices, faces=faces, process=False)
        k = min(args.trimesh_points, n)
        s, out = timed(lambda: trimesh.proximity.closest_point(mesh, points[:k]), 1)
        print(f"trimesh {trimesh.__version__} closest point  {k / s:.1f} points/s (on {k}); "
              f"max |distance - sahkd| {np.abs(out[1] - distance[:k]).max():.3g}")
    except ImportError as e:
        print(f"trimesh not available: {e}")


if __name__ == "__main__":
    main()
