"""An Open3D-style raycasting scene on sahkd, without Open3D.

    >>> import numpy as np
    >>> from sahkd.open3d import RaycastingScene
    >>> scene = RaycastingScene()
    >>> v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], np.float32)
    >>> f = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]], np.uint32)
    >>> scene.add_triangles(v, f)
    0
    >>> scene.compute_occupancy(np.array([[0.1, 0.1, 0.1], [1, 1, 1]], np.float32)).tolist()
    [1.0, 0.0]

`RaycastingScene` has the methods, argument shapes and result shapes and dtypes of
`open3d.t.geometry.RaycastingScene`: `add_triangles`, `cast_rays`, `test_occlusions`,
`count_intersections`, `list_intersections`, `compute_closest_points`, `compute_distance`,
`compute_signed_distance` and `compute_occupancy`. Query points are arrays of shape (..., 3)
and rays of shape (..., 6) (origin, direction); results are numpy arrays (Open3D returns
tensors), so code that calls `.numpy()` on results must drop that call. Inputs may be numpy
arrays or anything with a `.numpy()` method.

Differences: several geometries share one kd-tree, rebuilt on the first query after an
`add_triangles`; closest points are exact (float64, then rounded to float32 like Open3D's
results); `compute_signed_distance` and `compute_occupancy` take `inside="parity"` (one
ray's crossing parity, three voting where it passes near an edge; for closed meshes, like
Open3D's assumption) or `inside="winding"`
(the generalized winding number, right also for meshes with holes); `nthreads` and
`nsamples` are accepted and ignored (the tree's `threads` applies).
"""

import numpy as np

from ._sahkd import KdTree

INVALID_ID = np.iinfo(np.uint32).max


def _array(x, dtype):
    if hasattr(x, "numpy") and not isinstance(x, np.ndarray):
        x = x.numpy()
    return np.asarray(x, dtype=dtype)


def _rows(x, width, name):
    """An array of shape (..., width) as (n, width) float32 and its leading shape."""
    a = _array(x, np.float32)
    if a.ndim < 1 or a.shape[-1] != width:
        raise ValueError(f"{name} must have shape (..., {width}), got {a.shape}")
    return a.reshape(-1, width), a.shape[:-1]


