"""A drop-in ray intersector for trimesh meshes.

    >>> import trimesh, sahkd.trimesh
    >>> mesh = trimesh.creation.icosphere()
    >>> mesh.ray = sahkd.trimesh.RayMeshIntersector(mesh)
    >>> mesh.contains([[0, 0, 0], [2, 0, 0]]).tolist()
    [True, False]

It has the methods and return conventions of trimesh's intersectors
(`trimesh.ray.ray_triangle.RayMeshIntersector` and the embree one): `intersects_id`,
`intersects_location`, `intersects_first`, `intersects_any` and `contains_points`, and works
wherever trimesh uses `mesh.ray`. The tree is built on first use and rebuilt when the mesh
changes; keyword arguments given to the constructor go to `sahkd.KdTree`.

Differences from trimesh's pure-Python intersector, which the tests check:

- sahkd works in float32 (trimesh in float64) and uses a watertight ray/triangle test: a ray
  through an edge or vertex shared by several faces hits at least one of them, possibly
  more; trimesh accepts a hit within 1e-12 (in barycentric terms) outside a face, so near an
  edge it may report one more or one fewer face than sahkd.
- Hits count from the ray origin on (t >= 0); trimesh also keeps hits up to 1e-6 behind it.
- With `return_locations=True` (and so in `intersects_location`), hits of one ray closer
  together than `merge_distance` are reported once, like trimesh's merging of identical
  locations but with a tolerance that suits float32.
- `max_hits` defaults to no limit (trimesh's embree intersector stops at 100).
- Zero-area faces are never hit (trimesh's intersectors skip them too).

Proximity drop-ins for `trimesh.proximity`: `closest_point(mesh, points)` and
`signed_distance(mesh, points)` take and return what trimesh's functions do (signed distance
positive inside, as trimesh has it), answered exactly (float64 point-triangle distances) by
the kd-tree instead of trimesh's candidate search. The tree is cached per mesh object and
rebuilt when the mesh changes. Query points are rounded to float32, the mesh's precision.

This module does not import trimesh: any object with `vertices`, `faces` and `bounds` works
as the mesh.
"""

import weakref

import numpy as np

from ._sahkd import KdTree

# Directions for the inside/outside ray tests: fixed (so results are reproducible), not
# parallel to any axis or to each other.
_CONTAINS_DIRECTIONS = np.array(
    [
        [0.4395064455, 0.617598629942, 0.652231566745],
        [-0.5341584237, 0.2907217349, 0.7938415622],
        [0.7283910131, -0.6008413582, 0.3292461711],
    ]
)


def _rays(ray_origins, ray_directions):
    origins = np.asanyarray(ray_origins, dtype=np.float64)
    directions = np.asanyarray(ray_directions, dtype=np.float64)
    if origins.ndim != 2 or origins.shape[1] != 3:
        raise ValueError(f"ray_origins must have shape (n, 3), got {origins.shape}")
    if directions.shape != origins.shape:
        raise ValueError(
            f"ray_directions must have the shape of ray_origins {origins.shape}, "
            f"got {directions.shape}"
        )
    return origins, directions


