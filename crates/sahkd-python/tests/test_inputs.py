"""Bad input raises ValueError or TypeError naming what is wrong; it never crashes."""

import numpy as np
import pytest

import sahkd

V = np.array([[0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]], np.float32)
F = np.array([[0, 1, 2], [0, 2, 3]], np.int32)
O = np.array([[0.5, 0.5, 0]], np.float32)
D = np.array([[0, 0, 1]], np.float32)


def with_value(a, index, value):
    a = a.astype(np.float64).copy()
    a[index] = value
    return a


@pytest.mark.parametrize(
    "vertices, faces, error, message",
    [
        (V[:, :2], F, ValueError, r"vertices must have shape \(V, 3\), got \(4, 2\)"),
        (V.ravel(), F, ValueError, r"vertices must have shape \(V, 3\), got \(12,\)"),
        (V[None], F, ValueError, r"vertices must have shape \(V, 3\), got \(1, 4, 3\)"),
        (V, F[:, :2], ValueError, r"faces must have shape \(F, 3\), got \(2, 2\)"),
        (V, np.zeros((2, 4), np.int32), ValueError, r"faces must have shape \(F, 3\)"),
        (with_value(V, (2, 1), np.nan), F, ValueError, r"vertices\[2\] = \(1, NaN, 1\) is not finite"),
        (with_value(V, (3, 0), np.inf), F, ValueError, r"vertices\[3\] .* is not finite"),
        (with_value(V, (1, 2), 1e300), F, ValueError, r"vertices\[1\] .* not finite in float32"),
        (V, np.array([[0, 1, 4], [0, 2, 3]]), ValueError, r"faces\[0\] refers to vertex 4, but there are only 4 vertices \(valid indices are 0 to 3\)"),
        (V, np.array([[0, 1, 2], [0, -1, 3]]), ValueError, r"faces\[1\] refers to vertex -1"),
        (V, np.array([[0, 1, 2], [0, 2, 2**40]], np.uint64), ValueError, r"refers to vertex 1099511627776"),
        (V.astype(np.int64), F, TypeError, r"vertices must be a float32 or float64 array, got dtype int64"),
        (V.astype(np.float16), F, TypeError, r"vertices must be a float32 or float64 array, got dtype float16"),
        (V.astype(np.complex64), F, TypeError, r"vertices must be a float32 or float64 array"),
        (V.astype(object), F, TypeError, r"vertices must be a float32 or float64 array, got dtype object"),
        (V, F.astype(np.float64), TypeError, r"faces must be an integer array, got dtype float64"),
        (V, F.astype(bool), TypeError, r"faces must be an integer array, got dtype bool"),
        ("not an array", F, TypeError, r"vertices must be a float32 or float64 array, got dtype <U12"),
        (np.zeros(4, [("x", "f4"), ("y", "f4"), ("z", "f4")]), F, TypeError, r"vertices must be a plain numeric array"),
        ([[0, 0, 1], [1, 0]], F, TypeError, r"vertices must be a numpy array or array-like"),
    ],
)
def test_bad_meshes_are_refused_clearly(vertices, faces, error, message):
    with pytest.raises(error, match=message):
        sahkd.KdTree(vertices, faces)


