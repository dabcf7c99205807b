//! The level's output: its nodes appended to the tree, breadth first, and its leaves'
//! references, placed by one scan over the nodes.

use super::{Work, NONE};
use crate::builders::choice::Split;
use crate::builders::level::entries::ListEntry;
use crate::builders::level::segments::{filled, Prefix, Scatter, Tally};
use crate::builders::level::Level;
use crate::builders::BuiltTree;
use crate::tree::Node;

/// Children and leaf references before a node: the scan that places the level's output.
#[derive(Clone, Copy, Default)]
struct Placed {
    children: u32,
    leaf_refs: u32,
}

impl Tally for Placed {
    fn add(self, o: Self) -> Self {
        Placed {
            children: self.children + o.children,
            leaf_refs: self.leaf_refs + o.leaf_refs,
        }
    }
    fn restart(self) -> Self {
        self
    }
}

/// Appends the level's nodes to the tree (breadth first: children of the level's split nodes
/// follow the level, side by side) and its leaves' references. Sets, per node, the index of
/// its left child within the next level (`NONE` for a leaf).
pub(super) fn write_nodes_and_leaves<E: ListEntry>(
    level: &Level<E>,
    splits: &[Option<Split>],
    out: &mut BuiltTree,
    work: &mut Work,
) {
    let nodes = level.nodes();
    let next_base = (out.nodes.len() + nodes) as u32;
    let count = |k: usize| match splits[k] {
        Some(_) => Placed {
            children: 2,
            leaf_refs: 0,
        },
        None => Placed {
            children: 0,
            leaf_refs: level.refs(k),
        },
    };
    let scan = Prefix::new(nodes, count);
    let (base, first_ref) = (out.nodes.len(), out.refs.len());
    let node_sink = Scatter::tail(&mut out.nodes, nodes);
    let ref_sink = Scatter::tail(&mut out.refs, scan.total.leaf_refs as usize);
    work.left.clear();
    work.leaf_first.clear();
    let left = Scatter::tail(&mut work.left, nodes);
    let leaf_first = Scatter::tail(&mut work.leaf_first, nodes);
    // Safety (all writes): one per node index, and each leaf's references at its own offset.
    scan.visit(nodes, count, |k, before| unsafe {
        match splits[k] {
            Some(s) => {
                node_sink.write(
                    base + k,
                    Node::interior(s.axis, s.pos, next_base + before.children),
                );
                left.write(k, before.children);
                leaf_first.write(k, 0);
            }
            None => {
                let first = (first_ref as u32) + before.leaf_refs;
                let (s, e) = (
                    level.ref_starts[k] as usize,
                    level.ref_starts[k + 1] as usize,
                );
                node_sink.write(base + k, Node::leaf(first, (e - s) as u32));
                left.write(k, NONE);
                leaf_first.write(k, first);
                ref_sink
                    .slice(first as usize..first as usize + e - s)
                    .copy_from_slice(&level.prims[s..e]);
            }
        }
    });
    unsafe {
        filled(&mut out.nodes, base + nodes);
        filled(&mut out.refs, first_ref + scan.total.leaf_refs as usize);
        filled(&mut work.left, nodes);
        filled(&mut work.leaf_first, nodes);
    }
}
