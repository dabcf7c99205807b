"""sahkd.Scene against a float64 numpy brute force: every triangle of every geometry placed
by this test (the transforms applied in float64), then the rays of conftest's Moeller-Trumbore
oracle, the point-triangle distances of test_proximity, and for the inside test each cube's
inverse transform."""

import numpy as np
import pytest

import sahkd
from conftest import oracle, random_rays, triangle_soup
from test_proximity import brute_distances


def cube():
    """The unit cube [0, 1]^3 as 8 vertices and 12 faces wound outwards."""
    v = np.array([[i & 1, (i >> 1) & 1, (i >> 2) & 1] for i in range(8)], np.float32)
    faces = []
    for axis in range(3):
        a, b = (axis + 1) % 3, (axis + 2) % 3
        for side in (0, 1):
            q = [(side << axis) | (i << a) | (j << b) for i, j in ((0, 0), (1, 0), (1, 1), (0, 1))]
            n = np.zeros(3)
            n[axis] = 1 if side else -1
            for t in ([q[0], q[1], q[2]], [q[0], q[2], q[3]]):
                p = v[t].astype(np.float64)
                if np.cross(p[1] - p[0], p[2] - p[0]) @ n < 0:
                    t = [t[0], t[2], t[1]]
                faces.append(t)
    return v, np.array(faces, np.int64)


def rot(axis, angle):
    c, s = np.cos(angle), np.sin(angle)
    a, b = (axis + 1) % 3, (axis + 2) % 3
    m = np.eye(3)
    m[a, a], m[a, b], m[b, a], m[b, b] = c, -s, s, c
    return m


def affine(a, t, rows=4):
    m = np.eye(4)
    m[:3, :3], m[:3, 3] = a, t
    return m[:rows]


SHEAR = np.array([[1.5, 0.4, 0.0], [0.0, 0.7, 0.2], [0.1, 0.0, 1.2]])
MIRROR = np.diag([-1.0, 1.0, 1.0])
MIRROR_ROT = rot(1, 0.4) @ np.diag([1.3, -0.8, 1.1])


def mixed_scene():
    """Soups and cubes: moved, sheared, mirrored, overlapping, a mesh added twice. Returns
    the scene and, per geometry, (vertices, faces, 4x4 transform)."""
    rng = np.random.default_rng(3)
    sv, sf = triangle_soup(rng, 40, spread=1.0, size=0.3)
    cv, cf = cube()
    scene = sahkd.Scene()
    placed = []

    def mesh(v, f):
        placed.append((v, f, np.eye(4)))
        return scene.add_mesh(v, f)

    def instance(m, t):
        g = scene.add_instance(m, t)
        full = np.eye(4)
        full[: len(t)] = t
        placed.append((placed[m][0], placed[m][1], full))
        return g

    a, c = mesh(sv, sf), mesh(cv, cf)
    assert mesh(sv, sf) == 2  # the same mesh again: ties go to geometry 0
    assert instance(a, affine(rot(2, 0.7) @ rot(0, 0.3), [2.5, 0.0, 0.5])) == 3
    instance(c, affine(SHEAR, [-2.0, 1.0, 0.0], rows=3))
    instance(c, affine(MIRROR, [0.5, -2.5, 0.0]))
    instance(c, affine(MIRROR_ROT, [2.0, 2.0, -1.5], rows=3).tolist())  # nested lists too
    instance(a, affine(rot(1, 0.05), [0.1, 0.05, 0.0]))  # overlaps the soup it places
    instance(c, affine(np.eye(3), [0.4, 0.3, 0.2]))
    return scene, placed


def world(placed):
    """All placed triangles, transformed in float64: vertices, faces, and per face its
    geometry and its face in that geometry's mesh."""
    verts, faces, geometry, prim = [], [], [], []
    offset = 0
    for g, (v, f, m) in enumerate(placed):
        w = v.astype(np.float64) @ m[:3, :3].T + m[:3, 3]
        verts.append(w)
        faces.append(f + offset)
        geometry.append(np.full(len(f), g))
        prim.append(np.arange(len(f)))
        offset += len(v)
    return (
        np.vstack(verts),
        np.vstack(faces),
        np.concatenate(geometry),
        np.concatenate(prim),
    )


@pytest.fixture(scope="module")
def mixed():
    scene, placed = mixed_scene()
    scene.build()
    return scene, placed, world(placed)


