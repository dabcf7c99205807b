//! The Wald & Havran (2006) builder: exact SAH in O(N log N), serial on purpose.
//!
//! Split events (start, end, planar) of every primitive on every axis are made once at the
//! root and sorted once. A node is priced by one sweep per axis over its sorted events
//! ([`search`]); its children's events come from its own by a stable split, with straddlers
//! re-clipped and merged in ([`partition`]). Nodes are built depth first from an explicit
//! stack, left child before right, both children's slots allocated together.

mod events;
mod partition;
mod search;

use super::{BuildOptions, BuiltTree, Primitives};
use crate::geometry::Aabb;
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
    let cost = &options.cost;
    let total_prims = prims.triangles.len();
    let max_depth = cost.max_depth_for(total_prims);
    let budget = cost.reference_budget(total_prims);
    let clip = options.clip.then_some(prims.triangles);

    let presort = Instant::now();
    let mut work = Workspace::new(&prims.boxes);
    let presort_ms = presort.elapsed().as_secs_f64() * 1e3;

    let mut nodes = vec![Node::leaf(0, 0)];
    let mut refs = Vec::new();
    // References held by the finished leaves and the pending nodes: the running total the
    // reference budget applies to.
    let mut references = total_prims;
    let mut stack = vec![Pending {
        slot: 0,
        bounds: prims.bounds,
        depth: 0,
        n: total_prims as u32,
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
            work.collect_prims(&node.events, &mut refs);
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
    let mut built = BuiltTree {
        nodes,
        refs,
        ..BuiltTree::default()
    };
    built.report.presort_ms = presort_ms;
    built.report.peak_working_bytes = work.peak_bytes();
    built
}
