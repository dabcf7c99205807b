//! The hybrid builder with exact SAH (`bins` 0; with bins it runs `sweep::binned`'s parallel
//! top instead, see `build`): the paper's level passes at the top of the tree, where a few
//! big nodes hold all the work and only parallelism within a node helps; then, once a level holds
//! enough independent nodes, each node's whole subtree by the sweep on one worker, from the
//! node's sorted lists as they are (no second sort). The subtrees are placed in the sweep's
//! own layout (`stitch::depth_first`), so nodes and references come out as the sweep's,
//! array for array.
//!
//! Both parts follow the sweep's split rules, so where the reference budget refuses no split
//! the tree is the sweep's whatever level the hand-over happens at. The sweep checks the
//! budget as a running total in depth-first order, which subtrees built at once cannot
//! follow; here the level passes check it per level and the subtrees against one shared
//! total, as a guard on memory. When nothing was refused and the whole tree's references,
//! plus those clipping removed, fit the budget, the sweep's running total (never more than
//! that sum) could not have refused a split either: the tree is the sweep's. Otherwise (a
//! budget that binds: needles across a scene, say) the sweep builds it. Either way the tree
//! is the same on any number of threads.
//!
//! With binning (the default, [`crate::HYBRID_BINS`]; `bins: Some(0)` turns it off) the level
//! passes are not used: they price every candidate exactly, and where they stop depends on
//! the number of threads, so the tree would too.
//! The binned sweep builds the tree instead, the two children of each binned node at once
//! (`sweep::build_binned_parallel`): the tree of `sweep` with the same bins, on every core.

use super::choice::searched;
use super::driver::{Budget, BudgetUse};
use super::level;
use super::stitch::{self, Piece};
use super::sweep::{self, Handed, Start, SubtreeReport};
use super::{BuildOptions, BuiltTree, Primitives};
use crate::tree::Node;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;
use std::time::Instant;

/// Nodes per worker a level must hold before it is handed over.
const NODES_PER_THREAD: usize = 8;
/// A level is handed over once its biggest node holds at most this share of its references
/// (so one subtree cannot keep one worker busy long after the others), or once it holds
/// `SPREAD_NODES_PER_THREAD` nodes per worker whatever their sizes.
const BIGGEST_SHARE: usize = 4;
const SPREAD_NODES_PER_THREAD: usize = 64;

/// Whether a level of `nodes` nodes and `refs` references, the biggest node holding
/// `biggest`, is enough independent work for `threads` workers. One worker hands over the
/// root: the level passes only pay off in parallel.
pub(crate) fn hand_off(threads: usize, nodes: usize, refs: usize, biggest: usize) -> bool {
    threads <= 1
        || (nodes >= NODES_PER_THREAD * threads
            && (biggest * BIGGEST_SHARE <= refs || nodes >= SPREAD_NODES_PER_THREAD * threads))
}

pub(crate) fn build(prims: &Primitives, options: &BuildOptions) -> BuiltTree {
    if options.resolved_bins() != 0 {
        return sweep::build_binned_parallel(prims, options);
    }
    let threads = rayon::current_num_threads();
    let (built, frontier, mut budget_use) =
        level::build_top(prims, options, |nodes, refs, biggest| {
            hand_off(threads, nodes, refs, biggest)
        });
    let budget = options.cost.reference_budget(prims.triangles.len());
    let the_sweeps = |budget_use: BudgetUse, refs: usize| {
        !budget_use.bound && refs + budget_use.clipped_away <= budget
    };
    let Some(frontier) = frontier else {
        if !the_sweeps(budget_use, built.refs.len()) {
            return sweep::build(prims, options);
        }
        // The sweep's layout of the level passes' tree.
        let mut tree = stitch::depth_first(&built, built.nodes.len(), &[]);
        tree.report = built.report;
        return tree;
    };
    let start = Instant::now();
    let max_depth = options.cost.max_depth_for(prims.triangles.len());
    let first_slot = frontier.first_slot;
    let held = built.refs.len()
        + (0..frontier.nodes())
            .map(|k| frontier.refs(k))
            .sum::<usize>();
    let shared_total = AtomicUsize::new(held);
    // Biggest first, each worker taking the next node when it is free (longest processing
    // time first), so that the last subtrees to start are the small ones. Rayon's recursive
    // halving would instead give one worker the first (biggest) half of the list to start with.
    let mut order: Vec<usize> = (0..frontier.nodes()).collect();
    order.sort_by_key(|&k| std::cmp::Reverse(frontier.refs(k)));
    let build_one = |k: usize| {
        let node = frontier.node(k);
        let n = node.prims.len();
        if !searched(n as u32, node.depth, max_depth, &options.cost) {
            // A leaf by the leaf rules: the level passes made no lists for it.
            let piece = Piece {
                nodes: vec![Node::leaf(0, n as u32)],
                refs: node.prims.to_vec(),
            };
            return (k, piece, None);
        }
        let handed = Handed {
            prims: node.prims,
            bounds: node.bounds,
            depth: node.depth,
            start: Start::Sorted(node.events),
        };
        let budget = Budget {
            limit: budget,
            shared: Some(&shared_total),
        };
        let (piece, report) = sweep::handed_subtree(handed, prims.triangles, budget, options);
        (k, piece, Some(report))
    };
    let next = AtomicUsize::new(0);
    let done = Mutex::new(Vec::with_capacity(order.len()));
    rayon::scope(|scope| {
        for _ in 0..threads {
            scope.spawn(|_| loop {
                let i = next.fetch_add(1, Ordering::Relaxed);
                let Some(&k) = order.get(i) else { break };
                let piece = build_one(k);
                done.lock()
                    .expect("no worker panics while holding it")
                    .push(piece);
            });
        }
    });
    let mut pieces: Vec<(usize, Piece, Option<SubtreeReport>)> =
        done.into_inner().expect("no worker panicked");
    pieces.sort_unstable_by_key(|p| p.0);
    let mut subtree_peak = 0;
    for report in pieces.iter().filter_map(|p| p.2.as_ref()) {
        subtree_peak = subtree_peak.max(report.peak_working_bytes);
        budget_use = budget_use.add(report.budget);
    }
    let pieces: Vec<Piece> = pieces.into_iter().map(|p| p.1).collect();
    drop(frontier);
    let refs = built.refs.len() + pieces.iter().map(|p| p.refs.len()).sum::<usize>();
    if !the_sweeps(budget_use, refs) {
        return sweep::build(prims, options);
    }
    let mut tree = stitch::depth_first(&built, first_slot, &pieces);
    tree.report = built.report;
    let report = &mut tree.report;
    report.subtrees_ms = start.elapsed().as_secs_f64() * 1e3;
    report.peak_working_bytes = report.peak_working_bytes.max(subtree_peak * threads);
    tree
}
