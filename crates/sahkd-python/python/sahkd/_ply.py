"""A minimal reader of binary PLY triangle meshes, for when trimesh is not installed.

It reads binary PLY (either byte order) whose faces are all triangles: a `vertex` element
with float `x`, `y`, `z` among its scalar properties, a `face` element whose one list
property holds the corner indices, and any other elements made of scalar properties. ASCII
PLY, polygons and list properties elsewhere are refused with a message saying so.
"""

import numpy as np

_TYPES = {
    "char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1",
    "short": "i2", "int16": "i2", "ushort": "u2", "uint16": "u2",
    "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
    "float": "f4", "float32": "f4", "double": "f8", "float64": "f8",
}  # fmt: skip


def _type(name, path):
    try:
        return _TYPES[name]
    except KeyError:
        raise ValueError(f"{path}: unknown PLY property type '{name}'") from None


def _header(data, path):
    end = data.find(b"end_header")
    if not data.startswith(b"ply") or end < 0:
        raise ValueError(f"{path}: not a PLY file (no 'ply' ... 'end_header' header)")
    body = data.index(b"\n", end) + 1
    lines = data[:end].decode("ascii", errors="replace").splitlines()
    byte_order, elements = None, []
    for line in lines[1:]:
        words = line.split()
        if not words or words[0] in ("comment", "obj_info"):
            continue
        if words[0] == "format":
            fmt = words[1] if len(words) > 1 else ""
            if fmt == "binary_little_endian":
                byte_order = "<"
            elif fmt == "binary_big_endian":
                byte_order = ">"
            else:
                raise ValueError(
                    f"{path}: PLY format '{fmt}' is not supported by the built-in reader "
                    "(binary only); install trimesh to read it"
                )
        elif words[0] == "element":
            elements.append((words[1], int(words[2]), []))
        elif words[0] == "property":
            if not elements:
                raise ValueError(f"{path}: PLY property before any element")
            if words[1] == "list":
                prop = (words[4], "list", _type(words[2], path), _type(words[3], path))
            else:
                prop = (words[2], "scalar", _type(words[1], path), None)
            elements[-1][2].append(prop)
    if byte_order is None:
        raise ValueError(f"{path}: PLY header has no format line")
    return byte_order, elements, body


def read_ply(path):
    """Vertices (V, 3) float32 and faces (F, 3) int64 of a binary triangle PLY file."""
    with open(path, "rb") as f:
        data = f.read()
    order, elements, at = _header(data, path)
    vertices = faces = None
    for name, count, props in elements:
        lists = [p for p in props if p[1] == "list"]
        if lists and not (name == "face" and len(lists) == 1):
            raise ValueError(
                f"{path}: element '{name}' has list properties the built-in reader cannot "
                "skip; install trimesh to read it"
            )
        fields = []
        for prop_name, kind, t, idx in props:
            if kind == "list":
                fields += [("_n", order + t), (prop_name, order + idx, (3,))]
            else:
                fields.append((prop_name, order + t))
        dtype = np.dtype(fields)
        size = dtype.itemsize * count
        if at + size > len(data):
            raise ValueError(f"{path}: truncated in element '{name}'")
        rows = np.frombuffer(data, dtype=dtype, count=count, offset=at)
        at += size
        if name == "vertex":
            if not all(k in dtype.names for k in "xyz"):
                raise ValueError(f"{path}: vertex element has no x, y, z properties")
            vertices = np.column_stack([rows[k].astype(np.float32) for k in "xyz"])
        elif name == "face":
            if not lists:
                raise ValueError(f"{path}: face element has no list of vertex indices")
            if count and not (rows["_n"] == 3).all():
                raise ValueError(
                    f"{path}: faces are not all triangles; the built-in reader reads "
                    "triangle meshes only (install trimesh to read polygons)"
                )
            faces = rows[lists[0][0]].astype(np.int64).reshape(-1, 3)
    if vertices is None or faces is None:
        raise ValueError(f"{path}: PLY file has no vertex or no face element")
    return vertices, faces
