//! The paper's reference [14]: Zhou, Hou, Wang & Guo 2008, "Real-time kd-tree construction on
//! graphics hardware", as implemented by Chang, Seo & Ihm 2015, on the CPU with rayon.
//!
//! The tree is built breadth first. A *large* node (more than `median_large_node`
//! primitives) is not priced over all candidates: when one side of its box is more than 25%
//! empty along an axis, that empty space is cut off (a split at the primitives' extent, whose
//! other child is an empty leaf); otherwise it is split at the spatial median of its longest
//! axis. A level's large nodes are decided and partitioned in parallel, over nodes and over
//! each node's primitives. Once nodes are *small*, each gets its exact SAH subtree from the
//! sweep builder, all of them in parallel.
//!
//! Shared with the other builders: the partition rule (straddlers to both sides, re-clipped
//! with `clip`), the leaf rules (leaf size, depth cap from the root, a split must be cheaper
//! than the leaf, also for large nodes), the reference budget and the tree format. Results
//! are placed by index, never by completion order, so any thread count gives the same tree.
//!
//! The budget is checked breadth first: a level's splits are taken in node order while the
//! running total of references stays within it; the small nodes then share what is left in
//! proportion to their primitives. The root can never be an empty-space cut, since the
//! scene box is the triangles' own box.

use super::choice::{split_or_leaf, Split};
use super::driver::Budget;
use super::stitch::{self, Piece};
use super::sweep::{self, Handed, Start};
use super::{BuildOptions, BuiltTree, LevelReport, Primitives};
use crate::clip::clipped_bounds;
use crate::cost::CostModel;
use crate::geometry::{Aabb, Triangle, Vec3};
use crate::tree::Node;
use rayon::prelude::*;
use std::time::Instant;

/// The share of a node's extent on one side that must be empty for an empty-space cut
/// (Zhou et al.'s `C_e`).
const EMPTY_SPACE_RATIO: f32 = 0.25;

/// Fewer primitives than this are handled by one thread: splitting the work finer costs more
/// than it saves.
const MIN_ITEMS_PER_TASK: usize = 4096;

/// A primitive of a node: its triangle and its box within the node.
#[derive(Clone, Copy, Debug)]
struct Item {
    id: u32,
    bounds: Aabb,
}

/// A node waiting to be built: its slot, box, depth, primitives and their extent.
struct Pending {
    slot: u32,
    bounds: Aabb,
    depth: u32,
    items: Vec<Item>,
    /// The union of the items' boxes.
    extent: Aabb,
}

/// What became of a large node.
enum Outcome {
    Leaf(Pending),
    Split {
        node: Pending,
        split: Split,
        children: [Side; 2],
    },
}

/// What stays fixed over a build.
struct Limits<'a> {
    cost: &'a CostModel,
    max_depth: u32,
    /// The reference budget of the whole tree.
    budget: usize,
    /// Nodes with more primitives than this are large.
    large: usize,
    /// The triangles, to re-clip straddlers (`None` without clipping).
    clip: Option<&'a [Triangle]>,
}

pub(crate) fn build(prims: &Primitives, options: &BuildOptions) -> BuiltTree {
    let cost = &options.cost;
    let total_prims = prims.triangles.len();
    let limits = Limits {
        cost,
        max_depth: cost.max_depth_for(total_prims),
        budget: cost.reference_budget(total_prims),
        large: options.median_large_node as usize,
        clip: options.clip.then_some(prims.triangles),
    };
    let root = Pending {
        slot: 0,
        bounds: prims.bounds,
        depth: 0,
        items: prims
            .boxes
            .iter()
            .enumerate()
            .map(|(i, &bounds)| Item {
                id: i as u32,
                bounds,
            })
            .collect(),
        extent: without_negative_zeros(prims.bounds),
    };
    let mut built = BuiltTree {
        nodes: vec![Node::leaf(0, 0)],
        ..BuiltTree::default()
    };
    let large = build_large_nodes(root, &limits, &mut built);
    build_small_nodes(
        prims.triangles,
        large.small,
        options,
        limits.budget.saturating_sub(large.references),
        &mut built,
    );
    built.report.peak_working_bytes = large.peak_items * std::mem::size_of::<Item>();
    built
}