class RayMeshIntersector:
    """Ray queries on a trimesh mesh through a sahkd kd-tree."""

    def __init__(self, mesh, **options):
        self.mesh = mesh
        self._options = options
        self._tree = None
        self._key = None

    def _mesh_key(self):
        try:
            return hash(self.mesh)
        except TypeError:
            return id(self.mesh)

    @property
    def tree(self):
        """The `sahkd.KdTree` of the mesh, built on first use and after a mesh change."""
        key = self._mesh_key()
        if self._tree is None or key != self._key:
            faces = np.asarray(self.mesh.faces)
            vertices = np.asarray(self.mesh.vertices)
            if len(faces) == 0:
                faces = faces.reshape(0, 3).astype(np.int64)
            self._tree = KdTree(vertices, faces, **self._options)
            self._key = key
        return self._tree

    @property
    def merge_distance(self):
        """Hits of one ray closer than this are one location in `intersects_location`:
        1e-6 of the mesh's size and distance from the origin of coordinates, about eight
        float32 roundings at that scale."""
        bounds = np.asarray(self.tree.bounds, dtype=np.float64)
        if not np.isfinite(bounds).all():
            return 0.0
        return 1e-6 * (np.abs(bounds).max() + np.linalg.norm(bounds[1] - bounds[0]))

    def _merged(self, hits, directions):
        """A mask keeping the first of each run of hits of one ray that lie within
        merge_distance of the previous one."""
        keep = np.ones(len(hits.t), dtype=bool)
        if len(hits.t) < 2:
            return keep
        ray = hits.ray
        speed = np.linalg.norm(directions[ray], axis=1)
        gap = np.diff(hits.t.astype(np.float64)) * speed[1:]
        same_ray = ray[1:] == ray[:-1]
        keep[1:] = ~(same_ray & (gap <= self.merge_distance))
        return keep

    def intersects_id(
        self,
        ray_origins,
        ray_directions,
        multiple_hits=True,
        max_hits=None,
        return_locations=False,
        **kwargs,
    ):
        """The faces the rays hit.

        Returns index_tri (h,) int64, index_ray (h,) int64 and, with return_locations,
        locations (h, 3) float64. With multiple_hits every face along each ray (at most
        max_hits per ray, nearest first), else only the nearest. Other keyword arguments are
        accepted and ignored, as trimesh's intersector does.
        """
        origins, directions = _rays(ray_origins, ray_directions)
        tree = self.tree
        if not multiple_hits:
            first = tree.intersect(origins, directions)
            index_ray = np.flatnonzero(first.prim >= 0)
            index_tri = first.prim[index_ray]
            t = first.t[index_ray]
        else:
            hits = tree.intersect_all(origins, directions, max_hits=max_hits)
            index_tri, index_ray, t = hits.prim, hits.ray, hits.t
            if return_locations:
                keep = self._merged(hits, directions)
                index_tri, index_ray, t = index_tri[keep], index_ray[keep], t[keep]
        if not return_locations:
            return index_tri, index_ray
        locations = origins[index_ray] + directions[index_ray] * t.astype(np.float64)[:, None]
        return index_tri, index_ray, locations

    def intersects_location(self, ray_origins, ray_directions, multiple_hits=True, **kwargs):
        """Where the rays hit: locations (h, 3) float64, index_ray (h,), index_tri (h,);
        coincident hits of one ray (a ray through a shared edge) are reported once."""
        index_tri, index_ray, locations = self.intersects_id(
            ray_origins,
            ray_directions,
            multiple_hits=multiple_hits,
            return_locations=True,
            **kwargs,
        )
        return locations, index_ray, index_tri

    def intersects_first(self, ray_origins, ray_directions, **kwargs):
        """The nearest face each ray hits, int64 (n,), -1 where it hits none."""
        origins, directions = _rays(ray_origins, ray_directions)
        return self.tree.intersect(origins, directions).prim

    def intersects_any(self, ray_origins, ray_directions, **kwargs):
        """Whether each ray hits any face, bool (n,)."""
        origins, directions = _rays(ray_origins, ray_directions)
        return self.tree.occluded(origins, directions)

    def _crossings(self, points, direction):
        """Surfaces crossed by rays from the points along +direction and -direction, with
        coincident hits counted once: two (n,) int arrays."""
        n = len(points)
        origins = np.vstack((points, points))
        directions = np.vstack((np.tile(direction, (n, 1)), np.tile(-direction, (n, 1))))
        hits = self.tree.intersect_all(origins, directions)
        keep = self._merged(hits, directions)
        counts = np.bincount(hits.ray[keep], minlength=2 * n)
        return counts[:n], counts[n:]

    def contains_points(self, points):
        # Crossings are counted from intersect_all, which gives each face once, in ray
        # order, whatever the number of hits (no max_hits cut-off).
        """Whether each point is inside the mesh, bool (n,), by the parity of surface
        crossings; undefined for points on the surface, meaningful for closed meshes.

        A point is outside when a ray from it in some direction crosses nothing, and
        decided by parity when the rays both ways agree; otherwise the next of three fixed
        directions is tried, and the majority of all the parities decides at the end."""
        points = np.asanyarray(points, dtype=np.float64)
        if points.ndim != 2 or points.shape[1] != 3:
            raise ValueError(f"points must have shape (n, 3), got {points.shape}")
        contains = np.zeros(len(points), dtype=bool)
        bounds = np.asarray(self.tree.bounds, dtype=np.float64)
        undecided = np.flatnonzero(
            np.isfinite(points).all(axis=1)
            & (points >= bounds[0]).all(axis=1)
            & (points <= bounds[1]).all(axis=1)
        )
        votes = np.zeros(len(points), dtype=np.int64)
        for direction in _CONTAINS_DIRECTIONS:
            if len(undecided) == 0:
                break
            forward, backward = self._crossings(points[undecided], direction)
            odd_f, odd_b = forward % 2 == 1, backward % 2 == 1
            votes[undecided] += odd_f.astype(np.int64) + odd_b - (~odd_f) - (~odd_b)
            free = (forward == 0) | (backward == 0)
            agree = odd_f == odd_b
            decided = free | agree
            contains[undecided[decided]] = agree[decided] & odd_f[decided] & ~free[decided]
            undecided = undecided[~decided]
        contains[undecided] = votes[undecided] > 0
        return contains


# One intersector (and so one tree) per mesh object, for the proximity functions.
_INTERSECTORS = weakref.WeakKeyDictionary()


def _tree_of(mesh, options):
    ray = getattr(mesh, "__dict__", {}).get("ray")
    if isinstance(ray, RayMeshIntersector) and not options:
        return ray.tree
    try:
        intersector = _INTERSECTORS.get(mesh)
        if intersector is None or intersector._options != options:
            intersector = RayMeshIntersector(mesh, **options)
            _INTERSECTORS[mesh] = intersector
    except TypeError:  # not weakly referenceable: no cache
        intersector = RayMeshIntersector(mesh, **options)
    return intersector.tree


def _points(points):
    points = np.asanyarray(points, dtype=np.float64)
    if points.ndim != 2 or points.shape[1] != 3:
        raise ValueError(f"points must have shape (n, 3), got {points.shape}")
    return points


def closest_point(mesh, points, **options):
    """`trimesh.proximity.closest_point`: closest (m, 3) float64, distance (m,) float64 and
    triangle_id (m,) int64 of each point (the lowest face index among equally near ones).
    Keyword arguments go to `sahkd.KdTree`."""
    found = _tree_of(mesh, options).closest_point(_points(points))
    return found.point, found.distance, found.prim


def signed_distance(mesh, points, inside="parity", **options):
    """`trimesh.proximity.signed_distance`: (n,) float64, positive inside the mesh and
    negative outside (trimesh's convention, the opposite of `KdTree.signed_distance`).
    inside: "parity" (fast, for closed meshes) or "winding" (robust for meshes with holes,
    O(faces) per point)."""
    return -_tree_of(mesh, options).signed_distance(_points(points), inside=inside)
