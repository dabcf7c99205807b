"""sahkd on Dask: many rays against one tree, and many meshes, on a cluster.

    >>> from dask.distributed import Client
    >>> import dask.array as da, sahkd, sahkd.dask
    >>> client = Client("tcp://scheduler:8786")            # or Client(LocalCluster()), or none
    >>> hits = sahkd.dask.trace(tree, rays, client=client)  # rays: dask array (R, 6)
    >>> t, prim = da.compute(hits.t, hits.prim)            # one trace per block, both fields
    >>> out = sahkd.dask.map_meshes(paths, fn, client=client, algorithm="hybrid")

`trace` sends the tree's bytes once to every worker, unpickles it once per worker process and
traces each block of rays with `KdTree.intersect` / `KdTree.occluded`, which release the
interpreter. `map_meshes` loads, builds and applies `fn` to one mesh per task, reruns a mesh
whose worker died, and reports a mesh that fails without stopping the others.

This module needs `dask` (and `distributed` for a cluster): `pip install "sahkd[dask]"`.
`import sahkd` does not import it.
"""

import hashlib
import math
import os
import sys
import threading
import traceback
from collections import OrderedDict, namedtuple

import numpy as np

try:
    import dask
    import dask.array as da
except ImportError as e:  # the one place sahkd needs dask: say how to get it
    raise ImportError(
        'sahkd.dask needs dask: pip install "sahkd[dask]" (or "dask[distributed]")'
    ) from e

from ._sahkd import KdTree, _read_mesh, from_bytes
from ._types import Hits

__all__ = ["trace", "map_meshes", "read_mesh", "MeshFailure", "MeshError"]

_HITS_DTYPE = {
    "f32": np.dtype([("t", "f4"), ("prim", "i8"), ("u", "f4"), ("v", "f4")]),
    "f64": np.dtype([("t", "f8"), ("prim", "i8"), ("u", "f8"), ("v", "f8")]),
}
# Rows per block when trace is given numpy arrays instead of dask arrays.
_DEFAULT_BLOCK = 1 << 20


# -- the tree on the workers ----------------------------------------------------------------

# Trees unpickled in this process, by the digest of their bytes, most recently used last. A few
# are kept so that tracing one tree after another does not reload each block, and no more so
# that a long-lived worker does not accumulate every tree it ever saw.
_TREES = OrderedDict()
_TREES_KEEP = 4
_TREES_LOCK = threading.Lock()
# How many trees this process has unpickled (the tests check that it is one per worker).
_loads = 0


def _cached_tree(key, data):
    global _loads
    # One lock around the unpickling too: two threads of one worker starting at once must not
    # both build the same tree (from_bytes releases the interpreter while it reads).
    with _TREES_LOCK:
        tree = _TREES.get(key)
        if tree is None:
            tree = from_bytes(data)
            _loads += 1
            _TREES[key] = tree
            while len(_TREES) > _TREES_KEEP:
                _TREES.popitem(last=False)
        else:
            _TREES.move_to_end(key)
        return tree


def _trace_block(origins, directions, t_min, t_max, *, key, data, kind, precision):
    tree = _cached_tree(key, data)
    if kind == "any":
        return tree.occluded(origins, directions, t_min, t_max, precision=precision)
    hits = tree.intersect(origins, directions, t_min, t_max, precision=precision)
    out = np.empty(len(hits.t), _HITS_DTYPE[precision])
    for name in Hits._fields:
        out[name] = getattr(hits, name)
    return out


def _trace_rays_block(rays, t_min, t_max, **kw):
    return _trace_block(rays[:, :3], rays[:, 3:], t_min, t_max, **kw)


def _default_client():
    """The distributed client that dask.compute would use, or None. distributed is looked at
    only if something imported it already: without that import there can be no client."""
    if "distributed" not in sys.modules:
        return None
    from distributed import default_client

    try:
        return default_client()
    except ValueError:
        return None


def _as_dask(x, name, rows):
    if isinstance(x, da.Array):
        return x
    arr = np.asarray(x)
    chunks = (rows,) + (-1,) * (arr.ndim - 1) if arr.ndim else ()
    return da.from_array(arr, chunks=chunks)


