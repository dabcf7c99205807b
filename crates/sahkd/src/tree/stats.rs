//! Tree statistics: size, shape and SAH cost.

use super::{KdTree, Node};
use crate::CostModel;
use serde::Serialize;

/// What a built tree looks like.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct TreeStats {
    pub triangles: usize,
    pub nodes: usize,
    pub interior: usize,
    pub leaves: usize,
    pub empty_leaves: usize,
    pub references: usize,
    /// References per triangle.
    pub duplication: f64,
    pub max_depth: u32,
    /// Mean primitives per non-empty leaf.
    pub mean_leaf_size: f64,
    /// Expected cost of a ray under the cost model, normalised by the root's surface area:
    /// `sum K_T * SA(interior) + sum K_I * n * SA(leaf)`, divided by `SA(root)`.
    pub sah_cost: f64,
    /// Bytes of nodes, references and triangle data.
    pub bytes: usize,
}

pub(super) fn compute(tree: &KdTree, cost: &CostModel) -> TreeStats {
    let mut s = TreeStats {
        triangles: tree.triangles.len(),
        nodes: tree.nodes.len(),
        references: tree.refs.len(),
        bytes: std::mem::size_of_val(tree.nodes.as_slice())
            + std::mem::size_of_val(tree.refs.as_slice())
            + std::mem::size_of_val(tree.triangles.as_slice()),
        ..TreeStats::default()
    };
    let root_area = tree.bounds.surface_area();
    let mut weighted = 0.0f64;
    let mut leaf_prims = 0usize;
    tree.visit(|_, node: &Node, bounds, depth| {
        s.max_depth = s.max_depth.max(depth);
        let area = bounds.surface_area();
        if node.is_leaf() {
            s.leaves += 1;
            if node.count() == 0 {
                s.empty_leaves += 1;
            }
            leaf_prims += node.count() as usize;
            weighted += cost.intersection as f64 * node.count() as f64 * area;
        } else {
            s.interior += 1;
            weighted += cost.traversal as f64 * area;
        }
    });
    s.duplication = if s.triangles > 0 {
        s.references as f64 / s.triangles as f64
    } else {
        0.0
    };
    let full = s.leaves - s.empty_leaves;
    s.mean_leaf_size = if full > 0 {
        leaf_prims as f64 / full as f64
    } else {
        0.0
    };
    s.sah_cost = if root_area > 0.0 {
        weighted / root_area
    } else {
        0.0
    };
    s
}
