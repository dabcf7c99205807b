"""A typed program using every public call of sahkd: `mypy --strict` checks it against the
package's stubs (test.sh), and running it checks the answers it prints are right."""

import math
import os
import pickle
import tempfile

import numpy as np
import numpy.typing as npt

import sahkd


def unit_square() -> tuple[npt.NDArray[np.float32], npt.NDArray[np.int64]]:
    vertices = np.array([[0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]], np.float32)
    faces = np.array([[0, 1, 2], [0, 2, 3]], np.int64)
    return vertices, faces


def main() -> None:
    vertices, faces = unit_square()
    tree: sahkd.KdTree = sahkd.KdTree(vertices, faces, algorithm="sweep", threads=1, traversal=45.0)
    assert len(sahkd.KdTree(vertices, faces, preset="fast", clip=False)) == 2
    assert len(tree) == 2 and tree.bounds.shape == (2, 3) and tree.triangles.shape == (2, 3, 3)
    assert tree.stats["triangles"] == 2
    tree.validate()

    origins = np.array([[0.25, 0.5, 0.0], [2.0, 2.0, 0.0]])
    directions = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, 1.0]])
    hits: sahkd.Hits = tree.intersect(origins, directions, t_max=math.inf)
    assert float(hits.t[0]) == 1.0 and int(hits.prim[0]) == 1 and int(hits.prim[1]) == -1
    hits64 = tree.intersect(origins, directions, precision="f64")
    assert hits64.t.dtype == np.float64
    occluded: npt.NDArray[np.bool_] = tree.occluded(origins, directions, t_min=0.0)
    assert occluded.tolist() == [True, False]
    counts: npt.NDArray[np.int64] = tree.count_hits(origins, directions)
    everything: sahkd.AllHits = tree.intersect_all(origins, directions, max_hits=4)
    assert everything.counts.tolist() == counts.tolist() == [1, 0]
    assert everything.ray.tolist() == [0]

    points = np.array([[0.25, 0.5, 3.0]])
    closest: sahkd.Closest = tree.closest_point(points)
    assert float(closest.distance[0]) == 2.0
    distance: npt.NDArray[np.float64] = tree.distance(points)
    signed = tree.signed_distance(points, inside="winding")
    inside = tree.contains(points, inside="parity")
    winding = tree.winding_number(points)
    assert float(distance[0]) == float(signed[0]) == 2.0 and not bool(inside[0])
    assert abs(float(winding[0])) < 0.5

    copy: sahkd.KdTree = sahkd.from_bytes(tree.to_bytes())
    assert pickle.loads(pickle.dumps(copy)).intersect(origins, directions).prim.tolist() == [1, -1]
    with tempfile.TemporaryDirectory() as folder:
        path = os.path.join(folder, "square.sahkd")
        tree.save(path)
        assert len(sahkd.load(path)) == 2

    scene = sahkd.Scene()
    mesh_id: int = scene.add_mesh(vertices, faces)
    shift = np.eye(4)
    shift[2, 3] = 1.0
    instance: int = scene.add_instance(mesh_id, shift)
    scene.build(preset="quality")
    assert len(scene) == 2 and instance == 1
    down = np.array([[0.25, 0.5, 5.0]]), np.array([[0.0, 0.0, -1.0]])
    scene_hits: sahkd.SceneHits = scene.intersect(*down)
    assert int(scene_hits.geometry_id[0]) == 1 and float(scene_hits.t[0]) == 3.0
    assert bool(scene.occluded(*down)[0])
    near: sahkd.SceneClosest = scene.closest_point(points)
    assert int(near.geometry_id[0]) == 1 and float(scene.distance(points)[0]) == 1.0
    assert float(scene.signed_distance(points)[0]) == 1.0 and not bool(scene.contains(points)[0])
    print("typed example: all answers as expected, sahkd", sahkd.__version__)


if __name__ == "__main__":
    main()
