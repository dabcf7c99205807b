//! The Wald & Havran (2006) builder: exact SAH in O(N log N), serial on purpose.
//!
//! Split events (start, end, planar) of every primitive on every axis are made once at the
//! root and sorted once. A node is priced by one sweep per axis over its sorted events
//! ([`search`]); its children's events come from its own by a stable split, with straddlers
//! re-clipped and merged in ([`partition`]). Nodes are built depth first from an explicit
//! stack, left child before right, both children's slots allocated together.
//!
//! With `BuildOptions::bins`, nodes above a size threshold are priced at bin boundaries
//! instead ([`binned`]), and the sweep runs below it.
//!
//! [`build_subtree`] builds below any node, not only the root: the median builder hands it
//! its small nodes. [`build_subtree_sorted`] starts from events already sorted elsewhere (the
//! hybrid builder hands over the level builder's lists, which use the same encoding).

mod binned;
mod events;
mod partition;
mod search;

pub(crate) use events::Event;

use super::choice::split_or_leaf;
use super::{BuildOptions, BuiltTree, Primitives};
use crate::geometry::{Aabb, Triangle};
use crate::tree::Node;
use partition::{Segment, Workspace};
use std::sync::atomic::{AtomicUsize, Ordering};
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
    if options.resolved_bins() != 0 {
        return binned::build(prims, options, false);
    }
    let total_prims = prims.triangles.len();
    let subtree = Subtree {
        triangles: prims.triangles,
        bounds: prims.bounds,
        depth: 0,
        max_depth: options.cost.max_depth_for(total_prims),
        budget: options.cost.reference_budget(total_prims),
        shared_total: None,
    };
    let mut built = BuiltTree::default();
    let report = build_subtree(
        &subtree,
        &prims.boxes,
        options,
        &mut built.nodes,
        &mut built.refs,
    );
    built.report.presort_ms = report.presort_ms;
    built.report.peak_working_bytes = report.peak_working_bytes;
    built
}

/// The tree of [`build`] with binning (`options.resolved_bins()` not 0), the children of every binned node
/// built at once: the same tree on any number of threads.
pub(crate) fn build_binned_parallel(prims: &Primitives, options: &BuildOptions) -> BuiltTree {
    binned::build(prims, options, true)
}

/// A node to build the whole subtree of, with the limits that come from the whole tree.
pub(crate) struct Subtree<'a> {
    /// The node's primitives' triangles (for clipping). Primitive `i` here is `triangles[i]`;
    /// the leaves reference these local indices.
    pub triangles: &'a [Triangle],
    /// The node's box.
    pub bounds: Aabb,
    /// The node's depth in the whole tree.
    pub depth: u32,
    /// The whole tree's depth limit.
    pub max_depth: u32,
    /// The most references the subtree's leaves may hold together: a running total, checked
    /// depth first (Wald and Havran's rule).
    pub budget: usize,
    /// With subtrees built at once: the references of the whole tree so far, which every
    /// split adds to (through the subtree's `Claims`) and which must stay within `budget` too
    /// (a guard on memory: the order of the additions varies, so a build that hits it is not
    /// deterministic, see `hybrid`).
    pub shared_total: Option<&'a AtomicUsize>,
}

/// What building a subtree took.
pub(crate) struct SubtreeReport {
    pub presort_ms: f64,
    pub peak_working_bytes: usize,
    /// Whether the budget refused a split the SAH wanted.
    pub budget_bound: bool,
    /// References clipping removed, summed over the splits (before minus after).
    pub clipped_away: usize,
}

/// Builds the subtree of `subtree`'s node from its primitives' `boxes` (within the node's
/// box), appending its nodes to `nodes` (its root first, at the index `nodes.len()` had on
/// entry) and its leaves' references to `refs`.
pub(crate) fn build_subtree(
    subtree: &Subtree,
    boxes: &[Aabb],
    options: &BuildOptions,
    nodes: &mut Vec<Node>,
    refs: &mut Vec<u32>,
) -> SubtreeReport {
    let presort = Instant::now();
    let work = Workspace::new(boxes);
    let presort_ms = presort.elapsed().as_secs_f64() * 1e3;
    SubtreeReport {
        presort_ms,
        ..grow(subtree, work, options, nodes, refs)
    }
}

/// As [`build_subtree`], from each axis's events of the node's primitives (local indices,
/// sorted by the event order), without sorting again.
pub(crate) fn build_subtree_sorted(
    subtree: &Subtree,
    events: [Vec<Event>; 3],
    options: &BuildOptions,
    nodes: &mut Vec<Node>,
    refs: &mut Vec<u32>,
) -> SubtreeReport {
    let work = Workspace::from_sorted(events, subtree.triangles.len());
    grow(subtree, work, options, nodes, refs)
}

