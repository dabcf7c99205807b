//! The Wald & Havran (2006) builder: exact SAH in O(N log N), serial on purpose.
//!
//! Split events (start, end, planar) of every primitive on every axis are made once at the
//! root and sorted once. A node is priced by one sweep per axis over its sorted events
//! ([`search`]); its children's events come from its own by a stable split, with straddlers
//! re-clipped and merged in ([`partition`]). That is the search ([`ExactSweep`]) the serial
//! driver (`driver::serial`) runs: depth first from an explicit stack, left child before
//! right, both children's slots allocated together, the reference budget a running total.
//!
//! With `BuildOptions::bins`, nodes above a size threshold are priced at bin boundaries
//! instead ([`binned`], another search for the driver), which hands them to the sweep below
//! it.
//!
//! [`handed_subtree`] builds below any node another phase hands over, not only the root:
//! from the node's boxes (the median builder's small nodes, the binned top's) or from events
//! already sorted elsewhere (the hybrid builder hands over the level builder's lists, which
//! use the same encoding).

mod binned;
mod events;
mod partition;
mod search;

pub(crate) use events::Event;

use super::choice::Split;
use super::driver::{self, Budget, BudgetUse, Rules, SplitSearch};
use super::stitch::Piece;
use super::{BuildOptions, BuiltTree, Primitives};
use crate::geometry::{Aabb, Triangle};
use crate::tree::Node;
use partition::{Segment, Workspace};
use std::time::Instant;

pub(crate) fn build(prims: &Primitives, options: &BuildOptions) -> BuiltTree {
    if options.resolved_bins() != 0 {
        return binned::build(prims, options, false);
    }
    let total_prims = prims.triangles.len();
    let subtree = Subtree {
        triangles: options.clip.then_some(prims.triangles),
        n: total_prims as u32,
        bounds: prims.bounds,
        depth: 0,
        max_depth: options.cost.max_depth_for(total_prims),
        budget: Budget {
            limit: options.cost.reference_budget(total_prims),
            shared: None,
        },
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

/// A node another phase hands to the sweep for its whole subtree: the level passes'
/// frontier (`hybrid`), the median builder's small nodes, the binned top's nodes below its
/// threshold.
pub(crate) struct Handed<'a> {
    /// The node's primitives (the whole tree's indices); the sweep's primitive `i` is
    /// `prims[i]`.
    pub prims: &'a [u32],
    pub bounds: Aabb,
    /// The node's depth in the whole tree.
    pub depth: u32,
    pub start: Start<'a>,
}

/// A handed node's references as the sweep starts from them.
pub(crate) enum Start<'a> {
    /// Their boxes (within the node), in the order of `prims`: the events are made and
    /// sorted here.
    Boxes(&'a [Aabb]),
    /// Each axis's events, primitives numbered as in `prims`, sorted by the event order: no
    /// sort (the level passes' lists, which use the same encoding).
    Sorted([Vec<Event>; 3]),
}

/// The sweep's subtree of `node`, a node of the tree of `triangles` (all of them), its leaves
/// referencing the whole tree's primitives, within `budget` (see `driver::Budget`).
pub(crate) fn handed_subtree(
    node: Handed,
    triangles: &[Triangle],
    budget: Budget,
    options: &BuildOptions,
) -> (Piece, SubtreeReport) {
    // The node's own triangles, gathered only where clipping needs them.
    let local: Option<Vec<Triangle>> = options
        .clip
        .then(|| node.prims.iter().map(|&p| triangles[p as usize]).collect());
    let subtree = Subtree {
        triangles: local.as_deref(),
        n: node.prims.len() as u32,
        bounds: node.bounds,
        depth: node.depth,
        max_depth: options.cost.max_depth_for(triangles.len()),
        budget,
    };
    let (mut nodes, mut refs) = (Vec::new(), Vec::new());
    let report = match node.start {
        Start::Boxes(boxes) => build_subtree(&subtree, boxes, options, &mut nodes, &mut refs),
        Start::Sorted(events) => {
            let work = Workspace::from_sorted(events, node.prims.len());
            grow(&subtree, work, options, &mut nodes, &mut refs)
        }
    };
    for r in refs.iter_mut() {
        *r = node.prims[*r as usize];
    }
    (Piece { nodes, refs }, report)
}

/// A node to build the whole subtree of, with the limits that come from the whole tree.
struct Subtree<'a> {
    /// The node's primitives' triangles, to clip with (`None` without clipping). Primitive
    /// `i` here is `triangles[i]`; the leaves reference these local indices.
    triangles: Option<&'a [Triangle]>,
    /// How many primitives the node holds.
    n: u32,
    /// The node's box.
    bounds: Aabb,
    /// The node's depth in the whole tree.
    depth: u32,
    /// The whole tree's depth limit.
    max_depth: u32,
    /// The most references the subtree's leaves may hold together (a running total, checked
    /// depth first: Wald and Havran's rule) and, with subtrees built at once, the shared
    /// total every split adds to, a guard on memory (see `driver::Budget` and `hybrid`).
    budget: Budget<'a>,
}

