//! The exact SAH search of one node: one sweep per axis over its sorted events.
//!
//! Walking the events in order, at each distinct position `p` the running counts are exactly
//! the shared semantics' `L = #(lo < p)` and `R = #(hi > p)`: starts and planars seen before
//! `p` are the primitives with `lo < p`; `R` starts at `n` and drops by the ends and planars
//! at or before `p`. The planars at `p` are `P`.

use super::events::{self, plane_bits, Event, END, PLANAR, START};
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
    // Candidates lie strictly inside the node (compare keys, not floats), and the events are
    // sorted: those at or below the node's low face only count, those at or beyond its high
    // face do not matter, and no test of the range is left in the loop over groups (it
    // mispredicted on every group crossing a face). Few events lie outside a node, so plain
    // scans find them (a binary search mispredicts about half its steps).
    let (lo_key, hi_key) = (plane_bits(node.lo[axis]), plane_bits(node.hi[axis]));
    let (mut below, mut above) = (0u32, n);
    let mut first = 0;
    while let Some(e) = events.get(first).filter(|e| e.pos_bits() <= lo_key) {
        below += (e.kind() != END) as u32;
        above -= (e.kind() != START) as u32;
        first += 1;
    }
    let mut last = events.len();
    while last > first && events[last - 1].pos_bits() >= hi_key {
        last -= 1;
    }
    // The axis's cheapest plane, kept by selects rather than a branch per improvement (the
    // costs along an axis fall and rise unevenly, so that branch mispredicted often): the
    // first of equal costs, which is the one ranking's choice, since positions increase
    // here. Its split is priced again from the counts kept, the same bits.
    let (mut cheapest, mut at) = (f32::INFINITY, (0u32, 0u32, 0u32, 0u32));
    let inside = &events[first..last];
    let mut i = 0;
    while i < inside.len() {
        let key = inside[i].pos_bits();
        let (count, ends, planar) = group(&inside[i..], key);
        i += count;
        let starts = count as u32 - ends - planar;
        above -= ends + planar;
        let cost = priced(&splits, axis, unordered(key), below, above, planar).cost;
        // Masks, not `if`: the compiler made a branch of the plain select.
        let keep = ((cost < cheapest) as u32).wrapping_neg();
        let pick = |new: u32, old: u32| (new & keep) | (old & !keep);
        cheapest = cost.min(cheapest);
        at = (
            pick(key, at.0),
            pick(below, at.1),
            pick(above, at.2),
            pick(planar, at.3),
        );
        below += starts + planar;
    }
    if cheapest < f32::INFINITY {
        let (key, below, above, planar) = at;
        let candidate = priced(&splits, axis, unordered(key), below, above, planar);
        if candidate.beats(best) {
            *best = Some(candidate);
        }
    }
}

/// The events at the head of `events` whose position is `key` (the first one's): how many,
/// and how many of them are ends and planars.
///
/// A position's group is mostly one to four events, and a loop stopping at its end
/// mispredicted that end about once per group (over 40 % of a build's mispredicted
/// branches). Here eight events are compared at once ([`masks8`]) and the group is the run of
/// matches from the first. Within a group the events are sorted by kind, ends first, then
/// planars, then starts (`END < PLANAR < START`), so the ends and planars are runs too.
#[inline(always)]
fn group(events: &[Event], key: u32) -> (usize, u32, u32) {
    let (mut count, mut ends, mut ends_planars) = (0, 0, 0);
    while let Some(chunk) = events.get(count..count + 8) {
        let (same, end, end_or_flat) = masks8(chunk.try_into().expect("eight events"), key);
        let run = same.trailing_ones();
        ends += end.trailing_ones().min(run);
        ends_planars += end_or_flat.trailing_ones().min(run);
        count += run as usize;
        if run < 8 {
            return (count, ends, ends_planars - ends);
        }
    }
    let (mut planar, rest) = (ends_planars - ends, &events[count..]);
    for e in rest.iter().take_while(|e| e.pos_bits() == key) {
        let k = e.kind();
        ends += (k == END) as u32;
        planar += (k == PLANAR) as u32;
        count += 1;
    }
    (count, ends, planar)
}

/// Bit `j` set where event `j` has position `key`, is an end, is an end or a planar.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn masks8(chunk: &[Event; 8], key: u32) -> (u32, u32, u32) {
    use std::arch::x86_64::*;
    const _: () = assert!(END == 0 && PLANAR == 1 && START == 2);
    const _: () = assert!(std::mem::size_of::<Event>() == 8);
    // SAFETY: SSE2 is part of x86_64; the loads read the 64 bytes of `chunk` (unaligned).
    unsafe {
        let p = chunk.as_ptr() as *const __m128i;
        let key = _mm_set1_epi32(key as i32);
        let mut masks = [0u32; 3];
        for half in 0..2 {
            let a = _mm_castsi128_ps(_mm_loadu_si128(p.add(2 * half)));
            let b = _mm_castsi128_ps(_mm_loadu_si128(p.add(2 * half + 1)));
            // Four events' upper words (positions) and lower words (kind in the top two bits).
            let pos = _mm_castps_si128(_mm_shuffle_ps::<0b11_01_11_01>(a, b));
            let low = _mm_castps_si128(_mm_shuffle_ps::<0b10_00_10_00>(a, b));
            let kind = _mm_srli_epi32::<30>(low);
            let bits = |m: __m128i| (_mm_movemask_ps(_mm_castsi128_ps(m)) as u32) << (4 * half);
            masks[0] |= bits(_mm_cmpeq_epi32(pos, key));
            masks[1] |= bits(_mm_cmpeq_epi32(kind, _mm_setzero_si128()));
            masks[2] |= bits(_mm_cmplt_epi32(kind, _mm_set1_epi32(2)));
        }
        (masks[0], masks[1], masks[2])
    }
}

#[cfg(not(target_arch = "x86_64"))]
#[inline(always)]
fn masks8(chunk: &[Event; 8], key: u32) -> (u32, u32, u32) {
    let mut masks = [0u32; 3];
    for (j, e) in chunk.iter().enumerate() {
        masks[0] |= ((e.pos_bits() == key) as u32) << j;
        masks[1] |= ((e.kind() == END) as u32) << j;
        masks[2] |= ((e.kind() < START) as u32) << j;
    }
    (masks[0], masks[1], masks[2])
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
    fn groups_are_counted_as_one_event_at_a_time_counts_them() {
        // Runs of every length from 1 to 20 at one position, of mixed kinds in the sweep's
        // order, then one event elsewhere, seen from every start and with every tail cut.
        let kinds = [END, END, PLANAR, START, START, START, END, PLANAR];
        for len in 1..=20usize {
            let mut list: Vec<Event> = (0..len as u32)
                .map(|i| Event::new(2.0, kinds[(i as usize * 5 + len) % 8], i))
                .collect();
            list.push(Event::new(3.0, START, 99));
            list.sort_unstable();
            for from in 0..list.len() {
                for to in from + 1..=list.len() {
                    let events = &list[from..to];
                    let key = events[0].pos_bits();
                    let run: Vec<&Event> =
                        events.iter().take_while(|e| e.pos_bits() == key).collect();
                    let count = |k| run.iter().filter(|e| e.kind() == k).count() as u32;
                    let want = (run.len(), count(END), count(PLANAR));
                    assert_eq!(group(events, key), want, "run {len}, events {from}..{to}");
                }
            }
        }
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
