//! Min-max binning for big nodes (`BuildOptions::bins`), as Shevtsov, Soupikov & Kapustin
//! (2007) and Mitsuba's kd-tree do: a node holding more than `BINNED_REFS_PER_BIN * bins`
//! references is priced at the `bins - 1` boundaries of equal bins of its box only, with the
//! counts from two histograms (of its references' lo and hi ends); smaller nodes get the
//! exact sweep, unchanged.
//!
//! Counts and pricing follow the exact sweep's rules to the letter (`L = #(lo < p)`,
//! `R = #(hi > p)`, the primitives lying in the plane to the cheaper side, the one cost model
//! and ranking), so a binned split is the exact search restricted to the boundaries. Big
//! nodes keep their references as (triangle, box) arrays split by one pass each, with no
//! event lists and no sort: the events are made and sorted per node once it is small enough
//! for the sweep, which sorts `n log(threshold)` instead of `n log n` at the root.
//!
//! This is a search for the driver ([`BinnedTop`]), which hands its small nodes to the
//! sweep. The tree is the one a depth-first build makes (the driver's layout and the sweep's
//! reference budget); [`build`] runs it so on one worker (`driver::serial`), or with the two
//! children of every binned node (and of the biggest exact ones, split here by the sweep's
//! own search) built at once (`driver::fork_join`), which gives the same tree (see there).

use super::search::{best_split_of_boxes, priced, Split};
use super::{handed_subtree, Handed, Start};
use crate::builders::driver::{self, Budget, BudgetUse, Fork, Rules, SplitSearch};
use crate::builders::options::BINNED_REFS_PER_BIN;
use crate::builders::stitch::Piece;
use crate::builders::{Axes, BuildOptions, BuiltTree, Primitives};
use crate::clip::clipped_halves;
use crate::cost::CostModel;
use crate::geometry::{Aabb, Triangle};
use crate::tree::Node;
use rayon::prelude::*;
use std::borrow::Cow;
use std::mem::MaybeUninit;
use std::sync::atomic::AtomicUsize;
use std::time::Instant;

/// Nodes with more references than this get their histograms from parallel chunks (when
/// building in parallel): the top nodes, where there are too few nodes to keep the workers busy.
const PARALLEL_HISTOGRAM: usize = 1 << 16;

/// When building in parallel, a node below the threshold that holds more than a
/// `1 / (FORK_SHARE * threads)` share of the mesh's triangles (and more than `FORK_MIN`)
/// is split here by the sweep's own search and its children built at once, instead of its
/// whole subtree on one worker: on small meshes the binned top ends after two or three
/// levels, and a handful of exact subtrees of unequal size left a worker idle (bunny at 2
/// threads 75.6 -> 71.7 ms, dragon_res2 206 -> 198; dragon has enough subtrees and never
/// forks). The split is the one the sweep makes of that node, so the tree is the same; the
/// price is one more sort of the node's events.
const FORK_SHARE: usize = 16;
const FORK_MIN: usize = 1024;

/// The references a node of the binned part holds: triangle indices (increasing) and the
/// boxes the sweep would hold for them (clipped to the node on the way down when clipping).
/// The root borrows the primitives' boxes: a copy would be one more pass, and the page
/// faults of a fresh array, on one worker before any other has work.
struct Refs<'a> {
    ids: Vec<u32>,
    boxes: Cow<'a, [Aabb]>,
    bounds: Aabb,
    depth: u32,
}

/// What a part of the build took, summed up the tree.
#[derive(Default)]
struct Tally {
    presort_ms: f64,
    /// Time spent pricing and partitioning binned nodes, and building exact subtrees (their
    /// presorts included), summed over the workers.
    binned_ms: f64,
    subtrees_ms: f64,
    peak_working_bytes: usize,
}

impl Tally {
    fn add(&mut self, other: Tally) {
        self.presort_ms += other.presort_ms;
        self.binned_ms += other.binned_ms;
        self.subtrees_ms += other.subtrees_ms;
        self.peak_working_bytes = self.peak_working_bytes.max(other.peak_working_bytes);
    }
}

struct Ctx<'a> {
    triangles: &'a [Triangle],
    options: &'a BuildOptions,
    threshold: usize,
    /// Nodes below the threshold split here rather than by one sweep (see `FORK_SHARE`).
    fork_above: usize,
    max_depth: u32,
    budget: usize,
    /// Children of a binned node built at once, the budget kept as a shared guard.
    parallel: bool,
}

