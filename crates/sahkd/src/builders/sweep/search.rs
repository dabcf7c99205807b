//! The exact SAH search of one node: one sweep per axis over its sorted events.
//!
//! Walking the events in order, at each distinct position `p` the running counts are exactly
//! the shared semantics' `L = #(lo < p)` and `R = #(hi > p)`: starts and planars seen before
//! `p` are the primitives with `lo < p`; `R` starts at `n` and drops by the ends and planars
//! at or before `p`. The planars at `p` are `P`.

use super::events::{self, plane_bits, Event, END, PLANAR};
pub(super) use crate::builders::choice::Split;
use crate::builders::event::unordered;
use crate::builders::Axes;
use crate::cost::{CostModel, SplitPricer};
use crate::geometry::Aabb;

/// The best split of a node of `n` primitives whose events on each axis are `events`, or
/// `None` when no candidate plane lies strictly inside `node`.
pub(super) fn best_split(
    events: [&[Event]; 3],
    node: &Aabb,
    n: u32,
    axes: Axes,
    cost: &CostModel,
) -> Option<Split> {
    let mut best = None;
    match axes {
        Axes::All => {
            for (axis, list) in events.iter().enumerate() {
                sweep(list, axis, node, n, cost, &mut best);
            }
        }
        Axes::Longest => {
            let axis = node.longest_axis();
            sweep(events[axis], axis, node, n, cost, &mut best);
        }
    }
    best
}

/// The split [`best_split`] finds for a node whose references have `boxes`, from events made
/// and sorted here for the axes it prices: the sweep's choice for a node that is not on a
/// sweep's stack (the binned builder's nodes below its threshold, built at once).
pub(super) fn best_split_of_boxes(
    boxes: &[Aabb],
    node: &Aabb,
    axes: Axes,
    cost: &CostModel,
) -> Option<Split> {
    let mut lists: [Vec<Event>; 3] = Default::default();
    let mut scratch = Vec::new();
    for (axis, list) in lists.iter_mut().enumerate() {
        if axes == Axes::All || axis == node.longest_axis() {
            events::sorted_of_boxes(list, axis, boxes, &mut scratch);
        }
    }
    let events = [&lists[0][..], &lists[1][..], &lists[2][..]];
    best_split(events, node, boxes.len() as u32, axes, cost)
}

/// Sweeps one axis, with the axis a constant so that the cost's index arithmetic folds.
fn sweep(
    events: &[Event],
    axis: usize,
    node: &Aabb,
    n: u32,
    cost: &CostModel,
    best: &mut Option<Split>,
) {
    match axis {
        0 => sweep_axis::<0>(events, node, n, cost, best),
        1 => sweep_axis::<1>(events, node, n, cost, best),
        _ => sweep_axis::<2>(events, node, n, cost, best),
    }
}

fn sweep_axis<const AXIS: usize>(
    events: &[Event],
    node: &Aabb,
    n: u32,
    cost: &CostModel,
    best: &mut Option<Split>,
) {
    let axis = AXIS;
    // What the price depends on only through the node, computed once per sweep, not per
    // candidate (the same bits: `splits_of` is what `split_cost` calls).
    let splits = cost.splits_of(node, axis);
    // Candidates must lie strictly inside the node; compare keys, not floats.
    let (lo_key, hi_key) = (plane_bits(node.lo[axis]), plane_bits(node.hi[axis]));
    let (mut below, mut above) = (0u32, n);
    let mut i = 0;
    while i < events.len() {
        let key = events[i].pos_bits();
        // Ends (low half) and planars (high half) of the group, counted in one register so
        // that the hot loop does no stores; starts are the rest of the group.
        let group_start = i;
        let mut packed = 0u64;
        while i < events.len() && events[i].pos_bits() == key {
            let k = events[i].kind();
            packed += (k == END) as u64 | ((k == PLANAR) as u64) << 32;
            i += 1;
        }
        let (ends, planar) = (packed as u32, (packed >> 32) as u32);
        let starts = (i - group_start) as u32 - ends - planar;
        above -= ends + planar;
        if key > lo_key && key < hi_key {
            let candidate = priced(&splits, axis, unordered(key), below, above, planar);
            if candidate.beats(best) {
                *best = Some(candidate);
            }
        }
        below += starts + planar;
    }
}

