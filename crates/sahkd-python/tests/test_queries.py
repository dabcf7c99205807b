"""Queries through the Python API against oracles: a hand-computed case, the float64 numpy
oracle of conftest, and the core's brute force (`_brute_force_all`, every triangle tested
with the same watertight test, no tree), which the tree's answers must match exactly."""

import threading
import time

import numpy as np
import pytest

import sahkd
from conftest import oracle, random_rays, triangle_soup

SQUARE_V = np.array([[0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]], np.float32)
SQUARE_F = np.array([[0, 1, 2], [0, 2, 3]])


def test_hand_computed_square():
    tree = sahkd.KdTree(SQUARE_V, SQUARE_F)
    origins = np.array([[0.75, 0.25, 0], [0.25, 0.75, -1], [2, 2, 0], [0.5, 0.25, 3]], np.float32)
    directions = np.array([[0, 0, 1], [0, 0, 2], [0, 0, 1], [0, 0, 1]], np.float32)
    h = tree.intersect(origins, directions)
    # Ray 0 hits triangle 0 (0,0)-(1,0)-(1,1) at z = 1: p = 0.5 p0 + 0.5 p1 + ... solve:
    # (0.75, 0.25) = u (1, 0) + v (1, 1) -> v = 0.25, u = 0.5.
    assert h.prim.tolist() == [0, 1, -1, -1]
    assert h.t[0] == 1.0 and h.t[1] == 1.0  # direction (0, 0, 2) from z = -1
    assert np.isinf(h.t[2]) and np.isinf(h.t[3])
    np.testing.assert_allclose([h.u[0], h.v[0]], [0.5, 0.25], atol=1e-7)
    # Triangle 1 is (0,0)-(1,1)-(0,1): (0.25, 0.75) = u (1, 1) + v (0, 1) -> u = .25, v = .5
    np.testing.assert_allclose([h.u[1], h.v[1]], [0.25, 0.5], atol=1e-7)
    assert tree.occluded(origins, directions).tolist() == [True, True, False, False]
    assert tree.count_hits(origins, directions).tolist() == [1, 1, 0, 0]
    # Backwards from z = 3 the square is behind t = 0 unless the range allows negative t.
    back = tree.intersect(origins[3:], directions[3:], t_min=-10.0)
    assert back.prim.tolist() == [0] and back.t[0] == -2.0


@pytest.mark.parametrize("vertex_dtype", [np.float32, np.float64])
@pytest.mark.parametrize("face_dtype", [np.int32, np.int64, np.uint16, np.uint32, np.int16])
def test_every_query_matches_the_float64_oracle(vertex_dtype, face_dtype):
    rng = np.random.default_rng(7)
    vertices, faces = triangle_soup(rng, 150)
    origins, directions = random_rays(rng, vertices, faces, 600)
    tree = sahkd.KdTree(vertices.astype(vertex_dtype), faces.astype(face_dtype))
    expected, ambiguous = oracle(vertices, faces, origins, directions)
    clear = np.flatnonzero(~ambiguous)
    assert len(clear) > 0.9 * len(origins), "too many rays near edges for a meaningful test"
    first = tree.intersect(origins.astype(vertex_dtype), directions.astype(vertex_dtype))
    every = tree.intersect_all(origins, directions)
    counts = tree.count_hits(origins, directions)
    occluded = tree.occluded(origins, directions)
    hit_rays = 0
    for i in clear:
        rows = expected[i]
        got = slice(every.offsets[i], every.offsets[i + 1])
        assert sorted(every.prim[got].tolist()) == sorted(r[1] for r in rows), f"ray {i}"
        assert counts[i] == len(rows) and occluded[i] == bool(rows)
        by_prim = {r[1]: r for r in rows}
        for t, p, u, v in zip(every.t[got], every.prim[got], every.u[got], every.v[got]):
            et, _, eu, ev = by_prim[p]
            assert abs(t - et) <= 1e-5 * max(1.0, abs(et)), f"ray {i} prim {p}: t {t} vs {et}"
            assert abs(u - eu) <= 1e-4 and abs(v - ev) <= 1e-4, f"ray {i} prim {p}"
        assert np.all(np.diff(every.t[got]) >= 0), "hits of a ray must be nearest first"
        if not rows:
            assert first.prim[i] == -1 and np.isinf(first.t[i])
            continue
        hit_rays += 1
        # The nearest hit is comparable when it is not tied with the next one.
        if len(rows) == 1 or rows[1][0] - rows[0][0] > 1e-4 * max(1.0, abs(rows[0][0])):
            assert first.prim[i] == rows[0][1], f"ray {i}"
            assert abs(first.t[i] - rows[0][0]) <= 1e-5 * max(1.0, abs(rows[0][0]))
    assert hit_rays > 0.5 * len(clear), "the rays should mostly hit"


