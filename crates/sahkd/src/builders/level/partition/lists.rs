//! The sorted lists split into the children's segments: a stable partition, so everything
//! that is not a clipped straddler keeps its order, and the clipped straddlers sorted on their
//! own and merged in.

use super::{Clipped, Work, NONE};
use crate::builders::choice::Split;
use crate::builders::level::entries::ListEntry;
use crate::builders::level::segments::{Scatter, CHUNK};
use crate::builders::level::Level;
use rayon::prelude::*;

/// List segments from this size on are partitioned in parallel chunks.
pub(super) const PARALLEL_SPLIT: usize = 2 * CHUNK;

/// Stable partition of every split node's lists into its children's segments, with the
/// children's clipped straddlers (sorted on their own) merged in on the way. Parallel over
/// nodes; a node with a large list partitions it in parallel chunks and merges afterwards.
pub(super) fn partition_lists<E: ListEntry>(
    level: &Level<E>,
    splits: &[Option<Split>],
    next_starts: &[Vec<u32>; 3],
    work: &Work,
    sinks: &[Scatter<E>],
) {
    let slot_map = &work.slot_map;
    let regen = &work.regen;
    (0..level.nodes())
        .into_par_iter()
        .with_min_len(16)
        .for_each_init(
            || [Vec::new(), Vec::new()],
            |bufs: &mut [Vec<E>; 2], k| {
                if splits[k].is_none() {
                    return;
                }
                let first = work.left[k] as usize;
                let kids = [first, first + 1];
                if !work.lists[first] && !work.lists[first + 1] {
                    return;
                }
                for axis in 0..3 {
                    let starts = &level.list_starts[axis];
                    let seg = &level.lists[axis][starts[k] as usize..starts[k + 1] as usize];
                    let at = kids.map(|c| next_starts[axis][c] as usize);
                    for (side, buf) in bufs.iter_mut().enumerate() {
                        let c = kids[side];
                        let copies = &regen
                            [work.regen_starts[c] as usize..work.regen_starts[c + 1] as usize];
                        clipped_entries(copies, axis, buf);
                    }
                    let sink = &sinks[axis];
                    let clipped = [bufs[0].as_slice(), bufs[1].as_slice()];
                    if seg.len() >= PARALLEL_SPLIT {
                        split_chunks(seg, slot_map, at, clipped, sink);
                    } else {
                        split_merging(seg, slot_map, at, clipped, sink);
                    }
                }
            },
        );
}

/// A child's clipped straddlers' entries on `axis`, sorted, into `buf`.
fn clipped_entries<E: ListEntry>(copies: &[Clipped], axis: usize, buf: &mut Vec<E>) {
    buf.clear();
    for cp in copies {
        let (lo, hi) = (cp.bbox.lo[axis], cp.bbox.hi[axis]);
        let made = E::make(lo, hi, cp.slot);
        buf.push(made[0]);
        if E::count(lo, hi) == 2 {
            buf.push(made[1]);
        }
    }
    if buf.len() > 1 {
        buf.sort_unstable_by_key(|e| e.key());
    }
}