/// Builds with binning above the threshold, the exact sweep below. On one worker (or with
/// `parallel` false) it is the depth-first build with the sweep's running reference total;
/// otherwise the two children of each binned node are built at once, the budget checked
/// against one shared total as the hybrid does, and when that refused nothing and the
/// references (plus those clipping removed) fit the budget, the depth-first build could not
/// have refused a split either: the same tree. Else the tree is built depth first.
pub(crate) fn build(prims: &Primitives, options: &BuildOptions, parallel: bool) -> BuiltTree {
    let n = prims.triangles.len();
    let ctx = Ctx {
        triangles: prims.triangles,
        options,
        threshold: BINNED_REFS_PER_BIN * options.resolved_bins() as usize,
        fork_above: (n / (FORK_SHARE * rayon::current_num_threads())).max(FORK_MIN),
        max_depth: options.cost.max_depth_for(n),
        budget: options.cost.reference_budget(n),
        parallel: parallel && rayon::current_num_threads() > 1,
    };
    let built = run(&ctx, prims);
    match built {
        Some(tree) => tree,
        None => run(
            &Ctx {
                parallel: false,
                ..ctx
            },
            prims,
        )
        .expect("the depth-first build always finishes"),
    }
}

/// The build, or `None` when built in parallel and the budget may have decided differently.
fn run(ctx: &Ctx, prims: &Primitives) -> Option<BuiltTree> {
    let n = prims.triangles.len();
    let root = Refs {
        ids: (0..n as u32).collect(),
        boxes: Cow::Borrowed(&prims.boxes),
        bounds: prims.bounds,
        depth: 0,
    };
    let root_bytes = root.ids.len() * (4 + std::mem::size_of::<Aabb>());
    let rules = Rules {
        cost: &ctx.options.cost,
        max_depth: ctx.max_depth,
    };
    let mut top = BinnedTop {
        ctx,
        tally: Tally::default(),
    };
    let mut built = BuiltTree::default();
    if ctx.parallel {
        let total = AtomicUsize::new(n);
        let (tree, used) = driver::fork_join(&mut top, root, rules, ctx.budget, &total);
        let layout = Instant::now();
        built.nodes.push(Node::leaf(0, 0));
        driver::lay_out(tree, &mut built, 0);
        built.report.layout_ms = layout.elapsed().as_secs_f64() * 1e3;
        if used.bound || built.refs.len() + used.clipped_away > ctx.budget {
            return None;
        }
    } else {
        let budget = Budget {
            limit: ctx.budget,
            shared: None,
        };
        driver::serial(
            &mut top,
            root,
            rules,
            budget,
            &mut built.nodes,
            &mut built.refs,
        );
    }
    let tally = top.tally;
    built.report.presort_ms = tally.presort_ms;
    built.report.binned_ms = tally.binned_ms;
    built.report.subtrees_ms = tally.subtrees_ms;
    // The root's arrays and their two children's, beside the biggest sweep's working set.
    built.report.peak_working_bytes = 2 * root_bytes + tally.peak_working_bytes;
    Some(built)
}

/// The binned top as the driver's search: nodes above the threshold priced at their bin
/// boundaries; when building in parallel, nodes above `fork_above` by the sweep's own search
/// (see `FORK_SHARE`); every other node handed over to the exact sweep.
struct BinnedTop<'a> {
    ctx: &'a Ctx<'a>,
    tally: Tally,
}

impl<'a> SplitSearch for BinnedTop<'a> {
    type Node = Refs<'a>;

    fn size(node: &Refs) -> u32 {
        node.ids.len() as u32
    }

    fn depth(node: &Refs) -> u32 {
        node.depth
    }

    fn search(&mut self, node: &Refs) -> Option<Split> {
        let start = Instant::now();
        let (ctx, cost) = (self.ctx, &self.ctx.options.cost);
        let split = if node.ids.len() > ctx.threshold {
            best_split(
                &node.boxes,
                &node.bounds,
                ctx.options.axes,
                ctx.options.resolved_bins(),
                cost,
                ctx.parallel,
            )
        } else {
            best_split_of_boxes(&node.boxes, &node.bounds, ctx.options.axes, cost)
        };
        self.tally.binned_ms += start.elapsed().as_secs_f64() * 1e3;
        split
    }