@pytest.mark.parametrize(
    "options",
    [
        dict(),
        dict(algorithm="sweep"),
        dict(algorithm="naive", axes="all", clip=False),
        dict(algorithm="median", axes="all"),
        dict(axes="all", counting="space-tree"),
        dict(threads=1, leaf_size=4, traversal=5.0, intersection=30.0),
        # Binned above 128 and 256 references (332 triangles): the top levels are binned.
        dict(algorithm="hybrid", bins=2, threads=2),
        dict(algorithm="sweep", bins=4, axes="all", clip=False),
    ],
)
def test_tree_answers_equal_brute_force_exactly(options):
    rng = np.random.default_rng(11)
    vertices, faces = triangle_soup(rng, 300, size=0.4)
    # A shared-edge grid as well, so that rays through edges and vertices occur.
    g = np.stack(np.meshgrid(np.arange(5.0), np.arange(5.0)), -1).reshape(-1, 2) * 0.5 - 1
    grid_v = np.column_stack([g, np.full(len(g), 0.1)]).astype(np.float32)
    quads = np.array([[r * 5 + c, r * 5 + c + 1, r * 5 + c + 6, r * 5 + c + 5] for r in range(4) for c in range(4)])
    grid_f = np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]]) + len(vertices)
    vertices = np.concatenate([vertices, grid_v])
    faces = np.concatenate([faces, grid_f])
    origins, directions = random_rays(rng, vertices, faces, 700)
    # Rays straight down through grid vertices and edges.
    lattice = np.array([[x, y, 2.0] for x in np.arange(-1, 1.01, 0.25) for y in (-1.0, -0.5, 0.25)], np.float32)
    origins = np.concatenate([origins, lattice])
    directions = np.concatenate([directions, np.tile(np.float32([0, 0, -1]), (len(lattice), 1))])
    r = len(origins)
    t_min = np.where(rng.random(r) < 0.3, rng.uniform(0, 2, r), 0).astype(np.float32)
    t_max = np.where(rng.random(r) < 0.3, rng.uniform(1, 4, r), np.inf).astype(np.float32)

    tree = sahkd.KdTree(vertices, faces, **options)
    tree.validate()
    for lo, hi in [(0.0, np.inf), (t_min, t_max), (0.5, 3.0)]:
        brute = tree._brute_force_all(origins, directions, lo, hi)
        every = tree.intersect_all(origins, directions, lo, hi)
        for name in ("t", "prim", "u", "v", "offsets"):
            np.testing.assert_array_equal(getattr(every, name), getattr(brute, name), err_msg=name)
        counts = np.diff(brute.offsets)
        np.testing.assert_array_equal(tree.count_hits(origins, directions, lo, hi), counts)
        np.testing.assert_array_equal(tree.occluded(origins, directions, lo, hi), counts > 0)
        first = tree.intersect(origins, directions, lo, hi)
        has = counts > 0
        at = brute.offsets[:-1][has]
        np.testing.assert_array_equal(first.prim[has], brute.prim[at])
        np.testing.assert_array_equal(first.t[has], brute.t[at])
        np.testing.assert_array_equal(first.u[has], brute.u[at])
        np.testing.assert_array_equal(first.prim[~has], -1)
        assert np.isinf(first.t[~has]).all()
    # Every lattice ray crosses the closed grid: the watertight test lets none slip through.
    lattice_hits = tree.count_hits(origins[-len(lattice):], directions[-len(lattice):])
    inside = (np.abs(lattice[:, :2]) <= 1).all(axis=1)
    assert (lattice_hits[inside] >= 1).all()