/// What the large-node phase leaves to the small-node phase.
struct LargePhase {
    /// The small nodes, in the order they were made.
    small: Vec<Pending>,
    /// References held by the finished leaves and the small nodes.
    references: usize,
    /// The most items held at once.
    peak_items: usize,
}

/// The large-node phase: level by level, every large node is cut (empty space or spatial
/// median) or made a leaf, until no node is large; the small nodes are collected.
fn build_large_nodes(root: Pending, limits: &Limits, built: &mut BuiltTree) -> LargePhase {
    let mut phase = LargePhase {
        references: root.items.len(),
        peak_items: root.items.len(),
        small: Vec::new(),
    };
    let mut level = Vec::new();
    if root.items.len() > limits.large {
        level.push(root);
    } else {
        phase.small.push(root);
    }
    while !level.is_empty() {
        let mut report = LevelReport {
            depth: level[0].depth,
            nodes: level.len(),
            candidates: level.len(),
            references: level.iter().map(|n| n.items.len()).sum(),
            ..LevelReport::default()
        };
        let start = Instant::now();
        let splits = decide_level(&level, phase.references, limits);
        report.ms.decision = start.elapsed().as_secs_f64() * 1e3;

        let start = Instant::now();
        let outcomes: Vec<Outcome> = level
            .into_par_iter()
            .zip(splits)
            .map(|(node, split)| match split {
                None => Outcome::Leaf(node),
                Some(split) => {
                    let children = partition(&node, &split, limits.clip);
                    Outcome::Split {
                        node,
                        split,
                        children,
                    }
                }
            })
            .collect();
        report.ms.partition = start.elapsed().as_secs_f64() * 1e3;

        let next = place_level(outcomes, limits, built, &mut phase, &mut report);
        // The level's items and its children's were held at once.
        let held_items: usize = next
            .iter()
            .chain(phase.small.iter())
            .map(|n| n.items.len())
            .sum();
        phase.peak_items = phase.peak_items.max(report.references + held_items);
        built.report.levels.push(report);
        level = next;
    }
    phase
}

/// The splits of a level of large nodes, with the budget taken in level order: a split is
/// kept while the running total of references (`references` before the level) stays
/// within it.
fn decide_level(level: &[Pending], references: usize, limits: &Limits) -> Vec<Option<Split>> {
    let mut splits: Vec<Option<Split>> = level
        .par_iter()
        .map(|node| choose_split(node, limits.cost, limits.max_depth))
        .collect();
    let mut held = references;
    for (node, split) in level.iter().zip(splits.iter_mut()) {
        if let Some(s) = split {
            let after = held + s.refs() as usize - node.items.len();
            if after <= limits.budget {
                held = after;
            } else {
                *split = None;
            }
        }
    }
    splits
}

/// Writes a level's leaves and split nodes into the tree, in node order, and returns the
/// next level's large nodes; small children go to `phase.small`.
fn place_level(
    outcomes: Vec<Outcome>,
    limits: &Limits,
    built: &mut BuiltTree,
    phase: &mut LargePhase,
    report: &mut LevelReport,
) -> Vec<Pending> {
    let mut next = Vec::new();
    for outcome in outcomes {
        match outcome {
            Outcome::Leaf(node) => {
                report.leaves += 1;
                let first = built.refs.len() as u32;
                built.refs.extend(node.items.iter().map(|it| it.id));
                built.nodes[node.slot as usize] = Node::leaf(first, node.items.len() as u32);
            }
            Outcome::Split {
                node,
                split,
                children,
            } => {
                let slot = built.nodes.len() as u32;
                built.nodes[node.slot as usize] = Node::interior(split.axis, split.pos, slot);
                built.nodes.extend([Node::leaf(0, 0); 2]);
                let [left, right] = children;
                phase.references =
                    phase.references + left.items.len() + right.items.len() - node.items.len();
                let (left_box, right_box) = node.bounds.split(split.axis, split.pos);
                for (slot, bounds, side) in [(slot, left_box, left), (slot + 1, right_box, right)] {
                    let child = Pending {
                        slot,
                        bounds,
                        depth: node.depth + 1,
                        items: side.items,
                        extent: side.extent,
                    };
                    if child.items.len() > limits.large {
                        next.push(child);
                    } else {
                        phase.small.push(child);
                    }
                }
            }
        }
    }
    next
}