    fn partition(&mut self, node: Refs<'a>, split: &Split) -> [Refs<'a>; 2] {
        let start = Instant::now();
        let children = partition(self.ctx, node, split);
        self.tally.binned_ms += start.elapsed().as_secs_f64() * 1e3;
        children
    }

    fn leaf(&mut self, node: Refs, refs: &mut Vec<u32>) {
        refs.extend_from_slice(&node.ids);
    }

    /// A node at or below the threshold (and, in parallel, at or below `fork_above`): the
    /// exact sweep's subtree, from its events made and sorted here.
    fn hand_over(
        &mut self,
        node: Refs<'a>,
        budget: Budget,
    ) -> Result<(Piece, BudgetUse), Refs<'a>> {
        let ctx = self.ctx;
        let n = node.ids.len();
        if n > ctx.threshold || (ctx.parallel && n > ctx.fork_above) {
            return Err(node);
        }
        let start = Instant::now();
        let handed = Handed {
            prims: &node.ids,
            bounds: node.bounds,
            depth: node.depth,
            start: Start::Boxes(&node.boxes),
        };
        let (piece, report) = handed_subtree(handed, ctx.triangles, budget, ctx.options);
        self.tally.add(Tally {
            presort_ms: report.presort_ms,
            binned_ms: 0.0,
            subtrees_ms: start.elapsed().as_secs_f64() * 1e3,
            peak_working_bytes: report.peak_working_bytes,
        });
        Ok((piece, report.budget))
    }
}

impl Fork for BinnedTop<'_> {
    fn fork(&self) -> Self {
        BinnedTop {
            ctx: self.ctx,
            tally: Tally::default(),
        }
    }

    fn join(&mut self, other: Self) {
        self.tally.add(other.tally);
    }
}

/// The node's references split between its children by the sweep's rules ([`route`]).
fn partition<'a>(ctx: &Ctx, node: Refs<'a>, split: &Split) -> [Refs<'a>; 2] {
    let (left_box, right_box) = node.bounds.split(split.axis, split.pos);
    let (mut left, mut right) = (
        Part::with_capacity(split.n_left),
        Part::with_capacity(split.n_right),
    );
    if ctx.options.clip {
        for (&id, b) in node.ids.iter().zip(node.boxes.iter()) {
            route(ctx, id, b, &node.bounds, split, |side, b| {
                let part = if side == 0 { &mut left } else { &mut right };
                part.ids.push(id);
                part.boxes.push(b);
            });
        }
    } else if ctx.parallel && node.ids.len() > PARALLEL_PARTITION {
        split_unclipped_in_chunks(&node, split, &mut left, &mut right);
    } else {
        let (l, r) = (left.spare(), right.spare());
        let counts = split_unclipped(&node.ids, &node.boxes, split, l, r);
        // SAFETY: `split_unclipped` wrote the first `counts` slots of each side.
        unsafe {
            left.set_len(counts.0);
            right.set_len(counts.1);
        }
    }
    debug_assert!(
        ctx.options.clip
            || (left.ids.len(), right.ids.len()) == (split.n_left as usize, split.n_right as usize)
    );
    let child = |part: Part, bounds| Refs {
        ids: part.ids,
        boxes: Cow::Owned(part.boxes),
        bounds,
        depth: node.depth + 1,
    };
    [child(left, left_box), child(right, right_box)]
}

/// Nodes with more references than this are split in chunks on the workers (when building
/// in parallel): on one worker, the root's split and the page faults of its children's
/// arrays leave the other workers idle, which on small meshes is a fair part of the build.
const PARALLEL_PARTITION: usize = 1 << 14;
/// References per chunk of a split in chunks.
const PARTITION_CHUNK: usize = 1 << 12;

/// One child's arrays while a node is split.
struct Part {
    ids: Vec<u32>,
    boxes: Vec<Aabb>,
}

/// One side's free slots: ids and boxes.
type Slots<'s> = (&'s mut [MaybeUninit<u32>], &'s mut [MaybeUninit<Aabb>]);

impl Part {
    fn with_capacity(count: u32) -> Part {
        Part {
            ids: Vec::with_capacity(count as usize),
            boxes: Vec::with_capacity(count as usize),
        }
    }