def test_ranges_and_max_hits_select_from_all_hits():
    rng = np.random.default_rng(3)
    vertices, faces = triangle_soup(rng, 200, spread=0.5, size=0.5)
    origins, directions = random_rays(rng, vertices, faces, 300)
    tree = sahkd.KdTree(vertices, faces)
    every = tree.intersect_all(origins, directions)
    assert (every.counts > 2).sum() > 20, "need rays with several hits"
    t_min = rng.uniform(0, 1.5, len(origins)).astype(np.float32)
    t_max = (t_min + rng.uniform(0, 1.5, len(origins))).astype(np.float32)
    ranged = tree.intersect_all(origins, directions, t_min, t_max)
    capped = tree.intersect_all(origins, directions, max_hits=2)
    for i in range(len(origins)):
        got = slice(every.offsets[i], every.offsets[i + 1])
        t, prim = every.t[got], every.prim[got]
        keep = (t >= t_min[i]) & (t <= t_max[i])
        sub = slice(ranged.offsets[i], ranged.offsets[i + 1])
        assert ranged.prim[sub].tolist() == prim[keep].tolist()
        cap = slice(capped.offsets[i], capped.offsets[i + 1])
        assert capped.prim[cap].tolist() == prim[:2].tolist()
    np.testing.assert_array_equal(every.ray, np.repeat(np.arange(len(origins)), every.counts))
    with pytest.raises(ValueError, match="max_hits"):
        tree.intersect_all(origins, directions, max_hits=-1)


def test_rays_that_cannot_hit_and_the_empty_mesh():
    tree = sahkd.KdTree(SQUARE_V, SQUARE_F)
    o = np.array([[0.5, 0.5, 0]] * 3, np.float32)
    d = np.array([[0, 0, 0], [0, 0, 1], [0, 0, 1]], np.float32)
    h = tree.intersect(o, d, t_min=np.float32([0, 2, 0]), t_max=np.float32([9, 1, 0.5]))
    assert h.prim.tolist() == [-1, -1, -1]  # zero direction; empty range; range ends short
    empty = sahkd.KdTree(np.zeros((0, 3)), np.zeros((0, 3), np.int32))
    assert len(empty) == 0 and empty.stats["triangles"] == 0
    assert empty.intersect(o, d).prim.tolist() == [-1, -1, -1]
    assert empty.intersect_all(o, d).offsets.tolist() == [0, 0, 0, 0]
    none = tree.intersect(np.zeros((0, 3)), np.zeros((0, 3)))
    assert none.t.shape == (0,) and none.prim.dtype == np.int64


def test_float32_and_float64_inputs_give_identical_answers():
    rng = np.random.default_rng(5)
    vertices, faces = triangle_soup(rng, 100)
    origins, directions = random_rays(rng, vertices, faces, 200)
    a = sahkd.KdTree(vertices, faces)
    b = sahkd.KdTree(vertices.astype(np.float64), faces.astype(np.uint16))
    ha = a.intersect(origins, directions)
    hb = b.intersect(origins.astype(np.float64), directions.astype(np.float64))
    for x, y in zip(ha, hb):
        np.testing.assert_array_equal(x, y)


