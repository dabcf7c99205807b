//! The inside test by ray parity: a point is inside a closed mesh when a ray from it crosses
//! the surface an odd number of times.
//!
//! The kd-tree's [`KdTree::for_each_hit`] visits every leaf along the ray and reports a
//! triangle referenced by several of them once per leaf, so the crossings are counted as
//! distinct triangles (sorted and deduplicated). What remains inexact is a ray through a
//! shared edge or vertex (counted once per triangle there, which can flip the parity) or
//! through a hole in the mesh; so three rays in fixed, unrelated, off-axis directions vote,
//! and the majority wins (the third is cast only when the first two disagree).
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

/// Whether the ray from `p` along `d` crosses an odd number of distinct triangles; `buf` is
/// scratch space kept between calls.
pub(crate) fn odd_crossings(tree: &KdTree, p: Vec3, d: Vec3, buf: &mut Vec<u32>) -> bool {
    buf.clear();
    tree.for_each_hit(&Ray::new(p, d), |h| buf.push(h.prim));
    buf.sort_unstable();
    buf.dedup();
    buf.len() % 2 == 1
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

/// The majority of the three rays' parities; false for a non-finite point or one outside
/// the mesh's bounding box.
pub(crate) fn inside(tree: &KdTree, p: Vec3, buf: &mut Vec<u32>) -> bool {
    let b = &tree.bounds;
    let within = (0..3).all(|a| b.lo[a] <= p[a] && p[a] <= b.hi[a]);
    if !within {
        // Also false for NaN coordinates, which fail both comparisons.
        return false;
    }
    let vote = |k: usize, buf: &mut Vec<u32>| odd_crossings(tree, p, direction(k, p, b), buf);
    let first = vote(0, buf);
    if first == vote(1, buf) {
        return first;
    }
    vote(2, buf)
}
