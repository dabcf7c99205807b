//! The sweep's event lists: the builders' one [`Event`] (id = the primitive's index in the
//! sweep's numbering), made, merged and sorted.

use crate::builders::event::ID_BITS;
pub(crate) use crate::builders::event::{plane_bits, Event, END, PLANAR, START};
use crate::geometry::Aabb;

/// The event's primitive, as an index.
#[inline(always)]
pub(super) fn prim(e: Event) -> usize {
    e.id() as usize
}

/// Appends the events of `prim`'s box on `axis`: one planar event for a flat box, else a
/// start and an end.
#[inline]
pub(super) fn push_box(out: &mut Vec<Event>, axis: usize, b: &Aabb, prim: u32) {
    let (lo, hi) = (b.lo[axis], b.hi[axis]);
    if lo == hi {
        out.push(Event::new(lo, PLANAR, prim));
    } else {
        out.push(Event::new(lo, START, prim));
        out.push(Event::new(hi, END, prim));
    }
}

/// `list` made the events of `boxes` on `axis` (primitive `i` is `boxes[i]`), sorted;
/// `scratch` is the sort's spare buffer.
pub(super) fn sorted_of_boxes(
    list: &mut Vec<Event>,
    axis: usize,
    boxes: &[Aabb],
    scratch: &mut Vec<Event>,
) {
    list.reserve(boxes.len() * 2);
    for (i, b) in boxes.iter().enumerate() {
        push_box(list, axis, b, i as u32);
    }
    sort_prim_ordered(list, scratch);
}

/// Appends to `out` the merge of the sorted lists `a` and `b` (usually a few re-clipped
/// primitives). When `b` is short, runs of `a` are found by binary search and copied whole,
/// so the cost is a memcpy of `a` plus `O(|b| log |a|)`; otherwise a plain merge.
pub(super) fn merge_into(out: &mut Vec<Event>, mut a: &[Event], b: &[Event]) {
    out.reserve(a.len() + b.len());
    if b.len() * 16 > a.len() {
        let mut b = b;
        while let (Some(&x), Some(&y)) = (a.first(), b.first()) {
            if x < y {
                out.push(x);
                a = &a[1..];
            } else {
                out.push(y);
                b = &b[1..];
            }
        }
        out.extend_from_slice(a);
        out.extend_from_slice(b);
        return;
    }
    for &e in b {
        let run = a.partition_point(|&x| x < e);
        out.extend_from_slice(&a[..run]);
        out.push(e);
        a = &a[run..];
    }
    out.extend_from_slice(a);
}

/// Merges the sorted `b` into the sorted tail `list[start..]`, in place: from the back, so
/// that no event of `list` is overwritten before it is moved. As in [`merge_into`], runs of
/// `list` are found by binary search and moved whole when `b` is short; otherwise events
/// are moved one by one as the backward scan passes them (no call per run: the runs are
/// short).
pub(super) fn merge_in_place(list: &mut Vec<Event>, start: usize, b: &[Event]) {
    let mut i = list.len();
    let galloping = b.len() * 16 <= i - start;
    list.resize(list.len() + b.len(), Event::default());
    let mut w = list.len();
    for &e in b.iter().rev() {
        if galloping {
            let run_start = start + list[start..i].partition_point(|&x| x < e);
            list.copy_within(run_start..i, w - (i - run_start));
            w -= i - run_start;
            i = run_start;
        } else {
            while i > start && list[i - 1] > e {
                i -= 1;
                w -= 1;
                list[w] = list[i];
            }
        }
        w -= 1;
        list[w] = e;
    }
    debug_assert_eq!(w, i);
}

/// Sorts events whose primitive indices increase in input order, by position and kind only:
/// a stable LSD radix sort on the upper 34 bits then yields the full (position, kind, prim)
/// order. Counting passes cost less on a big root than a comparison sort's log n passes over
/// the whole key.
///
/// The digits cover only the bits in which the keys differ (the key minus the smallest): a
/// node's events span a small range of positions, so its keys share their upper bits and
/// often need one pass fewer, and the count arrays are only as wide as the digits.
pub(super) fn sort_prim_ordered(events: &mut Vec<Event>, scratch: &mut Vec<Event>) {
    if events.len() < 256 {
        events.sort_unstable();
        return;
    }
    let (lo, hi) = events.iter().fold((u64::MAX, 0), |(lo, hi), e| {
        let k = e.0 >> ID_BITS;
        (lo.min(k), hi.max(k))
    });
    let bits = u64::BITS - (hi - lo).leading_zeros();
    let passes = bits.div_ceil(11);
    if passes == 0 {
        return;
    }
    let width = bits.div_ceil(passes);
    let mask = (1u64 << width) - 1;
    let digit = |e: &Event, pass: u32| (((e.0 >> ID_BITS) - lo) >> (pass * width) & mask) as usize;
    scratch.resize(events.len(), Event::default());
    scratch.truncate(events.len());
    let mut offsets = [0u32; 1 << 11];
    for pass in 0..passes {
        let offsets = &mut offsets[..1 << width];
        offsets.fill(0);
        for e in events.iter() {
            offsets[digit(e, pass)] += 1;
        }
        let mut sum = 0;
        for o in offsets.iter_mut() {
            let c = *o;
            *o = sum;
            sum += c;
        }
        for e in events.iter() {
            let d = digit(e, pass);
            scratch[offsets[d] as usize] = *e;
            offsets[d] += 1;
        }
        std::mem::swap(events, scratch);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn radix_sort_agrees_with_comparison_sort() {
        let mut seed = 7u64;
        let mut next = move || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            seed >> 33
        };
        // Lengths on both sides of the comparison-sort cut; positions few and across zero
        // (kinds and prims decide many comparisons), in a narrow range far from zero (keys
        // sharing their upper bits: fewer passes), all equal (none), and over many exponents.
        for (len, spread) in [
            (5000, 0),
            (300, 1),
            (9000, 1),
            (2000, 2),
            (700, 3),
            (20_000, 3),
        ] {
            let mut events = Vec::new();
            for prim in 0..len as u32 {
                let r = next();
                let pos = match spread {
                    0 => (r % 40) as f32 - 20.0,
                    1 => 1000.0 + (r % 5000) as f32 / 4096.0,
                    2 => 3.5,
                    _ => {
                        f32::from_bits(0x3000_0000 + (r as u32 % 0x1800_0000))
                            * [1.0, -1.0][prim as usize % 2]
                    }
                };
                events.push(Event::new(pos, (next() % 3) as u32, prim));
            }
            let mut expected = events.clone();
            expected.sort_unstable();
            sort_prim_ordered(&mut events, &mut Vec::new());
            assert_eq!(events, expected, "{len} events, spread {spread}");
        }
    }

    #[test]
    fn merge_interleaves_short_and_long_lists() {
        for long in [10u32, 100] {
            let a: Vec<Event> = (0..long).map(|i| Event::new(i as f32, START, i)).collect();
            let b = vec![
                Event::new(-1.0, END, 200),
                Event::new(3.0, END, 201),
                Event::new(9.5, PLANAR, 202),
                Event::new(1e9, START, 203),
            ];
            let mut out = vec![Event::new(-5.0, START, 300)];
            merge_into(&mut out, &a, &b);
            let mut expected = [vec![Event::new(-5.0, START, 300)], a.clone(), b.clone()].concat();
            expected.sort_unstable();
            assert_eq!(out, expected);
            let mut in_place = vec![Event::new(-5.0, START, 300)];
            in_place.extend_from_slice(&a);
            merge_in_place(&mut in_place, 1, &b);
            assert_eq!(in_place, expected);
        }
    }
}