def test_non_contiguous_and_list_inputs_are_read_in_place():
    rng = np.random.default_rng(9)
    vertices, faces = triangle_soup(rng, 80)
    origins, directions = random_rays(rng, vertices, faces, 150)
    reference = sahkd.KdTree(vertices, faces).intersect(origins, directions)
    wide = np.zeros((len(vertices), 5), np.float64)
    wide[:, 1:4] = vertices
    strided_v = wide[:, 1:4]  # a column slice: rows not contiguous
    fortran_f = np.asfortranarray(faces)
    reversed_o = np.ascontiguousarray(origins[::-1])[::-1]  # negative strides
    transposed_d = np.ascontiguousarray(directions.T).T
    assert not strided_v.flags.c_contiguous and not transposed_d.flags.c_contiguous
    tree = sahkd.KdTree(strided_v, fortran_f)
    got = tree.intersect(reversed_o, transposed_d)
    for x, y in zip(got, reference):
        np.testing.assert_array_equal(x, y)
    as_lists = sahkd.KdTree(vertices.tolist(), faces.tolist()).intersect(
        origins.tolist(), directions.tolist()
    )
    np.testing.assert_array_equal(as_lists.prim, reference.prim)
    big_endian = sahkd.KdTree(vertices.astype(">f4"), faces.astype(">i4"))
    np.testing.assert_array_equal(big_endian.intersect(origins, directions).prim, reference.prim)


def test_per_ray_bounds_in_any_layout_and_dtype_give_the_same_answers():
    # float32 and float64 bounds are read where they lie, other dtypes converted: every form
    # of the same values traces alike, and a bad value is named by its row.
    rng = np.random.default_rng(12)
    vertices, faces = triangle_soup(rng, 200)
    origins, directions = random_rays(rng, vertices, faces, 300)
    r = len(origins)
    t_min = rng.integers(0, 2, r).astype(np.float64) * 0.5
    t_max = np.where(rng.random(r) < 0.5, rng.integers(1, 4, r), np.inf)
    tree = sahkd.KdTree(vertices, faces)
    want = tree.intersect(origins, directions, t_min, t_max)
    want_any = tree.occluded(origins, directions, t_min, t_max)
    want_count = tree.count_hits(origins, directions, t_min, t_max)
    wide = np.zeros((r, 3))
    wide[:, 0], wide[:, 2] = t_min, t_max
    forms = [
        (t_min.astype(np.float32), t_max.astype(np.float32)),
        (wide[:, 0], wide[:, 2]),  # strided views
        (t_min[::-1].copy()[::-1], t_max.astype(np.float16)),
        ((t_min * 2).astype(np.int64) / 2, np.where(np.isinf(t_max), np.inf, t_max).tolist()),
    ]
    for lo, hi in forms:
        got = tree.intersect(origins, directions, lo, hi)
        for x, y in zip(got, want):
            np.testing.assert_array_equal(x, y)
        np.testing.assert_array_equal(tree.occluded(origins, directions, lo, hi), want_any)
        np.testing.assert_array_equal(tree.count_hits(origins, directions, lo, hi), want_count)
    # The same in every layout of the rays themselves (count_hits and intersect_all read them
    # as the others do).
    want_all = tree.intersect_all(origins, directions, t_min, t_max)
    for o, d in [(origins.astype(np.float64), directions[::-1].copy()[::-1]), (np.asfortranarray(origins), directions)]:
        np.testing.assert_array_equal(tree.count_hits(o, d, t_min, t_max), want_count)
        for x, y in zip(tree.intersect_all(o, d, t_min, t_max), want_all):
            np.testing.assert_array_equal(x, y)
    np.testing.assert_array_equal(np.diff(want_all.offsets), want_count)
    bad = t_min.astype(np.float32)
    bad[7] = np.inf
    with pytest.raises(ValueError, match=r"t_min\[7\] is not finite"):
        tree.intersect(origins, directions, bad, t_max)
    bad = np.array(t_max[::-1])[::-1]
    bad[250] = np.nan
    with pytest.raises(ValueError, match=r"t_max\[250\] is NaN"):
        tree.occluded(origins, directions, t_min, bad)
    with pytest.raises(ValueError, match=r"t_max\[250\] is NaN"):
        tree.count_hits(origins, directions, t_min, bad)
    bad_origins = np.asfortranarray(origins)
    bad_origins[123, 1] = np.nan
    for query in (tree.count_hits, tree.intersect_all):
        with pytest.raises(ValueError, match=r"origins\[123\] = .* is not finite"):
            query(bad_origins, directions)


