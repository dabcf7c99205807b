//! The level's candidate planes: one flat array for the whole level. Every (node, axis) pair
//! that is priced owns a contiguous range of it, laid out by an exclusive scan over the pairs'
//! capacities (two slots per list entry where every candidate is kept, one slot where a sweep
//! keeps only the pair's best), so that filling, counting and the per-node minimum need no
//! search and no second pass.

use super::segments::{Prefix, Scatter, Tally};
use crate::builders::choice::{Ranked, Split};
use crate::cost::{CostModel, SplitPricer};
use crate::geometry::Aabb;
use rayon::prelude::*;
use std::mem::MaybeUninit;

/// One candidate plane of the level's flat array: its position, the node it belongs to and,
/// once counted, what the builders' one [`Split`] records (its axis is the array block's).
#[derive(Clone, Copy, Debug)]
pub(super) struct Candidate {
    pub pos: f32,
    pub cost: f32,
    /// Index of the node in the level ([`HOLE`] for a slot that holds no candidate).
    pub owner: u32,
    /// `n_left << 1 | planar_left`: the left child's primitives, planar ones counted on
    /// their side, and the side they go to.
    left: u32,
    /// The right child's primitives, planar ones counted on their side.
    n_right: u32,
}

/// The owner of an empty slot (a lo or hi that is not strictly inside its node).
pub(super) const HOLE: u32 = u32::MAX;

impl Candidate {
    pub fn new(pos: f32, owner: u32) -> Self {
        Candidate {
            pos,
            cost: f32::INFINITY,
            owner,
            left: 0,
            n_right: 0,
        }
    }
    pub fn hole() -> Self {
        Candidate::new(0.0, HOLE)
    }
    /// Where this candidate falls in the builders' one order, on `axis`.
    #[inline]
    pub fn ranked(&self, axis: usize) -> Ranked {
        Ranked {
            cost: self.cost,
            pos: self.pos,
            axis,
        }
    }
    /// The split this candidate makes on `axis`.
    pub fn split(&self, axis: usize) -> Split {
        Split {
            axis,
            pos: self.pos,
            cost: self.cost,
            planar_left: self.left & 1 == 1,
            n_left: self.left >> 1,
            n_right: self.n_right,
        }
    }
}

/// The level's candidates. `ranges[axis][k]` is node k's range on that axis; only those
/// ranges are initialised.
#[derive(Default)]
pub(super) struct Candidates {
    items: Vec<MaybeUninit<Candidate>>,
    pub ranges: [Vec<[usize; 2]>; 3],
    /// Candidates priced (holes excluded).
    pub priced: usize,
}

impl Candidates {
    /// Lays out `capacity(axis, k)` slots for every node and axis (0 for pairs not priced).
    /// Each range starts empty-ended at its start; fillers set the ends.
    pub fn lay_out(&mut self, nodes: usize, capacity: impl Fn(usize, usize) -> usize + Sync) {
        let mut total = 0usize;
        for (axis, ranges) in self.ranges.iter_mut().enumerate() {
            let count = |k: usize| Slots(capacity(axis, k));
            let scan = Prefix::new(nodes, count);
            ranges.clear();
            let sink = Scatter::tail(ranges, nodes);
            // Safety: one write per node.
            scan.visit(nodes, count, |k, before| unsafe {
                let start = total + before.0;
                sink.write(k, [start, start]);
            });
            unsafe { super::segments::filled(ranges, nodes) };
            total += scan.total.0;
        }
        self.items.clear();
        super::segments::reserve(&mut self.items, total);
        // Safety: MaybeUninit needs no initialisation.
        unsafe { self.items.set_len(total) };
        self.priced = 0;
    }

    /// Shared access for filling the ranges in parallel, one task per (node, axis) pair.
    pub fn filler(&mut self) -> Filler<'_> {
        let [r0, r1, r2] = &mut self.ranges;
        Filler {
            items: Scatter::new(&mut self.items),
            ranges: [Scatter::new(r0), Scatter::new(r1), Scatter::new(r2)],
        }
    }

    /// Node k's candidates on `axis`.
    #[inline]
    pub fn of(&self, axis: usize, k: usize) -> &[Candidate] {
        let [s, e] = self.ranges[axis][k];
        // Safety: every filler initialises its ranges before setting their ends.
        unsafe { std::mem::transmute::<&[MaybeUninit<Candidate>], &[Candidate]>(&self.items[s..e]) }
    }

    /// All slots, when every one of them was written (the fillers that write holes).
    ///
    /// # Safety
    /// Every slot was initialised.
    pub unsafe fn all_mut(&mut self) -> &mut [Candidate] {
        std::mem::transmute::<&mut [MaybeUninit<Candidate>], &mut [Candidate]>(&mut self.items)
    }

    pub fn bytes(&self) -> usize {
        self.items.capacity() * std::mem::size_of::<Candidate>()
            + self.ranges.iter().map(|r| r.capacity() * 16).sum::<usize>()
    }
}

#[derive(Clone, Copy, Default)]
struct Slots(usize);