def _check_float(x, name, shape):
    if x.ndim != 2 or x.shape[1] != shape:
        raise ValueError(f"{name} must have shape (R, {shape}), got {x.shape}")
    if x.dtype not in (np.float32, np.float64):
        raise TypeError(f"{name} must be float32 or float64, got dtype {x.dtype}")


def _range_arg(value, name, rows_chunks, n):
    """t_min / t_max: a scalar (passed to every block) or an (R,) array (split as the rays)."""
    if np.ndim(value) == 0 and not isinstance(value, da.Array):
        v = float(value)
        if math.isnan(v):
            raise ValueError(f"{name} is NaN")
        return v, None
    arr = _as_dask(value, name, _DEFAULT_BLOCK)
    if arr.ndim != 1 or (not math.isnan(n) and not math.isnan(arr.shape[0]) and arr.shape[0] != n):
        raise ValueError(f"{name} must be a scalar or have shape ({n},), got {arr.shape}")
    return None, arr.rechunk((rows_chunks,))


def trace(tree, rays, *, kind="closest", t_min=0.0, t_max=math.inf, precision="f32", client=None):
    """Trace many rays against one tree, block by block, on Dask.

    tree: a `sahkd.KdTree`. rays: a dask array (R, 6) of origin and direction per row, or a
    pair (origins, directions) of (R, 3) arrays; float32 or float64. numpy arrays are accepted
    too and split into blocks of 2**20 rays. t_min, t_max: scalars or (R,) arrays.

    kind="closest" returns `Hits(t, prim, u, v)` of dask arrays with the names and dtypes of
    `KdTree.intersect` (t float32, inf on a miss; prim int64, -1 on a miss; u, v float32; all
    float64 with precision="f64"); each block is traced once however many of the four are
    computed, when they are computed together (`dask.compute(*hits)`). kind="any" returns
    the bool dask array of `KdTree.occluded`.

    client: a `distributed.Client`; its workers get the tree's bytes once each (scattered with
    broadcast=True) before anything is computed; compute the results on that client
    (`client.compute`, or `dask.compute(..., scheduler=client)` when it is not the default
    client: the graph holds the scattered bytes as a Future). None uses the default client if there is one,
    else the bytes travel in the graph as one key, and Dask's default scheduler (or whichever
    the caller picks at compute time) runs the blocks. Each worker process unpickles the tree
    once and keeps it for later blocks and later calls.

    Each block runs on the tree's own `threads` (pickled with it; None means every core, or
    RAYON_NUM_THREADS). With several worker processes on one machine, give them
    RAYON_NUM_THREADS (e.g. `LocalCluster(env={"RAYON_NUM_THREADS": "1"})`) or build the tree
    with `threads=1`, so that they do not all start a thread per core.
    """
    if not isinstance(tree, KdTree):
        raise TypeError(f"tree must be a sahkd.KdTree, got {type(tree).__name__}")
    if kind not in ("closest", "any"):
        raise ValueError(f"kind must be 'closest' or 'any', got {kind!r}")
    if precision not in _HITS_DTYPE:
        raise ValueError(f"precision must be 'f32' or 'f64', got {precision!r}")

    if isinstance(rays, (tuple, list)):
        if len(rays) != 2:
            raise ValueError(f"rays as a sequence must be (origins, directions), got {len(rays)} items")
        origins = _as_dask(rays[0], "origins", _DEFAULT_BLOCK)
        directions = _as_dask(rays[1], "directions", _DEFAULT_BLOCK)
        _check_float(origins, "origins", 3)
        _check_float(directions, "directions", 3)
        n = origins.shape[0]
        if not (math.isnan(n) or math.isnan(directions.shape[0])) and directions.shape[0] != n:
            raise ValueError(
                f"origins and directions must have the same number of rows, got {n} and "
                f"{directions.shape[0]}"
            )
        # One chunk across the 3 columns, rows split as the origins are.
        origins = origins.rechunk({1: -1})
        directions = directions.rechunk((origins.chunks[0], (3,)))
        arrays = [(origins, "ij"), (directions, "ij")]
        block = _trace_block
    else:
        rays = _as_dask(rays, "rays", _DEFAULT_BLOCK)
        _check_float(rays, "rays", 6)
        rays = rays.rechunk({1: -1})
        n = rays.shape[0]
        arrays = [(rays, "ij")]
        block = _trace_rays_block
    rows = arrays[0][0].chunks[0]

    lo, lo_arr = _range_arg(t_min, "t_min", rows, n)
    hi, hi_arr = _range_arg(t_max, "t_max", rows, n)
    if lo is not None and math.isinf(lo):
        raise ValueError("t_min must be finite")
    args = [a for pair in arrays for a in pair]
    args += [lo_arr, "i"] if lo_arr is not None else [lo, None]
    args += [hi_arr, "i"] if hi_arr is not None else [hi, None]

    data = tree.to_bytes()
    # The digest names the tree in each worker's cache, so the same tree traced again is not
    # unpickled again, and two trees never share an entry.
    key = "sahkd-tree-" + hashlib.blake2b(data, digest_size=16).hexdigest()
    if client is None:
        client = _default_client()
    if client is not None:
        data = client.scatter(data, broadcast=True, hash=False)
    else:
        data = dask.delayed(data, name=key, pure=True)

    if kind == "any":
        meta = np.empty((0,), bool)
    else:
        meta = np.empty((0,), _HITS_DTYPE[precision])
    out = da.blockwise(
        block, "i", *args,
        concatenate=True, meta=meta,
        key=key, data=data, kind=kind, precision=precision,
        name=f"sahkd-trace-{kind}-" + dask.base.tokenize(key, *args, kind, precision),
    )  # fmt: skip
    if kind == "any":
        return out
    return Hits(*(out[name] for name in Hits._fields))