/// The depth-first loop over the node's subtree (its report's `presort_ms` is 0).
fn grow(
    subtree: &Subtree,
    mut work: Workspace,
    options: &BuildOptions,
    nodes: &mut Vec<Node>,
    refs: &mut Vec<u32>,
) -> SubtreeReport {
    let cost = &options.cost;
    let (max_depth, budget) = (subtree.max_depth, subtree.budget);
    let clip = options.clip.then_some(subtree.triangles);
    let n = subtree.triangles.len();

    let root = nodes.len() as u32;
    nodes.push(Node::leaf(0, 0));
    // References held by the finished leaves and the pending nodes: the running total the
    // reference budget applies to.
    let mut references = n;
    let (mut budget_bound, mut clipped_away) = (false, 0);
    let mut claims = Claims::new(subtree.shared_total, budget);
    let mut stack = vec![Pending {
        slot: root,
        bounds: subtree.bounds,
        depth: subtree.depth,
        n: n as u32,
        events: [0; 3],
    }];
    while let Some(node) = stack.pop() {
        let split = split_or_leaf(node.n, node.depth, max_depth, cost, || {
            search::best_split(
                work.events(&node.events),
                &node.bounds,
                node.n,
                options.axes,
                cost,
            )
        })
        .filter(|s| {
            let extra = (s.refs() - node.n) as usize;
            let fits = references + extra <= budget && claims.take(extra, budget);
            budget_bound |= !fits;
            fits
        });
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
        clipped_away +=
            (split.n_left + split.n_right - children.n_left - children.n_right) as usize;
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
    claims.give_back_unused();
    SubtreeReport {
        presort_ms: 0.0,
        peak_working_bytes: work.peak_bytes(),
        budget_bound,
        clipped_away,
    }
}

/// A subtree's share of the shared reference total (`Subtree::shared_total`), claimed in
/// chunks: one atomic add per split, with two workers bouncing its cache line, cost about
/// 6 % of the sweep's loop at 2 threads. Claims count more than the splits add, by less than
/// a chunk per subtree at work, so the guard can refuse early, never late; a refusal sends
/// every builder that shares a total back to the depth-first build, so the tree is the same.
struct Claims<'a> {
    total: Option<&'a AtomicUsize>,
    /// Claimed and not yet spent.
    unspent: usize,
    chunk: usize,
}

impl<'a> Claims<'a> {
    fn new(total: Option<&'a AtomicUsize>, budget: usize) -> Claims<'a> {
        Claims {
            total,
            unspent: 0,
            chunk: (budget / 1024).clamp(1, 4096),
        }
    }

    /// Whether `extra` more references fit the shared total (always, without one).
    fn take(&mut self, extra: usize, budget: usize) -> bool {
        let Some(total) = self.total else {
            return true;
        };
        if extra > self.unspent {
            let claim = (extra - self.unspent).max(self.chunk);
            if total.fetch_add(claim, Ordering::Relaxed) + claim > budget {
                return false;
            }
            self.unspent += claim;
        }
        self.unspent -= extra;
        true
    }

    /// Returns what was claimed and not spent, so that subtrees built later may use it.
    fn give_back_unused(self) {
        if let Some(total) = self.total {
            total.fetch_sub(self.unspent, Ordering::Relaxed);
        }
    }
}

/// Random boxes for the searches' tests, checked against counting every box.
#[cfg(test)]
mod testing {
    use crate::geometry::{Aabb, Vec3};

    /// A seeded linear congruential generator.
    pub(super) struct Lcg(pub u64);

    impl Lcg {
        /// A number in `0..k`.
        pub(super) fn below(&mut self, k: u64) -> u64 {
            self.0 = self
                .0
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (self.0 >> 33) % k
        }
    }

    /// The boxes counted by brute force at the plane `p` on axis `a`: those starting below
    /// it, those ending above it, and the flat ones lying in it.
    pub(super) fn counts_at(boxes: &[Aabb], a: usize, p: f32) -> (u32, u32, u32) {
        let count = |f: &dyn Fn(&Aabb) -> bool| boxes.iter().filter(|b| f(b)).count() as u32;
        (
            count(&|b| b.lo[a] < p),
            count(&|b| b.hi[a] > p),
            count(&|b| b.lo[a] == p && b.hi[a] == p),
        )
    }

    /// 300 rounds (numbered) of [`grid_boxes`], each of 1 to `most` boxes, drawn from the
    /// generator seeded with `seed`.
    pub(super) fn grid_rounds(
        seed: u64,
        most: u64,
        grid: (u64, u64, f32, f32),
    ) -> impl Iterator<Item = (usize, Vec<Aabb>)> {
        let mut rng = Lcg(seed);
        let (cells, widths, step, cap) = grid;
        (0..300).map(move |round| {
            let n = 1 + rng.below(most) as usize;
            (round, grid_boxes(&mut rng, n, cells, widths, step, cap))
        })
    }

    /// `n` boxes with corners on a grid of `step` (so that ends coincide and flat boxes lie
    /// in each other's planes): each axis starts at one of `cells` grid points and is flat one
    /// time in three, else up to `widths - 1` steps wide, its end kept at most `cap`.
    pub(super) fn grid_boxes(
        rng: &mut Lcg,
        n: usize,
        cells: u64,
        widths: u64,
        step: f32,
        cap: f32,
    ) -> Vec<Aabb> {
        (0..n)
            .map(|_| {
                let (mut lo, mut hi) = (Vec3::splat(0.0), Vec3::splat(0.0));
                for a in 0..3 {
                    let x = rng.below(cells) as f32 * step;
                    let w = if rng.below(3) == 0 {
                        0.0
                    } else {
                        rng.below(widths) as f32 * step
                    };
                    lo[a] = x;
                    hi[a] = (x + w).min(cap);
                }
                Aabb::new(lo, hi)
            })
            .collect()
    }
}
