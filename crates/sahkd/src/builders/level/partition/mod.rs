//! Phase 5: the level's leaves write their references out, and every other node's references
//! and sorted lists are stably partitioned into its children's segments of the next level.
//!
//! The children a reference goes to are read off the node's list on the split axis (its
//! entries hold the reference's extent there). The next level's arrays are laid out by
//! exclusive scans over the children's sizes (the paper's formulas (5) and (6)), and each
//! reference is written at its child's offset plus its rank among the references going there
//! (a segmented scan over chunks, see [`segments`]); each list is split node by node, a large
//! node in parallel chunks.
//! A straddler goes to both children; with clipping it is clipped to each child's box (and
//! dropped from a child its clipped box misses), and since its clipped box can move it in the
//! children's sort orders, its entries are taken out of the partitioned lists, sorted on their
//! own (they are few) and merged into each child's segment. Everything else keeps its order, so
//! the children's lists come out sorted without sorting them.
//!
//! A child that will be a leaf by the size or depth rule gets no list entries at all (its
//! references are all the next level needs), as the paper skips the children it will not split.
//!
//! [`segments`]: super::segments
//!
//! The phase's parts: [`output`] writes the level's nodes and its leaves' references,
//! [`refs`] decides where each reference goes and lays the next level's references out, and
//! [`lists`] splits the sorted lists.

mod lists;
mod output;
mod refs;

pub(super) use refs::flat_mask;

use super::entries::ListEntry;
use super::segments::{filled, Scatter};
use super::{Context, Level};
use crate::builders::choice::Split;
use crate::builders::BuiltTree;
use crate::geometry::Aabb;
use lists::partition_lists;
use output::write_nodes_and_leaves;
use refs::{classify, lay_out, mark_sides, node_totals, scatter_refs, RefTally};

/// A slot that goes nowhere (or whose list entries are rebuilt rather than moved).
const NONE: u32 = u32::MAX;

/// A clipped straddler in a child: its slot there and its clipped box.
#[derive(Clone, Copy, Debug)]
pub(super) struct Clipped {
    slot: u32,
    bbox: Aabb,
}

/// Working arrays of the partition, reused from level to level (fresh memory costs page
/// faults, which at the deep levels cost more than the work).
#[derive(Default)]
pub(super) struct Work {
    /// Per level node: the index of its left child in the next level (`NONE` for a leaf).
    left: Vec<u32>,
    /// Per level node that is a leaf: its first reference in the tree.
    leaf_first: Vec<u32>,
    /// Per level node: what it sends to its children.
    totals: Vec<RefTally>,
    /// Per child: whether it gets list entries.
    lists: Vec<bool>,
    /// Per child: the start of its clipped straddlers in `regen` (len children + 1).
    regen_starts: Vec<u32>,
    /// Per slot of a split node (`2 * slot + side`): whether its reference goes to that child,
    /// read off the split axis's list (sorted builds; the naive one has the boxes).
    go: Vec<bool>,
    /// Per slot of the level: where its reference goes in each child (`NONE`: nowhere, or its
    /// entries are rebuilt from its clipped box).
    slot_map: Vec<[u32; 2]>,
    /// Clipped straddlers of the listed children, grouped by child.
    regen: Vec<Clipped>,
}

impl Work {
    /// The index in the next level of the left child of the level's node `k`, a split node.
    pub fn left_child(&self, k: usize) -> usize {
        debug_assert_ne!(self.left[k], NONE);
        self.left[k] as usize
    }

    pub fn bytes(&self) -> usize {
        use std::mem::size_of;
        self.left.capacity() * 4
            + self.leaf_first.capacity() * 4
            + self.totals.capacity() * size_of::<RefTally>()
            + self.lists.capacity()
            + self.go.capacity()
            + self.regen_starts.capacity() * 4
            + self.slot_map.capacity() * 8
            + self.regen.capacity() * size_of::<Clipped>()
    }
}

/// Runs phase 5. Returns false when the level split nothing (the tree is done); otherwise
/// `next` holds the next level.
pub(super) fn partition<E: ListEntry>(
    level: &Level<E>,
    splits: &[Option<Split>],
    ctx: &Context,
    out: &mut BuiltTree,
    next: &mut Level<E>,
    work: &mut Work,
) -> bool {
    write_nodes_and_leaves(level, splits, out, work);
    if !splits.iter().any(|s| s.is_some()) {
        return false;
    }
    if level.sorted {
        mark_sides(level, splits, &mut work.go);
    }
    let chunks = classify(level, splits, ctx, &work.go);
    let carry = node_totals(&chunks, level.nodes(), &mut work.totals);
    lay_out(level, splits, ctx, next, work);
    scatter_refs(level, splits, ctx, &chunks, &carry, next, work);
    if level.sorted {
        let [l0, l1, l2] = &mut next.lists;
        let mut sinks = [l0, l1, l2].map(|l| {
            l.clear();
            Some(l)
        });
        let mut totals = [0usize; 3];
        let sinks: Vec<Scatter<E>> = (0..3)
            .map(|axis| {
                let total = *next.list_starts[axis].last().unwrap() as usize;
                totals[axis] = total;
                Scatter::tail(sinks[axis].take().unwrap(), total)
            })
            .collect();
        partition_lists(level, splits, &next.list_starts, work, &sinks);
        drop(sinks);
        for (axis, total) in totals.into_iter().enumerate() {
            // Safety: the kept entries and the merged clipped ones fill every child segment.
            unsafe { filled(&mut next.lists[axis], total) };
        }
    }
    true
}