# -- many meshes ----------------------------------------------------------------------------


def read_mesh(path):
    """(vertices, faces) of a mesh file: PLY (ASCII or binary) and OBJ with the library's reader
    (the one the sahkd CLI uses; polygons split into fans), anything else (STL, ...) with
    trimesh if installed. Raises ValueError naming the path when the file cannot be read as a
    mesh."""
    path = os.fspath(path)
    ext = os.path.splitext(path)[1].lower()
    if ext in (".ply", ".obj"):
        return _read_mesh(path)
    try:
        import trimesh
    except ImportError:
        raise ValueError(
            f"{path}: unknown mesh format '{ext}' (read are .ply and .obj; others need trimesh)"
        ) from None
    mesh = trimesh.load(path, force="mesh", process=False)
    return np.asarray(mesh.vertices), np.asarray(mesh.faces)


MeshFailure = namedtuple("MeshFailure", ["path", "message"])
MeshFailure.__doc__ = """A mesh that map_meshes could not load, build or apply fn to: the path as
given and a message (the error's type and text, or why the task was given up)."""


class MeshError(RuntimeError):
    """Raised by map_meshes(errors="raise") after every mesh has run, when any failed: lists
    every failed path. `.results` has every result in path order (MeshFailure where failed),
    `.failures` the failures alone."""

    def __init__(self, results):
        self.results = results
        self.failures = [r for r in results if isinstance(r, MeshFailure)]
        lines = [f"  {f.path}: {f.message}" for f in self.failures]
        super().__init__(
            f"{len(self.failures)} of {len(results)} meshes failed:\n" + "\n".join(lines)
        )


def _one_mesh(path, open_path, fn, loader, options):
    """Runs on a worker: every error of one mesh becomes its MeshFailure, so that it is
    reported, not retried (a corrupt file stays corrupt), and the other meshes go on."""
    try:
        vertices, faces = loader(open_path)
        tree = KdTree(vertices, faces, **options)
        return fn(tree, path)
    except Exception as e:
        where = traceback.extract_tb(e.__traceback__)[-1]
        return MeshFailure(
            path, f"{type(e).__name__}: {e} (at {os.path.basename(where.filename)}:{where.lineno})"
        )