    fn spare(&mut self) -> Slots<'_> {
        (
            self.ids.spare_capacity_mut(),
            self.boxes.spare_capacity_mut(),
        )
    }

    /// # Safety
    /// The first `len` slots of both arrays must have been written.
    unsafe fn set_len(&mut self, len: usize) {
        self.ids.set_len(len);
        self.boxes.set_len(len);
    }
}

/// Which children the sweep's rules send a reference with box `b` to, without clipping.
#[inline(always)]
fn sides(b: &Aabb, split: &Split) -> (bool, bool) {
    let (lo, hi) = (b.lo[split.axis], b.hi[split.axis]);
    let in_plane = lo == split.pos && hi == split.pos;
    let to_left = lo < split.pos || (in_plane && split.planar_left);
    let to_right = hi > split.pos || (in_plane && !split.planar_left);
    (to_left, to_right)
}

/// [`partition`] without clipping of `ids` and `boxes` into two sides' free slots: every
/// reference goes whole to each side [`route`] sends it to, so the children hold exactly
/// the split's counts; returns how many slots of each side were filled. Each reference is
/// written to both sides' next free slot and each cursor advances only where the reference
/// belongs, which spends no branch on the side (the sides of a big node's references are
/// not predictable); the test of a free slot left fails at most once, at a side's end.
fn split_unclipped(
    ids: &[u32],
    boxes: &[Aabb],
    split: &Split,
    (left_ids, left_boxes): Slots,
    (right_ids, right_boxes): Slots,
) -> (usize, usize) {
    let (mut nl, mut nr) = (0, 0);
    for (&id, b) in ids.iter().zip(boxes) {
        let (to_left, to_right) = sides(b, split);
        if nl < left_ids.len() && nl < left_boxes.len() {
            left_ids[nl].write(id);
            left_boxes[nl].write(*b);
        }
        if nr < right_ids.len() && nr < right_boxes.len() {
            right_ids[nr].write(id);
            right_boxes[nr].write(*b);
        }
        nl += to_left as usize;
        nr += to_right as usize;
    }
    // Only a split whose counts are not its partition's could leave a reference unwritten.
    assert!(nl <= left_ids.len() && nr <= right_ids.len());
    (nl, nr)
}

/// [`split_unclipped`] on the workers: each chunk's count of both sides first, then every
/// chunk written into its own run of each child's slots, in order, so that the children
/// are the ones one pass makes.
fn split_unclipped_in_chunks(node: &Refs, split: &Split, left: &mut Part, right: &mut Part) {
    let counts: Vec<(usize, usize)> = node
        .boxes
        .par_chunks(PARTITION_CHUNK)
        .map(|chunk| {
            chunk.iter().fold((0, 0), |(l, r), b| {
                let (to_left, to_right) = sides(b, split);
                (l + to_left as usize, r + to_right as usize)
            })
        })
        .collect();
    let (total_left, total_right) = counts
        .iter()
        .fold((0, 0), |(l, r), &(cl, cr)| (l + cl, r + cr));
    let (mut l, mut r) = (left.spare(), right.spare());
    let mut runs = Vec::with_capacity(counts.len());
    for &(cl, cr) in &counts {
        let (l_ids, rest_ids) = std::mem::take(&mut l.0).split_at_mut(cl);
        let (l_boxes, rest_boxes) = std::mem::take(&mut l.1).split_at_mut(cl);
        let (r_ids, rest_r_ids) = std::mem::take(&mut r.0).split_at_mut(cr);
        let (r_boxes, rest_r_boxes) = std::mem::take(&mut r.1).split_at_mut(cr);
        runs.push(((l_ids, l_boxes), (r_ids, r_boxes)));
        l = (rest_ids, rest_boxes);
        r = (rest_r_ids, rest_r_boxes);
    }
    node.ids
        .par_chunks(PARTITION_CHUNK)
        .zip(node.boxes.par_chunks(PARTITION_CHUNK))
        .zip(runs)
        .for_each(|((ids, boxes), (l, r))| {
            split_unclipped(ids, boxes, split, l, r);
        });
    // SAFETY: each chunk filled its whole runs: a chunk's counts are those of its own pass.
    unsafe {
        left.set_len(total_left);
        right.set_len(total_right);
    }
}