/// What building a subtree took.
pub(crate) struct SubtreeReport {
    pub presort_ms: f64,
    pub peak_working_bytes: usize,
    /// Whether the budget refused a split, and the references clipping removed.
    pub budget: BudgetUse,
}

/// Builds the subtree of `subtree`'s node from its primitives' `boxes` (within the node's
/// box), appending its nodes to `nodes` (its root first, at the index `nodes.len()` had on
/// entry) and its leaves' references to `refs`.
fn build_subtree(
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

/// The node's subtree by the driver, with the exact sweep as its search (its report's
/// `presort_ms` is 0).
fn grow(
    subtree: &Subtree,
    work: Workspace,
    options: &BuildOptions,
    nodes: &mut Vec<Node>,
    refs: &mut Vec<u32>,
) -> SubtreeReport {
    let mut sweep = ExactSweep {
        work,
        options,
        clip: subtree.triangles,
    };
    let root = SweepNode {
        bounds: subtree.bounds,
        depth: subtree.depth,
        n: subtree.n,
        events: [0; 3],
    };
    let rules = Rules {
        cost: &options.cost,
        max_depth: subtree.max_depth,
    };
    let budget = driver::serial(&mut sweep, root, rules, subtree.budget, nodes, refs);
    SubtreeReport {
        presort_ms: 0.0,
        peak_working_bytes: sweep.work.peak_bytes(),
        budget,
    }
}

/// The exact sweep as the driver's search: every pending node's events live in one
/// workspace, as stacks, the node being built on top (the serial driver builds the left child
/// first, which the workspace's split leaves on top).
struct ExactSweep<'a> {
    work: Workspace,
    options: &'a BuildOptions,
    /// The triangles, to re-clip straddlers (`None` without clipping).
    clip: Option<&'a [Triangle]>,
}

/// A node of the sweep: its box, depth, primitive count and the start of its events.
struct SweepNode {
    bounds: Aabb,
    depth: u32,
    n: u32,
    events: Segment,
}

impl SplitSearch for ExactSweep<'_> {
    type Node = SweepNode;

    #[inline]
    fn size(node: &SweepNode) -> u32 {
        node.n
    }

    #[inline]
    fn depth(node: &SweepNode) -> u32 {
        node.depth
    }

    #[inline]
    fn search(&mut self, node: &SweepNode) -> Option<Split> {
        search::best_split(
            self.work.events(&node.events),
            &node.bounds,
            node.n,
            self.options.axes,
            &self.options.cost,
        )
    }

    #[inline]
    fn partition(&mut self, node: SweepNode, split: &Split) -> [SweepNode; 2] {
        let children = self
            .work
            .split(&node.events, &node.bounds, split, self.clip);
        let (left_box, right_box) = node.bounds.split(split.axis, split.pos);
        let depth = node.depth + 1;
        [
            SweepNode {
                bounds: left_box,
                depth,
                n: children.n_left,
                events: children.left,
            },
            SweepNode {
                bounds: right_box,
                depth,
                n: children.n_right,
                events: children.right,
            },
        ]
    }

    #[inline]
    fn leaf(&mut self, node: SweepNode, refs: &mut Vec<u32>) {
        let first = refs.len();
        self.work.collect_prims(&node.events, refs);
        debug_assert_eq!(refs.len() - first, node.n as usize);
        self.work.pop(&node.events);
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
