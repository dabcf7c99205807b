//! The level-parallel SAH kd-tree builder of Li, Tan and Liao, and its naive baseline.
//!
//! The tree is built breadth first, one whole level at a time, on flat arrays: a level is
//! - its nodes (boxes and, per node, a segment of each array below),
//! - its references in canonical order (`prims`, and `flat`, or `ref_boxes` for the naive
//!   builder; a reference's index there is its *slot*),
//! - per axis, one sorted list of the references' entries (spans or events, see [`entries`]),
//!   each node's entries a contiguous, sorted segment.
//!
//! Each level runs the same phases over those arrays. No phase is one serial task per node:
//! a pass runs over chunks of a flat array, or over all (candidate, node) items of the level,
//! and a node too big for one task (the top levels) is itself split into chunks, with
//! exclusive scans over the chunks giving each its offsets:
//! 1. candidates: the lo and hi of every reference on the node's axes, strictly inside the
//!    node (one slot pair per list entry, holes where a value is not inside);
//! 2. space trees (space-tree counting only): the implicit interval tree of every node's list;
//! 3. counting: L, R, P and the SAH cost of every candidate, in one parallel pass over the
//!    candidate array (space tree, naive) or by one sweep per node and axis (scan, which keeps
//!    only each pair's best candidate, see [`scan`]);
//! 4. decision: each node's cheapest candidate (a segmented min: ties to the smaller position,
//!    then the lower axis), the leaf rules, and the reference budget, checked per level;
//! 5. partition: leaves write their references out; the other nodes' references, and each
//!    axis's sorted list, are stably partitioned into the children's segments of the next
//!    level's arrays (offsets by exclusive scans), so no level ever sorts again.
//!
//! Output nodes are written breadth first: a level's nodes are contiguous, and the children of
//! its split nodes follow it, side by side, in the order of their parents.
//!
//! Counts follow the shared semantics of `builders/mod.rs`: L = #(lo < p), R = #(hi > p),
//! P = #(lo == p == hi). With clipping off a reference's box is its triangle's box, not
//! clamped to the node: for a plane strictly inside the node the counts, the candidates and
//! the partition come out exactly as with the clamped box, and the lists never need re-sorting.

mod candidates;
mod decision;
mod entries;
mod handoff;
mod naive;
mod partition;
mod presort;
mod scan;
mod segments;
mod space_tree;

pub(crate) use handoff::Frontier;

use super::choice::{searched, Split};
use super::driver::BudgetUse;
use super::{Algorithm, Axes, BuildOptions, BuiltTree, Counting, LevelReport, Primitives};
use crate::cost::CostModel;
use crate::geometry::{Aabb, Triangle};
use candidates::Candidates;
use entries::{Event, ListEntry, Span};
use rayon::prelude::*;
use std::time::Instant;

/// How a level counts L, R and P.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum Mode {
    /// The paper: walk of the implicit interval tree over the lo-sorted list.
    SpaceTree,
    /// Running counts over the position-sorted start/end/planar events.
    Scan,
    /// Every candidate tests every reference of its node; no sorted lists (the `naive`
    /// algorithm's counting).
    BruteForce,
}

/// What stays fixed over a build.
struct Context<'a> {
    triangles: &'a [Triangle],
    cost: CostModel,
    axes: Axes,
    clip: bool,
    max_depth: u32,
    budget: usize,
}

/// One level of the tree under construction.
struct Level<E> {
    depth: u32,
    /// Node boxes.
    boxes: Vec<Aabb>,
    /// Segments of the canonical arrays, one per node (len = nodes + 1).
    ref_starts: Vec<u32>,
    /// Segments of each axis's list, one per node (len = nodes + 1; empty without lists).
    list_starts: [Vec<u32>; 3],
    /// Canonical arrays: the primitive of each reference (slot), and
    prims: Vec<u32>,
    /// with sorted lists, the axes on which its box is flat (bit a: `lo == hi` on axis a; the
    /// rest of the box is in the lists),
    flat: Vec<u8>,
    /// without, its box.
    ref_boxes: Vec<Aabb>,
    /// Per axis, the sorted entries; a node's segment is sorted by entry key.
    lists: [Vec<E>; 3],
    /// Whether this build keeps sorted lists (all but the naive one).
    sorted: bool,
}

impl<E: ListEntry> Level<E> {
    fn empty(sorted: bool) -> Self {
        Level {
            depth: 0,
            boxes: Vec::new(),
            ref_starts: Vec::new(),
            list_starts: Default::default(),
            prims: Vec::new(),
            flat: Vec::new(),
            ref_boxes: Vec::new(),
            lists: Default::default(),
            sorted,
        }
    }
    fn nodes(&self) -> usize {
        self.boxes.len()
    }
    fn refs(&self, k: usize) -> u32 {
        self.ref_starts[k + 1] - self.ref_starts[k]
    }
    /// Bytes held by the level's arrays.
    fn bytes(&self) -> usize {
        use std::mem::size_of;
        self.boxes.capacity() * size_of::<Aabb>()
            + self.ref_starts.capacity() * 4
            + self
                .list_starts
                .iter()
                .map(|s| s.capacity() * 4)
                .sum::<usize>()
            + self.prims.capacity() * 4
            + self.flat.capacity()
            + self.ref_boxes.capacity() * size_of::<Aabb>()
            + self
                .lists
                .iter()
                .map(|l| l.capacity() * size_of::<E>())
                .sum::<usize>()
    }
}

