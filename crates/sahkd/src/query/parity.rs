//! The inside test by ray parity: a point is inside a closed mesh when a ray from it crosses
//! the surface an odd number of times.
//!
//! The kd-tree's [`KdTree::for_each_hit`] visits every leaf along the ray and reports a
//! triangle referenced by several of them once per leaf, so the crossings are counted as
//! distinct triangles (sorted and deduplicated). What remains inexact is a ray through a
//! shared edge or vertex (counted once per triangle there, which can flip the parity) or
//! through a hole in the mesh; so three rays in fixed, unrelated, off-axis directions vote,
//! and the majority wins (the third is cast only when the first two disagree).

use crate::geometry::Vec3;
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

/// The majority of the three rays' parities; false for a non-finite point.
pub(crate) fn inside(tree: &KdTree, p: Vec3, buf: &mut Vec<u32>) -> bool {
    if !p.is_finite() {
        return false;
    }
    let a = odd_crossings(tree, p, DIRECTIONS[0], buf);
    let b = odd_crossings(tree, p, DIRECTIONS[1], buf);
    if a == b {
        return a;
    }
    odd_crossings(tree, p, DIRECTIONS[2], buf)
}
