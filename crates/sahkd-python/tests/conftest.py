"""Shared test data and the float64 oracle.

The oracle is Moller-Trumbore in float64 over every (ray, triangle) pair, written here in
numpy and sharing nothing with sahkd. sahkd computes in float32 with a different (watertight)
test, so the two can disagree only where a ray passes within rounding of a triangle's edge
or plane; `oracle` reports those rays as ambiguous and the tests compare all the others
exactly (which triangles, in which order) and the numbers within float32 tolerance.
"""

import os
from pathlib import Path

import numpy as np
import pytest

# Barycentric and distance margins below which a (ray, triangle) pair counts as ambiguous.
EDGE_MARGIN = 1e-4
T_MARGIN = 1e-4


def scenes_dir():
    """The shared scenes folder, or None (tests that need it skip with a message)."""
    env = os.environ.get("SAHKD_SCENES")
    candidates = [Path(env)] if env else []
    root = Path(__file__).resolve().parents[3]  # crates/sahkd-python/tests -> workspace
    candidates += [root.parent / "shared" / "scenes", root / "shared" / "scenes"]
    for c in candidates:
        if (c / "dragon_res4.ply").exists():
            return c
    return None


@pytest.fixture
def scenes():
    d = scenes_dir()
    if d is None:
        pytest.skip("scenes folder not found (set SAHKD_SCENES or put it at ../shared/scenes)")
    return d


def triangle_soup(rng, n, spread=1.0, size=0.25):
    """n random triangles (as float32 vertices and int64 faces, 3 vertices per face)."""
    centres = rng.uniform(-spread, spread, (n, 1, 3))
    corners = centres + rng.uniform(-size, size, (n, 3, 3))
    vertices = corners.reshape(-1, 3).astype(np.float32)
    faces = np.arange(3 * n, dtype=np.int64).reshape(n, 3)
    return vertices, faces


def random_rays(rng, vertices, faces, n, aimed=0.7):
    """n rays from a box around the scene; a fraction aimed at random points of random
    triangles (so they hit), the rest in random directions. float32."""
    lo, hi = vertices.min(axis=0), vertices.max(axis=0)
    pad = hi - lo
    origins = rng.uniform(lo - pad, hi + pad, (n, 3))
    k = int(n * aimed)
    directions = rng.normal(size=(n, 3))
    if len(faces):
        tri = vertices[faces[rng.integers(0, len(faces), k)]].astype(np.float64)
        w = rng.dirichlet([1, 1, 1], k)
        targets = np.einsum("ij,ijk->ik", w, tri)
        directions[:k] = targets - origins[:k]
    return origins.astype(np.float32), directions.astype(np.float32)


def oracle(vertices, faces, origins, directions, t_min=0.0, t_max=np.inf):
    """Every hit in float64: (hits, ambiguous) where hits[i] is a list of (t, prim, u, v)
    sorted by (t, prim) and ambiguous[i] says whether ray i passes within the margins of an
    edge, a plane or the ends of its range, so that float32 rounding may decide it."""
    tri = vertices[faces].astype(np.float64)
    o = origins.astype(np.float64)[:, None, :]
    d = directions.astype(np.float64)[:, None, :]
    v0, e1, e2 = tri[None, :, 0], (tri[:, 1] - tri[:, 0])[None], (tri[:, 2] - tri[:, 0])[None]
    p = np.cross(d, e2)
    det = (e1 * p).sum(-1)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / det
        s = o - v0
        u = (s * p).sum(-1) * inv
        q = np.cross(s, e1)
        v = (d * q).sum(-1) * inv
        t = (e2 * q).sum(-1) * inv
    # Scale-free tests: barycentrics against EDGE_MARGIN, t against T_MARGIN of its size.
    area = np.linalg.norm(np.cross(e1, e2), axis=-1)
    dnorm = np.linalg.norm(d, axis=-1)
    enorm = np.maximum(np.linalg.norm(e1, axis=-1), np.linalg.norm(e2, axis=-1))
    sine = np.abs(det) / np.maximum(area * dnorm, 1e-300)  # |cos| of ray vs. normal
    w = 1 - u - v
    t_min = np.broadcast_to(np.asarray(t_min, np.float64), (len(origins),))[:, None]
    t_max = np.broadcast_to(np.asarray(t_max, np.float64), (len(origins),))[:, None]
    inside = (u > EDGE_MARGIN) & (v > EDGE_MARGIN) & (w > EDGE_MARGIN)
    outside = (u < -EDGE_MARGIN) | (v < -EDGE_MARGIN) | (w < -EDGE_MARGIN)
    tol = T_MARGIN * np.maximum(np.abs(t), enorm / dnorm)
    in_range = (t > t_min + tol) & (t < t_max - tol)
    out_range = (t < t_min - tol) | (t > t_max + tol)
    grazing = sine < 1e-3
    degenerate = area == 0
    hit = inside & in_range & ~grazing & ~degenerate
    clear_miss = degenerate | outside | out_range | ~np.isfinite(t)
    ambiguous = ~(hit | clear_miss)
    hits = []
    for i in range(len(origins)):
        js = np.flatnonzero(hit[i])
        rows = sorted((t[i, j], int(j), u[i, j], v[i, j]) for j in js)
        hits.append(rows)
    return hits, ambiguous.any(axis=1)
