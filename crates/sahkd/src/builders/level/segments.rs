//! Flat, segmented arrays processed in fixed-size chunks.
//!
//! A level keeps each of its arrays (references, list entries) as one flat array in which every
//! node owns a contiguous segment, given by a `starts` array (`starts[k]..starts[k + 1]`).
//! Passes run over fixed-size chunks of the flat array, not over nodes, so that a level with one
//! huge node is as parallel as a level of many small ones. A pass that needs ranks within a
//! node (a stable partition, a running count) is a segmented scan in two parallel passes:
//! each chunk tallies itself, a serial scan over the (few) chunk tallies gives each chunk its
//! carry, and each chunk then runs again from its carry.

use rayon::prelude::*;
use std::marker::PhantomData;
use std::ops::Range;

/// Elements per chunk: large enough to amortise a task, small enough to balance two to eight
/// threads on a level of a million references.
pub(super) const CHUNK: usize = 1 << 14;

/// The chunks of a flat array of `len` elements, as a parallel iterator of (index, range).
pub(super) fn par_chunks(len: usize) -> impl IndexedParallelIterator<Item = (usize, Range<usize>)> {
    (0..len.div_ceil(CHUNK))
        .into_par_iter()
        .map(move |c| (c, c * CHUNK..((c + 1) * CHUNK).min(len)))
}

/// Walks the segments overlapping a range of a flat array, in order.
pub(super) struct Cursor<'a> {
    starts: &'a [u32],
    /// The node whose segment holds the current element.
    pub seg: usize,
    /// Its segment.
    pub begin: usize,
    pub end: usize,
}

impl<'a> Cursor<'a> {
    /// The cursor at element `i` (`i` must be below `starts.last()`).
    pub fn new(starts: &'a [u32], i: usize) -> Cursor<'a> {
        let seg = starts.partition_point(|&s| s as usize <= i) - 1;
        Cursor {
            starts,
            seg,
            begin: starts[seg] as usize,
            end: starts[seg + 1] as usize,
        }
    }

    /// Moves forward to the segment holding `i` (skipping empty ones).
    #[inline]
    pub fn at(&mut self, i: usize) {
        while i >= self.end {
            self.seg += 1;
            self.begin = self.end;
            self.end = self.starts[self.seg + 1] as usize;
        }
    }
}

/// Counts summed by a segmented scan. `restart` is what carries over a segment boundary:
/// per-segment counts start again from zero, running counts over the whole array go on.
pub(super) trait Tally: Copy + Default + Send + Sync {
    fn add(self, other: Self) -> Self;
    fn restart(self) -> Self;
}

/// The tally each chunk starts from, given each chunk's tally since its last segment start
/// (or over the whole chunk when it has none) and whether it has one. One more entry at the
/// end holds the tally after the last chunk.
pub(super) fn carries<T: Tally>(chunks: &[(T, bool)]) -> Vec<T> {
    let mut out = Vec::with_capacity(chunks.len() + 1);
    let mut carry = T::default();
    for &(tally, restarted) in chunks {
        out.push(carry);
        carry = if restarted { carry.restart() } else { carry }.add(tally);
    }
    out.push(carry);
    out
}

/// Indices per chunk of a parallel scan over nodes.
const NODE_CHUNK: usize = 4096;

/// Exclusive prefix sums over `0..n` computed in parallel: the first pass sums `count` per
/// chunk of indices; [`Prefix::visit`] then calls `visit(i, sum of count over 0..i)` for every
/// index, in parallel, from each chunk's sum before it.
pub(super) struct Prefix<T> {
    starts: Vec<T>,
    /// The sum over all indices.
    pub total: T,
}

impl<T: Tally> Prefix<T> {
    pub fn new(n: usize, count: impl Fn(usize) -> T + Sync) -> Self {
        let sums: Vec<T> = (0..n.div_ceil(NODE_CHUNK))
            .into_par_iter()
            .map(|c| {
                (c * NODE_CHUNK..((c + 1) * NODE_CHUNK).min(n))
                    .fold(T::default(), |t, i| t.add(count(i)))
            })
            .collect();
        let mut starts = Vec::with_capacity(sums.len());
        let mut total = T::default();
        for s in sums {
            starts.push(total);
            total = total.add(s);
        }
        Prefix { starts, total }
    }

    pub fn visit(
        &self,
        n: usize,
        count: impl Fn(usize) -> T + Sync,
        visit: impl Fn(usize, T) + Sync,
    ) {
        (0..self.starts.len()).into_par_iter().for_each(|c| {
            let mut t = self.starts[c];
            for i in c * NODE_CHUNK..((c + 1) * NODE_CHUNK).min(n) {
                visit(i, t);
                t = t.add(count(i));
            }
        });
    }
}

/// Shared write access to distinct elements of a slice from parallel tasks: the scatter of a
/// stable partition, where every destination is written by exactly one task.
pub(super) struct Scatter<'a, T> {
    ptr: *mut T,
    len: usize,
    _slice: PhantomData<&'a mut [T]>,
}

// Safety: a Scatter only hands out writes (and disjoint sub-slices) whose callers promise not
// to overlap; with that, sharing it between threads is like sharing `&mut` to disjoint parts.
unsafe impl<T: Send> Send for Scatter<'_, T> {}
unsafe impl<T: Send> Sync for Scatter<'_, T> {}