def test_stats_report_the_tree_and_its_options():
    rng = np.random.default_rng(1)
    vertices, faces = triangle_soup(rng, 120)
    tree = sahkd.KdTree(vertices, faces, algorithm="sweep", axes="all", counting="scan", clip=False, threads=1)
    s = tree.stats
    assert set(s) == {
        "triangles", "nodes", "leaves", "empty_leaves", "references", "duplication",
        "max_depth", "mean_leaf_size", "sah_cost", "bytes", "build_ms", "presort_ms",
        "binned_ms", "subtrees_ms", "layout_ms", "preset",
        "algorithm", "axes", "counting", "clip", "threads", "bins",
    }  # fmt: skip
    nodes, refs = tree._structure()
    leaf = (nodes[:, 1] & 3) == 3
    assert s["triangles"] == len(tree) == 120
    assert s["nodes"] == len(nodes) and s["leaves"] == leaf.sum()
    assert s["references"] == len(refs) == (nodes[leaf, 1] >> 2).sum()
    assert s["empty_leaves"] == ((nodes[leaf, 1] >> 2) == 0).sum()
    assert s["duplication"] == pytest.approx(len(refs) / 120)
    assert (s["algorithm"], s["axes"], s["counting"], s["clip"], s["threads"]) == ("sweep", "all", "scan", False, 1)
    assert s["bins"] == 0
    assert s["build_ms"] >= 0 and s["sah_cost"] > 0
    np.testing.assert_array_equal(tree.bounds, [vertices.min(0), vertices.max(0)])
    np.testing.assert_array_equal(tree.triangles, vertices[faces])
    assert "120 triangles" in repr(tree)
    # Cost options reach the builder: depth 0 or a huge leaf size leave one leaf.
    for kw in (dict(max_depth=0), dict(leaf_size=1000)):
        assert sahkd.KdTree(vertices, faces, **kw).stats["nodes"] == 1


def test_the_same_tree_on_any_number_of_threads():
    rng = np.random.default_rng(2)
    vertices, faces = triangle_soup(rng, 400)
    for algorithm in ("level", "sweep", "naive", "median"):
        trees = [sahkd.KdTree(vertices, faces, algorithm=algorithm, threads=n) for n in (1, 2, 3)]
        structures = [t._structure() for t in trees]
        for nodes, refs in structures[1:]:
            np.testing.assert_array_equal(nodes, structures[0][0])
            np.testing.assert_array_equal(refs, structures[0][1])


def test_queries_release_the_interpreter():
    """A Python thread keeps running while a long query is under way in another."""
    # 300 stacked squares and rays up through them: every ray hits 300 faces, so a query
    # takes long whatever tree the builder makes.
    layers = 300
    square = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], np.float32)
    vertices = np.concatenate([np.column_stack([square, np.full(4, z, np.float32)]) for z in range(layers)])
    faces = np.concatenate([np.array([[0, 1, 2], [0, 2, 3]]) + 4 * z for z in range(layers)])
    tree = sahkd.KdTree(vertices, faces, threads=1)
    rng = np.random.default_rng(4)
    n = 20_000
    while True:  # rays enough for a query of at least 0.2 s, forty switch intervals
        xy = rng.uniform(0.01, 0.99, (n, 2))
        xy[np.abs(xy[:, 0] - xy[:, 1]) < 1e-3, 1] += 0.005  # off the squares' diagonals
        origins = np.column_stack([xy, np.full(n, -1.0)])
        directions = np.tile([0.0, 0.0, 1.0], (n, 1))
        start = time.perf_counter()
        counts = tree.count_hits(origins, directions)
        if time.perf_counter() - start >= 0.2 or n >= 2_000_000:
            break
        n *= 4
    assert (counts == layers).all()
    assert _python_runs_beside(lambda: tree.count_hits(origins, directions))