/// Builds with the level framework: `Algorithm::Level` with either counting, or
/// `Algorithm::Naive`.
pub(crate) fn build(prims: &Primitives, options: &BuildOptions) -> BuiltTree {
    fn whole<E>(_: &Level<E>) -> bool {
        false
    }
    match (options.algorithm, options.counting) {
        (Algorithm::Naive, _) => run::<Span>(prims, options, Mode::BruteForce, whole).0,
        (_, Counting::SpaceTree) => run::<Span>(prims, options, Mode::SpaceTree, whole).0,
        (_, Counting::Scan) => run::<Event>(prims, options, Mode::Scan, whole).0,
    }
}

/// The top of a hybrid build: level passes (scan counting) until `hand_off` says a level's nodes are enough independent work, then that level as a
/// [`Frontier`] (`None` when the tree was finished first). `hand_off` sees the level's node
/// count, its references and its biggest node's references.
pub(crate) fn build_top(
    prims: &Primitives,
    options: &BuildOptions,
    hand_off: impl Fn(usize, usize, usize) -> bool,
) -> (BuiltTree, Option<Frontier>, BudgetUse) {
    let stop = |level: &Level<Event>| {
        let biggest = (0..level.nodes())
            .map(|k| level.refs(k) as usize)
            .max()
            .unwrap_or(0);
        hand_off(level.nodes(), level.prims.len(), biggest)
    };
    let (built, level, budget) = run::<Event>(prims, options, Mode::Scan, stop);
    let frontier = level.map(|level| Frontier::new(level, built.nodes.len()));
    (built, frontier, budget)
}

