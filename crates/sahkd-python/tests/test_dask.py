"""sahkd.dask on a LocalCluster of two worker processes and on Dask's default scheduler.

The oracles are the local tree's own queries (`KdTree.intersect` / `occluded`, tested against
the float64 oracle and the brute force elsewhere) and `fn` applied here to a tree built here
from the same file: what the workers return must equal them exactly. Skips, saying so, when
dask or distributed is not installed.
"""

import functools
import os
import subprocess
import sys

import numpy as np
import pytest

import sahkd
from conftest import random_rays, triangle_soup

NO_DASK = "dask[distributed] is not installed (pip install 'sahkd[dask]'); sahkd.dask not tested"


@pytest.fixture(scope="module")
def sdask():
    pytest.importorskip("dask", reason=NO_DASK)
    pytest.importorskip("dask.array", reason=NO_DASK)
    import sahkd.dask

    return sahkd.dask


@pytest.fixture(scope="module")
def client(sdask):
    pytest.importorskip("distributed", reason=NO_DASK)
    import dask
    from distributed import Client, LocalCluster

    # allowed-failures=0: the scheduler gives a task up at its first dead worker, so the
    # worker-death test exercises map_meshes' own resubmission (retries=), not the
    # scheduler's silent rerun. RAYON_NUM_THREADS=1: two workers on a small machine.
    with dask.config.set({"distributed.scheduler.allowed-failures": 0}):
        cluster = LocalCluster(
            n_workers=2, processes=True, threads_per_worker=1, dashboard_address=None,
            env={"RAYON_NUM_THREADS": "1"},
        )  # fmt: skip
    c = Client(cluster, set_as_default=False)  # tests with client=None must not find it
    yield c
    c.close()
    cluster.close()


def test_import_sahkd_does_not_import_dask():
    code = "import sys, sahkd, sahkd.trimesh; print(sorted(m for m in sys.modules if m.split('.')[0] in ('dask', 'distributed')))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


def test_without_dask_the_module_says_how_to_install_it():
    # sys.modules[name] = None makes `import name` fail as if it were not installed.
    code = "import sys; sys.modules['dask'] = None; import sahkd.dask"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.returncode != 0
    assert "ImportError" in out.stderr and 'pip install "sahkd[dask]"' in out.stderr


def scene(seed, n=400, rays=3000):
    rng = np.random.default_rng(seed)
    vertices, faces = triangle_soup(rng, n)
    origins, directions = random_rays(rng, vertices, faces, rays)
    return sahkd.KdTree(vertices, faces), origins, directions


def worker_loads():
    import sahkd.dask

    return sahkd.dask._loads


@pytest.mark.parametrize("where", ["client", "default scheduler"])
def test_trace_equals_the_local_tree(sdask, request, where):
    import dask
    import dask.array as da

    c = request.getfixturevalue("client") if where == "client" else None
    tree, origins, directions = scene(3)
    rays = da.from_array(np.hstack([origins, directions]), chunks=(400, 6))  # 8 blocks
    t_max = np.random.default_rng(4).uniform(0.5, 3.0, len(origins)).astype(np.float32)

    before = c.run(worker_loads) if c else None
    hits = sdask.trace(tree, rays, client=c)
    assert hits.t.dtype == np.float32 and hits.prim.dtype == np.int64
    got = dask.compute(*hits, scheduler=c)  # c is not the default client; None: threads
    want = tree.intersect(origins, directions)
    for name, g, w in zip(want._fields, got, want):
        assert g.dtype == w.dtype, name
        np.testing.assert_array_equal(g, w, err_msg=name)
    assert (want.prim >= 0).sum() > 1000  # the test means something: many rays hit

    occ = sdask.trace(tree, rays, kind="any", t_max=t_max, client=c).compute(scheduler=c)
    want_occ = tree.occluded(origins, directions, t_max=t_max)
    assert occ.dtype == bool and 0 < want_occ.sum() < len(want_occ)
    np.testing.assert_array_equal(occ, want_occ)

    if c is not None:
        # Eight blocks, two calls, two workers: each worker unpickled the tree at most once.
        after = c.run(worker_loads)
        new = {w: after[w] - before.get(w, 0) for w in after}
        assert 1 <= sum(new.values()) <= len(new) and max(new.values()) == 1, new