@pytest.mark.parametrize("dtype", [np.int8, np.uint16, np.int32, np.uint32, np.int64, np.uint64])
@pytest.mark.parametrize("layout", ["c", "fortran", "column slice", "reversed"])
def test_meshes_of_every_dtype_and_layout_are_read_as_numpy_reads_them(dtype, layout):
    # The arrays are read on the workers; numpy's own fancy indexing is the oracle, on enough
    # rows for both workers to take a share, and a bad row near the end is named all the same.
    rng = np.random.default_rng(5)
    n = 120 if dtype == np.int8 else 30000
    vertices = rng.uniform(-1, 1, (n, 3))
    faces = rng.integers(0, 100, (20000, 3)).astype(dtype)
    vertices, faces = (np.asfortranarray(vertices), np.asfortranarray(faces)) if layout == "fortran" else (vertices, faces)
    if layout == "column slice":
        wide, vwide = np.zeros((len(faces), 5), dtype), np.zeros((len(vertices), 4))
        wide[:, 1:4], vwide[:, 1:4] = faces, vertices
        faces, vertices = wide[:, 1:4], vwide[:, 1:4]
    elif layout == "reversed":
        faces = np.ascontiguousarray(faces[::-1])[::-1]
        vertices = np.ascontiguousarray(vertices[::-1])[::-1]
    for v in (vertices, vertices.astype(np.float32)):
        tree = sahkd.KdTree(v, faces, threads=2)
        np.testing.assert_array_equal(tree.triangles, v.astype(np.float32)[faces])
    bad = faces.copy()
    bad[-2, 2] = n
    with pytest.raises(ValueError, match=rf"faces\[19998\] refers to vertex {n}, but there are only {n} vertices"):
        sahkd.KdTree(vertices, bad, threads=2)
    for bad in (with_value(vertices, (n - 2, 1), np.nan), with_value(vertices, (n - 2, 1), 1e300)):
        with pytest.raises(ValueError, match=rf"vertices\[{n - 2}\] = .* is not finite"):
            sahkd.KdTree(bad, faces, threads=2)


@pytest.mark.parametrize(
    "kwargs, error, message",
    [
        (dict(preset="fastest"), ValueError, r"preset must be one of 'fast', 'balanced', 'quality', 'paper', 'sweep', got 'fastest'"),
        (dict(preset=1), TypeError, r"preset must be a string, got int"),
        (dict(algorithm="fast"), ValueError, r"algorithm must be one of 'hybrid', 'sweep', 'level', 'naive', 'median', got 'fast'"),
        (dict(axes="x"), ValueError, r"axes must be one of 'longest', 'all'"),
        (dict(counting="tree"), ValueError, r"counting must be one of 'space-tree', 'scan'"),
        (dict(threads=0), ValueError, r"threads must be at least 1"),
        (dict(threads=-2), ValueError, r"threads must be at least 1 .* got -2"),
        (dict(threads=100000), ValueError, r"threads: 100000 threads is too many: at most \d+ on this machine"),
        (dict(threads="two"), TypeError, r"threads must be an integer or None, got str"),
        (dict(threads=1.5), TypeError, r"threads must be an integer or None, got float"),
        (dict(threads=True), TypeError, r"threads must be an integer or None, not a bool"),
        (dict(threads=2**70), ValueError, r"threads = 1180591620717411303424 is out of range"),
        (dict(algorithm=1), TypeError, r"algorithm must be a string, got int"),
        (dict(axes=["all"]), TypeError, r"axes must be a string, got list"),
        (dict(clip="yes"), TypeError, r"clip must be True or False, got str"),
        (dict(traversal=-1), ValueError, r"traversal cost \(K_T\) must be a finite number of at least 0, got -1"),
        (dict(intersection=float("nan")), ValueError, r"intersection cost \(K_I\) must be a finite number above 0"),
        (dict(empty_bonus=1.5), ValueError, r"empty_bonus must be in \(0, 1\]"),
        (dict(leaf_size=-1), ValueError, r"leaf_size must be in 0..="),
        (dict(leaf_size=2.5), TypeError, r"leaf_size must be an integer"),
        (dict(max_depth=61), ValueError, r"max_depth must be at most 60, got 61"),
        (dict(max_depth=True), TypeError, r"max_depth must be an integer, not a bool"),
        (dict(max_duplication=0.5), ValueError, r"max_duplication must be a finite number of at least 1"),
        (dict(traversal="fast"), TypeError, r"traversal must be a number"),
        (dict(algorithm="sweep", bins=1), ValueError, r"bins must be 0 \(exact SAH\) or from 2 to 1024, got 1$"),
        (dict(algorithm="hybrid", bins=1025), ValueError, r"bins must be 0 .* got 1025"),
        (dict(algorithm="sweep", bins=-4), ValueError, r"bins must be 0 .* got -4"),
        (dict(algorithm="level", bins=16), ValueError, r"bins works with the sweep and hybrid builders only, not level"),
        (dict(algorithm="median", bins=16), ValueError, r"bins works with .* not median"),
        (dict(algorithm="sweep", bins="16"), TypeError, r"bins must be an integer or None, got str"),
        (dict(algorithm="sweep", bins=True), TypeError, r"bins must be an integer or None, not a bool"),
        (dict(travesal=10, colour=1), TypeError, r"unexpected keyword argument\(s\) 'travesal', 'colour'; the cost options are traversal, intersection"),
    ],
)
def test_bad_options_are_refused_clearly(kwargs, error, message):
    with pytest.raises(error, match=message):
        sahkd.KdTree(V, F, **kwargs)