fn ms_since(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

/// The level loop. Stops before pricing the first level `stop` accepts and returns it with
/// the tree so far, whose next node slots are that level's nodes.
fn run<E: ListEntry>(
    prims: &Primitives,
    options: &BuildOptions,
    mode: Mode,
    stop: impl Fn(&Level<E>) -> bool,
) -> (BuiltTree, Option<Level<E>>, BudgetUse)
where
    Level<E>: Pricing,
{
    let n = prims.triangles.len();
    let ctx = Context {
        triangles: prims.triangles,
        cost: options.cost,
        axes: options.axes,
        clip: options.clip,
        max_depth: options.cost.max_depth_for(n),
        budget: options.cost.reference_budget(n).min(entries::MAX_SLOTS),
    };
    let mut out = BuiltTree::default();
    let sorted = mode != Mode::BruteForce;
    let start = Instant::now();
    let mut level = presort::root_level::<E>(prims, sorted);
    if sorted {
        out.report.presort_ms = ms_since(start);
    }
    let mut spare = Level::<E>::empty(sorted);
    let mut scratch = Scratch::default();
    let mut peak = 0usize;
    let mut budget_use = BudgetUse::default();
    loop {
        if stop(&level) {
            out.report.peak_working_bytes = peak.max(level.bytes() + scratch.bytes());
            return (out, Some(level), budget_use);
        }
        let mut report = LevelReport {
            depth: level.depth,
            nodes: level.nodes(),
            references: level.prims.len(),
            ..LevelReport::default()
        };
        axes_in_use(&level, &ctx, &mut scratch.uses);
        level.price(mode, &ctx, &mut scratch, &mut report);
        report.candidates = scratch.candidates.priced;

        let t = Instant::now();
        let mut splits = std::mem::take(&mut scratch.splits);
        decision::decide(
            &level,
            &scratch.uses,
            &scratch.candidates,
            &ctx,
            &mut splits,
        );
        // The reference budget, breadth first: the references already in leaves, this level's
        // leaves and the next level's (before clipping, which only removes) must fit, or the
        // whole level becomes leaves.
        let (leaves, leaf_refs, next_refs) = (0..level.nodes())
            .into_par_iter()
            .with_min_len(4096)
            .map(|k| match &splits[k] {
                None => (1, level.refs(k) as usize, 0),
                Some(s) => (0, 0, s.refs() as usize),
            })
            .reduce(|| (0, 0, 0), |a, b| (a.0 + b.0, a.1 + b.1, a.2 + b.2));
        report.leaves = leaves;
        if out.refs.len() + leaf_refs + next_refs > ctx.budget {
            budget_use.bound = true;
            splits.par_iter_mut().for_each(|s| *s = None);
            report.leaves = level.nodes();
        }
        report.ms.decision = ms_since(t);

        let t = Instant::now();
        let more = partition::partition(
            &level,
            &splits,
            &ctx,
            &mut out,
            &mut spare,
            &mut scratch.work,
        );
        if more && level.sorted {
            budget_use.clipped_away += clipped_away(&splits, &scratch.work, &spare);
        }
        scratch.splits = splits;
        report.ms.partition = ms_since(t);
        peak = peak.max(level.bytes() + spare.bytes() + scratch.bytes());
        out.report.levels.push(report);
        if !more {
            break;
        }
        std::mem::swap(&mut level, &mut spare);
    }
    out.report.peak_working_bytes = peak;
    (out, None, budget_use)
}

/// References clipping removed from the children of the level's split nodes (`next` is the
/// level they make).
fn clipped_away<E: ListEntry>(
    splits: &[Option<Split>],
    work: &partition::Work,
    next: &Level<E>,
) -> usize {
    (0..splits.len())
        .into_par_iter()
        .with_min_len(4096)
        .map(|k| match splits[k] {
            Some(s) => {
                let c = work.left_child(k);
                (s.refs() - next.refs(c) - next.refs(c + 1)) as usize
            }
            None => 0,
        })
        .sum()
}

/// Per node, a bit mask of the axes whose candidates it prices (0 for a node that is a leaf
/// by size or depth).
fn axes_in_use<E: ListEntry>(level: &Level<E>, ctx: &Context, uses: &mut Vec<u8>) {
    (0..level.nodes())
        .into_par_iter()
        .with_min_len(1024)
        .map(|k| {
            if !searched(level.refs(k), level.depth, ctx.max_depth, &ctx.cost) {
                return 0;
            }
            match ctx.axes {
                Axes::Longest => 1 << level.boxes[k].longest_axis(),
                Axes::All => 7,
            }
        })
        .collect_into_vec(uses);
}

/// Working arrays reused from level to level, so that a build touches fresh memory only when
/// a level outgrows the previous ones.
#[derive(Default)]
struct Scratch {
    candidates: Candidates,
    /// Space-tree counting: the level's space trees, aligned with the lists.
    trees: Vec<space_tree::TreeNode>,
    /// Naive counting: the level's boxes per axis, structure of arrays.
    naive: naive::Extents,
    /// Per node: the axes priced, and the decision.
    uses: Vec<u8>,
    splits: Vec<Option<Split>>,
    /// The partition's arrays.
    work: partition::Work,
}

impl Scratch {
    fn bytes(&self) -> usize {
        use std::mem::size_of;
        self.candidates.bytes()
            + self.trees.capacity() * size_of::<space_tree::TreeNode>()
            + self.naive.bytes()
            + self.uses.capacity()
            + self.splits.capacity() * size_of::<Option<Split>>()
            + self.work.bytes()
    }
}

/// Phases 1-3 for one kind of list: the level's candidates with their costs, into
/// `scratch.candidates`, for the axes `scratch.uses` names.
trait Pricing {
    fn price(&self, mode: Mode, ctx: &Context, scratch: &mut Scratch, report: &mut LevelReport);
}

impl Pricing for Level<Span> {
    fn price(&self, mode: Mode, ctx: &Context, scratch: &mut Scratch, report: &mut LevelReport) {
        let Scratch {
            candidates: cands,
            uses,
            naive,
            trees,
            ..
        } = scratch;
        if mode == Mode::BruteForce {
            let t = Instant::now();
            naive::candidates(self, uses, cands, naive);
            report.ms.candidates = ms_since(t);
            let t = Instant::now();
            cands.priced = naive::count(self, cands, naive, &ctx.cost);
            report.ms.counting = ms_since(t);
            return;
        }
        let t = Instant::now();
        space_tree::candidates(self, uses, cands);
        report.ms.candidates = ms_since(t);
        let t = Instant::now();
        let all = ctx.axes == Axes::All;
        space_tree::build_trees(self, uses, all, trees);
        report.ms.space_trees = ms_since(t);
        let t = Instant::now();
        let (priced, steps, cut) = space_tree::count(self, cands, trees, all, &ctx.cost);
        cands.priced = priced;
        report.walk_steps = steps;
        report.cut_primitives = cut;
        report.ms.counting = ms_since(t);
    }
}

impl Pricing for Level<Event> {
    fn price(&self, _mode: Mode, ctx: &Context, scratch: &mut Scratch, report: &mut LevelReport) {
        let cands = &mut scratch.candidates;
        scan::price(self, &scratch.uses, &ctx.cost, cands, report)
    }
}

/// A small deterministic generator for the level's unit tests.
#[cfg(test)]
struct Lcg(u64);

#[cfg(test)]
impl Lcg {
    /// The next value in `0..m`.
    fn next(&mut self, m: u32) -> u32 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((self.0 >> 33) % m as u64) as u32
    }
}