/// The split of a large node, or `None` when it must be a leaf: the builders' rules around
/// this builder's search, [`cut`].
fn choose_split(node: &Pending, cost: &CostModel, max_depth: u32) -> Option<Split> {
    let n = node.items.len() as u32;
    split_or_leaf(n, node.depth, max_depth, cost, || cut(node, n, cost))
}

/// The large node's cut: of empty space where there is enough of it, else at the spatial
/// median of its longest axis (`None` where that median is not strictly inside the box).
fn cut(node: &Pending, n: u32, cost: &CostModel) -> Option<Split> {
    let bounds = &node.bounds;
    if let Some(cut) = empty_space_cut(bounds, &node.extent, n, cost) {
        return Some(cut);
    }
    let axis = bounds.longest_axis();
    // Halves first, so that coordinates near the largest float do not overflow.
    let pos = bounds.lo[axis] * 0.5 + bounds.hi[axis] * 0.5 + 0.0;
    if !(pos > bounds.lo[axis] && pos < bounds.hi[axis]) {
        return None;
    }
    let (below, above, planar) = count_at(&node.items, axis, pos);
    let cost_left = cost.split_cost(bounds, axis, pos, below + planar, above);
    let cost_right = cost.split_cost(bounds, axis, pos, below, above + planar);
    let planar_left = cost_left <= cost_right;
    Some(Split {
        axis,
        pos,
        cost: cost_left.min(cost_right),
        planar_left,
        n_left: below + if planar_left { planar } else { 0 },
        n_right: above + if planar_left { 0 } else { planar },
    })
}

/// The cut of the largest empty space beyond `EMPTY_SPACE_RATIO` of the node's extent, at
/// the primitives' extent, all `n` primitives going to the other side (planar ones too).
/// Ties go to the lower axis, then to the low side. Priced by `cost` as it stands.
fn empty_space_cut(bounds: &Aabb, extent: &Aabb, n: u32, cost: &CostModel) -> Option<Split> {
    let mut best: Option<(f32, Split)> = None;
    for axis in 0..3 {
        let (lo, hi) = (bounds.lo[axis], bounds.hi[axis]);
        let size = hi - lo;
        for (gap, pos, empty_left) in [
            (extent.lo[axis] - lo, extent.lo[axis], true),
            (hi - extent.hi[axis], extent.hi[axis], false),
        ] {
            let ratio = gap / size;
            let better = best.is_none_or(|(r, _)| ratio > r);
            if ratio > EMPTY_SPACE_RATIO && pos > lo && pos < hi && better {
                let (n_left, n_right) = if empty_left { (0, n) } else { (n, 0) };
                best = Some((
                    ratio,
                    Split {
                        axis,
                        pos,
                        cost: cost.split_cost(bounds, axis, pos, n_left, n_right),
                        planar_left: !empty_left,
                        n_left,
                        n_right,
                    },
                ));
            }
        }
    }
    best.map(|(_, split)| split)
}

/// The shared semantics' counts at `axis = pos`: `#(lo < pos)`, `#(hi > pos)` and the
/// primitives lying in the plane.
fn count_at(items: &[Item], axis: usize, pos: f32) -> (u32, u32, u32) {
    items
        .par_iter()
        .with_min_len(MIN_ITEMS_PER_TASK)
        .map(|it| {
            let (lo, hi) = (it.bounds.lo[axis], it.bounds.hi[axis]);
            (
                (lo < pos) as u32,
                (hi > pos) as u32,
                (lo == pos && hi == pos) as u32,
            )
        })
        .reduce(|| (0, 0, 0), |a, b| (a.0 + b.0, a.1 + b.1, a.2 + b.2))
}

/// One child's items and the union of their boxes.
struct Side {
    items: Vec<Item>,
    extent: Aabb,
}

impl Side {
    fn with_capacity(n: usize) -> Side {
        Side {
            items: Vec::with_capacity(n),
            extent: Aabb::EMPTY,
        }
    }
    fn push(&mut self, item: Item) {
        self.extent = self.extent.union(item.bounds);
        self.items.push(item);
    }
}