def test_good_options_are_accepted():
    tree = sahkd.KdTree(
        V, F, algorithm="SWEEP", axes="all", counting="space_tree", clip=np.False_, threads=np.int64(2),
        traversal=10, intersection=25.0, empty_bonus=1, leaf_size=0, max_depth=None,
        max_duplication=2,
    )  # fmt: skip
    assert tree.stats["counting"] == "space-tree" and tree.stats["algorithm"] == "sweep"
    assert tree.stats["clip"] is False and tree.stats["threads"] == 2
    binned = sahkd.KdTree(V, F, algorithm="hybrid", bins=np.int64(64))
    assert binned.stats["bins"] == 64 and binned.stats["algorithm"] == "hybrid"
    # Unset, bins is the hybrid's default binning and exact SAH for the other builders.
    assert sahkd.KdTree(V, F).stats["bins"] == 256
    assert sahkd.KdTree(V, F, algorithm="sweep").stats["bins"] == 0
    assert sahkd.KdTree(V, F, algorithm="level").stats["bins"] == 0
    assert sahkd.KdTree(V, F, bins=None).stats["bins"] == 256


# The library's edge values for each option (BuildOptions::validate): the last value accepted
# and the first refused, every door giving the library's answer.
EDGES = [
    (dict(traversal=0), True),
    (dict(traversal=-1e-6), False),
    (dict(intersection=1e-6), True),
    (dict(intersection=0), False),
    (dict(empty_bonus=1), True),
    (dict(empty_bonus=0), False),
    (dict(max_duplication=1), True),
    (dict(max_duplication=0.999), False),
    (dict(max_depth=60), True),
    (dict(max_depth=61), False),
    (dict(leaf_size=0), True),
    (dict(threads=1), True),
    (dict(threads=0), False),
    (dict(bins=0), True),
    (dict(bins=1), False),
    (dict(bins=2), True),
    (dict(bins=1024), True),
    (dict(bins=1025), False),
    (dict(algorithm="level", bins=0), True),
    (dict(algorithm="level", bins=2), False),
]


@pytest.mark.parametrize("kwargs, accepted", EDGES)
def test_options_at_their_edges_get_the_librarys_answer(kwargs, accepted):
    if accepted:
        sahkd.KdTree(V, F, **kwargs)
        scene = sahkd.Scene()
        scene.add_mesh(V, F)
        scene.build(**kwargs)
    else:
        with pytest.raises(ValueError):
            sahkd.KdTree(V, F, **kwargs)
        scene = sahkd.Scene()
        scene.add_mesh(V, F)
        with pytest.raises(ValueError):
            scene.build(**kwargs)


def _structure(tree):
    nodes, refs = tree._structure()
    return nodes.tobytes(), refs.tobytes()


