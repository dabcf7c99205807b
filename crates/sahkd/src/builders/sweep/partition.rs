//! Splitting a node's sorted events into its children's, without re-sorting.
//!
//! One pass over the split axis classifies every primitive as left only, right only or both
//! (a straddler). Each axis's list is then split stably in one pass, so both children's lists
//! stay sorted. Straddlers with clip off keep their events in both children: their boxes
//! intersected with a child box differ from the stored ones only beyond the child's
//! boundary, where no candidate lies, so every count the sweep takes is the same. With clip
//! on, straddlers' events are dropped from the split and re-made from their boxes clipped to
//! each child; these few are sorted and merged into the stable split.

use super::events::{self, prim, Event, END, PLANAR, START};
use super::search::Split;
use crate::clip::clipped_halves;
use crate::geometry::{Aabb, Triangle};

/// Where a primitive goes: bit 0 left, bit 1 right. A straddler re-made by clipping is
/// `NEITHER` during the stable split.
const NEITHER: u8 = 0;
const LEFT: u8 = 1;
const RIGHT: u8 = 2;
const BOTH: u8 = 3;

/// The event lists of all pending nodes and the scratch space to split them, reused for the
/// whole build so that the hot loop does not allocate.
///
/// Each axis's events live in one stack (`arena`): a node's events are the top segment,
/// from its `start` to the end. Splitting a node replaces its segment by the right child's
/// events followed by the left child's, so the left child (built first) is on top.
pub(super) struct Workspace {
    pub arena: [Vec<Event>; 3],
    tmp_left: Vec<Event>,
    new_left: [Vec<Event>; 3],
    new_right: [Vec<Event>; 3],
    side: Vec<u8>,
    straddlers: Vec<u32>,
    peak_events: usize,
}

/// The start of a node's segment in each axis's stack.
pub(super) type Segment = [usize; 3];

/// The children made by [`Workspace::split`]: their segments and primitive counts.
pub(super) struct Children {
    pub left: Segment,
    pub right: Segment,
    pub n_left: u32,
    pub n_right: u32,
}

impl Workspace {
    /// The root's events: every box's events on each axis, sorted once.
    pub fn new(boxes: &[Aabb]) -> Workspace {
        let mut arena: [Vec<Event>; 3] = Default::default();
        let mut scratch = Vec::new();
        for (axis, list) in arena.iter_mut().enumerate() {
            events::sorted_of_boxes(list, axis, boxes, &mut scratch);
        }
        let mut work = Workspace::from_sorted(arena, boxes.len());
        work.tmp_left = scratch;
        work
    }

    /// A root node whose events on each axis (`prims` primitives, local indices) come sorted.
    pub fn from_sorted(arena: [Vec<Event>; 3], prims: usize) -> Workspace {
        debug_assert!(arena.iter().all(|l| l.windows(2).all(|w| w[0] < w[1])));
        let peak_events = arena.iter().map(Vec::len).sum();
        Workspace {
            arena,
            tmp_left: Vec::new(),
            new_left: Default::default(),
            new_right: Default::default(),
            side: vec![NEITHER; prims],
            straddlers: Vec::new(),
            peak_events,
        }
    }

    /// The events of the node whose segment starts at `seg` (the top of the stacks).
    pub fn events(&self, seg: &Segment) -> [&[Event]; 3] {
        [
            &self.arena[0][seg[0]..],
            &self.arena[1][seg[1]..],
            &self.arena[2][seg[2]..],
        ]
    }

    /// Appends the primitives of the top node to `out`.
    pub fn collect_prims(&self, seg: &Segment, out: &mut Vec<u32>) {
        out.extend(
            self.arena[0][seg[0]..]
                .iter()
                .filter(|&&e| e.kind() != END)
                .map(|&e| prim(e) as u32),
        );
    }

    /// Drops the top node's events.
    pub fn pop(&mut self, seg: &Segment) {
        for (list, &s) in self.arena.iter_mut().zip(seg) {
            list.truncate(s);
        }
    }

    /// Bytes of event storage at the peak (the stacks plus the scratch lists).
    pub fn peak_bytes(&self) -> usize {
        let scratch = self.tmp_left.capacity()
            + self.new_left.iter().map(Vec::capacity).sum::<usize>()
            + self.new_right.iter().map(Vec::capacity).sum::<usize>();
        (self.peak_events + scratch) * std::mem::size_of::<Event>()
            + self.side.len()
            + self.straddlers.capacity() * 4
    }

