"""sahkd.trimesh.RayMeshIntersector against trimesh's own pure-Python intersector.

Both must give the same answers on every ray that does not pass within rounding of an edge
or a plane (decided by the float64 oracle of conftest); on the others the two may differ by
design (float32 and a watertight test here, a 1e-12 barycentric tolerance there), which the
module's docstring documents. Most rays are clear, and the tests require that too.
"""

import pickle

import numpy as np
import pytest

trimesh = pytest.importorskip("trimesh")
pytest.importorskip("rtree")  # trimesh's pure-Python intersector needs it
from trimesh.ray.ray_triangle import RayMeshIntersector as Reference  # noqa: E402

import sahkd.trimesh  # noqa: E402
from conftest import oracle, random_rays, triangle_soup  # noqa: E402


def meshes():
    rng = np.random.default_rng(8)
    v, f = triangle_soup(rng, 200, size=0.3)
    yield "icosphere", trimesh.creation.icosphere(subdivisions=3)
    yield "capsule", trimesh.creation.capsule(height=1.0, radius=0.5, count=[16, 16])
    yield "torus", trimesh.creation.torus(major_radius=1.0, minor_radius=0.3)
    yield "soup", trimesh.Trimesh(v.astype(np.float64), f, process=False)


MESHES = dict(meshes())


def rays_for(mesh, n=400, seed=0):
    rng = np.random.default_rng(seed)
    v = np.asarray(mesh.vertices, np.float32)
    o, d = random_rays(rng, v, np.asarray(mesh.faces), n)
    return o.astype(np.float64), d.astype(np.float64)


def clear_rays(mesh, origins, directions):
    """Rays that no rounding can decide, and the float64 oracle's hits for each ray."""
    v = np.asarray(mesh.vertices, np.float32)
    hits, ambiguous = oracle(v, np.asarray(mesh.faces), origins.astype(np.float32), directions.astype(np.float32))
    clear = ~ambiguous
    assert clear.mean() > 0.9
    return clear, hits


def pairs(index_tri, index_ray, rays):
    keep = np.isin(index_ray, rays)
    return sorted(zip(index_ray[keep].tolist(), index_tri[keep].tolist()))


@pytest.mark.parametrize("name", list(MESHES))
def test_hits_match_trimesh_on_every_clear_ray(name):
    mesh = MESHES[name]
    # The sahkd tree is built from the float64 vertices rounded to float32; the reference
    # gets the same rounded mesh so that only the intersection arithmetic differs.
    mesh = trimesh.Trimesh(np.asarray(mesh.vertices, np.float32).astype(np.float64), mesh.faces, process=False)
    origins, directions = rays_for(mesh)
    ours, ref = sahkd.trimesh.RayMeshIntersector(mesh), Reference(mesh)
    clear, expected = clear_rays(mesh, origins, directions)
    rays = np.flatnonzero(clear)

    first, first_ref = ours.intersects_first(origins, directions), ref.intersects_first(origins, directions)
    assert first.dtype == first_ref.dtype == np.int64
    ties = np.array([len(h) > 1 and h[1][0] - h[0][0] < 1e-4 * max(1.0, h[0][0]) for h in expected])
    sure = clear & ~ties
    np.testing.assert_array_equal(first[sure], first_ref[sure])
    assert (first[sure] >= 0).sum() > 100, "most rays should hit"

    anyhit, any_ref = ours.intersects_any(origins, directions), ref.intersects_any(origins, directions)
    assert anyhit.dtype == bool
    np.testing.assert_array_equal(anyhit[clear], any_ref[clear])

    tri, ray = ours.intersects_id(origins, directions)
    tri_ref, ray_ref = ref.intersects_id(origins, directions)
    assert tri.dtype == ray.dtype == np.int64
    assert pairs(tri, ray, rays) == pairs(tri_ref, ray_ref, rays)
    assert pairs(tri, ray, rays) == sorted((i, h[1]) for i in rays for h in expected[i])

    locations, lray, ltri = ours.intersects_location(origins, directions)
    loc_ref, lray_ref, ltri_ref = ref.intersects_location(origins, directions)
    assert pairs(ltri, lray, rays) == pairs(ltri_ref, lray_ref, rays)
    ours_at = {(r, t): p for r, t, p in zip(lray, ltri, locations) if clear[r]}
    for r, t, p in zip(lray_ref, ltri_ref, loc_ref):
        if clear[r]:
            np.testing.assert_allclose(ours_at[(r, t)], p, atol=1e-5 * mesh.scale)

    ftri, fray, floc = ours.intersects_id(origins, directions, multiple_hits=False, return_locations=True)
    np.testing.assert_array_equal(fray, np.flatnonzero(first >= 0))
    np.testing.assert_array_equal(ftri, first[first >= 0])
    assert floc.shape == (len(fray), 3)


def _radial(name, mesh, points):
    """(distance from the shape's core, core radius): the sphere's centre, the capsule's
    axis segment, the torus's circle. Points well inside or outside the radius are clearly
    inside or outside the faceted mesh."""
    x, y, z = points.T
    if name == "icosphere":
        return np.linalg.norm(points, axis=1), 1.0
    if name == "capsule":
        radius = 0.5
        half = mesh.bounds[1, 2] - radius
        return np.hypot(np.hypot(x, y), np.abs(z) - np.minimum(np.abs(z), half)), radius
    return np.hypot(np.hypot(x, y) - 1.0, z), 0.3


