//! A level handed over whole to depth-first builders: the hybrid builder's seam.
//!
//! Each node of the level becomes the root of a subtree that one worker builds with the
//! sweep. Its sorted lists are already the sweep's events (the same packed encoding, see
//! [`crate::builders::event::Event`]) with level slots where the sweep wants the node's own primitive
//! indices; slots keep the primitives' order within a node, so renumbering them from 0 keeps
//! every list sorted and the hand-over is linear, with no sort.

use super::entries::{Event, ListEntry};
use super::Level;
use crate::geometry::Aabb;

/// The level the level passes stopped at, and where its nodes go in the tree.
pub(crate) struct Frontier {
    level: Level<Event>,
    /// The tree slot of the level's node 0; node `k` goes to `first_slot + k`.
    pub first_slot: usize,
}

/// One frontier node: what the sweep needs to build its subtree.
pub(crate) struct FrontierNode<'a> {
    pub bounds: Aabb,
    pub depth: u32,
    /// The node's primitives; the sweep's primitive `i` is `prims[i]`.
    pub prims: &'a [u32],
    /// Per axis, the node's events with primitives numbered as in `prims`, sorted.
    pub events: [Vec<Event>; 3],
}

impl Frontier {
    pub(super) fn new(level: Level<Event>, first_slot: usize) -> Frontier {
        Frontier { level, first_slot }
    }

    pub fn nodes(&self) -> usize {
        self.level.nodes()
    }

    /// References of node `k`.
    pub fn refs(&self, k: usize) -> usize {
        self.level.refs(k) as usize
    }

    /// Node `k`, its events renumbered (linear in its entries).
    pub fn node(&self, k: usize) -> FrontierNode<'_> {
        let level = &self.level;
        let first = level.ref_starts[k];
        let prims = &level.prims[first as usize..level.ref_starts[k + 1] as usize];
        let events = [0, 1, 2].map(|axis| {
            let starts = &level.list_starts[axis];
            level.lists[axis][starts[k] as usize..starts[k + 1] as usize]
                .iter()
                .map(|e| e.with_slot(e.slot() - first))
                .collect()
        });
        FrontierNode {
            bounds: level.boxes[k],
            depth: level.depth,
            prims,
            events,
        }
    }
}
