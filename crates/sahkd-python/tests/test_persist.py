"""Saving, loading and pickling trees, and refusing damaged or forged files."""

import copy
import json
import multiprocessing
import pickle
import struct
import sys

import numpy as np
import pytest

import sahkd
from conftest import random_rays, triangle_soup


def _tree_and_rays(seed=21, n=200, **options):
    rng = np.random.default_rng(seed)
    vertices, faces = triangle_soup(rng, n)
    origins, directions = random_rays(rng, vertices, faces, 300)
    return sahkd.KdTree(vertices, faces, **options), origins, directions


def assert_same_tree(a, b, origins, directions):
    for x, y in zip(a._structure(), b._structure()):
        np.testing.assert_array_equal(x, y)
    np.testing.assert_array_equal(a.triangles, b.triangles)
    np.testing.assert_array_equal(a.bounds, b.bounds)
    assert a.stats == b.stats
    for x, y in zip(a.intersect(origins, directions), b.intersect(origins, directions)):
        np.testing.assert_array_equal(x, y)


@pytest.mark.parametrize(
    "options", [dict(), dict(algorithm="sweep", axes="all", clip=False, threads=1, leaf_size=3)]
)
def test_save_and_load_give_back_the_same_tree(tmp_path, options):
    tree, origins, directions = _tree_and_rays(**options)
    path = tmp_path / "scene.sahkd"
    tree.save(path)
    assert_same_tree(tree, sahkd.load(path), origins, directions)
    tree.save(str(path))
    assert_same_tree(tree, sahkd.load(str(path)), origins, directions)
    assert path.read_bytes() == tree.to_bytes()
    assert_same_tree(tree, sahkd.from_bytes(bytearray(tree.to_bytes())), origins, directions)


def test_pickle_and_copies():
    tree, origins, directions = _tree_and_rays()
    for clone in (
        pickle.loads(pickle.dumps(tree)),
        pickle.loads(pickle.dumps(tree, protocol=2)),
        copy.deepcopy(tree),
        copy.copy(tree),
    ):
        assert isinstance(clone, sahkd.KdTree)
        assert_same_tree(tree, clone, origins, directions)


def _cast(args):
    """Runs in a worker process: the closest hits of some rays on a pickled tree."""
    tree, origins, directions = args
    return tree.intersect(origins, directions).prim


def _cast_with_build(args):
    vertices, faces, origins, directions = args
    return sahkd.KdTree(vertices, faces).intersect(origins, directions).prim


def test_trees_travel_to_a_spawned_process_pool():
    tree, origins, directions = _tree_and_rays()
    expected = tree.intersect(origins, directions).prim
    chunks = [(tree, o, d) for o, d in zip(np.array_split(origins, 3), np.array_split(directions, 3))]
    with multiprocessing.get_context("spawn").Pool(2) as pool:
        got = pool.map_async(_cast, chunks).get(timeout=120)
    np.testing.assert_array_equal(np.concatenate(got), expected)


@pytest.mark.skipif(
    "fork" not in multiprocessing.get_all_start_methods(), reason="no fork on this platform"
)
@pytest.mark.filterwarnings("ignore:This process .* is multi-threaded:DeprecationWarning")
def test_forked_workers_do_not_hang_on_the_parents_threads():
    """The parent's worker threads do not exist in a forked child; sahkd starts new ones
    there instead of waiting forever on the inherited pool."""
    tree, origins, directions = _tree_and_rays()
    rng = np.random.default_rng(0)
    vertices, faces = triangle_soup(rng, 50)
    expected = tree.intersect(origins, directions).prim  # the parent's pools are running now
    expected_built = sahkd.KdTree(vertices, faces).intersect(origins, directions).prim
    with multiprocessing.get_context("fork").Pool(2) as pool:
        got = pool.map_async(_cast, [(tree, origins, directions)] * 2).get(timeout=120)
        built = pool.map_async(_cast_with_build, [(vertices, faces, origins, directions)]).get(timeout=120)
    for g in got:
        np.testing.assert_array_equal(g, expected)
    np.testing.assert_array_equal(built[0], expected_built)