    /// Replaces the top node (segment `seg`, box `node`) by its children at `split`.
    /// With `clip`, straddlers are re-clipped from their `triangles` to each child's box.
    pub fn split(
        &mut self,
        seg: &Segment,
        node: &Aabb,
        split: &Split,
        clip: Option<&[Triangle]>,
    ) -> Children {
        self.classify(seg[split.axis], split);
        let (mut n_left, mut n_right) = (split.n_left, split.n_right);
        if let Some(triangles) = clip {
            for list in self.new_left.iter_mut().chain(self.new_right.iter_mut()) {
                list.clear();
            }
            for &s in &self.straddlers {
                self.side[s as usize] = NEITHER;
                let tri = &triangles[s as usize];
                let (left_box, right_box) = clipped_halves(tri, node, split.axis, split.pos);
                for (b, lists, count) in [
                    (left_box, &mut self.new_left, &mut n_left),
                    (right_box, &mut self.new_right, &mut n_right),
                ] {
                    if b.is_empty() {
                        *count -= 1;
                    } else {
                        for (axis, list) in lists.iter_mut().enumerate() {
                            events::push_box(list, axis, &b, s);
                        }
                    }
                }
            }
        }
        let mut left = [0; 3];
        let mut right = [0; 3];
        for axis in 0..3 {
            let (l, r) = self.split_axis(axis, seg[axis], clip.is_some());
            right[axis] = seg[axis];
            left[axis] = seg[axis] + r;
            debug_assert_eq!(self.arena[axis].len(), seg[axis] + r + l);
        }
        let total: usize = self.arena.iter().map(Vec::len).sum();
        self.peak_events = self.peak_events.max(total);
        debug_assert_eq!(count_prims(&self.arena[0][left[0]..]), n_left as usize);
        debug_assert_eq!(
            count_prims(&self.arena[0][right[0]..left[0]]),
            n_right as usize
        );
        Children {
            left,
            right,
            n_left,
            n_right,
        }
    }

    /// Sets `side` for every primitive of the node from its events on the split axis, and
    /// lists the straddlers.
    ///
    /// The events are sorted, so those before the plane, in it and after it are three runs,
    /// each with a simpler rule than one loop deciding by kind and place. Starts come before
    /// their ends: a start before the plane marks a tentative straddler, which its end
    /// confirms (after the plane) or turns into left only (at or before it).
    fn classify(&mut self, start: usize, split: &Split) {
        let plane = events::plane_bits(split.pos);
        let events = &self.arena[split.axis][start..];
        let before = events.partition_point(|&e| e.pos_bits() < plane);
        let at = before + events[before..].partition_point(|&e| e.pos_bits() == plane);
        if self.straddlers.len() < events.len() / 2 {
            self.straddlers.resize(events.len() / 2, 0);
        }
        let (side, straddlers) = (&mut self.side[..], &mut self.straddlers[..]);
        // Before the plane: a start is a tentative straddler, an end or a planar left only.
        // START is 2 and END and PLANAR are below it, so `LEFT | (kind & 2)` is BOTH or LEFT.
        const _: () = assert!(START == 2 && END < 2 && PLANAR < 2);
        for &e in &events[..before] {
            side[prim(e)] = LEFT | (e.kind() as u8 & 2);
        }
        // In the plane: an end is left only, a start right only, a planar on its chosen side.
        let planar_side = if split.planar_left { LEFT } else { RIGHT };
        for &e in &events[before..at] {
            side[prim(e)] = [LEFT, planar_side, RIGHT][e.kind() as usize];
        }
        // After the plane: starts and planars are right only; an end leaves its primitive's
        // side as its start set it, and is a straddler's when that start was before the plane.
        // Straddlers have two events, so there are at most half as many as events.
        let mut count = 0;
        for &e in &events[at..] {
            let (p, k) = (prim(e), e.kind());
            let old = side[p];
            // `old` for an end, else RIGHT, without a branch: ends and starts alternate
            // unpredictably here, and the branch the plain form compiled to mispredicted
            // more than any other of the build.
            let keep = ((k == END) as u8).wrapping_neg();
            side[p] = RIGHT ^ ((old ^ RIGHT) & keep);
            straddlers[count] = p as u32;
            count += (k == END && old == BOTH) as usize;
        }
        self.straddlers.truncate(count);
    }

