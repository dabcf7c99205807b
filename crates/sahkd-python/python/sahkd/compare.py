"""Side by side: sahkd and the other ray casters installed, on the same mesh and rays.

    python -m sahkd.compare MESH [--size 1024] [--threads N] [--repeat 3]

Casts one camera's primary rays (from the centre of the mesh's bounds plus (0, 0, 2 x the
diagonal of the bounds), looking at the centre, up +y, 45 degree vertical field of view,
size x size pixels) with sahkd and with whichever of embreex, open3d and trimesh are
installed. For each it prints the build time, the trace time (median of --repeat casts),
million rays per second, the rays that hit, and how many rays agree with sahkd: both miss,
or both hit at distances within --tolerance (relative). trimesh's intersector is pure Python,
so it casts an evenly spaced sample of --trimesh-rays rays, and its numbers are for those.

Meshes are read with the library's reader (PLY, OBJ), as every other door of sahkd reads them;
other formats with trimesh, when it is installed.
"""

import argparse
import json
import os
import sys
import time

import numpy as np

import sahkd


def load_mesh(path):
    """(vertices float32 (V, 3), faces int32 (F, 3), reader name): the library's reader, or
    trimesh (when installed) for a file the library cannot read."""
    from ._sahkd import _read_mesh

    try:
        vertices, faces = _read_mesh(path)
        reader = "sahkd's mesh reader"
    except ValueError:
        try:
            import trimesh
        except ImportError:
            raise
        mesh = trimesh.load(path, force="mesh", process=False)
        vertices, faces, reader = mesh.vertices, mesh.faces, f"trimesh {trimesh.__version__}"
    return (
        np.ascontiguousarray(vertices, dtype=np.float32),
        np.ascontiguousarray(faces, dtype=np.int32),
        reader,
    )


def camera_rays(vertices, faces, size, fov_degrees=45.0):
    """Primary rays of the fixed camera, row by row from the top: origins and unit
    directions, float32 (size * size, 3)."""
    used = vertices[np.unique(faces)] if len(faces) else vertices[:0]
    if len(used) == 0:
        lo = hi = np.zeros(3)
    else:
        lo, hi = used.min(axis=0).astype(np.float64), used.max(axis=0).astype(np.float64)
    centre = (lo + hi) / 2
    diagonal = np.linalg.norm(hi - lo)
    eye = centre + np.array([0.0, 0.0, 2.0 * diagonal])
    half = np.tan(np.radians(fov_degrees) / 2)
    s = (np.arange(size) + 0.5) / size * 2 - 1
    x, y = np.meshgrid(s * half, -s * half)
    directions = np.stack([x.ravel(), y.ravel(), -np.ones(size * size)], axis=1)
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    origins = np.tile(eye, (size * size, 1))
    return origins.astype(np.float32), directions.astype(np.float32)


def _median_time(fn, repeat):
    times, result = [], None
    for _ in range(repeat):
        start = time.perf_counter()
        result = fn()
        times.append(time.perf_counter() - start)
    return float(np.median(times)), result


class Caster:
    """One library: build() then cast(origins, directions) -> (t float64, prim int64);
    misses are t = inf, prim = -1."""

    name = ""
    sample = None  # rays it casts, when fewer than all

    def build(self, vertices, faces):
        raise NotImplementedError

    def cast(self, origins, directions):
        raise NotImplementedError


class Sahkd(Caster):
    def __init__(self, threads, algorithm):
        self.name = f"sahkd {sahkd.__version__}"
        self.threads, self.algorithm = threads, algorithm

    def build(self, vertices, faces):
        self.tree = sahkd.KdTree(vertices, faces, algorithm=self.algorithm, threads=self.threads)

    def cast(self, origins, directions):
        h = self.tree.intersect(origins, directions)
        return h.t.astype(np.float64), h.prim