def test_trace_origins_directions_ranges_and_f64(sdask, client):
    import dask
    import dask.array as da

    tree, origins, directions = scene(5, rays=1000)
    rng = np.random.default_rng(6)
    t_min = rng.uniform(0.0, 0.5, len(origins))
    t_max = rng.uniform(0.5, 3.0, len(origins))
    # Row blocks that differ between origins and directions, and a numpy t_min.
    o = da.from_array(origins.astype(np.float64), chunks=(300, 3))
    d = da.from_array(directions, chunks=(250, 3))
    hits = sdask.trace(tree, (o, d), t_min=t_min, t_max=da.from_array(t_max, chunks=100), client=client)
    got = dask.compute(*hits, scheduler=client)
    want = tree.intersect(origins.astype(np.float64), directions, t_min=t_min, t_max=t_max)
    for g, w in zip(got, want):
        np.testing.assert_array_equal(g, w)

    f64 = sdask.trace(tree, (origins, directions), precision="f64")  # numpy input, no client
    got = dask.compute(*f64)
    want = tree.intersect(origins, directions, precision="f64")
    assert got[0].dtype == np.float64
    for g, w in zip(got, want):
        np.testing.assert_array_equal(g, w)


def test_trace_bad_input_is_a_clear_error(sdask):
    import dask.array as da

    tree, origins, directions = scene(8, n=10, rays=10)
    rays = np.hstack([origins, directions])
    with pytest.raises(TypeError, match="sahkd.KdTree"):
        sdask.trace("tree", rays)
    with pytest.raises(ValueError, match=r"shape \(R, 6\), got \(10, 3\)"):
        sdask.trace(tree, da.from_array(origins))
    with pytest.raises(TypeError, match="dtype int64"):
        sdask.trace(tree, rays.astype(np.int64))
    with pytest.raises(ValueError, match="kind must be"):
        sdask.trace(tree, rays, kind="all")
    with pytest.raises(ValueError, match="same number of rows, got 10 and 9"):
        sdask.trace(tree, (origins, directions[:9]))
    with pytest.raises(ValueError, match=r"t_max must be a scalar or have shape \(10,\)"):
        sdask.trace(tree, rays, t_max=np.ones(4))
    with pytest.raises(ValueError, match="t_min must be finite"):
        sdask.trace(tree, rays, t_min=-np.inf)
    # Values are checked by the tree on the worker, with its message.
    rays[3, 0] = np.nan
    with pytest.raises(ValueError, match="not finite"):
        sdask.trace(tree, rays).t.compute()


# -- map_meshes -----------------------------------------------------------------------------


def write_ply(path, vertices, faces):
    """A binary little-endian triangle PLY, written from numpy bytes (not by sahkd)."""
    header = (
        "ply\nformat binary_little_endian 1.0\n"
        f"element vertex {len(vertices)}\nproperty float x\nproperty float y\nproperty float z\n"
        f"element face {len(faces)}\nproperty list uchar int vertex_indices\nend_header\n"
    )
    rows = np.zeros(len(faces), np.dtype([("n", "u1"), ("i", "<i4", (3,))]))
    rows["n"], rows["i"] = 3, faces
    with open(path, "wb") as f:
        f.write(header.encode())
        f.write(np.asarray(vertices, "<f4").tobytes())
        f.write(rows.tobytes())


def summary(tree, path):
    """What fn computes per mesh: its size, SAH cost, and hits of rays from the bounds."""
    lo, hi = np.asarray(tree.bounds[0]), np.asarray(tree.bounds[1])
    u = np.linspace(0, 1, 50)
    origins = np.stack([lo[0] + u * (hi[0] - lo[0]), np.full(50, lo[1] + 0.5 * (hi[1] - lo[1])), np.full(50, lo[2] - 1)], 1)
    hits = tree.intersect(origins.astype(np.float32), np.tile(np.float32([0, 0, 1]), (50, 1)))
    return os.path.basename(path), len(tree), tree.stats["sah_cost"], hits.prim, hits.t


def die_once(marker, tree, path):
    """Kills its worker process the first time it runs (marked by a file), then summarises."""
    if not os.path.exists(marker):
        open(marker, "w").close()
        os._exit(1)
    return summary(tree, path)


@pytest.fixture(scope="module")
def meshes(tmp_path_factory):
    d = tmp_path_factory.mktemp("meshes")
    good = []
    for i, n in enumerate([50, 200, 120]):
        vertices, faces = triangle_soup(np.random.default_rng(100 + i), n)
        p = d / f"soup{i}.ply"
        write_ply(p, vertices, faces)
        good.append(str(p))
    corrupt = d / "corrupt.ply"
    write_ply(corrupt, *triangle_soup(np.random.default_rng(9), 40))
    corrupt.write_bytes(corrupt.read_bytes()[:300])  # cut inside the vertex data
    return good, str(corrupt)