/// Sends reference `id` (box `b`) of `node` to the children of `split` by the sweep's rules:
/// left (`put(0, box)`) if `lo < pos`, right (`put(1, box)`) if `hi > pos`, one lying in the
/// plane to the split's planar side; a straddler re-clipped to each child's box when
/// clipping (and dropped where that is empty).
#[inline(always)]
fn route(
    ctx: &Ctx,
    id: u32,
    b: &Aabb,
    node: &Aabb,
    split: &Split,
    mut put: impl FnMut(usize, Aabb),
) {
    let (to_left, to_right) = sides(b, split);
    if to_left && to_right && ctx.options.clip {
        let (l, r) = clipped_halves(&ctx.triangles[id as usize], node, split.axis, split.pos);
        for (side, c) in [(0, l), (1, r)] {
            if !c.is_empty() {
                put(side, c);
            }
        }
        return;
    }
    if to_left {
        put(0, *b);
    }
    if to_right {
        put(1, *b);
    }
}

/// The cheapest bin boundary of a node whose references have `boxes`, by the one ranking,
/// or `None` when no boundary lies strictly inside the node.
fn best_split(
    boxes: &[Aabb],
    node: &Aabb,
    axes: Axes,
    bins: u32,
    cost: &CostModel,
    parallel: bool,
) -> Option<Split> {
    let axis_list = match axes {
        Axes::All => 0..3,
        Axes::Longest => {
            let a = node.longest_axis();
            a..a + 1
        }
    };
    let n = boxes.len() as u32;
    let mut best = None;
    for axis in axis_list {
        let planes = planes(node, axis, bins);
        if planes.is_empty() {
            continue;
        }
        let h = if parallel && boxes.len() > PARALLEL_HISTOGRAM {
            boxes
                .par_chunks(PARALLEL_HISTOGRAM / 4)
                .map(|chunk| Histograms::of(chunk, axis, &planes, node, bins))
                .reduce_with(Histograms::add)
                .expect("boxes is not empty")
        } else {
            Histograms::of(boxes, axis, &planes, node, bins)
        };
        let (mut below, mut above) = (0, n);
        let splits = cost.splits_of(node, axis);
        for (j, &pos) in planes.iter().enumerate() {
            // `lo[k]` counts lo ends with k boundaries at or below them: those below boundary
            // j have k <= j. `hi[k]` counts hi ends with k boundaries below them: those above
            // boundary j have k > j. Ends in the plane are in neither.
            below += h.lo[j];
            above -= h.hi[j];
            let candidate = priced(&splits, axis, pos, below, above, h.planar[j]);
            if candidate.beats(&best) {
                best = Some(candidate);
            }
        }
    }
    best
}

/// The bin boundaries `lo + (hi - lo) * i / bins` of the node on `axis` that lie strictly
/// inside it, increasing (boundaries that round onto the node's faces or onto each other,
/// in a box thin for its coordinates, are dropped).
fn planes(node: &Aabb, axis: usize, bins: u32) -> Vec<f32> {
    let (lo, hi) = (node.lo[axis], node.hi[axis]);
    let mut out: Vec<f32> = Vec::with_capacity(bins as usize);
    for i in 1..bins {
        let p = lo + (hi - lo) * (i as f32 / bins as f32) + 0.0;
        if p > lo && p < hi && out.last().is_none_or(|&q| p > q) {
            out.push(p);
        }
    }
    out
}

/// Counts of a node's references against its boundaries on one axis.
struct Histograms {
    /// By the number of boundaries at or below a reference's lo end (`planes.len() + 1`).
    lo: Vec<u32>,
    /// By the number of boundaries strictly below a reference's hi end.
    hi: Vec<u32>,
    /// References flat on the axis lying in boundary j.
    planar: Vec<u32>,
}