def test_presets_are_the_librarys_and_arguments_beside_them_override():
    rng = np.random.default_rng(7)
    # Small triangles scattered in a box: a tree of many nodes, where clipping changes it.
    centres = rng.random((2000, 1, 3))
    v = (centres + 0.03 * rng.standard_normal((2000, 3, 3))).reshape(-1, 3).astype(np.float32)
    f = np.arange(6000).reshape(2000, 3)
    for name in ["fast", "balanced", "quality", "paper", "sweep"]:
        assert sahkd.KdTree(v, f, preset=name).stats["preset"] == name
    assert sahkd.KdTree(v, f).stats["preset"] == "balanced"
    # Each preset is its options: the same tree given them one by one.
    quality = sahkd.KdTree(v, f, preset="quality")
    assert _structure(quality) == _structure(sahkd.KdTree(v, f, axes="all", bins=0, clip=True))
    sweep = sahkd.KdTree(v, f, preset="sweep")
    assert sweep.stats["algorithm"] == "sweep" and sweep.stats["bins"] == 0
    paper = sahkd.KdTree(v, f, preset="paper")
    assert (paper.stats["algorithm"], paper.stats["clip"]) == ("level", False)
    # Arguments given beside a preset override it, and the preset is still named.
    fast = sahkd.KdTree(v, f, preset="fast")
    fast_clipped = sahkd.KdTree(v, f, preset="fast", clip=True)
    assert fast.stats["clip"] is False and fast_clipped.stats["clip"] is True
    assert fast_clipped.stats["preset"] == "fast"
    assert _structure(fast_clipped) != _structure(fast)
    # fast is balanced with fewer bins, leaves of 2 and K_T 120 (the library's FAST_TRAVERSAL).
    assert _structure(fast) == _structure(
        sahkd.KdTree(v, f, preset="balanced", bins=fast.stats["bins"], leaf_size=2, traversal=120.0)
    )


@pytest.mark.parametrize(
    "origins, directions, kwargs, error, message",
    [
        (O[:, :2], D, {}, ValueError, r"origins must have shape \(R, 3\), got \(1, 2\)"),
        (O, D[0], {}, ValueError, r"directions must have shape \(R, 3\), got \(3,\)"),
        (np.repeat(O, 2, 0), D, {}, ValueError, r"same number of rays, got 2 and 1"),
        (with_value(O, (0, 0), np.nan), D, {}, ValueError, r"origins\[0\] = \(NaN, 0.5, 0\) is not finite"),
        (O, with_value(D, (0, 2), -np.inf), {}, ValueError, r"directions\[0\] .* is not finite"),
        (O.astype(np.int32), D, {}, TypeError, r"origins must be a float32 or float64 array, got dtype int32"),
        (O, D, dict(t_min=np.nan), ValueError, r"t_min is not finite"),
        (O, D, dict(t_min=np.inf), ValueError, r"t_min is not finite"),
        (O, D, dict(t_max=np.nan), ValueError, r"t_max is NaN"),
        (O, D, dict(t_max=np.array([1.0, 2.0])), ValueError, r"t_max must be a scalar or have shape \(1,\) like the rays, got \(2,\)"),
        (O, D, dict(t_max=np.array([[1.0]])), ValueError, r"t_max must be a scalar or have shape \(1,\)"),
        (O, D, dict(t_min=np.array([np.nan])), ValueError, r"t_min\[0\] is not finite"),
        (O, D, dict(t_min="0"), TypeError, r"t_min must be a number or an array of numbers"),
    ],
)
def test_bad_rays_are_refused_clearly(origins, directions, kwargs, error, message):
    tree = sahkd.KdTree(V, F)
    for query in (tree.intersect, tree.occluded, tree.count_hits, tree.intersect_all):
        with pytest.raises(error, match=message):
            query(origins, directions, **kwargs)


def test_bad_max_hits_is_refused_clearly():
    tree = sahkd.KdTree(V, F)
    with pytest.raises(TypeError, match="max_hits must be an integer or None, got str"):
        tree.intersect_all(O, D, max_hits="3")
    with pytest.raises(ValueError, match="max_hits must be at least 0"):
        tree.intersect_all(O, D, max_hits=-1)


def test_infinite_t_max_and_integer_ranges_are_fine():
    tree = sahkd.KdTree(V, F)
    assert tree.intersect(O, D, t_min=0, t_max=np.inf).prim[0] >= 0
    assert tree.occluded(O, D, t_min=np.array([0]), t_max=np.array([2])).tolist() == [True]
    assert tree.occluded(O, D, t_min=np.float32(0), t_max=0.5).tolist() == [False]
