"""python -m sahkd.compare, its camera and its fallback PLY reader."""

import json
import struct
import subprocess
import sys

import numpy as np
import pytest

import sahkd
from sahkd import compare
from sahkd._sahkd import _read_mesh


def write_ply(path, vertices, faces, order="<", extra_vertex_property=False, extra_element=False):
    fmt = {"<": "binary_little_endian", ">": "binary_big_endian"}[order]
    header = ["ply", f"format {fmt} 1.0", "comment written by the sahkd tests"]
    header += [f"element vertex {len(vertices)}", "property float x", "property float y", "property float z"]
    if extra_vertex_property:
        header.append("property uchar flag")
    if extra_element:
        header += ["element material 2", "property double shininess"]
    header += [f"element face {len(faces)}", "property list uchar int vertex_indices", "end_header"]
    out = ("\n".join(header) + "\n").encode()
    for i, v in enumerate(vertices):
        out += struct.pack(order + "3f", *v)
        if extra_vertex_property:
            out += struct.pack("B", i % 256)
    if extra_element:
        out += struct.pack(order + "2d", 0.5, 2.0)
    for f in faces:
        out += struct.pack(order + "B3i", 3, *f)
    path.write_bytes(out)


def sphere_mesh():
    trimesh = pytest.importorskip("trimesh")
    m = trimesh.creation.icosphere(subdivisions=2)
    return np.asarray(m.vertices, np.float32), np.asarray(m.faces, np.int64)


@pytest.mark.parametrize(
    "order, extra_vertex_property, extra_element",
    [("<", False, False), (">", True, False), ("<", True, True)],
)
def test_the_mesh_reader_reads_binary_triangle_meshes(tmp_path, order, extra_vertex_property, extra_element):
    rng = np.random.default_rng(0)
    vertices = rng.normal(size=(30, 3)).astype(np.float32)
    faces = rng.integers(0, 30, (50, 3))
    path = tmp_path / "mesh.ply"
    write_ply(path, vertices, faces, order, extra_vertex_property, extra_element)
    v, f = _read_mesh(path)
    assert (v.dtype, f.dtype) == (np.float32, np.int64)
    np.testing.assert_array_equal(v, vertices)
    np.testing.assert_array_equal(f, faces)


def test_the_mesh_reader_agrees_with_trimesh_on_a_real_scene(scenes):
    trimesh = pytest.importorskip("trimesh")
    path = scenes / "dragon_res4.ply"
    v, f = _read_mesh(path)
    mesh = trimesh.load(path, force="mesh", process=False)
    assert (len(v), len(f)) == (5205, 11102)
    np.testing.assert_array_equal(v, np.asarray(mesh.vertices, np.float32))
    np.testing.assert_array_equal(f, mesh.faces)


def test_the_mesh_reader_splits_polygons_and_names_what_it_refuses(tmp_path):
    quads = tmp_path / "quads.ply"
    header = b"ply\nformat binary_little_endian 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\nelement face 2\nproperty list uchar int vertex_indices\nend_header\n"
    body = np.zeros(12, "<f4").tobytes() + struct.pack("<B4i", 4, 0, 1, 2, 3) + struct.pack("<B3i", 3, 0, 1, 2)
    quads.write_bytes(header + body)
    assert _read_mesh(quads)[1].tolist() == [[0, 1, 2], [0, 2, 3], [0, 1, 2]]
    not_ply = tmp_path / "x.ply"
    not_ply.write_bytes(b"solid x\n")
    with pytest.raises(ValueError, match="x.ply: .*not a PLY file"):
        _read_mesh(not_ply)
    truncated = tmp_path / "short.ply"
    write_ply(truncated, np.zeros((3, 3)), [[0, 1, 2]])
    truncated.write_bytes(truncated.read_bytes()[:-5])
    with pytest.raises(ValueError, match="short.ply: "):
        _read_mesh(truncated)
    with pytest.raises(FileNotFoundError, match="missing.ply"):
        _read_mesh(tmp_path / "missing.ply")


def test_the_camera_looks_at_the_centre_from_twice_the_diagonal():
    vertices = np.array([[0, 0, 0], [2, 0, 0], [0, 4, 0], [0, 0, 4], [9, 9, 9]], np.float32)
    faces = np.array([[0, 1, 2], [0, 2, 3]])  # vertex 4 is unused and must not count
    origins, directions = compare.camera_rays(vertices, faces, 9)
    diagonal = np.sqrt(2**2 + 4**2 + 4**2)
    np.testing.assert_allclose(origins[0], [1, 2, 2 + 2 * diagonal], rtol=1e-6)
    np.testing.assert_allclose(np.linalg.norm(directions, axis=1), 1, rtol=1e-6)
    np.testing.assert_allclose(directions[4 * 9 + 4], [0, 0, -1], atol=1e-7)  # centre pixel
    # The top and bottom rows are half a pixel inside the 45 degree field of view, top first.
    top, bottom = directions[4], directions[8 * 9 + 4]
    half = np.tan(np.radians(22.5)) * (1 - 1 / 9)
    np.testing.assert_allclose([top[1] / -top[2], bottom[1] / -bottom[2]], [half, -half], rtol=1e-6)


@pytest.mark.parametrize("trimesh_installed", [True, False])
def test_meshes_are_read_with_the_library_reader(tmp_path, monkeypatch, trimesh_installed):
    vertices, faces = sphere_mesh()
    path = tmp_path / "sphere.ply"
    write_ply(path, vertices, faces)
    if not trimesh_installed:
        monkeypatch.setitem(sys.modules, "trimesh", None)  # makes `import trimesh` fail
    v, f, reader = compare.load_mesh(path)
    assert reader == "sahkd's mesh reader"
    np.testing.assert_array_equal(v, vertices)
    np.testing.assert_array_equal(f, faces)


def test_the_default_builder_is_the_librarys():
    vertices, faces = sphere_mesh()
    caster = compare.Sahkd(None, None)
    caster.build(vertices, faces)
    assert caster.tree.stats["algorithm"] == sahkd.KdTree(vertices, faces).stats["algorithm"]


def test_compare_runs_and_the_libraries_agree(tmp_path):
    vertices, faces = sphere_mesh()
    path = tmp_path / "sphere.ply"
    write_ply(path, vertices, faces)
    args = [sys.executable, "-m", "sahkd.compare", str(path), "--size", "24", "--repeat", "1"]
    out = subprocess.run(args + ["--json"], capture_output=True, text=True, timeout=300, check=True)
    report = json.loads(out.stdout)
    rows = {r["library"].split()[0]: r for r in report["results"]}
    assert report["rays"] == 24 * 24 and report["triangles"] == len(faces)
    assert rows["sahkd"]["hits"] > 0 and rows["sahkd"]["agree"] == 1.0
    for name, row in rows.items():
        assert row["agree"] > 0.99, f"{name} disagrees with sahkd on {1 - row['agree']:.1%} of rays"
        assert row["mrays_per_s"] > 0
    skipped = {s["library"] for s in report["skipped"]}
    assert set(rows) | skipped == {"sahkd", "embreex", "open3d", "trimesh"}
    text = subprocess.run(args + ["--libraries", "sahkd"], capture_output=True, text=True, timeout=300, check=True).stdout
    assert "Mrays/s" in text and "sahkd" in text