/// One node's list (or a piece of it), serially: each entry goes (with its new slot) to the
/// children `slot_map` sends it to, in order, from `at`, and each child's sorted clipped
/// entries are merged in (all of them: those after the last entry follow it).
#[inline]
fn split_merging<E: ListEntry>(
    seg: &[E],
    slot_map: &[[u32; 2]],
    at: [usize; 2],
    clipped: [&[E]; 2],
    sink: &Scatter<E>,
) {
    let Some(&first) = seg.first() else {
        for side in 0..2 {
            for (i, &e) in clipped[side].iter().enumerate() {
                // Safety: the child's segment on this axis belongs to this task.
                unsafe { sink.write(at[side] + i, e) };
            }
        }
        return;
    };
    // The side an entry goes to is unpredictable on the axes not split, so the writes are
    // chosen without a branch (a mispredicted branch per entry costs far more than a wasted store): an entry a
    // child does not get is written to a local instead, and the volatile write keeps the
    // compiler from turning the select back into a branch. Clipped entries are rare, so the
    // test for one due before the entry is well predicted.
    let mut trash = first;
    let mut w = at;
    let mut j = [0usize; 2];
    // Most segments have no clipped entries to merge: they take a loop without the test.
    if clipped[0].is_empty() && clipped[1].is_empty() {
        split_loop::<E, false>(seg, slot_map, clipped, sink, &mut w, &mut j, &mut trash);
    } else {
        split_loop::<E, true>(seg, slot_map, clipped, sink, &mut w, &mut j, &mut trash);
    }
    for side in 0..2 {
        for &e in &clipped[side][j[side]..] {
            unsafe { sink.write(w[side], e) };
            w[side] += 1;
        }
    }
}

/// The loop of [`split_merging`] over `seg`, from the places `w` and clipped entries `j`
/// (merging them only when `MERGE`).
#[inline(always)]
fn split_loop<E: ListEntry, const MERGE: bool>(
    seg: &[E],
    slot_map: &[[u32; 2]],
    clipped: [&[E]; 2],
    sink: &Scatter<E>,
    w: &mut [usize; 2],
    j: &mut [usize; 2],
    trash: &mut E,
) {
    let trash: *mut E = trash;
    for e in seg {
        let m = slot_map[e.slot() as usize];
        for side in 0..2 {
            let keep = m[side] != NONE;
            let moved = e.with_slot(m[side]);
            let new = clipped[side];
            while MERGE && j[side] < new.len() && new[j[side]].key() < moved.key() && keep {
                // Safety: the child's segment on this axis belongs to this task, and its
                // places are taken in order, once each.
                unsafe { sink.write(w[side], new[j[side]]) };
                w[side] += 1;
                j[side] += 1;
            }
            let dst = if keep { sink.at(w[side]) } else { trash };
            // Safety: as above, or the local.
            unsafe { dst.write_volatile(moved) };
            w[side] += keep as usize;
        }
    }
}

