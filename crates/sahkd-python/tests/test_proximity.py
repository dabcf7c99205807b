"""Point queries through the Python API against a float64 numpy brute force written here
(plane projection or nearest edge, every point against every triangle), the face planes of
a convex mesh for the inside test, and the drop-in modules against their conventions."""

import numpy as np
import pytest

import sahkd
import sahkd.trimesh
from conftest import triangle_soup
from sahkd.open3d import INVALID_ID, RaycastingScene


def _segment_distance(p, a, b):
    ab = b - a
    l2 = (ab * ab).sum(-1)
    s = np.where(l2 > 0, ((p - a) * ab).sum(-1) / np.where(l2 > 0, l2, 1), 0).clip(0, 1)
    return np.linalg.norm(p - (a + s[..., None] * ab), axis=-1)


def brute_distances(corners, points):
    """(P, T) float64 distances from every point to every triangle."""
    c = corners.astype(np.float64)[None]  # (1, T, 3, 3)
    p = points.astype(np.float64)[:, None]  # (P, 1, 3)
    a, b, cc = c[..., 0, :], c[..., 1, :], c[..., 2, :]
    edges = np.minimum(
        np.minimum(_segment_distance(p, a, b), _segment_distance(p, b, cc)),
        _segment_distance(p, cc, a),
    )
    n = np.cross(b - a, cc - a)
    n2 = (n * n).sum(-1)
    h = ((p - a) * n).sum(-1) / np.where(n2 > 0, n2, 1)
    q = p - h[..., None] * n

    def side(u, v):
        return (np.cross(v - u, q - u) * n).sum(-1)

    inside = (n2 > 0) & (side(a, b) >= 0) & (side(b, cc) >= 0) & (side(cc, a) >= 0)
    plane = np.abs(h) * np.sqrt(n2)
    return np.where(inside, np.minimum(plane, edges), edges)


def query_points(rng, vertices, faces, n):
    """On corners, on faces, near the surface, in the box and far away (float32)."""
    tri = vertices[faces].astype(np.float64)
    lo, hi = vertices.min(0), vertices.max(0)
    k = n // 5
    w = rng.dirichlet([1, 1, 1], 2 * k)
    on = np.einsum("ij,ijk->ik", w, tri[rng.integers(0, len(faces), 2 * k)])
    on[k:] += rng.normal(scale=1e-3, size=(k, 3))
    corners = tri[rng.integers(0, len(faces), k), rng.integers(0, 3, k)]
    box = rng.uniform(lo, hi, (k, 3))
    far = rng.uniform(lo - 3 * (hi - lo), hi + 3 * (hi - lo), (n - 4 * k, 3))
    return np.vstack([on, corners, box, far]).astype(np.float32)


def check_against_brute(tree, vertices, faces, points):
    found = tree.closest_point(points)
    point, distance, prim = found  # a plain 3-tuple
    assert point.shape == (len(points), 3) and point.dtype == np.float64
    assert distance.dtype == np.float64 and prim.dtype == np.int64
    d = brute_distances(vertices[faces], points)
    best = d.min(axis=1)
    np.testing.assert_allclose(distance, best, rtol=0, atol=1e-9)
    # The face: the brute force's wherever no other face is within rounding.
    second = np.partition(d, 1, axis=1)[:, 1] if d.shape[1] > 1 else np.full(len(d), np.inf)
    clear = second - best > 1e-9
    assert clear.sum() > len(points) // 2
    np.testing.assert_array_equal(prim[clear], d.argmin(axis=1)[clear])
    # The point lies on its face, at the distance.
    own = brute_distances(vertices[faces], point)[np.arange(len(points)), prim]
    assert own.max() <= 1e-9
    np.testing.assert_allclose(
        np.linalg.norm(point - points.astype(np.float64), axis=1), distance, atol=1e-9
    )
    np.testing.assert_array_equal(tree.distance(points), distance)


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_closest_point_matches_the_numpy_brute_force(dtype):
    rng = np.random.default_rng(5)
    vertices, faces = triangle_soup(rng, 300)
    tree = sahkd.KdTree(vertices, faces)
    points = query_points(rng, vertices, faces, 500)
    check_against_brute(tree, vertices, faces, points)
    # float64 points give the answers of the same points rounded to float32.
    found = tree.closest_point(points.astype(dtype))
    np.testing.assert_array_equal(found.distance, tree.closest_point(points).distance)