def local(path, **options):
    return summary(sahkd.KdTree(*sahkd.dask.read_mesh(path), **options), path)


def assert_same(got, want):
    assert got[:3] == want[:3]
    np.testing.assert_array_equal(got[3], want[3])
    np.testing.assert_array_equal(got[4], want[4])


@pytest.mark.parametrize("where", ["client", "default scheduler"])
def test_map_meshes_results_in_order_and_a_clear_error_for_the_bad_one(sdask, request, where, meshes):
    c = request.getfixturevalue("client") if where == "client" else None
    good, corrupt = meshes
    missing = os.path.join(os.path.dirname(corrupt), "missing.ply")
    paths = [good[0], corrupt, good[1], missing, good[2]]
    options = dict(algorithm="sweep", leaf_size=2)

    out = sdask.map_meshes(paths, summary, client=c, errors="return", **options)
    assert len(out) == len(paths)
    for i in (0, 2, 4):
        assert_same(out[i], local(paths[i], **options))
    assert sum(1 for g in good if local(g)[3].max() >= 0) >= 2  # rays do hit these meshes
    bad = out[1]
    assert isinstance(bad, sdask.MeshFailure) and bad.path == corrupt
    assert bad.message.startswith("ValueError: ") and "file ends after" in bad.message
    assert corrupt in bad.message  # the reader names the file too
    assert isinstance(out[3], sdask.MeshFailure) and out[3].path == missing
    assert out[3].message.startswith("FileNotFoundError")

    with pytest.raises(sdask.MeshError) as e:
        sdask.map_meshes(paths, summary, client=c, **options)
    text = str(e.value)
    assert text.startswith("2 of 5 meshes failed") and corrupt in text and missing in text
    assert_same(e.value.results[4], out[4])  # the others are not lost
    assert [f.path for f in e.value.failures] == [corrupt, missing]


def test_map_meshes_reruns_a_mesh_whose_worker_died(sdask, client, meshes, tmp_path):
    good, _ = meshes
    client.wait_for_workers(2, timeout=30)
    fn = functools.partial(die_once, str(tmp_path / "died"))
    out = sdask.map_meshes(good[:2], fn, client=client, retries=1)
    assert os.path.exists(tmp_path / "died")  # a worker did die
    for path, got in zip(good, out):
        assert_same(got, local(path))

    # With no retries left, the mesh is a failure naming the path. (One mesh only: a mesh
    # waiting on the same worker counts as killed too, which is what retries are for.)
    client.wait_for_workers(2, timeout=30)
    fn = functools.partial(die_once, str(tmp_path / "died-again"))
    out = sdask.map_meshes(good[:1], fn, client=client, retries=0, errors="return")
    assert isinstance(out[0], sdask.MeshFailure) and out[0].path == good[0]
    assert out[0].message.startswith("KilledWorker") and "gave up after 1 submissions" in out[0].message
    client.wait_for_workers(2, timeout=30)


def test_map_meshes_bad_arguments(sdask, meshes):
    good, _ = meshes
    with pytest.raises(TypeError, match="list of paths"):
        sdask.map_meshes(good[0], summary)
    with pytest.raises(TypeError, match="fn must be callable"):
        sdask.map_meshes(good, "summary")
    with pytest.raises(TypeError, match="bogus"):
        sdask.map_meshes(good, summary, bogus=1)
    with pytest.raises(ValueError, match="algorithm"):
        sdask.map_meshes(good, summary, algorithm="fastest")
    with pytest.raises(ValueError, match="errors must be"):
        sdask.map_meshes(good, summary, errors="ignore")
    assert sdask.map_meshes([], summary) == []


def test_read_mesh_obj(sdask, tmp_path):
    p = tmp_path / "quad.obj"
    p.write_text(
        "# a quad and a triangle\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvn 0 0 1\n"
        "f 1//1 2//1 3//1 4//1\nf -4/1 -2/1 -1/1\n"
    )
    vertices, faces = sdask.read_mesh(p)
    np.testing.assert_array_equal(vertices, [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]])
    assert faces.tolist() == [[0, 1, 2], [0, 2, 3], [0, 2, 3]]
    (tmp_path / "bad.obj").write_text("v 0 0\n")
    with pytest.raises(ValueError, match=r"bad.obj: line 1: "):
        sdask.read_mesh(tmp_path / "bad.obj")