def map_meshes(paths, fn, *, client=None, retries=2, errors="raise", loader=read_mesh, **build_options):
    """Build a tree per mesh on the workers and return [fn(tree, path) for path in paths].

    paths: mesh files the workers can read (relative paths are made absolute here, so they
    must be on a file system the workers share; fn and MeshFailure see the path as given).
    fn(tree, path): any picklable function; its results come back in path order (arrays, a
    dataframe per mesh to concatenate, ...). loader(path) -> (vertices, faces): read_mesh
    unless given. build_options: keyword arguments of `sahkd.KdTree`, checked here first.

    A mesh whose load, build or fn raises is a failure and is not run again. A mesh whose worker
    dies (killed, out of memory, crashed) is run again: Dask's scheduler reruns it itself up
    to `distributed.scheduler.allowed-failures` times (default 3), and when it gives up
    (KilledWorker) map_meshes submits the mesh again, up to `retries` more times.
    errors="raise": after every mesh has run, raise MeshError listing each failed path (its
    `.results` keeps the results of the others); errors="return": return the list with a
    MeshFailure(path, message) in place of each failure.

    client: a `distributed.Client`; None uses the default client if there is one, else Dask's
    default local scheduler (threads; a thread that dies cannot be rerun there).
    """
    if isinstance(paths, (str, bytes, os.PathLike)):
        raise TypeError("paths must be a list of paths, not one path")
    paths = list(paths)
    if not callable(fn):
        raise TypeError(f"fn must be callable, got {type(fn).__name__}")
    if not callable(loader):
        raise TypeError(f"loader must be callable, got {type(loader).__name__}")
    if errors not in ("raise", "return"):
        raise ValueError(f"errors must be 'raise' or 'return', got {errors!r}")
    if not isinstance(retries, int) or isinstance(retries, bool) or retries < 0:
        raise ValueError(f"retries must be an integer >= 0, got {retries!r}")
    # Bad options fail here once, not once per mesh on the workers.
    KdTree(np.eye(3, dtype=np.float32), np.array([[0, 1, 2]]), **build_options)
    for p in paths:
        if not isinstance(p, (str, os.PathLike)):
            raise TypeError(f"each path must be a str or os.PathLike, got {type(p).__name__}")
    given = [os.fspath(p) for p in paths]
    absolute = [os.path.abspath(p) for p in given]

    if client is None:
        client = _default_client()
    if client is None:
        tasks = [
            dask.delayed(_one_mesh, pure=False)(p, a, fn, loader, build_options)
            for p, a in zip(given, absolute)
        ]
        results = list(dask.compute(*tasks))
    else:
        results = _map_on_client(client, given, absolute, fn, loader, build_options, retries)
    if errors == "raise" and any(isinstance(r, MeshFailure) for r in results):
        raise MeshError(results)
    return results


def _map_on_client(client, given, absolute, fn, loader, options, retries):
    from distributed import as_completed

    # fn and loader travel inside each task. Scattered once instead, they would live on one
    # worker, and that worker's death would fail every mesh still waiting for them.
    def submit(i):
        return client.submit(_one_mesh, given[i], absolute[i], fn, loader, options, pure=False)

    results = [None] * len(given)
    attempts = [0] * len(given)
    index = {}
    # The client's own loop: the client need not be the default one.
    pending = as_completed(loop=client.loop)
    for i in range(len(given)):
        f = submit(i)
        index[f.key] = i
        pending.add(f)
    for f in pending:
        i = index.pop(f.key)
        if f.status == "finished":
            results[i] = f.result()
            continue
        # Only the task itself failed here (_one_mesh catches the mesh's own errors): its
        # worker died more often than the scheduler allows, or the result could not travel.
        try:
            error = f.exception()
        except Exception as e:  # a cancelled future raises instead of returning its error
            error = e
        why = f"{type(error).__name__}: {error}" if error is not None else f"task {f.status}"
        if attempts[i] < retries:
            attempts[i] += 1
            g = submit(i)
            index[g.key] = i
            pending.add(g)
        else:
            results[i] = MeshFailure(
                given[i], f"{why} (gave up after {attempts[i] + 1} submissions)"
            )
    return results