def test_closest_point_on_coplanar_needles_and_duplicates():
    rng = np.random.default_rng(6)
    flat = rng.uniform(0, 1, (100, 3, 3))
    flat[..., 2] = 0.5
    a = rng.uniform(0, 1, (100, 1, 3))
    d = rng.uniform(-0.5, 0.5, (100, 1, 3))
    needles = np.concatenate([a, a + d, a + 0.5 * d + 1e-4 * rng.uniform(size=(100, 1, 3))], 1)
    corners = np.concatenate([flat, needles, flat[:20]]).astype(np.float32)
    vertices = corners.reshape(-1, 3)
    faces = np.arange(len(vertices)).reshape(-1, 3)
    tree = sahkd.KdTree(vertices, faces)
    check_against_brute(tree, vertices, faces, query_points(rng, vertices, faces, 400))
    # A duplicate answers with the lower index.
    p = corners[:20].mean(axis=1) + np.float32([0, 0, 0.25])
    prim = tree.closest_point(p).prim
    assert (prim < 200).all()


def icosphere_like(n_lat=12, n_lon=24):
    """A closed convex UV sphere wound outwards (float32 vertices)."""
    lat = np.linspace(0, np.pi, n_lat + 1)[1:-1]
    lon = np.linspace(0, 2 * np.pi, n_lon, endpoint=False)
    ring = np.stack(
        [np.outer(np.sin(lat), np.cos(lon)), np.outer(np.sin(lat), np.sin(lon)),
         np.outer(np.cos(lat), np.ones_like(lon))], -1
    ).reshape(-1, 3)
    vertices = np.vstack([[0, 0, 1], ring, [0, 0, -1]]).astype(np.float32)
    faces = []
    idx = lambda i, j: 1 + i * n_lon + j % n_lon  # noqa: E731
    for j in range(n_lon):
        faces.append([0, idx(0, j), idx(0, j + 1)])
        faces.append([len(vertices) - 1, idx(n_lat - 2, j + 1), idx(n_lat - 2, j)])
        for i in range(n_lat - 2):
            faces.append([idx(i, j), idx(i + 1, j), idx(i + 1, j + 1)])
            faces.append([idx(i, j), idx(i + 1, j + 1), idx(i, j + 1)])
    return vertices, np.array(faces, np.int64)


def inside_convex(vertices, faces, points):
    c = vertices[faces].astype(np.float64)
    n = np.cross(c[:, 1] - c[:, 0], c[:, 2] - c[:, 0])
    h = np.einsum("tk,ptk->pt", n, points.astype(np.float64)[:, None] - c[None, :, 0])
    return (h < 0).all(axis=1)


def test_sphere_is_wound_outwards():
    v, f = icosphere_like()
    assert inside_convex(v, f, np.zeros((1, 3), np.float32))[0]


@pytest.mark.parametrize("inside", ["parity", "winding"])
def test_signed_distance_and_contains_match_the_face_planes(inside):
    v, f = icosphere_like()
    tree = sahkd.KdTree(v, f)
    rng = np.random.default_rng(7)
    points = rng.uniform(-1.5, 1.5, (3000, 3)).astype(np.float32)
    want = inside_convex(v, f, points)
    assert 300 < want.sum() < 2700
    d = tree.distance(points)
    away = d > 1e-6
    assert (tree.contains(points, inside=inside)[away] == want[away]).all()
    s = tree.signed_distance(points, inside=inside)
    np.testing.assert_array_equal(s[away], np.where(want, -d, d)[away])
    w = tree.winding_number(points[away])
    np.testing.assert_allclose(w, want[away].astype(float), atol=1e-9)