def test_closest_hits_carry_the_geometry_and_match_the_brute_force(mixed):
    scene, _, (v, f, geometry, prim) = mixed
    rng = np.random.default_rng(8)
    origins, directions = random_rays(rng, v.astype(np.float32), f, 3000)
    hits = scene.intersect(origins, directions)
    assert isinstance(hits, sahkd.SceneHits)
    assert hits.t.dtype == np.float32 and hits.u.dtype == np.float32 and hits.v.dtype == np.float32
    assert hits.prim.dtype == np.int64 and hits.geometry_id.dtype == np.int64
    expected, ambiguous = oracle(v, f, origins, directions)
    checked = ties = 0
    for i, rows in enumerate(expected):
        if ambiguous[i]:
            continue
        checked += 1
        if not rows:
            assert (hits.t[i], hits.prim[i], hits.geometry_id[i]) == (np.inf, -1, -1), i
            assert hits.u[i] == 0 and hits.v[i] == 0
            continue
        np.testing.assert_allclose(hits.t[i], rows[0][0], rtol=1e-5, err_msg=f"ray {i}")
        # Faces within rounding of the nearest may win; among exact copies (the mesh added
        # twice) the lowest geometry, as the brute force's (t, index) order has it, since
        # faces are numbered geometry after geometry.
        tied = [r for r in rows if r[0] - rows[0][0] < 1e-5 * max(rows[0][0], 1)]
        exact = [r for r in rows if r[0] == rows[0][0]]
        ties += len(exact) > 1
        found = (hits.geometry_id[i], hits.prim[i])
        matches = [r for r in tied if (geometry[r[1]], prim[r[1]]) == found]
        assert matches, f"ray {i}: {found} is not among the nearest {tied}"
        if len(exact) > 1:
            assert found == (geometry[exact[0][1]], prim[exact[0][1]]), f"ray {i}"
        t, j, u, w = matches[0]
        # Barycentrics of the mesh's own corners, mirrors included: they give the oracle's
        # hit point on the oracle's face. (A swap would be off by |u - v| times an edge;
        # float32 is off by its rounding of a ray 10 long.)
        corners = v[f[j]]
        weights = np.array([1 - hits.u[i] - hits.v[i], hits.u[i], hits.v[i]], np.float64)
        point = weights @ corners
        reach = np.linalg.norm(origins[i]) + t * np.linalg.norm(directions[i])
        on_ray = origins[i] + t * directions[i].astype(np.float64)
        np.testing.assert_allclose(point, on_ray, atol=1e-5 * reach, err_msg=f"ray {i}")
    assert checked > 2500 and ties > 50, (checked, ties)
    assert (hits.geometry_id >= 0).sum() > 1500
    assert np.isin(hits.geometry_id, [5, 6]).sum() > 100  # the mirrored cubes
    np.testing.assert_array_equal(scene.occluded(origins, directions), hits.prim >= 0)
    # float64 walk: the same faces wherever the answer is clear, float64 numbers.
    o64, d64 = origins.astype(np.float64), directions.astype(np.float64)
    h64 = scene.intersect(o64, d64, precision="f64")
    assert h64.t.dtype == np.float64 and h64.geometry_id.dtype == np.int64
    clear = ~ambiguous
    np.testing.assert_array_equal(h64.geometry_id[clear], hits.geometry_id[clear])
    np.testing.assert_array_equal(h64.prim[clear], hits.prim[clear])
    np.testing.assert_array_equal(
        scene.occluded(origins, directions, precision="f64")[clear], hits.prim[clear] >= 0
    )


def test_ray_ranges_limit_the_hits(mixed):
    scene, _, (v, f, geometry, prim) = mixed
    rng = np.random.default_rng(9)
    origins, directions = random_rays(rng, v.astype(np.float32), f, 800)
    t_max = rng.uniform(0.5, 3.0, len(origins))
    hits = scene.intersect(origins, directions, t_min=0.2, t_max=t_max)
    expected, ambiguous = oracle(v, f, origins, directions, 0.2, t_max)
    for i, rows in enumerate(expected):
        if not ambiguous[i]:
            want = (geometry[rows[0][1]], prim[rows[0][1]]) if rows else (-1, -1)
            assert (hits.geometry_id[i], hits.prim[i]) == want, i


