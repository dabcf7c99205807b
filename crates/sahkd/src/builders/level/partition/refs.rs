//! Where each reference of a split node goes: its sides (from the split axis's list, or its
//! box in the naive build), its clipped boxes when it straddles, per-node tallies by a
//! segmented scan, and the next level's reference arrays laid out and filled.

use super::lists::PARALLEL_SPLIT;
use super::{Clipped, Work, NONE};
use crate::builders::choice::Split;
use crate::builders::level::entries::ListEntry;
use crate::builders::level::segments::{
    carries, filled, par_chunks, Cursor, Prefix, Scatter, Tally, CHUNK,
};
use crate::builders::level::{Context, Level};
use crate::clip::clipped_bounds;
use crate::geometry::Aabb;
use rayon::prelude::*;

/// Per node of the level, what its references add to each child (0 = left, 1 = right).
#[derive(Clone, Copy, Default, Debug)]
pub(super) struct RefTally {
    refs: [u32; 2],
    /// List entries per child and axis.
    entries: [[u32; 3]; 2],
    /// Clipped straddlers per child.
    copies: [u32; 2],
}

impl Tally for RefTally {
    fn add(self, o: Self) -> Self {
        let mut t = self;
        for side in 0..2 {
            t.refs[side] += o.refs[side];
            t.copies[side] += o.copies[side];
            for axis in 0..3 {
                t.entries[side][axis] += o.entries[side][axis];
            }
        }
        t
    }
    fn restart(self) -> Self {
        RefTally::default()
    }
}

impl RefTally {
    /// Adds `n` (0 or 1) references with `entries` list entries per axis to a child.
    #[inline(always)]
    fn add_ref(&mut self, side: usize, entries: [u32; 3], n: u32) {
        self.refs[side] += n;
        for (sum, e) in self.entries[side].iter_mut().zip(entries) {
            *sum += n * e;
        }
    }
}

/// The shared partition rule, as the children a box goes to (left, right): in the plane ->
/// the chosen side; `hi <= p` -> left; `lo >= p` -> right; otherwise both. Computed without
/// branches: a node's references come in no order along the split axis, so a branch on the
/// side would be mispredicted half the time.
#[inline(always)]
fn sides(b: &Aabb, s: &Split) -> [bool; 2] {
    let (lo, hi) = (b.lo[s.axis], b.hi[s.axis]);
    let in_plane = (lo == s.pos) & (hi == s.pos);
    [
        (lo < s.pos) | (in_plane & s.planar_left),
        (hi > s.pos) | (in_plane & !s.planar_left),
    ]
}

/// Bit a set when the box is flat (`lo == hi`) on axis a.
#[inline]
pub(crate) fn flat_mask(b: &Aabb) -> u8 {
    (0..3).fold(0, |m, a| m | ((b.lo[a] == b.hi[a]) as u8) << a)
}

/// List entries per axis of a reference whose box is flat on the axes of `flat`.
#[inline(always)]
fn entries_of<E: ListEntry>(flat: u8) -> [u32; 3] {
    [0, 1, 2].map(|a| E::count_flat(flat >> a & 1 == 1))
}

/// The children a reference of a split node goes to, and its list entries per axis: from the
/// marks and flat bits of a sorted build, or from the box of the naive one.
#[inline(always)]
fn shape<E: ListEntry>(
    level: &Level<E>,
    go: &[bool],
    slot: usize,
    s: &Split,
) -> ([bool; 2], [u32; 3]) {
    if level.sorted {
        (
            [go[2 * slot], go[2 * slot + 1]],
            entries_of::<E>(level.flat[slot]),
        )
    } else {
        let b = &level.ref_boxes[slot];
        (sides(b, s), [0; 3])
    }
}

