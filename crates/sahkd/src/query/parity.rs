//! The inside test by ray parity: a point is inside a closed mesh when a ray from it crosses
//! the surface an odd number of times.
//!
//! The kd-tree's crossing walk (`KdTree::for_each_crossing`: the hits of
//! [`KdTree::for_each_hit`] without each hit's distance refined, which parity never reads)
//! visits every leaf along the ray and reports a triangle referenced by several of them once
//! per leaf, so the crossings are counted as distinct triangles (sorted and deduplicated). What remains inexact is a ray through a
//! shared edge or vertex (counted once per triangle there, which can flip the parity) or
//! through a hole in the mesh. So one ray decides when each of its crossings lies clear of
//! its triangle's edges (every barycentric weight above [`EDGE_CLEARANCE`]): on a closed mesh
//! its parity is then exact. A ray with a crossing near an edge or a vertex is outvoted by two
//! more in fixed, unrelated, off-axis directions, and the majority wins (the third is cast
//! only when the first two disagree). Most points need one ray, as Open3D casts; a mesh with
//! holes wants the winding number instead (`InsideTest::Winding`).
//!
//! Two shortcuts leave the answers of closed meshes as they were and save most of the walking:
//! a point outside the mesh's bounding box is outside (no closed surface encloses it), and
//! each voting ray has its direction's signs turned towards the nearer face of the box along
//! every axis, so it crosses half the box or less instead of up to all of it. The directions
//! stay off the axes and unrelated to each other; only their octant depends on the point.

use crate::geometry::{Aabb, Vec3};
use crate::trace::Ray;
use crate::tree::KdTree;

/// Directions of the voting rays: off the axes and the diagonals, where meshes' edges and
/// the tree's split planes are unlikely to line up with them.
pub const DIRECTIONS: [Vec3; 3] = [
    Vec3::new(0.5390, 0.3711, 0.7562),
    Vec3::new(-0.6952, 0.5123, -0.5046),
    Vec3::new(0.2269, -0.8633, 0.4508),
];

/// A crossing with a barycentric weight at or below this lies near an edge or a vertex of
/// its triangle, where the neighbouring triangle may count the same crossing again.
pub const EDGE_CLEARANCE: f32 = 1e-4;

/// Whether the ray from `p` along `d` crosses an odd number of distinct triangles, and
/// whether every crossing lies clear of its triangle's edges; `buf` is scratch space kept
/// between calls.
pub(crate) fn crossings(tree: &KdTree, p: Vec3, d: Vec3, buf: &mut Vec<u32>) -> (bool, bool) {
    buf.clear();
    let mut clear = true;
    // Only the triangles and barycentrics count here, not the distances.
    tree.for_each_crossing(&Ray::new(p, d), |h| {
        clear &= h.u.min(h.v).min(1.0 - h.u - h.v) > EDGE_CLEARANCE;
        buf.push(h.prim)
    });
    buf.sort_unstable();
    buf.dedup();
    (buf.len() % 2 == 1, clear)
}

/// Voting direction `k` for a point at `p` in `bounds`: `DIRECTIONS[k]` with each component's
/// sign pointing to the nearer face of the box along that axis.
pub fn direction(k: usize, p: Vec3, bounds: &Aabb) -> Vec3 {
    let mut d = DIRECTIONS[k];
    for a in 0..3 {
        let towards_hi = bounds.hi[a] - p[a] < p[a] - bounds.lo[a];
        d[a] = if towards_hi { d[a].abs() } else { -d[a].abs() };
    }
    d
}

/// Whether `p` lies in the closed box `b` (false for NaN coordinates, which fail both
/// comparisons); parity answers every other point "outside" without a ray.
pub(crate) fn within(b: &Aabb, p: Vec3) -> bool {
    (0..3).all(|a| b.lo[a] <= p[a] && p[a] <= b.hi[a])
}

/// The first ray's parity when its crossings are clear of edges, else the majority of three
/// rays' parities; false for a non-finite point or one outside the mesh's bounding box.
pub(crate) fn inside(tree: &KdTree, p: Vec3, buf: &mut Vec<u32>) -> bool {
    let b = &tree.bounds;
    if !within(b, p) {
        return false;
    }
    let vote = |k: usize, buf: &mut Vec<u32>| crossings(tree, p, direction(k, p, b), buf);
    let (first, clear) = vote(0, buf);
    if clear || first == vote(1, buf).0 {
        return first;
    }
    vote(2, buf).0
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{build_triangles, BuildOptions, Triangle};

    /// The unit cube, each face cut into two triangles along a diagonal.
    fn cube() -> KdTree {
        let v = |i: usize| Vec3::new((i & 1) as f32, (i >> 1 & 1) as f32, (i >> 2 & 1) as f32);
        let faces = [
            [0, 2, 3, 1],
            [4, 5, 7, 6],
            [0, 1, 5, 4],
            [2, 6, 7, 3],
            [0, 4, 6, 2],
            [1, 3, 7, 5],
        ];
        let tris: Vec<Triangle> = faces
            .iter()
            .flat_map(|f| [[v(f[0]), v(f[1]), v(f[2])], [v(f[0]), v(f[2]), v(f[3])]])
            .collect();
        build_triangles(tris, &BuildOptions::default())
            .unwrap()
            .tree
    }

    /// A first ray aimed at a face's diagonal edge (within rounding) is not trusted alone:
    /// the other rays outvote it, and the point is inside. A ray through a face's middle is.
    #[test]
    fn a_ray_near_an_edge_is_outvoted_and_one_clear_of_edges_decides() {
        let tree = cube();
        let mut buf = Vec::new();
        // The top face's diagonal runs from (0,0,1) to (1,1,1); aim at its point (0.8,0.8,1).
        let d = DIRECTIONS[0];
        let p = Vec3::new(0.8, 0.8, 1.0) - d * 0.3;
        assert_eq!(
            direction(0, p, &tree.bounds),
            d,
            "the ray heads up, as aimed"
        );
        let (_, clear) = crossings(&tree, p, d, &mut buf);
        assert!(!clear, "a crossing at the diagonal edge is near it");
        assert!(inside(&tree, p, &mut buf));
        let q = Vec3::new(0.6, 0.55, 0.7);
        let (odd, clear) = crossings(&tree, q, direction(0, q, &tree.bounds), &mut buf);
        assert!(odd && clear);
        assert!(inside(&tree, q, &mut buf));
        assert!(!inside(&tree, Vec3::new(0.5, 0.5, 1.5), &mut buf));
    }
}