def test_closest_points_carry_the_geometry_and_match_the_brute_force(mixed):
    scene, _, (v, f, geometry, prim) = mixed
    rng = np.random.default_rng(10)
    points = np.vstack([rng.uniform(-3.5, 3.5, (600, 3)), rng.uniform(-9, 9, (200, 3))])
    found = scene.closest_point(points)
    assert isinstance(found, sahkd.SceneClosest)
    assert found.point.shape == (len(points), 3) and found.point.dtype == np.float64
    assert found.distance.dtype == np.float64 and found.prim.dtype == np.int64
    assert found.geometry_id.dtype == np.int64
    d = brute_distances(v[f], points.astype(np.float32))
    best = d.min(axis=1)
    # The placed corners are rounded to float32 once: distances agree to that.
    np.testing.assert_allclose(found.distance, best, rtol=1e-6, atol=1e-6)
    # The face: one within rounding of the nearest; among exact copies (the mesh added twice)
    # the lowest geometry, faces being numbered geometry after geometry.
    for i in range(len(points)):
        near = np.flatnonzero(d[i] - best[i] <= 1e-5 * max(best[i], 1))
        found_i = (found.geometry_id[i], found.prim[i])
        assert found_i in {(geometry[k], prim[k]) for k in near}, f"point {i}"
        exact = np.flatnonzero(d[i] == best[i])
        if len(near) == len(exact):
            assert found_i == (geometry[exact[0]], prim[exact[0]]), f"point {i}"
    # The point lies on the face it names.
    index = {(g, p): k for k, (g, p) in enumerate(zip(geometry, prim))}
    face = np.array([index[g, p] for g, p in zip(found.geometry_id, found.prim)])
    own = brute_distances(v[f][face], found.point)
    assert own[np.arange(len(points)), np.arange(len(points))].max() < 1e-5
    np.testing.assert_array_equal(scene.distance(points), found.distance)


def cubes_scene():
    """Closed cubes: one plain, one overlapping it, a sheared one, two mirrored ones."""
    cv, cf = cube()
    transforms = [
        np.eye(4),
        affine(np.eye(3), [0.5, 0.4, 0.3]),
        affine(SHEAR, [-3.0, 1.0, 0.0]),
        affine(MIRROR, [0.5, -2.5, 0.0]),
        affine(MIRROR_ROT, [2.0, 2.0, -1.5]),
    ]
    scene = sahkd.Scene()
    c = scene.add_mesh(cv, cf)
    for t in transforms[1:]:
        scene.add_instance(c, t)
    scene.build(threads=2)
    return scene, transforms


@pytest.mark.parametrize("inside", ["parity", "winding"])
def test_inside_is_the_union_of_the_geometries_mirrors_included(inside):
    scene, transforms = cubes_scene()
    rng = np.random.default_rng(12)
    near = np.vstack(
        [rng.uniform(-0.2, 1.2, (400, 3)) @ t[:3, :3].T + t[:3, 3] for t in transforms]
    )
    points = np.vstack([near, rng.uniform(-3.5, 3.5, (1000, 3))]).astype(np.float32)
    p = points.astype(np.float64)
    local = np.stack([(p - t[:3, 3]) @ np.linalg.inv(t[:3, :3]).T for t in transforms])
    in_each = ((local > 0) & (local < 1)).all(axis=-1)
    near_face = (np.abs(local) < 1e-3) | (np.abs(local - 1) < 1e-3)
    keep = ~near_face.any(axis=(0, 2))
    expected = in_each.any(axis=0)
    assert (in_each.sum(axis=0)[keep] > 1).sum() > 20  # points in two cubes at once
    got = scene.contains(points, inside=inside)
    assert got.dtype == np.bool_
    np.testing.assert_array_equal(got[keep], expected[keep])
    sd = scene.signed_distance(points, inside=inside)
    d = scene.distance(points)
    np.testing.assert_array_equal(sd[keep], np.where(expected, -d, d)[keep])


def test_an_empty_scene_answers_nothing():
    scene = sahkd.Scene()
    scene.build()
    o, d = np.zeros((2, 3), np.float32), np.array([[0, 0, 1], [1, 0, 0]], np.float32)
    hits = scene.intersect(o, d)
    assert list(hits.t) == [np.inf, np.inf] and list(hits.geometry_id) == [-1, -1]
    assert list(hits.prim) == [-1, -1] and not scene.occluded(o, d).any()
    c = scene.closest_point(o)
    assert np.isnan(c.point).all() and (c.distance == np.inf).all()
    assert list(c.prim) == [-1, -1] and list(c.geometry_id) == [-1, -1]
    assert (scene.distance(o) == np.inf).all() and not scene.contains(o).any()
    # A mesh without faces, placed twice: still nothing.
    scene = sahkd.Scene()
    m = scene.add_mesh(np.zeros((0, 3), np.float32), np.zeros((0, 3), np.int64))
    scene.add_instance(m, affine(np.eye(3), [1, 2, 3]))
    scene.build()
    assert scene.intersect(o, d).geometry_id.tolist() == [-1, -1]


def test_threads_do_not_change_the_answers(mixed):
    scene, placed, (v, f, _, _) = mixed
    rng = np.random.default_rng(14)
    origins, directions = random_rays(rng, v.astype(np.float32), f, 500)
    other, _ = mixed_scene()
    other.build(threads=1, algorithm="sweep")
    a, b = scene.intersect(origins, directions), other.intersect(origins, directions)
    for x, y in zip(a, b):
        np.testing.assert_array_equal(x, y)
    for x, y in zip(scene.closest_point(origins), other.closest_point(origins)):
        np.testing.assert_array_equal(x, y)


