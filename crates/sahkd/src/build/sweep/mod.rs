//! The Wald & Havran (2006) builder: exact SAH in O(N log N), serial on purpose.
//!
//! Split events (start, end, planar) of every primitive on every axis are made once at the
//! root and sorted once. A node is priced by one sweep per axis over its sorted events
//! ([`search`]); its children's events come from its own by a stable split, with straddlers
//! re-clipped and merged in ([`partition`]). Nodes are built depth first from an explicit
//! stack, left child before right, both children's slots allocated together.
//!
//! [`build_subtree`] builds below any node, not only the root: the median builder hands it
//! its small nodes.

mod events;
mod partition;
mod search;

use super::{BuildOptions, BuiltTree, Primitives};
use crate::geometry::{Aabb, Triangle};
use crate::tree::Node;
use partition::{Segment, Workspace};
use std::time::Instant;

/// A node waiting to be built: its slot, box, depth, primitive count and events.
struct Pending {
    slot: u32,
    bounds: Aabb,
    depth: u32,
    n: u32,
    events: Segment,
}

pub(crate) fn build(prims: &Primitives, options: &BuildOptions) -> BuiltTree {
    let total_prims = prims.triangles.len();
    let subtree = Subtree {
        triangles: prims.triangles,
        boxes: &prims.boxes,
        bounds: prims.bounds,
        depth: 0,
        max_depth: options.cost.max_depth_for(total_prims),
        budget: options.cost.reference_budget(total_prims),
    };
    let mut built = BuiltTree::default();
    let report = build_subtree(&subtree, options, &mut built.nodes, &mut built.refs);
    built.report.presort_ms = report.presort_ms;
    built.report.peak_working_bytes = report.peak_working_bytes;
    built
}

/// A node to build the whole subtree of, with the limits that come from the whole tree.
pub(crate) struct Subtree<'a> {
    /// The node's primitives: their triangles (for clipping) and their boxes within `bounds`.
    /// Primitive `i` here is `triangles[i]`; the leaves reference these local indices.
    pub triangles: &'a [Triangle],
    pub boxes: &'a [Aabb],
    /// The node's box.
    pub bounds: Aabb,
    /// The node's depth in the whole tree.
    pub depth: u32,
    /// The whole tree's depth limit.
    pub max_depth: u32,
    /// The most references the subtree's leaves may hold together.
    pub budget: usize,
}

/// What building a subtree took.
pub(crate) struct SubtreeReport {
    pub presort_ms: f64,
    pub peak_working_bytes: usize,
}

/// Builds the subtree of `subtree`'s node, appending its nodes to `nodes` (its root first,
/// at the index `nodes.len()` had on entry) and its leaves' references to `refs`.
pub(crate) fn build_subtree(
    subtree: &Subtree,
    options: &BuildOptions,
    nodes: &mut Vec<Node>,
    refs: &mut Vec<u32>,
) -> SubtreeReport {
    let cost = &options.cost;
    let (max_depth, budget) = (subtree.max_depth, subtree.budget);
    let clip = options.clip.then_some(subtree.triangles);

    let presort = Instant::now();
    let mut work = Workspace::new(subtree.boxes);
    let presort_ms = presort.elapsed().as_secs_f64() * 1e3;

    let root = nodes.len() as u32;
    nodes.push(Node::leaf(0, 0));
    // References held by the finished leaves and the pending nodes: the running total the
    // reference budget applies to.
    let mut references = subtree.boxes.len();
    let mut stack = vec![Pending {
        slot: root,
        bounds: subtree.bounds,
        depth: subtree.depth,
        n: subtree.boxes.len() as u32,
        events: [0; 3],
    }];
    while let Some(node) = stack.pop() {
        let split = if node.n <= cost.leaf_size || node.depth >= max_depth {
            None
        } else {
            search::best_split(
                work.events(&node.events),
                &node.bounds,
                node.n,
                options.axes,
                cost,
            )
            .filter(|s| {
                s.cost < cost.leaf_cost(node.n)
                    && references + (s.n_left + s.n_right - node.n) as usize <= budget
            })
        };
        let Some(split) = split else {
            let first = refs.len() as u32;
            work.collect_prims(&node.events, refs);
            debug_assert_eq!(refs.len() as u32 - first, node.n);
            nodes[node.slot as usize] = Node::leaf(first, node.n);
            work.pop(&node.events);
            continue;
        };
        let left = nodes.len() as u32;
        nodes[node.slot as usize] = Node::interior(split.axis, split.pos, left);
        nodes.extend([Node::leaf(0, 0); 2]);
        let children = work.split(&node.events, &node.bounds, &split, clip);
        references = references + (children.n_left + children.n_right) as usize - node.n as usize;
        let (left_box, right_box) = node.bounds.split(split.axis, split.pos);
        let depth = node.depth + 1;
        stack.push(Pending {
            slot: left + 1,
            bounds: right_box,
            depth,
            n: children.n_right,
            events: children.right,
        });
        stack.push(Pending {
            slot: left,
            bounds: left_box,
            depth,
            n: children.n_left,
            events: children.left,
        });
    }
    SubtreeReport {
        presort_ms,
        peak_working_bytes: work.peak_bytes(),
    }
}