@pytest.mark.parametrize("name", ["icosphere", "capsule", "torus"])
def test_contains_points_matches_trimesh_and_geometry(name):
    mesh = MESHES[name]
    rng = np.random.default_rng(1)
    lo, hi = mesh.bounds
    points = rng.uniform(lo - 0.2, hi + 0.2, (3000, 3))
    # Keep points clearly off the faceted surface (the answer on it is undefined for both).
    distance, radius = _radial(name, mesh, points)
    clear_in, clear_out = distance < 0.9 * radius, distance > 1.001 * radius
    points = points[clear_in | clear_out]
    truth = clear_in[clear_in | clear_out]
    ours = sahkd.trimesh.RayMeshIntersector(mesh).contains_points(points)
    np.testing.assert_array_equal(ours, truth)
    np.testing.assert_array_equal(ours, Reference(mesh).contains_points(points))
    assert 0.1 < ours.mean() < 0.9


def test_a_ray_through_shared_edges_and_corners_crosses_once_per_surface():
    """Rays through the diagonals splitting a box's faces, and through its corners, hit
    several triangles at one point; intersects_location reports that point once, and the
    parity of crossings (contains_points) stays right."""
    box = trimesh.creation.box(extents=[2, 2, 2])
    ray = sahkd.trimesh.RayMeshIntersector(box)
    s = np.array([-0.6, -0.2, 0.0, 0.3, 0.7])
    # Along +x at y = z and at y = -z: one of the two lies on each face's diagonal.
    origins = np.concatenate([np.column_stack([np.full(5, -3.0), s, s]), np.column_stack([np.full(5, -3.0), s, -s])])
    directions = np.tile([1.0, 0, 0], (len(origins), 1))
    origins = np.vstack([origins, [[0, 0, 0], [0.5, 0.5, 0.5]]])  # to a corner, from inside
    directions = np.vstack([directions, [[1, 1, 1], [1, 1, 1]]])
    tri, idx = ray.intersects_id(origins, directions)
    locations, lidx, _ = ray.intersects_location(origins, directions)
    crossings = np.bincount(lidx, minlength=len(origins))
    assert crossings.tolist() == [2] * 10 + [1, 1]
    assert (np.bincount(idx, minlength=len(origins)) >= crossings).all()
    assert (np.bincount(idx, minlength=len(origins))[:10] > 2).any(), "no ray met a diagonal"
    inside = np.array([[0, 0, 0], [0.5, 0.5, 0.5], [-0.5, 0.5, -0.5], [0.25, 0, 0]])
    outside = np.array([[3, 3, 3], [-3, 0, 0], [0, 0, 2.5], [1.5, 1.5, 0]])
    assert ray.contains_points(np.vstack([inside, outside])).tolist() == [True] * 4 + [False] * 4


def test_drop_in_for_mesh_ray():
    mesh = trimesh.creation.icosphere(subdivisions=2)
    mesh.ray = sahkd.trimesh.RayMeshIntersector(mesh)
    assert mesh.contains([[0, 0, 0], [0, 0, 2], [0.5, 0.1, 0]]).tolist() == [True, False, True]
    # trimesh.proximity.longest_ray goes through intersects_id(return_locations=True).
    points = np.array([[0, 0, 0], [0.2, 0.1, 0.0]])
    directions = np.array([[1, 0, 0], [0, 0, 1.0]])
    ours = trimesh.proximity.longest_ray(mesh, points, directions)
    mesh.ray = Reference(mesh)
    np.testing.assert_allclose(ours, trimesh.proximity.longest_ray(mesh, points, directions), rtol=1e-5)


def test_the_tree_follows_changes_of_the_mesh():
    mesh = trimesh.creation.icosphere(subdivisions=1)
    ray = sahkd.trimesh.RayMeshIntersector(mesh)
    o, d = np.array([[0, 0, 5.0]]), np.array([[0, 0, -1.0]])
    _, _, loc = ray.intersects_id(o, d, multiple_hits=False, return_locations=True)
    mesh.vertices = mesh.vertices * 2
    _, _, loc2 = ray.intersects_id(o, d, multiple_hits=False, return_locations=True)
    np.testing.assert_allclose(loc2[0, 2], 2 * loc[0, 2], rtol=1e-6)


def test_max_hits_options_pickling_and_bad_rays():
    mesh = MESHES["soup"]
    origins, directions = rays_for(mesh, 100)
    ray = sahkd.trimesh.RayMeshIntersector(mesh, algorithm="sweep", leaf_size=2)
    assert ray.tree.stats["algorithm"] == "sweep"
    tri, idx = ray.intersects_id(origins, directions, max_hits=1, unknown_option=True)
    np.testing.assert_array_equal(tri, ray.intersects_first(origins, directions)[idx])
    assert len(np.unique(idx)) == len(idx)
    clone = pickle.loads(pickle.dumps(ray))
    np.testing.assert_array_equal(clone.intersects_first(origins, directions), ray.intersects_first(origins, directions))
    with pytest.raises(ValueError, match="ray_directions must have the shape of ray_origins"):
        ray.intersects_first(origins, directions[:5])
    with pytest.raises(ValueError, match="ray_origins must have shape"):
        ray.intersects_any(origins[0], directions[0])
    with pytest.raises(ValueError, match="points must have shape"):
        ray.contains_points([1, 2, 3])