class RaycastingScene:
    """Ray and point queries on triangle meshes, Open3D's RaycastingScene interface."""

    def __init__(self, nthreads=0, **options):
        if nthreads and "threads" not in options:
            options["threads"] = nthreads
        self._options = options
        self._vertices = []
        self._faces = []
        self._tree = None
        self._triangles = None
        self._offsets = np.zeros(1, np.int64)

    def add_triangles(self, vertex_positions, triangle_indices=None):
        """Adds a mesh, as (V, 3) vertices and (F, 3) triangles, or one object with
        `vertices` and `triangles` (or `faces`); returns its geometry id."""
        if triangle_indices is None:
            mesh = vertex_positions
            vertex_positions = mesh.vertices
            triangle_indices = getattr(mesh, "triangles", None)
            if triangle_indices is None:
                triangle_indices = mesh.faces
        v = _array(vertex_positions, np.float32)
        f = _array(triangle_indices, np.int64)
        if v.ndim != 2 or v.shape[1] != 3:
            raise ValueError(f"vertex_positions must have shape (V, 3), got {v.shape}")
        if f.size == 0:
            f = f.reshape(0, 3)
        if f.ndim != 2 or f.shape[1] != 3:
            raise ValueError(f"triangle_indices must have shape (F, 3), got {f.shape}")
        if f.size and (f.min() < 0 or f.max() >= len(v)):
            raise ValueError(
                f"triangle_indices must lie in 0..{len(v) - 1}, got {f.min()}..{f.max()}"
            )
        base = sum(len(x) for x in self._vertices)
        self._vertices.append(v)
        self._faces.append(f + base)
        self._offsets = np.append(self._offsets, self._offsets[-1] + len(f))
        self._tree = None
        self._triangles = None
        return len(self._faces) - 1

    @property
    def tree(self):
        """The `sahkd.KdTree` over every geometry added so far."""
        if self._tree is None:
            v = np.concatenate(self._vertices) if self._vertices else np.zeros((0, 3), np.float32)
            f = np.concatenate(self._faces) if self._faces else np.zeros((0, 3), np.int64)
            self._tree = KdTree(v, f, **self._options)
            self._triangles = None
        return self._tree

    def _ids(self, prim):
        """Geometry and per-geometry primitive ids (uint32, INVALID_ID where prim is -1)."""
        prim = np.asarray(prim, np.int64)
        valid = prim >= 0
        geometry = np.searchsorted(self._offsets, prim, side="right") - 1
        local = prim - self._offsets[np.clip(geometry, 0, len(self._offsets) - 1)]
        geometry = np.where(valid, geometry, INVALID_ID).astype(np.uint32)
        local = np.where(valid, local, INVALID_ID).astype(np.uint32)
        return geometry, local

    def _corners(self, prim):
        """The corners (n, 3, 3) float64 of the given faces (prim >= 0)."""
        if self._triangles is None:
            self._triangles = self.tree.triangles  # a copy: made once per tree
        return self._triangles[prim].astype(np.float64)

    def _normals(self, prim):
        out = np.zeros((len(prim), 3), np.float32)
        ok = prim >= 0
        c = self._corners(prim[ok])
        n = np.cross(c[:, 1] - c[:, 0], c[:, 2] - c[:, 0])
        length = np.linalg.norm(n, axis=1, keepdims=True)
        out[ok] = np.divide(n, length, out=np.zeros_like(n), where=length > 0)
        return out

    def _uvs(self, prim, points):
        """Barycentric (u, v) of corners 1 and 2 for points on the given faces."""
        out = np.zeros((len(prim), 2), np.float32)
        ok = prim >= 0
        c = self._corners(prim[ok])
        e1, e2, d = c[:, 1] - c[:, 0], c[:, 2] - c[:, 0], points[ok] - c[:, 0]
        a, b, cc = (e1 * e1).sum(1), (e1 * e2).sum(1), (e2 * e2).sum(1)
        p, q = (d * e1).sum(1), (d * e2).sum(1)
        det = a * cc - b * b
        safe = np.where(det > 0, det, 1.0)
        u = np.where(det > 0, (cc * p - b * q) / safe, 0.0)
        v = np.where(det > 0, (a * q - b * p) / safe, 0.0)
        out[ok] = np.stack([u, v], axis=1)
        return out

    def cast_rays(self, rays, nthreads=0):
        """The first hit of each ray: dict of t_hit (float32, inf on a miss), geometry_ids and
        primitive_ids (uint32, INVALID_ID on a miss), primitive_uvs (..., 2) and
        primitive_normals (..., 3) (float32)."""
        r, shape = _rows(rays, 6, "rays")
        hits = self.tree.intersect(r[:, :3], r[:, 3:])
        geometry, local = self._ids(hits.prim)
        uvs = np.stack([hits.u, hits.v], axis=1).astype(np.float32)
        return {
            "t_hit": hits.t.reshape(shape),
            "geometry_ids": geometry.reshape(shape),
            "primitive_ids": local.reshape(shape),
            "primitive_uvs": uvs.reshape(shape + (2,)),
            "primitive_normals": self._normals(hits.prim).reshape(shape + (3,)),
        }

    def test_occlusions(self, rays, tnear=0.0, tfar=np.inf, nthreads=0):
        """Whether anything is hit with tnear <= t <= tfar: bool (...)."""
        r, shape = _rows(rays, 6, "rays")
        return self.tree.occluded(r[:, :3], r[:, 3:], t_min=tnear, t_max=tfar).reshape(shape)

    def count_intersections(self, rays, nthreads=0):
        """How many faces each ray crosses (t >= 0), each face once: int32 (...)."""
        r, shape = _rows(rays, 6, "rays")
        return self.tree.count_hits(r[:, :3], r[:, 3:]).astype(np.int32).reshape(shape)

    def list_intersections(self, rays, nthreads=0):
        """Every hit of every ray, nearest first: dict of ray_splits (n + 1,) and ray_ids,
        geometry_ids, primitive_ids (uint32), primitive_uvs (m, 2) and t_hit (m,) float32.
        The hits of ray i are the slice ray_splits[i]:ray_splits[i + 1]."""
        r, _ = _rows(rays, 6, "rays")
        hits = self.tree.intersect_all(r[:, :3], r[:, 3:])
        geometry, local = self._ids(hits.prim)
        return {
            "ray_splits": hits.offsets.astype(np.uint32),
            "ray_ids": hits.ray.astype(np.uint32),
            "geometry_ids": geometry,
            "primitive_ids": local,
            "primitive_uvs": np.stack([hits.u, hits.v], axis=1).astype(np.float32),
            "t_hit": hits.t,
        }

    def compute_closest_points(self, query_points, nthreads=0):
        """The closest point of the scene to each point: dict of points (..., 3),
        geometry_ids and primitive_ids (uint32), primitive_uvs (..., 2) and
        primitive_normals (..., 3) (float32)."""
        p, shape = _rows(query_points, 3, "query_points")
        found = self.tree.closest_point(p)
        geometry, local = self._ids(found.prim)
        return {
            "points": found.point.astype(np.float32).reshape(shape + (3,)),
            "geometry_ids": geometry.reshape(shape),
            "primitive_ids": local.reshape(shape),
            "primitive_uvs": self._uvs(found.prim, found.point).reshape(shape + (2,)),
            "primitive_normals": self._normals(found.prim).reshape(shape + (3,)),
        }

    def compute_distance(self, query_points, nthreads=0):
        """Distance to the scene, float32 (...)."""
        p, shape = _rows(query_points, 3, "query_points")
        return self.tree.distance(p).astype(np.float32).reshape(shape)

    def compute_signed_distance(self, query_points, nthreads=0, nsamples=1, inside="parity"):
        """Distance to the scene, negative inside, float32 (...)."""
        p, shape = _rows(query_points, 3, "query_points")
        d = self.tree.signed_distance(p, inside=inside)
        return d.astype(np.float32).reshape(shape)

    def compute_occupancy(self, query_points, nthreads=0, nsamples=1, inside="parity"):
        """1.0 inside the scene and 0.0 outside, float32 (...)."""
        p, shape = _rows(query_points, 3, "query_points")
        return self.tree.contains(p, inside=inside).astype(np.float32).reshape(shape)