class Embreex(Caster):
    def __init__(self):
        import embreex
        from embreex import rtcore_scene
        from embreex.mesh_construction import TriangleMesh

        version = getattr(embreex, "__version__", "")
        self.name = f"embreex {version}".strip()
        self._scene_type, self._mesh_type = rtcore_scene.EmbreeScene, TriangleMesh

    def build(self, vertices, faces):
        self.scene = self._scene_type()
        self._mesh_type(scene=self.scene, vertices=vertices, indices=faces)
        # Embree builds its BVH on the first query: one ray makes the build part of this.
        one = np.zeros((1, 3), np.float32)
        self.scene.run(one, one + 1)

    def cast(self, origins, directions):
        r = self.scene.run(origins, directions, output=1)
        prim = r["primID"].astype(np.int64)
        t = np.where(prim >= 0, r["tfar"].astype(np.float64), np.inf)
        return t, prim


class Open3d(Caster):
    def __init__(self):
        import open3d

        self.name = f"open3d {open3d.__version__}"
        self.o3d = open3d

    def build(self, vertices, faces):
        o3d = self.o3d
        self.scene = o3d.t.geometry.RaycastingScene()
        self.scene.add_triangles(
            o3d.core.Tensor(vertices), o3d.core.Tensor(faces.astype(np.uint32))
        )
        # The BVH is built on the first query.
        self.scene.cast_rays(o3d.core.Tensor(np.array([[0, 0, 0, 0, 0, 1]], np.float32)))

    def cast(self, origins, directions):
        rays = np.ascontiguousarray(np.hstack([origins, directions]), dtype=np.float32)
        r = self.scene.cast_rays(self.o3d.core.Tensor(rays))
        t = r["t_hit"].numpy().astype(np.float64)
        prim = r["primitive_ids"].numpy().astype(np.int64)
        miss = ~np.isfinite(t)
        prim[miss] = -1
        t[miss] = np.inf
        return t, prim


class Trimesh(Caster):
    def __init__(self, sample):
        import trimesh
        import trimesh.ray.ray_triangle

        self.name = f"trimesh {trimesh.__version__} (ray_triangle)"
        self.trimesh, self.sample = trimesh, sample

    def build(self, vertices, faces):
        self.mesh = self.trimesh.Trimesh(vertices, faces, process=False)
        self.ray = self.trimesh.ray.ray_triangle.RayMeshIntersector(self.mesh)
        self.mesh.triangles_tree  # the r-tree of the faces' boxes

    def cast(self, origins, directions):
        o, d = origins.astype(np.float64), directions.astype(np.float64)
        index_tri, index_ray, locations = self.ray.intersects_id(
            o, d, multiple_hits=False, return_locations=True
        )
        t = np.full(len(o), np.inf)
        prim = np.full(len(o), -1, dtype=np.int64)
        t[index_ray] = np.einsum("ij,ij->i", locations - o[index_ray], d[index_ray]) / np.einsum(
            "ij,ij->i", d[index_ray], d[index_ray]
        )
        prim[index_ray] = index_tri
        return t, prim


def agreement(t_ref, prim_ref, t, prim, tolerance):
    """Fractions of rays that agree (both miss, or both hit within tolerance of t) and that
    hit the same face."""
    hit_ref, hit = prim_ref >= 0, prim >= 0
    both = hit_ref & hit
    close = np.zeros(len(t), dtype=bool)
    close[both] = np.abs(t[both] - t_ref[both]) <= tolerance * np.maximum(np.abs(t_ref[both]), 1e-30)
    agree = (~hit_ref & ~hit) | close
    same = (~hit_ref & ~hit) | (both & (prim == prim_ref))
    return float(agree.mean()) if len(t) else 1.0, float(same.mean()) if len(t) else 1.0


def casters(names, args):
    """The requested libraries that import, and why the others were skipped."""
    makers = {
        "sahkd": lambda: Sahkd(args.threads, args.algorithm),
        "embreex": Embreex,
        "open3d": Open3d,
        "trimesh": lambda: Trimesh(args.trimesh_rays),
    }
    found, skipped = [], []
    for name in names:
        if name not in makers:
            raise SystemExit(f"unknown library '{name}' (choose from {', '.join(makers)})")
        try:
            found.append(makers[name]())
        except Exception as e:  # an optional library that is missing or broken
            skipped.append((name, f"{type(e).__name__}: {e}"))
    return found, skipped