/// Marks, for every reference of every split node, the children it goes to, from the entries
/// of the node's list on the split axis (sorted builds). Parallel over nodes, and over chunks
/// of a large node's list.
pub(super) fn mark_sides<E: ListEntry>(
    level: &Level<E>,
    splits: &[Option<Split>],
    go: &mut Vec<bool>,
) {
    go.clear();
    go.resize(2 * level.prims.len(), false);
    let sink = Scatter::new(go);
    (0..level.nodes())
        .into_par_iter()
        .with_min_len(16)
        .for_each(|k| {
            let Some(s) = &splits[k] else { return };
            let starts = &level.list_starts[s.axis];
            let seg = &level.lists[s.axis][starts[k] as usize..starts[k + 1] as usize];
            let mark = |e: &E| {
                let known = e.sides(s.pos, s.planar_left);
                for (side, g) in known.into_iter().enumerate() {
                    if let Some(g) = g {
                        // Safety: each (slot, side) is told by exactly one entry of the list.
                        unsafe { sink.write(2 * e.slot() as usize + side, g) };
                    }
                }
            };
            if seg.len() >= PARALLEL_SPLIT {
                seg.par_chunks(CHUNK).for_each(|c| c.iter().for_each(mark));
            } else {
                seg.iter().for_each(mark);
            }
        });
}

/// What the first pass over one chunk of references found.
#[derive(Default)]
pub(super) struct ChunkSides {
    /// Since the chunk's last segment start (or over all of it).
    tally: RefTally,
    restarted: bool,
    /// Clipped boxes (left, right) of the chunk's straddlers, in order, for the second pass.
    clipped: Vec<[Aabb; 2]>,
    /// Nodes whose segment ends in the chunk, with their tally over the chunk's part of it and
    /// whether it also starts in the chunk.
    ends: Vec<(usize, RefTally, bool)>,
}

/// First pass over the references: sides, clipping, and tallies per chunk.
pub(super) fn classify<E: ListEntry>(
    level: &Level<E>,
    splits: &[Option<Split>],
    ctx: &Context,
    go: &[bool],
) -> Vec<ChunkSides> {
    par_chunks(level.prims.len())
        .map(|(_, r)| {
            let mut chunk = ChunkSides::default();
            let mut cur = Cursor::new(&level.ref_starts, r.start);
            let mut i = r.start;
            while i < r.end {
                cur.at(i);
                let (k, stop) = (cur.seg, cur.end.min(r.end));
                let mut t = RefTally::default();
                if let Some(s) = &splits[k] {
                    let halves = level.boxes[k].split(s.axis, s.pos);
                    for slot in i..stop {
                        let (go, entries) = shape(level, go, slot, s);
                        if go[0] & go[1] & ctx.clip {
                            let tri = &ctx.triangles[level.prims[slot] as usize];
                            let c = [
                                clipped_bounds(tri, &halves.0),
                                clipped_bounds(tri, &halves.1),
                            ];
                            for (side, b) in c.iter().enumerate() {
                                if !b.is_empty() {
                                    t.add_ref(side, entries_of::<E>(flat_mask(b)), 1);
                                    t.copies[side] += 1;
                                }
                            }
                            chunk.clipped.push(c);
                        } else {
                            t.add_ref(0, entries, go[0] as u32);
                            t.add_ref(1, entries, go[1] as u32);
                        }
                    }
                }
                let started = i == cur.begin;
                if cur.end <= r.end {
                    chunk.ends.push((k, t, started));
                }
                if started {
                    chunk.tally = t;
                    chunk.restarted = true;
                } else {
                    chunk.tally = chunk.tally.add(t);
                }
                i = stop;
            }
            chunk
        })
        .collect()
}

/// Every node's tally (what it sends to each child) from the chunks' partial tallies; returns
/// each chunk's carry, the tally of its first segment's part before the chunk.
pub(super) fn node_totals(
    chunks: &[ChunkSides],
    nodes: usize,
    totals: &mut Vec<RefTally>,
) -> Vec<RefTally> {
    let tallies: Vec<(RefTally, bool)> = chunks.iter().map(|c| (c.tally, c.restarted)).collect();
    let carry = carries(&tallies);
    totals.clear();
    totals.resize(nodes, RefTally::default());
    let sink = Scatter::new(totals);
    chunks.par_iter().enumerate().for_each(|(c, chunk)| {
        for &(k, t, started) in &chunk.ends {
            // Safety: a segment ends in one chunk only.
            unsafe { sink.write(k, if started { t } else { carry[c].add(t) }) };
        }
    });
    carry
}