def _python_runs_beside(call):
    """Whether this thread keeps running Python while call() runs in another thread: the
    longest pause of a loop here must be under half the call's time (a call that holds the
    interpreter stops the loop for all of it)."""
    done = threading.Event()
    took = []

    def run():
        start = time.perf_counter()
        call()
        took.append(time.perf_counter() - start)
        done.set()

    worker = threading.Thread(target=run)
    # Timed from before the start: the new thread may run first while this one waits.
    last = time.perf_counter()
    worker.start()
    longest = 0.0
    while not done.is_set():
        now = time.perf_counter()
        longest = max(longest, now - last)
        last = now
    longest = max(longest, time.perf_counter() - last)
    worker.join()
    print(f"longest pause {longest:.3f} s during a {took[0]:.3f} s call")
    return longest < took[0] / 2


def test_the_interpreter_check_detects_a_call_that_holds_it():
    """The check above fails on a call that keeps the interpreter: a long sum in C."""
    assert not _python_runs_beside(lambda: sum(range(10_000_000)))


def test_f64_precision_is_exact_where_float32_is_not():
    """Tiny triangles 1e5 from the origin above a ground plane 3e5 across, seen from near the
    origin: precision="f64" gives the float64 oracle's hit on every clear ray (float64 rays
    kept as given), with float64 t, u, v; a wrong precision name is a ValueError."""
    rng = np.random.default_rng(11)
    g = 3e5
    ground = np.array([[-g, -g, 0], [g, -g, 0], [g, g, 0], [-g, g, 0]], np.float64)
    centres = np.column_stack(
        [1e5 + rng.uniform(-2, 2, 200), 6e4 + rng.uniform(-2, 2, 200), rng.uniform(0.5, 3, 200)]
    )
    tiny = (centres[:, None, :] + rng.uniform(-0.03, 0.03, (200, 3, 3))).reshape(-1, 3)
    vertices = np.vstack([ground, tiny]).astype(np.float32)
    faces = np.vstack([[[0, 1, 2], [0, 2, 3]], 4 + np.arange(600).reshape(200, 3)]).astype(np.int64)
    n = 1500
    origins = np.column_stack([rng.uniform(-10, 10, n), rng.uniform(-10, 10, n), rng.uniform(5e4, 2e5, n)])
    tri = vertices[faces[rng.integers(2, len(faces), n)]].astype(np.float64)
    targets = np.einsum("ij,ijk->ik", rng.dirichlet([1, 1, 1], n), tri)
    directions = targets - origins
    directions /= np.linalg.norm(directions, axis=1)[:, None]

    tree = sahkd.KdTree(vertices, faces)
    hits = tree.intersect(origins, directions, precision="f64")
    assert hits.t.dtype == np.float64 and hits.u.dtype == np.float64
    occluded = tree.occluded(origins, directions, precision="f64")
    expected, ambiguous = oracle(vertices, faces, origins, directions)
    clear = np.flatnonzero(~ambiguous)
    assert len(clear) > 0.8 * n
    tiny_hits = 0
    for i in clear:
        rows = expected[i]
        assert occluded[i] == bool(rows), f"ray {i}"
        if not rows:
            assert hits.prim[i] == -1, f"ray {i}"
            continue
        assert hits.prim[i] == rows[0][1], f"ray {i}: {hits.prim[i]} vs {rows[0]}"
        assert abs(hits.t[i] - rows[0][0]) <= 1e-9 * rows[0][0], f"ray {i}"
        assert abs(hits.u[i] - rows[0][2]) <= 1e-6 and abs(hits.v[i] - rows[0][3]) <= 1e-6
        tiny_hits += rows[0][1] >= 2
    assert tiny_hits > len(clear) // 4, "the rays should mostly hit the tiny triangles"
    with pytest.raises(ValueError, match="precision"):
        tree.intersect(origins, directions, precision="f16")