def test_winding_number_is_right_on_a_sphere_with_a_hole():
    v, f = icosphere_like()
    holed = f[v[f].mean(axis=1)[:, 2] < 0.8]
    tree = sahkd.KdTree(v, holed)
    rng = np.random.default_rng(8)
    points = rng.uniform(-1.2, 1.2, (3000, 3)).astype(np.float32)
    r = np.linalg.norm(points, axis=1)
    keep = ((r < 0.85) | (r > 1.1)) & (points[:, 2] < 0.7)
    points = points[keep]
    want = inside_convex(v, f, points)
    assert (tree.contains(points, inside="winding") == want).all()
    assert ((tree.signed_distance(points, inside="winding") < 0) == want).all()


def test_empty_meshes_bad_points_and_bad_options():
    empty = sahkd.KdTree(np.zeros((0, 3), np.float32), np.zeros((0, 3), np.int64))
    p = np.array([[0, 0, 0], [1, 2, 3]], np.float32)
    point, distance, prim = empty.closest_point(p)
    assert np.isnan(point).all() and np.isinf(distance).all() and (prim == -1).all()
    assert not empty.contains(p).any()
    tree = sahkd.KdTree(*icosphere_like())
    for bad in [np.zeros((3, 2)), np.zeros(3), np.array([[np.nan, 0, 0]]), np.array([["a"] * 3])]:
        for query in (tree.closest_point, tree.distance, tree.signed_distance, tree.contains):
            with pytest.raises((ValueError, TypeError)):
                query(bad)
    with pytest.raises(ValueError, match="parity"):
        tree.contains(p, inside="vote")
    assert tree.closest_point(np.zeros((0, 3), np.float32)).point.shape == (0, 3)


def test_answers_do_not_depend_on_threads():
    rng = np.random.default_rng(9)
    vertices, faces = triangle_soup(rng, 2000)
    points = query_points(rng, vertices, faces, 5000)
    one = sahkd.KdTree(vertices, faces, threads=1)
    many = sahkd.KdTree(vertices, faces, threads=2)
    for a, b in zip(one.closest_point(points), many.closest_point(points)):
        np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(one.signed_distance(points), many.signed_distance(points))


class Mesh:
    """The attributes sahkd.trimesh reads."""

    def __init__(self, vertices, faces):
        self.vertices, self.faces = vertices, faces
        self.bounds = np.array([vertices.min(0), vertices.max(0)])


def test_trimesh_proximity_drop_ins_follow_trimesh_conventions():
    v, f = icosphere_like()
    mesh = Mesh(v, f)
    rng = np.random.default_rng(10)
    points = rng.uniform(-1.5, 1.5, (400, 3))
    closest, distance, triangle_id = sahkd.trimesh.closest_point(mesh, points)
    assert closest.shape == (400, 3) and distance.shape == (400,) and triangle_id.shape == (400,)
    d = brute_distances(v[f], points.astype(np.float32))
    np.testing.assert_allclose(distance, d.min(1), atol=1e-9)
    signed = sahkd.trimesh.signed_distance(mesh, points)
    want = inside_convex(v, f, points.astype(np.float32))
    away = distance > 1e-6
    assert ((signed[away] > 0) == want[away]).all()  # trimesh: positive inside
    np.testing.assert_array_equal(np.abs(signed), distance)
    trimesh = pytest.importorskip("trimesh")
    pytest.importorskip("scipy")  # trimesh.proximity needs it
    tm = trimesh.Trimesh(v, f, process=False)
    t_closest, t_distance, _ = trimesh.proximity.closest_point(tm, points[:100])
    np.testing.assert_allclose(distance[:100], t_distance, atol=1e-6)
    t_signed = trimesh.proximity.signed_distance(tm, points[:100])
    np.testing.assert_allclose(signed[:100][away[:100]], t_signed[away[:100]], atol=1e-6)