/// The children's items by the shared partition rule, in one pass that also gives their
/// extents. Straddlers go to both sides with their boxes re-clipped from the triangle
/// (`clip`) or cut to the child's box; a straddler whose clipped box is empty is dropped
/// from that child. A large node's items are split in chunks on all threads and the chunks'
/// results joined in order.
fn partition(node: &Pending, split: &Split, clip: Option<&[Triangle]>) -> [Side; 2] {
    let (axis, pos) = (split.axis, split.pos);
    let child_boxes = {
        let (l, r) = node.bounds.split(axis, pos);
        [l, r]
    };
    let part = |items: &[Item], capacity: [usize; 2]| -> [Side; 2] {
        let mut sides = capacity.map(Side::with_capacity);
        for it in items {
            let (lo, hi) = (it.bounds.lo[axis], it.bounds.hi[axis]);
            let (left, right) = if lo == pos && hi == pos {
                (split.planar_left, !split.planar_left)
            } else {
                (lo < pos, hi > pos)
            };
            if !(left && right) {
                sides[right as usize].push(*it);
                continue;
            }
            for (side, child_box) in sides.iter_mut().zip(&child_boxes) {
                let bounds = match clip {
                    Some(triangles) => clipped_bounds(&triangles[it.id as usize], child_box),
                    None => it.bounds.intersection(*child_box),
                };
                if !bounds.is_empty() {
                    side.push(Item { id: it.id, bounds });
                }
            }
        }
        sides
    };
    let items = &node.items;
    let mut sides = if items.len() <= MIN_ITEMS_PER_TASK {
        part(items, [split.n_left as usize, split.n_right as usize])
    } else {
        let chunks: Vec<[Side; 2]> = items
            .par_chunks(MIN_ITEMS_PER_TASK)
            .map(|chunk| part(chunk, [chunk.len() / 2; 2]))
            .collect();
        [0, 1].map(|k| Side {
            items: concat(chunks.iter().map(|c| &c[k].items[..]).collect()),
            extent: chunks.iter().fold(Aabb::EMPTY, |b, c| b.union(c[k].extent)),
        })
    };
    for side in &mut sides {
        side.extent = without_negative_zeros(side.extent);
    }
    sides
}

/// The parts one after the other, copied on all threads.
fn concat(parts: Vec<&[Item]>) -> Vec<Item> {
    let total = parts.iter().map(|p| p.len()).sum();
    let blank = Item {
        id: 0,
        bounds: Aabb::EMPTY,
    };
    let mut out = vec![blank; total];
    let mut targets = Vec::with_capacity(parts.len());
    let mut rest = &mut out[..];
    for part in &parts {
        let (target, tail) = rest.split_at_mut(part.len());
        targets.push(target);
        rest = tail;
    }
    targets
        .into_par_iter()
        .zip(parts)
        .for_each(|(target, part)| target.copy_from_slice(part));
    out
}

/// The box with `-0.0` made `0.0`: which of two zeros `min` returns depends on the order in
/// which threads combined boxes, and must not show in a split position.
fn without_negative_zeros(b: Aabb) -> Aabb {
    Aabb::new(b.lo + Vec3::splat(0.0), b.hi + Vec3::splat(0.0))
}

/// Builds every small node's exact SAH subtree in parallel, then places them in the tree in
/// the order of `small`. The references the budget leaves over (`slack`) are shared among
/// the small nodes in proportion to their primitives, so that no subtree depends on another.
fn build_small_nodes(
    triangles: &[Triangle],
    small: Vec<Pending>,
    options: &BuildOptions,
    slack: usize,
    built: &mut BuiltTree,
) {
    let small_prims: usize = small.iter().map(|n| n.items.len()).sum();
    let pieces: Vec<Piece> = small
        .par_iter()
        .map(|node| {
            let n = node.items.len();
            let ids: Vec<u32> = node.items.iter().map(|it| it.id).collect();
            let boxes: Vec<Aabb> = node.items.iter().map(|it| it.bounds).collect();
            let share = (slack as u128 * n as u128 / small_prims.max(1) as u128) as usize;
            let handed = Handed {
                prims: &ids,
                bounds: node.bounds,
                depth: node.depth,
                start: Start::Boxes(&boxes),
            };
            let budget = Budget {
                limit: n + share,
                shared: None,
            };
            sweep::handed_subtree(handed, triangles, budget, options).0
        })
        .collect();
    for (node, piece) in small.iter().zip(&pieces) {
        stitch::place(built, node.slot as usize, piece);
    }
}
