"""Result types of the queries (plain named tuples of numpy arrays)."""

from collections import namedtuple

import numpy as np

Hits = namedtuple("Hits", ["t", "prim", "u", "v"])
Hits.__doc__ = """Closest hit of each ray: t (float32, inf on a miss), prim (int64 face index,
-1 on a miss), u, v (float32 barycentrics of corners 1 and 2; the hit point is
(1 - u - v) * p0 + u * p1 + v * p2)."""


class AllHits(namedtuple("AllHits", ["t", "prim", "u", "v", "offsets"])):
    """Every hit of every ray as flat arrays: the hits of ray i are the slice
    offsets[i]:offsets[i + 1] of t, prim, u and v, nearest first."""

    __slots__ = ()

    @property
    def ray(self):
        """The ray index of each hit (int64)."""
        counts = np.diff(self.offsets)
        return np.repeat(np.arange(len(counts), dtype=np.int64), counts)

    @property
    def counts(self):
        """The number of hits of each ray (int64)."""
        return np.diff(self.offsets)


Closest = namedtuple("Closest", ["point", "distance", "prim"])
Closest.__doc__ = """Closest point of the mesh to each query point: point (float64, (N, 3)), distance
(float64, (N,)), prim (int64 face index, -1 on a mesh without faces)."""

SceneHits = namedtuple("SceneHits", ["t", "prim", "u", "v", "geometry_id"])
SceneHits.__doc__ = """Closest hit of each ray in a Scene: Hits' fields (prim is the face in the mesh of
the geometry hit, u, v its barycentrics) and geometry_id (int64, -1 on a miss)."""

SceneClosest = namedtuple("SceneClosest", ["point", "distance", "prim", "geometry_id"])
SceneClosest.__doc__ = """Closest point of a Scene to each query point: Closest's fields and the
geometry it lies on (int64, -1 on an empty scene)."""