def main(argv=None):
    p = argparse.ArgumentParser(
        prog="python -m sahkd.compare", description=__doc__.split("\n\n")[0]
    )
    p.add_argument("mesh", help="a mesh file (PLY; anything trimesh reads if installed)")
    p.add_argument("--size", type=int, default=1024, help="image side in pixels (default 1024)")
    p.add_argument("--threads", type=int, default=None, help="sahkd's threads (default: all)")
    p.add_argument(
        "--algorithm", default=None, help="sahkd's builder (default: the library's)"
    )
    p.add_argument("--repeat", type=int, default=3, help="casts timed per library (median)")
    p.add_argument("--tolerance", type=float, default=1e-4, help="relative t tolerance")
    p.add_argument("--trimesh-rays", type=int, default=4096, help="rays cast by trimesh")
    p.add_argument(
        "--libraries", default="sahkd,embreex,open3d,trimesh", help="comma-separated list"
    )
    p.add_argument("--json", action="store_true", help="print the results as JSON")
    args = p.parse_args(argv)
    if args.size < 1 or args.repeat < 1:
        p.error("--size and --repeat must be at least 1")

    vertices, faces, reader = load_mesh(args.mesh)
    origins, directions = camera_rays(vertices, faces, args.size)
    names = [n.strip() for n in args.libraries.split(",") if n.strip()]
    if "sahkd" not in names:
        names.insert(0, "sahkd")
    found, skipped = casters(names, args)

    rows, reference = [], None
    for caster in found:
        o, d = origins, directions
        if caster.sample is not None and caster.sample < len(o):
            pick = np.linspace(0, len(o) - 1, caster.sample).round().astype(np.int64)
            o, d = o[pick], d[pick]
        else:
            pick = None
        start = time.perf_counter()
        caster.build(vertices, faces)
        build_s = time.perf_counter() - start
        trace_s, (t, prim) = _median_time(lambda: caster.cast(o, d), args.repeat)
        if reference is None:
            reference = (t, prim)
        t_ref = reference[0] if pick is None else reference[0][pick]
        prim_ref = reference[1] if pick is None else reference[1][pick]
        agree, same = agreement(t_ref, prim_ref, t, prim, args.tolerance)
        rows.append(
            {
                "library": caster.name,
                "rays": len(o),
                "build_s": build_s,
                "trace_s": trace_s,
                "mrays_per_s": len(o) / trace_s / 1e6 if trace_s > 0 else float("inf"),
                "hits": int((prim >= 0).sum()),
                "agree": agree,
                "same_face": same,
            }
        )

    info = {
        "mesh": args.mesh,
        "reader": reader,
        "triangles": int(len(faces)),
        "vertices": int(len(vertices)),
        "image": f"{args.size}x{args.size}",
        "rays": int(len(origins)),
        "cores": os.cpu_count(),
        "sahkd_threads": args.threads,
        "results": rows,
        "skipped": [{"library": n, "reason": r} for n, r in skipped],
    }
    if args.json:
        print(json.dumps(info, indent=2))
        return 0
    print(f"mesh: {args.mesh} ({len(faces):,} triangles, {len(vertices):,} vertices; read with {reader})")
    print(
        f"rays: {args.size}x{args.size} = {len(origins):,} primary rays; {os.cpu_count()} cores; "
        f"sahkd threads: {args.threads or 'all'}; trace time is the median of {args.repeat}"
    )
    header = f"{'library':<34} {'rays':>9} {'build s':>9} {'trace s':>9} {'Mrays/s':>9} {'hits':>9} {'agree':>8} {'same face':>9}"
    print(header)
    print("-" * len(header))
    for r in rows:
        print(
            f"{r['library']:<34} {r['rays']:>9,} {r['build_s']:>9.3f} {r['trace_s']:>9.3f} "
            f"{r['mrays_per_s']:>9.2f} {r['hits']:>9,} {100 * r['agree']:>7.2f}% {100 * r['same_face']:>8.2f}%"
        )
    for name, reason in skipped:
        print(f"skipped {name}: {reason}")
    print(
        f"agree: both miss, or both hit with |t - t_sahkd| <= {args.tolerance:g} t_sahkd; "
        "same face: both miss or both hit the same triangle"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