/// The plane at `pos` with `below` primitives starting left of it, `above` ending right of
/// it and `planar` lying in it, priced by the node's `splits` on `axis` with the planar ones
/// on the cheaper side (the left on a tie): the one pricing of the exact and the binned
/// searches.
#[inline(always)]
pub(super) fn priced(
    splits: &SplitPricer,
    axis: usize,
    pos: f32,
    below: u32,
    above: u32,
    planar: u32,
) -> Split {
    if planar == 0 {
        Split {
            axis,
            pos,
            cost: splits.cost(pos, below, above),
            planar_left: true,
            n_left: below,
            n_right: above,
        }
    } else {
        let left = splits.cost(pos, below + planar, above);
        let right = splits.cost(pos, below, above + planar);
        let planar_left = left <= right;
        Split {
            axis,
            pos,
            cost: if planar_left { left } else { right },
            planar_left,
            n_left: below + if planar_left { planar } else { 0 },
            n_right: above + if planar_left { 0 } else { planar },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::events::{push_box, sort_prim_ordered};
    use super::super::testing::{counts_at, grid_rounds};
    use super::*;
    use crate::geometry::Vec3;

    /// Direct O(n^2) search over every candidate with the shared semantics.
    fn brute(boxes: &[Aabb], node: &Aabb, axes: Axes, cost: &CostModel) -> Option<Split> {
        let axis_list: Vec<usize> = match axes {
            Axes::All => vec![0, 1, 2],
            Axes::Longest => vec![node.longest_axis()],
        };
        let mut best: Option<Split> = None;
        for &a in &axis_list {
            for b in boxes {
                for p in [b.lo[a], b.hi[a]] {
                    if !(p > node.lo[a] && p < node.hi[a]) {
                        continue;
                    }
                    let (l, r, pl) = counts_at(boxes, a, p);
                    let cl = cost.split_cost(node, a, p, l + pl, r);
                    let cr = cost.split_cost(node, a, p, l, r + pl);
                    let (c, nl, nr) = if cl <= cr {
                        (cl, l + pl, r)
                    } else {
                        (cr, l, r + pl)
                    };
                    let better = match &best {
                        None => c.is_finite(),
                        Some(o) => (c, p, a) < (o.cost, o.pos, o.axis),
                    };
                    if better {
                        best = Some(Split {
                            axis: a,
                            pos: p,
                            cost: c,
                            planar_left: cl <= cr,
                            n_left: nl,
                            n_right: nr,
                        });
                    }
                }
            }
        }
        best
    }

    #[test]
    fn sweep_matches_brute_force_search() {
        let cost = CostModel::default();
        // Coordinates on a coarse grid, so that coincident and planar events abound.
        for (round, boxes) in grid_rounds(99, 60, (9, 5, 0.5, f32::INFINITY)) {
            let n = boxes.len();
            let bounds = boxes.iter().fold(Aabb::EMPTY, |b, &x| b.union(x));
            // Sometimes a node box tighter than the primitives, as with clip off below the root.
            let node = if round % 3 == 0 {
                Aabb::new(bounds.lo + Vec3::splat(0.5), bounds.hi)
            } else {
                bounds
            };
            let mut lists: [Vec<Event>; 3] = Default::default();
            for (a, list) in lists.iter_mut().enumerate() {
                for (i, b) in boxes.iter().enumerate() {
                    push_box(list, a, b, i as u32);
                }
                sort_prim_ordered(list, &mut Vec::new());
            }
            for axes in [Axes::All, Axes::Longest] {
                let got = best_split(
                    [&lists[0], &lists[1], &lists[2]],
                    &node,
                    n as u32,
                    axes,
                    &cost,
                );
                let want = brute(&boxes, &node, axes, &cost);
                assert_eq!(got, want, "round {round}, {axes:?}, boxes {boxes:?}");
            }
        }
    }
}