    /// Splits the top node's events on `axis` (from `start`) stably into the children's,
    /// merges in the re-clipped straddlers' events, and writes right then left in place of
    /// the parent. Returns the lengths (left, right).
    ///
    /// The right child's events are compacted in place (the write cursor never passes the
    /// read cursor); only the left child's go through a scratch list.
    fn split_axis(&mut self, axis: usize, start: usize, clip: bool) -> (usize, usize) {
        let list = &mut self.arena[axis];
        let len = list.len() - start;
        if self.tmp_left.len() < len {
            self.tmp_left.resize(len, Event::default());
        }
        let tl = &mut self.tmp_left[..len];
        let parent = &mut list[start..];
        let side = &self.side[..];
        let (mut nl, mut nr) = (0, 0);
        // Branch-free: write to both sides, advance the cursors the event belongs to.
        for i in 0..parent.len() {
            let e = parent[i];
            let s = side[prim(e)];
            debug_assert!(nl <= i && nr <= i && tl.len() == parent.len());
            // SAFETY: each cursor advances by at most one per event read, so `nl <= i` and
            // `nr <= i`, and `i` is within `parent`, as long as `tl`. The bound checks these
            // writes would otherwise take are a third of the loop's instructions.
            unsafe {
                *tl.get_unchecked_mut(nl) = e;
                *parent.get_unchecked_mut(nr) = e;
            }
            nl += (s & LEFT) as usize;
            nr += (s >> 1) as usize;
        }
        let (new_l, new_r) = (&mut self.new_left[axis], &mut self.new_right[axis]);
        let clipped = clip && !(new_l.is_empty() && new_r.is_empty());
        if clipped {
            new_r.sort_unstable();
            list.truncate(start + nr);
            events::merge_in_place(list, start, new_r);
            nr += new_r.len();
        }
        list.truncate(start + nr);
        if clipped {
            new_l.sort_unstable();
            events::merge_into(list, &tl[..nl], new_l);
            nl += new_l.len();
        } else {
            list.extend_from_slice(&tl[..nl]);
        }
        (nl, nr)
    }
}

fn count_prims(events: &[Event]) -> usize {
    events.iter().filter(|&&e| e.kind() != END).count()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::clip::clipped_bounds;
    use crate::geometry::{triangle_bounds, Vec3};

    /// Children's event lists equal the lists made and sorted afresh from the boxes the shared
    /// semantics give each child's primitives.
    #[test]
    fn split_lists_equal_freshly_sorted_children() {
        let mut seed = 3u64;
        let mut unit = move || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((seed >> 40) as f32 / (1u64 << 24) as f32 * 8.0).round() / 8.0
        };
        let mut checked = 0;
        for round in 0..200 {
            let n = 2 + round % 40;
            let tris: Vec<Triangle> = (0..n)
                .map(|_| {
                    let mut corner = || Vec3::new(unit(), unit(), unit());
                    [corner(), corner(), corner()]
                })
                .collect();
            let boxes: Vec<Aabb> = tris.iter().map(triangle_bounds).collect();
            let bounds = boxes.iter().fold(Aabb::EMPTY, |b, &x| b.union(x));
            let axis = round % 3;
            let pos = boxes[round % n].lo[axis];
            if !(pos > bounds.lo[axis] && pos < bounds.hi[axis]) {
                continue;
            }
            let planar_left = round % 2 == 0;
            let on_left = |b: &Aabb| b.lo[axis] < pos || (b.hi[axis] == pos && planar_left);
            let on_right = |b: &Aabb| b.hi[axis] > pos || (b.lo[axis] == pos && !planar_left);
            let split = Split {
                axis,
                pos,
                cost: 0.0,
                planar_left,
                n_left: boxes.iter().filter(|b| on_left(b)).count() as u32,
                n_right: boxes.iter().filter(|b| on_right(b)).count() as u32,
            };
            let (lbox, rbox) = bounds.split(axis, pos);
            checked += 1;
            for clip in [false, true] {
                let mut work = Workspace::new(&boxes);
                let children =
                    work.split(&[0; 3], &bounds, &split, clip.then_some(tris.as_slice()));
                for (child_box, seg, end, keep) in [
                    (
                        &lbox,
                        children.left,
                        None,
                        &on_left as &dyn Fn(&Aabb) -> bool,
                    ),
                    (&rbox, children.right, Some(children.left), &on_right),
                ] {
                    let mut want: [Vec<Event>; 3] = Default::default();
                    for (i, b) in boxes.iter().enumerate() {
                        if !keep(b) {
                            continue;
                        }
                        let straddles = b.lo[axis] < pos && b.hi[axis] > pos;
                        let b = if clip && straddles {
                            clipped_bounds(&tris[i], child_box)
                        } else {
                            *b
                        };
                        if b.is_empty() {
                            continue;
                        }
                        for (a, list) in want.iter_mut().enumerate() {
                            events::push_box(list, a, &b, i as u32);
                        }
                    }
                    for a in 0..3 {
                        want[a].sort_unstable();
                        let got = match end {
                            None => &work.arena[a][seg[a]..],
                            Some(e) => &work.arena[a][seg[a]..e[a]],
                        };
                        assert_eq!(got, &want[a][..], "round {round}, clip {clip}, axis {a}");
                    }
                }
            }
        }
        assert!(checked > 100, "only {checked} splits checked");
    }
}
