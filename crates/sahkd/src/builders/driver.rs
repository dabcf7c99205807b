//! The one recursion of the depth-first builders, over interchangeable split searches (after
//! Embree's builders: one split record, one driver, the searches plugged in).
//!
//! A search ([`SplitSearch`]) knows one kind of node: how to price it (`search`), split it
//! (`partition`) and write it out as a leaf (`leaf`). The driver owns the rest, the same for
//! every search: the rules around the search ([`split_or_leaf`]), the reference budget (the
//! sweep's running total in depth-first order, and the guard on a total shared by subtrees
//! built at once, [`Budget`]), what the budget refused and clipping removed ([`BudgetUse`]),
//! and the one layout: a node's two children side by side, appended when it is split, depth
//! first, left subtree first, leaves' references in the same order.
//!
//! Two drivers run a search: [`serial`] on one worker from an explicit stack, writing nodes
//! as it goes (the exact sweep, `sweep::search`; the binned top on one worker), and
//! [`fork_join`], the two children of every node at once (`rayon::join`) into a [`Top`] laid
//! out afterwards in the same order ([`lay_out`]), for searches that can split their state
//! ([`Fork`]: the binned top). A search may hand a node's whole subtree to another search
//! ([`SplitSearch::hand_over`]): the binned top hands nodes below its threshold to the sweep.
//!
//! The breadth-first builders are top phases in front of the driver, not searches in it: the
//! level passes (`level`) and the median builder's large nodes (`median`) decide a whole level
//! at once and check the budget per level, then hand their last level (a frontier) to the
//! sweep, one subtree per node, through `sweep::handed_subtree`.

use super::choice::{split_or_leaf, Split};
use super::stitch::{self, Piece};
use super::BuiltTree;
use crate::cost::CostModel;
use crate::tree::Node;
use std::sync::atomic::{AtomicUsize, Ordering};

/// One kind of node and how to price, split and emit it. The driver calls `search` only
/// where the leaf rules allow a split and keeps its answer only where it pays and fits the
/// budget.
pub(crate) trait SplitSearch {
    /// A node waiting to be built: its box and depth and its references in the search's own
    /// form (event segments, box arrays).
    type Node;
    /// References the node holds.
    fn size(node: &Self::Node) -> u32;
    fn depth(node: &Self::Node) -> u32;
    /// The node's best split by this search, or `None` when it has no candidate.
    fn search(&mut self, node: &Self::Node) -> Option<Split>;
    /// The node's two children at `split`, straddlers in both (re-clipped with clipping on).
    fn partition(&mut self, node: Self::Node, split: &Split) -> [Self::Node; 2];
    /// Appends the node's primitives, a leaf's references, to `refs`.
    fn leaf(&mut self, node: Self::Node, refs: &mut Vec<u32>);
    /// The node's whole subtree when another search builds it, within `budget`, or the node
    /// back when this search goes on with it (the default).
    fn hand_over(
        &mut self,
        node: Self::Node,
        budget: Budget,
    ) -> Result<(Piece, BudgetUse), Self::Node> {
        let _ = budget;
        Err(node)
    }
}

/// A search whose state can be split between two branches built at once and joined after.
pub(crate) trait Fork: SplitSearch<Node: Send> + Send {
    /// The state of a new branch (the shared parts, and empty tallies).
    fn fork(&self) -> Self;
    /// Adds a finished branch's tallies.
    fn join(&mut self, other: Self);
}

/// What bounds every split, from the whole tree.
#[derive(Clone, Copy)]
pub(crate) struct Rules<'a> {
    pub cost: &'a CostModel,
    /// The whole tree's depth limit (node depths count from the whole tree's root).
    pub max_depth: u32,
}

/// The references a subtree may hold: its leaves together at most `limit`, and, when
/// subtrees are built at once, every split added to `shared` too (the references of the
/// whole tree so far), which must stay within `limit` as well. The order of the additions to
/// `shared` varies, so a build that hits it is not deterministic: its builder then builds
/// again on one worker.
#[derive(Clone, Copy)]
pub(crate) struct Budget<'a> {
    pub limit: usize,
    pub shared: Option<&'a AtomicUsize>,
}

/// How the reference budget went in a build or a part of one.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct BudgetUse {
    /// Whether the budget refused a split the SAH wanted.
    pub bound: bool,
    /// References clipping removed, summed over the splits (before minus after).
    pub clipped_away: usize,
}

impl BudgetUse {
    pub fn add(self, other: BudgetUse) -> BudgetUse {
        BudgetUse {
            bound: self.bound || other.bound,
            clipped_away: self.clipped_away + other.clipped_away,
        }
    }