impl Tally for Slots {
    fn add(self, o: Self) -> Self {
        Slots(self.0 + o.0)
    }
    fn restart(self) -> Self {
        self
    }
}

/// Writes into the candidate array from parallel tasks, each owning some (node, axis) pairs.
pub(super) struct Filler<'a> {
    items: Scatter<'a, MaybeUninit<Candidate>>,
    ranges: [Scatter<'a, [usize; 2]>; 3],
}

impl Filler<'_> {
    /// The first slot of the pair's range.
    ///
    /// # Safety
    /// The caller owns the pair.
    #[inline]
    pub unsafe fn first(&self, axis: usize, k: usize) -> usize {
        self.ranges[axis].read(k)[0]
    }
    /// # Safety
    /// `i` is in a range the caller owns, written once.
    #[inline(always)]
    pub unsafe fn write(&self, i: usize, c: Candidate) {
        self.items.write(i, MaybeUninit::new(c))
    }
    /// Ends the pair's range after its first `count` slots, which the caller wrote.
    ///
    /// # Safety
    /// The caller owns the pair.
    #[inline]
    pub unsafe fn finish(&self, axis: usize, k: usize, count: usize) {
        let [s, _] = self.ranges[axis].read(k);
        self.ranges[axis].write(k, [s, s + count])
    }
}

/// The axis whose block holds slot `i`, given each axis's first slot.
#[inline]
pub(super) fn axis_in(firsts: &[usize; 3], i: usize) -> usize {
    (i >= firsts[1]) as usize + (i >= firsts[2]) as usize
}

/// Counts of one plane: L = #(lo < p), R = #(hi > p), P = #(lo == p == hi).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(super) struct Counts {
    pub left: u32,
    pub right: u32,
    pub planar: u32,
}

/// Prices a plane with the shared rule: planar primitives go to the cheaper side (left on a
/// tie). Non-finite costs (a degenerate node) become infinite, so they are never chosen.
/// A plane at -0 is written +0: the two are one plane, and which of them a builder meets
/// first depends on its order of work, so the tree must not.
#[inline]
pub(super) fn price(
    cost: &CostModel,
    node: &Aabb,
    axis: usize,
    pos: f32,
    owner: u32,
    c: Counts,
) -> Candidate {
    price_with(&cost.splits_of(node, axis), pos, owner, c)
}

/// [`price`] with the node's costs along the axis prepared (the same costs, bit for bit).
#[inline]
pub(super) fn price_with(splits: &SplitPricer, pos: f32, owner: u32, c: Counts) -> Candidate {
    let pos = pos + 0.0;
    let finite = |x: f32| if x.is_nan() { f32::INFINITY } else { x };
    let left = finite(splits.cost(pos, c.left + c.planar, c.right));
    let (value, planar_left) = if c.planar == 0 {
        (left, true)
    } else {
        let right = finite(splits.cost(pos, c.left, c.right + c.planar));
        if left <= right {
            (left, true)
        } else {
            (right, false)
        }
    };
    let (n_left, n_right) = if planar_left {
        (c.left + c.planar, c.right)
    } else {
        (c.left, c.right + c.planar)
    };
    Candidate {
        pos,
        cost: value,
        owner,
        left: n_left << 1 | planar_left as u32,
        n_right,
    }
}

/// Fills, for every node and axis it uses, two slots per element of the node's segment
/// (`starts`): the element's lo and hi (`extent(i)`) when strictly inside the node's box, a
/// hole otherwise. The layout is `2 * segment length` slots per priced pair, so every slot is
/// written. Parallel over nodes.
pub(super) fn fill_extents(
    cands: &mut Candidates,
    starts: [&[u32]; 3],
    uses: &[u8],
    boxes: &[Aabb],
    extent: impl Fn(usize, usize) -> (f32, f32) + Sync,
) {
    let nodes = boxes.len();
    let len = |axis: usize, k: usize| (starts[axis][k + 1] - starts[axis][k]) as usize;
    cands.lay_out(nodes, |axis, k| {
        if uses[k] & (1 << axis) != 0 {
            2 * len(axis, k)
        } else {
            0
        }
    });
    let fill = cands.filler();
    (0..nodes).into_par_iter().with_min_len(64).for_each(|k| {
        let b = &boxes[k];
        for (axis, starts) in starts.iter().enumerate() {
            if uses[k] & (1 << axis) == 0 {
                continue;
            }
            let s = starts[k] as usize;
            let n = len(axis, k);
            // Safety: this task owns node k's pairs; each slot is written once.
            unsafe {
                let first = fill.first(axis, k);
                for i in 0..n {
                    let (lo, hi) = extent(axis, s + i);
                    for (j, p) in [lo, hi].into_iter().enumerate() {
                        let c = if b.lo[axis] < p && p < b.hi[axis] {
                            Candidate::new(p, k as u32)
                        } else {
                            Candidate::hole()
                        };
                        fill.write(first + 2 * i + j, c);
                    }
                }
                fill.finish(axis, k, 2 * n);
            }
        }
    });
}
