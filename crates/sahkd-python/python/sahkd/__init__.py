"""sahkd: SAH kd-trees for ray casting from numpy.

    >>> import numpy as np, sahkd
    >>> vertices = np.array([[0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]], np.float32)
    >>> faces = np.array([[0, 1, 2], [0, 2, 3]])
    >>> tree = sahkd.KdTree(vertices, faces)
    >>> hits = tree.intersect(np.array([[0.25, 0.5, 0.0]]), np.array([[0.0, 0.0, 1.0]]))
    >>> float(hits.t[0]), int(hits.prim[0])
    (1.0, 1)

Builds and queries run on every core (or `threads=`) with the interpreter released. Trees
pickle (they travel as their bytes) and save to files (`tree.save(path)`, `sahkd.load(path)`).
`sahkd.Scene` holds several meshes and their instances (transformed copies) in one tree,
with the geometry id in every answer. `sahkd.trimesh.RayMeshIntersector` is a drop-in ray
intersector for trimesh meshes, and
`python -m sahkd.compare MESH` times sahkd against the other ray casters installed.
"""

from ._sahkd import KdTree, Scene, __version__, from_bytes, load
from ._types import AllHits, Closest, Hits, SceneClosest, SceneHits

__all__ = [
    "KdTree",
    "Scene",
    "load",
    "from_bytes",
    "Hits",
    "AllHits",
    "Closest",
    "SceneHits",
    "SceneClosest",
    "__version__",
]