def test_bad_input_is_refused_clearly():
    cv, cf = cube()
    scene = sahkd.Scene()
    o, d = np.zeros((1, 3), np.float32), np.ones((1, 3), np.float32)
    with pytest.raises(ValueError, match=r"not built: call build\(\)"):
        scene.intersect(o, d)
    c = scene.add_mesh(cv, cf)
    i = scene.add_instance(c, np.eye(4))
    scene.build()
    scene.intersect(o, d)
    with pytest.raises(ValueError, match=r"bins works with the sweep and hybrid builders only, not level"):
        scene.build(algorithm="level", bins=16)
    with pytest.raises(ValueError, match=r"bins must be 0 .* got 1"):
        scene.build(algorithm="hybrid", bins=1)
    scene.build(algorithm="hybrid", bins=2)
    scene.intersect(o, d)
    rows = np.zeros((300, 3), np.float32)
    rows[201] = [0, np.inf, 0]
    for query in (scene.intersect, scene.occluded):
        with pytest.raises(ValueError, match=r"origins\[201\] = .* is not finite"):
            query(rows, np.ones((300, 3), np.float32))
        with pytest.raises(ValueError, match=r"t_max\[7\] is NaN"):
            query(rows[:10] * 0, np.ones((10, 3)), 0.0, np.where(np.arange(10) == 7, np.nan, 1.0))
    bad_transforms = [
        (affine(np.diag([np.nan, 1, 1]), [0, 0, 0]), r"transform: entry \[0\]\[0\] is NaN"),
        (affine(np.eye(3), [np.inf, 0, 0]), r"entry \[0\]\[3\] is inf"),
        (affine([[1, 2, 3], [2, 4, 6], [0, 0, 1]], [0, 0, 0]), r"singular"),
        (np.zeros((3, 4)), r"singular"),
        (np.eye(3), r"must be a 4x4 or 3x4 array, got shape \[3, 3\]"),
        (np.eye(4)[None], r"must be a 4x4 or 3x4 array"),
        (np.eye(4)[[0, 1, 2, 2]], r"last row .* must be \[0, 0, 0, 1\]"),
        ("eye", r"must be a 4x4 or 3x4 array of numbers"),
        (None, r"must be a 4x4 or 3x4 array"),
    ]
    for t, message in bad_transforms:
        with pytest.raises(ValueError, match=message):
            scene.add_instance(c, t)
    for mesh_id in (99, -1, i):
        with pytest.raises(ValueError, match=rf"no mesh with id {mesh_id}"):
            scene.add_instance(mesh_id, np.eye(4))
    with pytest.raises(TypeError, match=r"mesh_id must be an integer"):
        scene.add_instance("0", np.eye(4))
    # Meshes are checked as KdTree checks them.
    bad = cv.copy()
    bad[1, 2] = np.nan
    with pytest.raises(ValueError, match=r"vertices\[1\]"):
        scene.add_mesh(bad, cf)
    with pytest.raises(ValueError, match=r"faces"):
        scene.add_mesh(cv, cf + 100)
    # Refused calls changed nothing: the last build still answers.
    assert len(scene) == 2
    scene.intersect(o, d)
    # Rays and points as KdTree refuses them.
    with pytest.raises(ValueError, match=r"origins must have shape \(R, 3\)"):
        scene.intersect(o[:, :2], d)
    with pytest.raises(ValueError, match=r"same number of rays"):
        scene.occluded(np.repeat(o, 2, 0), d)
    with pytest.raises(ValueError, match=r"precision must be 'f32' or 'f64'"):
        scene.intersect(o, d, precision="f16")
    with pytest.raises(ValueError, match=r"inside: unknown inside test 'odd'"):
        scene.contains(o, inside="odd")
    with pytest.raises(ValueError):
        scene.closest_point(np.zeros((2, 2)))
    # Build options as KdTree's.
    with pytest.raises(ValueError, match=r"threads must be at least 1"):
        scene.build(threads=0)
    with pytest.raises(ValueError, match=r"algorithm"):
        scene.build(algorithm="nope")
    # Placed beyond float32: refused at build.
    scene.add_instance(c, affine(np.eye(3) * 1e39, [0, 0, 0]))
    with pytest.raises(ValueError, match=r"geometry 2: triangle 0 placed beyond the float32 range"):
        scene.build()
    # Changed since the last build: refused until built again.
    with pytest.raises(ValueError, match=r"changed since build\(\)"):
        scene.distance(o)
    assert "3 geometries" in repr(scene)