impl<'a, T> Scatter<'a, T> {
    pub fn new(slice: &'a mut [T]) -> Self {
        Scatter {
            ptr: slice.as_mut_ptr(),
            len: slice.len(),
            _slice: PhantomData,
        }
    }

    /// Over `v` followed by `extra` elements of its spare capacity (indices
    /// `0..v.len() + extra`); the caller writes every new element, then calls [`filled`].
    pub fn tail(v: &'a mut Vec<T>, extra: usize) -> Self {
        reserve(v, extra);
        Scatter {
            ptr: v.as_mut_ptr(),
            len: v.len() + extra,
            _slice: PhantomData,
        }
    }

    /// # Safety
    /// `i < len`, and no other task writes or reads element `i` during the pass.
    #[inline(always)]
    pub unsafe fn write(&self, i: usize, value: T) {
        debug_assert!(i < self.len, "scatter index {i} past {}", self.len);
        self.ptr.add(i).write(value)
    }

    /// The address of element `i` (which may be one past the end), for writes whose target is
    /// chosen without a branch.
    #[inline(always)]
    pub fn at(&self, i: usize) -> *mut T {
        self.ptr.wrapping_add(i)
    }

    /// # Safety
    /// `i < len`, element `i` is initialised, and no other task writes it during the pass.
    #[inline(always)]
    pub unsafe fn read(&self, i: usize) -> T
    where
        T: Copy,
    {
        debug_assert!(i < self.len);
        self.ptr.add(i).read()
    }

    /// # Safety
    /// `range` is in bounds and touched by no other task during the pass, and its elements
    /// are initialised.
    #[allow(clippy::mut_from_ref)]
    pub unsafe fn slice(&self, range: Range<usize>) -> &mut [T] {
        debug_assert!(range.start <= range.end && range.end <= self.len);
        std::slice::from_raw_parts_mut(self.ptr.add(range.start), range.len())
    }
}

/// Makes room for `extra` more elements. An empty vector that is too small is replaced rather
/// than grown (growing copies its whole old buffer), with some slack for the next level.
pub(super) fn reserve<T>(v: &mut Vec<T>, extra: usize) {
    if v.capacity() - v.len() < extra {
        if v.is_empty() {
            *v = Vec::with_capacity(extra + extra / 2);
        } else {
            v.reserve(extra);
        }
    }
}

/// Sets the length of a vector whose first `len` elements were all written, some through a
/// [`Scatter::tail`].
///
/// # Safety
/// Every element of `0..len` was written.
pub(super) unsafe fn filled<T: Copy>(v: &mut Vec<T>, len: usize) {
    debug_assert!(len <= v.capacity());
    v.set_len(len)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Clone, Copy, Default, Debug, PartialEq)]
    struct Count {
        in_segment: u32,
        running: u32,
    }

    impl Tally for Count {
        fn add(self, o: Self) -> Self {
            Count {
                in_segment: self.in_segment + o.in_segment,
                running: self.running + o.running,
            }
        }
        fn restart(self) -> Self {
            Count {
                in_segment: 0,
                running: self.running,
            }
        }
    }

    /// The two-pass chunked scan against a serial one, on segments that start, end and skip
    /// (empty segments) anywhere relative to chunk boundaries.
    #[test]
    fn chunked_segmented_scan_matches_serial() {
        let mut starts = vec![0u32];
        let sizes = [
            5,
            0,
            CHUNK as u32 + 3,
            1,
            0,
            0,
            2 * CHUNK as u32,
            7,
            CHUNK as u32 - 7,
            3,
        ];
        for s in sizes {
            starts.push(starts.last().unwrap() + s);
        }
        let len = *starts.last().unwrap() as usize;
        let value = |i: usize| (i % 3 == 0) as u32;
        // Serial reference: exclusive prefix within the segment, and over everything.
        let mut expected = Vec::new();
        let mut cur = Cursor::new(&starts, 0);
        let (mut seg_sum, mut all) = (0, 0);
        for i in 0..len {
            let before = cur.seg;
            cur.at(i);
            if cur.seg != before || i == 0 {
                seg_sum = 0;
            }
            expected.push((cur.seg, seg_sum, all));
            seg_sum += value(i);
            all += value(i);
        }
        let tallies: Vec<(Count, bool)> = par_chunks(len)
            .map(|(_, r)| {
                let mut cur = Cursor::new(&starts, r.start);
                let (mut t, mut restarted) = (Count::default(), false);
                for i in r {
                    cur.at(i);
                    if i == cur.begin {
                        t = t.restart();
                        restarted = true;
                    }
                    t = t.add(Count {
                        in_segment: value(i),
                        running: value(i),
                    });
                }
                (t, restarted)
            })
            .collect();
        let carry = carries(&tallies);
        let got: Vec<Vec<(usize, u32, u32)>> = par_chunks(len)
            .map(|(c, r)| {
                let mut cur = Cursor::new(&starts, r.start);
                let mut t = carry[c];
                let mut out = Vec::new();
                for i in r {
                    cur.at(i);
                    if i == cur.begin {
                        t = t.restart();
                    }
                    out.push((cur.seg, t.in_segment, t.running));
                    t = t.add(Count {
                        in_segment: value(i),
                        running: value(i),
                    });
                }
                out
            })
            .collect();
        assert_eq!(got.concat(), expected);
        assert_eq!(
            carry.last().unwrap().running,
            (0..len).map(value).sum::<u32>()
        );
    }
}