/// One large node's list in parallel chunks. Each chunk counts what it sends to each child
/// and the key (with the new slot) of the first such entry; exclusive sums over the chunks give
/// each chunk its first destinations, and each child's clipped entries are dealt to the chunks
/// by those first keys (a chunk takes the clipped entries from its first key on, up to the
/// next chunk's), so that every chunk merges its share while it writes.
fn split_chunks<E: ListEntry>(
    seg: &[E],
    slot_map: &[[u32; 2]],
    at: [usize; 2],
    clipped: [&[E]; 2],
    sink: &Scatter<E>,
) {
    let firsts: Vec<([usize; 2], [Option<u64>; 2])> = seg
        .par_chunks(CHUNK)
        .map(|chunk| {
            let mut n = [0usize; 2];
            let mut first = [None; 2];
            for e in chunk {
                let m = slot_map[e.slot() as usize];
                for side in 0..2 {
                    if m[side] != NONE {
                        if n[side] == 0 {
                            first[side] = Some(e.with_slot(m[side]).key());
                        }
                        n[side] += 1;
                    }
                }
            }
            (n, first)
        })
        .collect();
    // Per chunk and side: first destination and its share of the clipped entries.
    let mut plan = vec![[(0usize, 0usize, 0usize); 2]; firsts.len()];
    for side in 0..2 {
        let new = clipped[side];
        let mut kept = 0;
        let mut last: Option<usize> = None;
        for (c, (n, first)) in firsts.iter().enumerate() {
            if let Some(key) = first[side] {
                let from = if last.is_none() {
                    0
                } else {
                    new.partition_point(|e| e.key() < key)
                };
                if let Some(l) = last {
                    plan[l][side].2 = from;
                }
                plan[c][side] = (at[side] + kept + from, from, new.len());
                last = Some(c);
            }
            kept += n[side];
        }
        if last.is_none() {
            // Nothing kept on this side: the clipped entries are the whole segment.
            for (i, &e) in new.iter().enumerate() {
                // Safety: the child's segment on this axis is this task's.
                unsafe { sink.write(at[side] + i, e) };
            }
        }
    }
    seg.par_chunks(CHUNK).enumerate().for_each(|(c, chunk)| {
        let [(l, l0, l1), (r, r0, r1)] = plan[c];
        // Safety: chunk c's destinations are its exclusive prefix of the child's segment,
        // disjoint from every other chunk's.
        split_merging(
            chunk,
            slot_map,
            [l, r],
            [&clipped[0][l0..l1], &clipped[1][r0..r1]],
            sink,
        );
    });
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::builders::level::entries::Event;
    use crate::builders::level::Lcg;

    /// A parent list, where each reference goes (order-preserving new slots per child, some
    /// dropped, some to both), and clipped entries for each child; the expected children are
    /// the sorted unions.
    type Case = (Vec<Event>, Vec<[u32; 2]>, [Vec<Event>; 2], [Vec<Event>; 2]);

    fn case(n: u32, seed: u64) -> Case {
        let mut rng = Lcg(seed);
        let events_of = |slot: u32, rng: &mut Lcg| {
            let lo = rng.next(n / 3 + 1) as f32;
            let hi = if rng.next(4) == 0 {
                lo
            } else {
                lo + rng.next(50) as f32
            };
            let made = Event::make(lo, hi, slot);
            made[..Event::count(lo, hi) as usize].to_vec()
        };
        let mut parent: Vec<Event> = Vec::new();
        let mut slot_map = Vec::new();
        let mut clipped: [Vec<Event>; 2] = Default::default();
        let mut expected: [Vec<Event>; 2] = Default::default();
        let mut next = [0u32; 2];
        for slot in 0..n {
            let evs = events_of(slot, &mut rng);
            parent.extend(&evs);
            let mut m = [NONE; 2];
            let goes = rng.next(4); // 0 left, 1 right, 2 both, 3 neither
            for side in 0..2 {
                if goes == side as u32 || goes == 2 {
                    m[side] = next[side];
                    expected[side].extend(evs.iter().map(|e| e.with_slot(next[side])));
                    next[side] += 1;
                }
                if rng.next(5) == 0 {
                    let evs = events_of(next[side], &mut rng);
                    clipped[side].extend(&evs);
                    expected[side].extend(&evs);
                    next[side] += 1;
                }
            }
            slot_map.push(m);
        }
        parent.sort_by_key(|e| e.key());
        for side in 0..2 {
            clipped[side].sort_by_key(|e| e.key());
            expected[side].sort_by_key(|e| e.key());
        }
        (parent, slot_map, clipped, expected)
    }

    #[test]
    fn chunked_and_serial_list_partitions_equal_sorted_unions() {
        for (n, seed) in [
            (10u32, 1u64),
            (1000, 2),
            (3 * CHUNK as u32, 3),
            (5 * CHUNK as u32, 4),
        ] {
            let (parent, slot_map, clipped, expected) = case(n, seed);
            let (l, r) = (expected[0].len(), expected[1].len());
            for chunked in [false, true] {
                let mut out = vec![Event(0); l + r];
                let sink = Scatter::new(&mut out);
                let clipped = [clipped[0].as_slice(), clipped[1].as_slice()];
                if chunked {
                    split_chunks(&parent, &slot_map, [0, l], clipped, &sink);
                } else {
                    split_merging(&parent, &slot_map, [0, l], clipped, &sink);
                }
                assert_eq!(
                    &out[..l],
                    &expected[0][..],
                    "n {n}, chunked {chunked}: left"
                );
                assert_eq!(
                    &out[l..],
                    &expected[1][..],
                    "n {n}, chunked {chunked}: right"
                );
            }
        }
    }
}