impl Histograms {
    fn of(boxes: &[Aabb], axis: usize, planes: &[f32], node: &Aabb, bins: u32) -> Histograms {
        let m = planes.len();
        let mut h = Histograms {
            lo: vec![0; m + 1],
            hi: vec![0; m + 1],
            planar: vec![0; m + 1],
        };
        // The boundaries between sentinels: `bound[k]` is boundary `k - 1`, so that the
        // searches below stop at either end without a test of the index.
        let mut bound = Vec::with_capacity(m + 2);
        bound.push(f32::NEG_INFINITY);
        bound.extend_from_slice(planes);
        bound.push(f32::INFINITY);
        // The bin a value falls in, guessed by arithmetic, then made exact by comparing with
        // the boundaries themselves (usually no step), so that the counts are the exact ones.
        let origin = node.lo[axis];
        let scale = bins as f32 / (node.hi[axis] - origin);
        let last = m as f32;
        let guess = |x: f32| {
            let g = (x - origin) * scale;
            // In [0, m] and not NaN (a NaN fails `g > 0.0`), so the conversion is exact.
            let g = if g > 0.0 { g } else { 0.0 };
            let g = if g < last { g } else { last };
            // SAFETY: `g` is finite and in [0, m], which `u32` holds.
            unsafe { g.to_int_unchecked::<u32>() as usize }
        };
        // Every index below is kept in [0, m] by the sentinels (`bound[k]` and `bound[k + 1]`
        // with `bound.len() == m + 2`), and the counts have `m + 1` entries: the bound checks
        // were a third of this loop's instructions.
        let (lo_count, hi_count, planar) = (&mut h.lo[..], &mut h.hi[..], &mut h.planar[..]);
        debug_assert!(bound.len() == m + 2 && lo_count.len() == m + 1 && hi_count.len() == m + 1);
        for b in boxes {
            let (lo, hi) = (b.lo[axis], b.hi[axis]);
            // SAFETY: see above; `guess` is at most `m`, and each loop stops at a sentinel.
            unsafe {
                let at = |k: usize| *bound.get_unchecked(k);
                // `k` boundaries at or below `lo`.
                let mut k = guess(lo);
                while at(k) > lo {
                    k -= 1;
                }
                while at(k + 1) <= lo {
                    k += 1;
                }
                *lo_count.get_unchecked_mut(k) += 1;
                // A flat box lying in boundary `k - 1` is counted at `k`; `planar[0]` is unused.
                *planar.get_unchecked_mut(k) += (lo == hi && at(k) == lo) as u32;
                // `k` boundaries strictly below `hi`.
                let mut k = guess(hi);
                while at(k) >= hi {
                    k -= 1;
                }
                while at(k + 1) < hi {
                    k += 1;
                }
                *hi_count.get_unchecked_mut(k) += 1;
            }
        }
        h.planar.remove(0);
        h
    }

    fn add(mut self, other: Histograms) -> Histograms {
        for (a, b) in [
            (&mut self.lo, &other.lo),
            (&mut self.hi, &other.hi),
            (&mut self.planar, &other.planar),
        ] {
            a.iter_mut().zip(b).for_each(|(x, y)| *x += y);
        }
        self
    }
}

#[cfg(test)]
mod tests {
    use super::super::testing::{counts_at, grid_boxes, grid_rounds, Lcg};
    use super::*;
    use crate::geometry::Vec3;

    /// Counting every box directly at each boundary, as the shared rules say.
    fn brute(
        boxes: &[Aabb],
        node: &Aabb,
        axes: Axes,
        bins: u32,
        cost: &CostModel,
    ) -> Option<Split> {
        let axis_list: Vec<usize> = match axes {
            Axes::All => vec![0, 1, 2],
            Axes::Longest => vec![node.longest_axis()],
        };
        let mut best: Option<Split> = None;
        for a in axis_list {
            for p in planes(node, a, bins) {
                let (l, r, pl) = counts_at(boxes, a, p);
                let s = priced(&cost.splits_of(node, a), a, p, l, r, pl);
                if s.beats(&best) {
                    best = Some(s);
                }
            }
        }
        best
    }

    #[test]
    fn histograms_count_as_direct_counting_does() {
        let cost = CostModel::default();
        // Corners on a grid of eighths that the boundaries of a [0, 4] box often hit, so ends
        // and flat boxes lie in boundaries.
        for (round, boxes) in grid_rounds(5, 80, (33, 9, 0.125, 4.0)) {
            let bins = [2, 3, 4, 8, 16][round % 5];
            let n = boxes.len();
            // Boxes reaching out of the node too, as with clipping off.
            let node = if round % 3 == 0 {
                Aabb::new(Vec3::splat(0.5), Vec3::splat(3.5))
            } else {
                Aabb::new(Vec3::splat(0.0), Vec3::splat(4.0))
            };
            for axes in [Axes::All, Axes::Longest] {
                let got = best_split(&boxes, &node, axes, bins, &cost, false);
                let want = brute(&boxes, &node, axes, bins, &cost);
                assert_eq!(got, want, "round {round}, {bins} bins, {axes:?}");
            }
            // Histograms of parts add up to the whole's, as the parallel chunks are summed.
            let planes = planes(&node, 0, bins);
            let whole = Histograms::of(&boxes, 0, &planes, &node, bins);
            let (a, b) = boxes.split_at(n / 2);
            let sum = Histograms::of(a, 0, &planes, &node, bins)
                .add(Histograms::of(b, 0, &planes, &node, bins));
            assert_eq!(
                (whole.lo, whole.hi, whole.planar),
                (sum.lo, sum.hi, sum.planar)
            );
        }
    }

