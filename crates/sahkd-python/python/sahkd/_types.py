"""Result types of the queries (plain named tuples of numpy arrays)."""

from typing import Any, NamedTuple

import numpy as np
import numpy.typing as npt

_Floats = npt.NDArray[np.floating[Any]]
_Ints = npt.NDArray[np.int64]


class Hits(NamedTuple):
    """Closest hit of each ray: t (float32, inf on a miss), prim (int64 face index,
    -1 on a miss), u, v (float32 barycentrics of corners 1 and 2; the hit point is
    (1 - u - v) * p0 + u * p1 + v * p2)."""

    t: _Floats
    prim: _Ints
    u: _Floats
    v: _Floats


class AllHits(NamedTuple):
    """Every hit of every ray as flat arrays: the hits of ray i are the slice
    offsets[i]:offsets[i + 1] of t, prim, u and v, nearest first."""

    t: _Floats
    prim: _Ints
    u: _Floats
    v: _Floats
    offsets: _Ints

    @property
    def ray(self) -> _Ints:
        """The ray index of each hit (int64)."""
        counts = np.diff(self.offsets)
        return np.repeat(np.arange(len(counts), dtype=np.int64), counts)

    @property
    def counts(self) -> _Ints:
        """The number of hits of each ray (int64)."""
        return np.diff(self.offsets)


class Closest(NamedTuple):
    """Closest point of the mesh to each query point: point (float64, (N, 3)), distance
    (float64, (N,)), prim (int64 face index, -1 on a mesh without faces)."""

    point: npt.NDArray[np.float64]
    distance: npt.NDArray[np.float64]
    prim: _Ints


class SceneHits(NamedTuple):
    """Closest hit of each ray in a Scene: Hits' fields (prim is the face in the mesh of
    the geometry hit, u, v its barycentrics) and geometry_id (int64, -1 on a miss)."""

    t: _Floats
    prim: _Ints
    u: _Floats
    v: _Floats
    geometry_id: _Ints


class SceneClosest(NamedTuple):
    """Closest point of a Scene to each query point: Closest's fields and the
    geometry it lies on (int64, -1 on an empty scene)."""

    point: npt.NDArray[np.float64]
    distance: npt.NDArray[np.float64]
    prim: _Ints
    geometry_id: _Ints