/// Sizes of a node's two children in the next level's arrays.
#[derive(Clone, Copy, Default)]
struct Sizes {
    refs: u32,
    entries: [u32; 3],
    copies: u32,
}

impl Tally for Sizes {
    fn add(self, o: Self) -> Self {
        Sizes {
            refs: self.refs + o.refs,
            entries: [0, 1, 2].map(|a| self.entries[a] + o.entries[a]),
            copies: self.copies + o.copies,
        }
    }
    fn restart(self) -> Self {
        self
    }
}

/// The next level's nodes: boxes and the segments of every array (exclusive scans over the
/// children's sizes, the paper's formulas (5) and (6)), in parallel over the level's nodes.
pub(super) fn lay_out<E: ListEntry>(
    level: &Level<E>,
    splits: &[Option<Split>],
    ctx: &Context,
    next: &mut Level<E>,
    work: &mut Work,
) {
    let depth = level.depth + 1;
    next.depth = depth;
    next.sorted = level.sorted;
    let sorted = level.sorted;
    let listed = |n: u32| sorted && !(n <= ctx.cost.leaf_size || depth >= ctx.max_depth);
    let child = |k: usize, side: usize| -> Sizes {
        let t = &work.totals[k];
        let n = t.refs[side];
        let l = listed(n);
        Sizes {
            refs: n,
            entries: [0, 1, 2].map(|a| if l { t.entries[side][a] } else { 0 }),
            copies: if l && ctx.clip { t.copies[side] } else { 0 },
        }
    };
    let count = |k: usize| match splits[k] {
        Some(_) => child(k, 0).add(child(k, 1)),
        None => Sizes::default(),
    };
    let scan = Prefix::new(level.nodes(), count);
    let children = 2 * splits.iter().filter(|s| s.is_some()).count();
    next.boxes.clear();
    next.ref_starts.clear();
    work.lists.clear();
    work.regen_starts.clear();
    let boxes = Scatter::tail(&mut next.boxes, children);
    let ref_starts = Scatter::tail(&mut next.ref_starts, children + 1);
    let lists = Scatter::tail(&mut work.lists, children);
    let regen_starts = Scatter::tail(&mut work.regen_starts, children + 1);
    let [s0, s1, s2] = &mut next.list_starts;
    let list_len = if sorted { children + 1 } else { 0 };
    let list_starts = [s0, s1, s2].map(|s| {
        s.clear();
        Scatter::tail(s, list_len)
    });
    let left = &work.left;
    // Safety (all writes): each child index once, and the totals at index `children`.
    scan.visit(level.nodes(), count, |k, before| unsafe {
        let Some(s) = splits[k] else { return };
        let first = left[k] as usize;
        let (l, r) = level.boxes[k].split(s.axis, s.pos);
        boxes.write(first, l);
        boxes.write(first + 1, r);
        let mut at = before;
        for side in 0..2 {
            let c = first + side;
            let size = child(k, side);
            ref_starts.write(c, at.refs);
            regen_starts.write(c, at.copies);
            lists.write(c, listed(size.refs));
            if sorted {
                for (starts, &e) in list_starts.iter().zip(&at.entries) {
                    starts.write(c, e);
                }
            }
            at = at.add(size);
        }
    });
    let total = scan.total;
    unsafe {
        ref_starts.write(children, total.refs);
        regen_starts.write(children, total.copies);
        if sorted {
            for (starts, &e) in list_starts.iter().zip(&total.entries) {
                starts.write(children, e);
            }
        }
        filled(&mut next.boxes, children);
        filled(&mut next.ref_starts, children + 1);
        filled(&mut work.lists, children);
        filled(&mut work.regen_starts, children + 1);
        for s in &mut next.list_starts {
            filled(s, list_len);
        }
    }
}