    /// Splits a node's references in chunks on several workers and in one pass, and checks
    /// both against the rule applied to each reference directly: lo below the plane (or
    /// flat in it, planar side left) goes left, hi above it (or flat in it, planar side
    /// right) goes right, in the node's order.
    #[test]
    fn a_split_in_chunks_is_the_split_of_one_pass() {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(3)
            .build()
            .unwrap();
        let mut rng = Lcg(11);
        for round in 0..12 {
            // From under one chunk to several, ending mid-chunk.
            let n = [1, 100, PARTITION_CHUNK - 1, 3 * PARTITION_CHUNK + 17][round % 4];
            let boxes = grid_boxes(&mut rng, n, 33, 9, 0.125, 4.0);
            let ids: Vec<u32> = (0..n as u32).map(|i| 3 * i + 1).collect();
            let node = Refs {
                ids: ids.clone(),
                boxes: Cow::Borrowed(&boxes),
                bounds: Aabb::new(Vec3::splat(0.0), Vec3::splat(4.0)),
                depth: 0,
            };
            let (axis, pos) = (round % 3, 0.125 * (1 + rng.below(31)) as f32);
            let planar_left = round % 2 == 0;
            let want = |left: bool| -> (Vec<u32>, Vec<Aabb>) {
                ids.iter()
                    .zip(&boxes)
                    .filter(|(_, b)| {
                        let flat_in = b.lo[axis] == pos && b.hi[axis] == pos;
                        if left {
                            b.lo[axis] < pos || (flat_in && planar_left)
                        } else {
                            b.hi[axis] > pos || (flat_in && !planar_left)
                        }
                    })
                    .map(|(&id, b)| (id, *b))
                    .unzip()
            };
            let (want_left, want_right) = (want(true), want(false));
            let split = Split {
                axis,
                pos,
                cost: 1.0,
                planar_left,
                n_left: want_left.0.len() as u32,
                n_right: want_right.0.len() as u32,
            };
            let one_pass = {
                let mut l = Part::with_capacity(split.n_left);
                let mut r = Part::with_capacity(split.n_right);
                let counts = split_unclipped(&ids, &boxes, &split, l.spare(), r.spare());
                assert_eq!(counts, (want_left.0.len(), want_right.0.len()));
                // SAFETY: the counts filled were checked just above.
                unsafe {
                    l.set_len(counts.0);
                    r.set_len(counts.1);
                }
                [(l.ids, l.boxes), (r.ids, r.boxes)]
            };
            let in_chunks = pool.install(|| {
                let mut l = Part::with_capacity(split.n_left);
                let mut r = Part::with_capacity(split.n_right);
                split_unclipped_in_chunks(&node, &split, &mut l, &mut r);
                [(l.ids, l.boxes), (r.ids, r.boxes)]
            });
            let want = [want_left, want_right];
            assert_eq!(one_pass, want, "round {round}: one pass");
            assert_eq!(in_chunks, want, "round {round}: in chunks");
        }
    }

    #[test]
    fn boundaries_lie_strictly_inside_and_increase() {
        let node = Aabb::new(Vec3::splat(1e7), Vec3::new(1e7 + 2.0, 1.0e7 + 1.0, 3e7));
        for bins in [2, 7, 64, 1024] {
            for axis in 0..3 {
                let p = planes(&node, axis, bins);
                assert!(p.len() < bins as usize);
                assert!(p.windows(2).all(|w| w[0] < w[1]));
                assert!(p.iter().all(|&x| x > node.lo[axis] && x < node.hi[axis]));
            }
        }
        // A box one float wide has no boundary inside it.
        let thin = Aabb::new(
            Vec3::splat(1.0),
            Vec3::splat(f32::from_bits(1.0f32.to_bits() + 1)),
        );
        assert!(planes(&thin, 0, 16).is_empty());
    }
}