def test_open3d_scene_shapes_ids_and_answers():
    v, f = icosphere_like()
    scene = RaycastingScene()
    assert scene.add_triangles(v, f) == 0
    assert scene.add_triangles(v + np.float32([5, 0, 0]), f) == 1
    rng = np.random.default_rng(11)
    q = rng.uniform(-1.5, 6.5, (4, 50, 3)).astype(np.float32)
    out = scene.compute_closest_points(q)
    assert out["points"].shape == (4, 50, 3) and out["points"].dtype == np.float32
    assert out["geometry_ids"].shape == (4, 50) and out["geometry_ids"].dtype == np.uint32
    assert out["primitive_uvs"].shape == (4, 50, 2)
    assert out["primitive_normals"].shape == (4, 50, 3)
    flat = q.reshape(-1, 3)
    all_v = np.vstack([v, v + np.float32([5, 0, 0])])
    all_f = np.vstack([f, f + len(v)])
    d = brute_distances(all_v[all_f], flat)
    best = d.argmin(1)
    # Ids as the brute force's wherever no other face is within rounding (on a shared edge
    # or corner several are equally near).
    clear = np.partition(d, 1, axis=1)[:, 1] - d.min(1) > 1e-9
    assert clear.sum() > 10
    # Everywhere, the face named is one of the nearest.
    named = out["geometry_ids"].ravel().astype(np.int64) * len(f) + out["primitive_ids"].ravel()
    np.testing.assert_allclose(d[np.arange(len(d)), named], d.min(1), atol=1e-9)
    np.testing.assert_array_equal(out["geometry_ids"].ravel()[clear], (best // len(f))[clear])
    np.testing.assert_array_equal(out["primitive_ids"].ravel()[clear], (best % len(f))[clear])
    # The uvs rebuild the point from its face.
    c = all_v[all_f[named]].astype(np.float64)
    uv = out["primitive_uvs"].reshape(-1, 2).astype(np.float64)
    rebuilt = c[:, 0] + uv[:, :1] * (c[:, 1] - c[:, 0]) + uv[:, 1:] * (c[:, 2] - c[:, 0])
    np.testing.assert_allclose(rebuilt, out["points"].reshape(-1, 3), atol=1e-5)
    dist = scene.compute_distance(q)
    assert dist.dtype == np.float32 and dist.shape == (4, 50)
    np.testing.assert_allclose(dist.ravel(), d.min(1), atol=1e-6)
    want = inside_convex(v, f, flat) | inside_convex(v + np.float32([5, 0, 0]), f, flat)
    occ = scene.compute_occupancy(q)
    assert occ.dtype == np.float32 and set(np.unique(occ)) <= {0.0, 1.0}
    away = d.min(1) > 1e-6
    np.testing.assert_array_equal(occ.ravel()[away], want[away].astype(np.float32))
    sd = scene.compute_signed_distance(q, inside="winding").ravel()
    np.testing.assert_array_equal((sd < 0)[away], want[away])

    rays = np.hstack([flat, np.tile([[1, 0, 0]], (len(flat), 1))]).astype(np.float32)
    counts = scene.count_intersections(rays)
    assert counts.dtype == np.int32
    listed = scene.list_intersections(rays)
    np.testing.assert_array_equal(np.diff(listed["ray_splits"].astype(np.int64)), counts)
    assert listed["t_hit"].shape == listed["primitive_ids"].shape == listed["ray_ids"].shape
    # A ray along +x from inside crosses its sphere once (its own sphere) plus both walls of
    # sphere 1 if it starts in sphere 0 and passes through sphere 1: parity is occupancy.
    assert ((counts[away] % 2 == 1) == want[away]).mean() > 0.98
    hits = scene.cast_rays(rays)
    miss = hits["geometry_ids"] == INVALID_ID
    np.testing.assert_array_equal(miss, counts == 0)
    assert np.isinf(hits["t_hit"][miss]).all()