    /// Counts a split of `split`'s planes whose children hold `kept` references.
    #[inline]
    fn split(&mut self, split: &Split, kept: u32) {
        self.clipped_away += (split.refs() - kept) as usize;
    }
}

/// Builds `root`'s subtree with `search` on this worker, depth first from an explicit stack,
/// appending its nodes to `nodes` (its root first, at the index `nodes.len()` had on entry)
/// and its leaves' references to `refs`. The budget is the sweep's: a running total of the
/// references of the finished leaves and the pending nodes, which a split may raise only
/// within `budget.limit` (Wald and Havran's rule).
pub(crate) fn serial<S: SplitSearch>(
    search: &mut S,
    root: S::Node,
    rules: Rules,
    budget: Budget,
    nodes: &mut Vec<Node>,
    refs: &mut Vec<u32>,
) -> BudgetUse {
    let limit = budget.limit;
    let mut held = S::size(&root) as usize;
    let mut used = BudgetUse::default();
    let mut claims = Claims::new(budget.shared, limit);
    let mut stack = vec![(nodes.len(), root)];
    nodes.push(Node::leaf(0, 0));
    while let Some((slot, node)) = stack.pop() {
        let n = S::size(&node);
        // The subtree may hold what the budget leaves beside the rest of the running total.
        let rest = held - n as usize;
        let below = Budget {
            limit: limit - rest,
            shared: budget.shared,
        };
        let node = match search.hand_over(node, below) {
            Ok((piece, piece_use)) => {
                held = rest + piece.refs.len();
                used = used.add(piece_use);
                stitch::place_at(nodes, refs, slot, &piece);
                continue;
            }
            Err(node) => node,
        };
        let split = split_or_leaf(n, S::depth(&node), rules.max_depth, rules.cost, || {
            search.search(&node)
        })
        .filter(|s| {
            let extra = (s.refs() - n) as usize;
            let fits = held + extra <= limit && claims.take(extra, limit);
            used.bound |= !fits;
            fits
        });
        let Some(split) = split else {
            let first = refs.len();
            search.leaf(node, refs);
            nodes[slot] = Node::leaf(first as u32, (refs.len() - first) as u32);
            continue;
        };
        let [left, right] = search.partition(node, &split);
        let kept = S::size(&left) + S::size(&right);
        held = held + kept as usize - n as usize;
        used.split(&split, kept);
        let first = nodes.len();
        nodes[slot] = Node::interior(split.axis, split.pos, first as u32);
        nodes.extend([Node::leaf(0, 0); 2]);
        stack.push((first + 1, right));
        stack.push((first, left));
    }
    claims.give_back_unused();
    used
}

/// A tree built with the children of its nodes at once, before it is laid out.
pub(crate) enum Top {
    Leaf(Vec<u32>),
    Split {
        axis: usize,
        pos: f32,
        children: Box<[Top; 2]>,
    },
    /// A node handed over, with its subtree.
    Handed(Piece),
}

/// Builds `node`'s subtree with `search`, the two children of every node at once, the
/// budget checked against the one shared total `total` (which holds every reference of the
/// tree so far, this node's included). Where that refused nothing and the tree's references,
/// plus those clipping removed, fit `limit`, the [`serial`] build's running total (never more
/// than that sum) could not have refused a split either: the tree is the serial one.
pub(crate) fn fork_join<S: Fork>(
    search: &mut S,
    node: S::Node,
    rules: Rules,
    limit: usize,
    total: &AtomicUsize,
) -> (Top, BudgetUse) {
    let below = Budget {
        limit,
        shared: Some(total),
    };
    let node = match search.hand_over(node, below) {
        Ok((piece, used)) => return (Top::Handed(piece), used),
        Err(node) => node,
    };
    let n = S::size(&node);
    let mut used = BudgetUse::default();
    let split = split_or_leaf(n, S::depth(&node), rules.max_depth, rules.cost, || {
        search.search(&node)
    })
    .filter(|s| {
        let extra = (s.refs() - n) as usize;
        let fits = total.fetch_add(extra, Ordering::Relaxed) + extra <= limit;
        used.bound |= !fits;
        fits
    });
    let Some(split) = split else {
        let mut refs = Vec::with_capacity(n as usize);
        search.leaf(node, &mut refs);
        return (Top::Leaf(refs), used);
    };
    let [left, right] = search.partition(node, &split);
    used.split(&split, S::size(&left) + S::size(&right));
    let mut other = search.fork();
    let ((l, left_use), (r, right_use)) = rayon::join(
        || fork_join(search, left, rules, limit, total),
        || fork_join(&mut other, right, rules, limit, total),
    );
    search.join(other);
    let top = Top::Split {
        axis: split.axis,
        pos: split.pos,
        children: Box::new([l, r]),
    };
    (top, used.add(left_use).add(right_use))
}