def test_save_replaces_a_file_whole_and_refuses_a_folder(tmp_path):
    tree, _, _ = _tree_and_rays()
    path = tmp_path / "scene.sahkd"
    path.write_bytes(b"an older file")
    tree.save(path)
    assert path.read_bytes() == tree.to_bytes()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["scene.sahkd"]
    with pytest.raises(OSError):
        tree.save(tmp_path)
    with pytest.raises(OSError):
        tree.save(tmp_path / "missing" / "scene.sahkd")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["scene.sahkd"]


def test_unreadable_files_raise_os_errors(tmp_path):
    with pytest.raises(FileNotFoundError):
        sahkd.load(tmp_path / "missing.sahkd")
    with pytest.raises(OSError):
        sahkd.load(tmp_path)


def test_damaged_files_are_refused_with_the_reason(tmp_path):
    tree, _, _ = _tree_and_rays(n=30)
    good = tree.to_bytes()
    cases = {
        "empty": (b"", "not a sahkd tree file"),
        "text": (b"ply\nformat ascii 1.0\n", "not a sahkd tree file"),
        "magic": (b"SAHKDTRX" + good[8:], "not a sahkd tree file"),
        "version": (good[:8] + struct.pack("<I", 3) + good[12:], "format version 3, but this sahkd reads versions 1 and 2"),
        "truncated": (good[: len(good) // 2], "checksum mismatch"),
        "header only": (good[:12], "truncated"),
        "flipped bit": (good[:100] + bytes([good[100] ^ 4]) + good[101:], "checksum mismatch"),
        "appended": (good + b"\0", "checksum mismatch"),
    }
    for name, (data, reason) in cases.items():
        path = tmp_path / f"{name}.sahkd"
        path.write_bytes(data)
        with pytest.raises(ValueError, match=reason):
            sahkd.load(path)
        with pytest.raises(ValueError, match=reason):
            sahkd.from_bytes(data)


# --- Forged files: a second writer of the documented layout, with a correct checksum, so
# that only the structural checks stand between them and the traversal.

LEAF = 3


def fnv1a(data):
    h = 0xCBF29CE484222325
    for b in data:
        h = ((h ^ b) * 0x100000001B3) & 0xFFFFFFFFFFFFFFFF
    return h


def interior(axis, split, left):
    return (struct.unpack("<I", struct.pack("<f", split))[0], (left << 2) | axis)


def leaf(first, count):
    return (first, (count << 2) | LEAF)


def forge(triangles, nodes, refs, bounds=None, meta=None, counts=None):
    triangles = np.asarray(triangles, np.float32).reshape(-1, 3, 3)
    if bounds is None:
        pts = triangles.reshape(-1, 3)
        bounds = np.concatenate([pts.min(0), pts.max(0)])
    if meta is None:
        meta = json.dumps({"options": json.loads(_options_json()), "build_ms": 0, "presort_ms": 0})
    meta = meta.encode()
    counts = counts or (len(triangles), len(nodes), len(refs))
    body = b"SAHKDTRE" + struct.pack("<II", 1, len(meta)) + meta
    body += struct.pack("<QQQ", *counts) + np.asarray(bounds, "<f4").tobytes()
    body += triangles.astype("<f4").tobytes()
    body += np.asarray(nodes, "<u4").reshape(-1, 2).tobytes() + np.asarray(refs, "<u4").tobytes()
    return body + struct.pack("<Q", fnv1a(body))


def _options_json():
    """The options object of a real file, so the forged ones differ only where meant to."""
    tree = sahkd.KdTree(np.eye(3, dtype=np.float32), np.array([[0, 1, 2]]))
    data = tree.to_bytes()
    (n,) = struct.unpack("<I", data[12:16])
    return json.dumps(json.loads(data[16 : 16 + n])["options"])


# Two triangles, one each side of x = 1.5: a root split there and a leaf for each.
TWO = [[[0, 0, 0], [1, 0, 0.5], [0, 1, 1]], [[2, 0, 0], [3, 0, 0], [2, 1, 1]]]
GOOD_NODES = [interior(0, 1.5, 1), leaf(0, 1), leaf(1, 1)]


def test_a_forged_but_sound_file_loads_and_answers():
    tree = sahkd.from_bytes(forge(TWO, GOOD_NODES, [0, 1]))
    tree.validate()
    o = np.array([[0.2, 0.2, -1], [2.2, 0.2, -1], [1.5, 0.5, -1]], np.float32)
    d = np.tile(np.float32([0, 0, 1]), (3, 1))
    assert tree.intersect(o, d).prim.tolist() == [0, 1, -1]
    assert tree.stats["nodes"] == 3 and tree.stats["leaves"] == 2


def _chain(depth):
    """A chain of `depth` interior nodes: the one at level k (node 0, then 2k - 1) splits x
    at 3 / 2^(k+1), inside its box [0, 3 / 2^k], with the next level on its left (node
    2k + 1) and a leaf of both triangles on its right (node 2k + 2); the last left child is a
    leaf too."""
    nodes = [None] * (2 * depth + 1)
    for k in range(depth):
        nodes[0 if k == 0 else 2 * k - 1] = interior(0, 3.0 / 2 ** (k + 1), 2 * k + 1)
        nodes[2 * k + 2] = leaf(0, 2)
    nodes[2 * depth - 1] = leaf(0, 2)
    return nodes


@pytest.mark.parametrize(
    "kwargs, reason",
    [
        (dict(nodes=[interior(0, 5.0, 1), leaf(0, 1), leaf(1, 1)]), "splits axis 0 at 5"),
        (dict(nodes=[interior(0, 1.5, 0), leaf(0, 1), leaf(1, 1)]), "node 0 has children 0 and 1"),
        (dict(nodes=[interior(0, 1.5, 2), leaf(0, 1), leaf(1, 1)]), "node 0 has children 2 and 3"),
        (dict(nodes=[interior(0, 1.5, 1), leaf(0, 1), leaf(1, 5)]), "leaf 2 ends at reference 6"),
        (dict(nodes=[interior(0, 1.5, 1), leaf(0, 1), leaf(2**32 - 1, 1)]), "leaf 2 ends at reference 4294967296"),
        (dict(nodes=[interior(0, 1.5, 1), interior(0, 0.5, 2), leaf(0, 1), leaf(1, 1)]), "node 2 has 2 parents"),
        (dict(nodes=[interior(0, 1.5, 1), leaf(0, 1), leaf(1, 1), leaf(0, 0)]), "node 3 has 0 parents"),
        (dict(refs=[0, 7]), "reference to triangle 7"),
        (dict(nodes=[interior(0, 1.5, 1), leaf(1, 0), leaf(1, 1)]), "triangle 0 overlaps leaf 1"),
        (dict(bounds=[0, 0, 0, 3, 1, 2]), "bounds are not those of the triangles"),
        (dict(triangles=[[[0, 0, np.nan], [1, 0, 0], [0, 1, 0]], TWO[1]], bounds=[0, 0, 0, 3, 1, 1]), "triangle 0 has a non-finite corner"),
        (dict(nodes=[]), "no root node"),
        (dict(meta="{not json"), "corrupt metadata"),
        (dict(meta='{"options": {"algorithm": "magic"}}'), r"corrupt metadata \(build options\)"),
        (dict(counts=(2, 3, 3)), "do not fit the file"),
        (dict(counts=(2**62, 3, 2)), "do not fit the file"),
    ],
)
def test_forged_files_with_a_broken_structure_are_refused(kwargs, reason):
    args = dict(triangles=TWO, nodes=GOOD_NODES, refs=[0, 1])
    args.update(kwargs)
    with pytest.raises(ValueError, match=reason):
        sahkd.from_bytes(forge(**args))


def test_forged_trees_deeper_than_the_traversal_allows_are_refused():
    tri = [[[0, 0, 0], [3, 0, 0], [0, 1, 0]], [[0, 0, 0], [3, 0, 0], [0, 0, 1]]]
    fine = sahkd.from_bytes(forge(tri, _chain(60), [0, 1]))
    assert fine.stats["max_depth"] == 60
    with pytest.raises(ValueError, match="deeper than the limit of 60"):
        sahkd.from_bytes(forge(tri, _chain(61), [0, 1]))