/// Second pass over the references: each goes to its children's segments; `slot_map` records
/// where (for the lists), and clipped straddlers are collected for the children's lists.
#[allow(clippy::too_many_arguments)]
pub(super) fn scatter_refs<E: ListEntry>(
    level: &Level<E>,
    splits: &[Option<Split>],
    ctx: &Context,
    chunks: &[ChunkSides],
    carry: &[RefTally],
    next: &mut Level<E>,
    work: &mut Work,
) {
    let total = *next.ref_starts.last().unwrap() as usize;
    let n_refs = level.prims.len();
    next.prims.clear();
    next.flat.clear();
    next.ref_boxes.clear();
    let sorted = level.sorted;
    let prims = Scatter::tail(&mut next.prims, total);
    let flat = Scatter::tail(&mut next.flat, if sorted { total } else { 0 });
    let boxes = Scatter::tail(&mut next.ref_boxes, if sorted { 0 } else { total });
    // The reference's shape in the next level: flat bits or its box.
    let put = |d: u32, prim: u32, f: u8, b: &Aabb| unsafe {
        prims.write(d as usize, prim);
        if sorted {
            flat.write(d as usize, f);
        } else {
            boxes.write(d as usize, *b);
        }
    };
    let Work {
        left,
        lists,
        regen_starts,
        slot_map,
        regen,
        go,
        ..
    } = work;
    let go = &*go;
    slot_map.clear();
    let map_len = if level.sorted { n_refs } else { 0 };
    let slot_sink = Scatter::tail(slot_map, map_len);
    regen.clear();
    let regen_total = *regen_starts.last().unwrap() as usize;
    let regen_sink = Scatter::tail(regen, regen_total);
    let ref_starts = &next.ref_starts;
    par_chunks(n_refs).for_each(|(c, r)| {
        let mut clipped = chunks[c].clipped.iter();
        let mut cur = Cursor::new(&level.ref_starts, r.start);
        let mut i = r.start;
        while i < r.end {
            cur.at(i);
            let (k, stop) = (cur.seg, cur.end.min(r.end));
            let Some(s) = &splits[k] else {
                if level.sorted {
                    for slot in i..stop {
                        unsafe { slot_sink.write(slot, [NONE; 2]) };
                    }
                }
                i = stop;
                continue;
            };
            let mut t = if i == cur.begin {
                RefTally::default()
            } else {
                carry[c]
            };
            let first = left[k] as usize;
            let at = [ref_starts[first], ref_starts[first + 1]];
            let listed = [lists[first], lists[first + 1]];
            let regen_at = [regen_starts[first], regen_starts[first + 1]];
            // Safety (all writes below): a reference's destination is its child's offset plus
            // its rank among the child's references, which the tallies make distinct and
            // covering; slot_map is written once per slot; clipped copies likewise by rank.
            for slot in i..stop {
                let prim = level.prims[slot];
                let mut map = [NONE; 2];
                let (go, _) = shape(level, go, slot, s);
                if go[0] & go[1] & ctx.clip {
                    let c = clipped.next().expect("first pass clipped every straddler");
                    for side in 0..2 {
                        if c[side].is_empty() {
                            continue;
                        }
                        let d = at[side] + t.refs[side];
                        put(d, prim, flat_mask(&c[side]), &c[side]);
                        t.refs[side] += 1;
                        if listed[side] {
                            let at = regen_at[side] + t.copies[side];
                            unsafe {
                                regen_sink.write(
                                    at as usize,
                                    Clipped {
                                        slot: d,
                                        bbox: c[side],
                                    },
                                )
                            };
                        }
                        t.copies[side] += 1;
                    }
                } else {
                    let (f, b) = if sorted {
                        (level.flat[slot], Aabb::EMPTY)
                    } else {
                        (0, level.ref_boxes[slot])
                    };
                    for side in 0..2 {
                        if go[side] {
                            let d = at[side] + t.refs[side];
                            put(d, prim, f, &b);
                            t.refs[side] += 1;
                            map[side] = if listed[side] { d } else { NONE };
                        }
                    }
                }
                if level.sorted {
                    unsafe { slot_sink.write(slot, map) };
                }
            }
            i = stop;
        }
    });
    unsafe {
        filled(&mut next.prims, total);
        filled(&mut next.flat, if sorted { total } else { 0 });
        filled(&mut next.ref_boxes, if sorted { 0 } else { total });
        filled(&mut work.slot_map, map_len);
        filled(&mut work.regen, regen_total);
    }
}