/// Writes `top` from slot `slot` on (a placeholder) in the driver's layout, as [`serial`]
/// would have written it: a split's two children side by side after everything written
/// before it, then the left child's subtree, then the right's. Each subtree's part of both
/// arrays is known from its size, so big subtrees are written at once.
pub(crate) fn lay_out(top: Top, out: &mut BuiltTree, slot: usize) {
    let (below, refs) = top.size();
    let (base, ref_base) = (out.nodes.len(), out.refs.len());
    out.nodes.resize(base + below, Node::leaf(0, 0));
    out.refs.resize(ref_base + refs, 0);
    let (head, tail) = out.nodes.split_at_mut(base);
    let place = Place {
        nodes: tail,
        base,
        refs: &mut out.refs[ref_base..],
        ref_base,
    };
    place.write(&top, &mut head[slot]);
}

/// Subtrees of more references than this are written beside each other by [`lay_out`].
const PARALLEL_LAY_OUT: usize = 4096;

impl Top {
    /// The nodes the subtree adds below its root, and its references.
    fn size(&self) -> (usize, usize) {
        match self {
            Top::Leaf(ids) => (0, ids.len()),
            Top::Handed(piece) => (piece.nodes.len() - 1, piece.refs.len()),
            Top::Split { children, .. } => {
                let ((ln, lr), (rn, rr)) = (children[0].size(), children[1].size());
                (2 + ln + rn, lr + rr)
            }
        }
    }
}

/// A subtree's part of the tree's arrays: `nodes` from index `base` on, `refs` from
/// `ref_base` on.
struct Place<'a> {
    nodes: &'a mut [Node],
    base: usize,
    refs: &'a mut [u32],
    ref_base: usize,
}

impl Place<'_> {
    /// Writes `top` with its root in `root`.
    fn write(self, top: &Top, root: &mut Node) {
        match top {
            Top::Leaf(ids) => {
                *root = Node::leaf(self.ref_base as u32, ids.len() as u32);
                self.refs.copy_from_slice(ids);
            }
            Top::Handed(piece) => {
                stitch::place_nodes(piece, root, self.nodes, self.base, self.ref_base);
                self.refs.copy_from_slice(&piece.refs);
            }
            Top::Split {
                axis,
                pos,
                children,
            } => {
                *root = Node::interior(*axis, *pos, self.base as u32);
                let [l, r] = &**children;
                let (left_nodes, left_refs) = l.size();
                let (pair, rest) = self.nodes.split_at_mut(2);
                let (left_root, right_root) = pair.split_at_mut(1);
                let (nodes_l, nodes_r) = rest.split_at_mut(left_nodes);
                let right_refs = self.refs.len() - left_refs;
                let (refs_l, refs_r) = self.refs.split_at_mut(left_refs);
                let left = Place {
                    nodes: nodes_l,
                    base: self.base + 2,
                    refs: refs_l,
                    ref_base: self.ref_base,
                };
                let right = Place {
                    nodes: nodes_r,
                    base: self.base + 2 + left_nodes,
                    refs: refs_r,
                    ref_base: self.ref_base + left_refs,
                };
                let write_left = || left.write(l, &mut left_root[0]);
                let write_right = || right.write(r, &mut right_root[0]);
                if left_refs.min(right_refs) > PARALLEL_LAY_OUT {
                    rayon::join(write_left, write_right);
                } else {
                    write_left();
                    write_right();
                }
            }
        }
    }
}

/// A subtree's share of the shared reference total (`Budget::shared`), claimed in chunks:
/// one atomic add per split, with two workers bouncing its cache line, cost about 6 % of the
/// sweep's loop at 2 threads. Claims count more than the splits add, by less than a chunk per
/// subtree at work, so the guard can refuse early, never late; a refusal sends every builder
/// that shares a total back to the depth-first build, so the tree is the same.
struct Claims<'a> {
    total: Option<&'a AtomicUsize>,
    /// Claimed and not yet spent.
    unspent: usize,
    chunk: usize,
}

impl<'a> Claims<'a> {
    fn new(total: Option<&'a AtomicUsize>, limit: usize) -> Claims<'a> {
        Claims {
            total,
            unspent: 0,
            chunk: (limit / 1024).clamp(1, 4096),
        }
    }

    /// Whether `extra` more references fit the shared total (always, without one).
    #[inline]
    fn take(&mut self, extra: usize, limit: usize) -> bool {
        let Some(total) = self.total else {
            return true;
        };
        if extra > self.unspent {
            let claim = (extra - self.unspent).max(self.chunk);
            if total.fetch_add(claim, Ordering::Relaxed) + claim > limit {
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
