//! The naive baseline of the paper: the same level framework, but every candidate counts L, R
//! and P by testing every reference of its node (O(n) per candidate), and nothing is sorted.

use super::candidates::{self, fill_extents, Candidates, Counts, HOLE};
use super::entries::Span;
use super::Level;
use crate::cost::CostModel;
use rayon::prelude::*;

/// The level's reference boxes as one array per axis and bound, so that the counting loop
/// reads two dense arrays (and vectorises).
#[derive(Default)]
pub(super) struct Extents {
    lo: [Vec<f32>; 3],
    hi: [Vec<f32>; 3],
}

impl Extents {
    pub fn bytes(&self) -> usize {
        self.lo
            .iter()
            .chain(&self.hi)
            .map(|v| v.capacity() * 4)
            .sum()
    }
}

/// Phase 1: candidates straight from the node's (unsorted) references, and their extents.
pub(super) fn candidates(
    level: &Level<Span>,
    uses: &[u8],
    cands: &mut Candidates,
    extents: &mut Extents,
) {
    for axis in 0..3 {
        for (v, hi) in [
            (&mut extents.lo[axis], false),
            (&mut extents.hi[axis], true),
        ] {
            v.clear();
            level
                .ref_boxes
                .par_iter()
                .map(|b| if hi { b.hi[axis] } else { b.lo[axis] })
                .collect_into_vec(v);
        }
    }
    let starts = [level.ref_starts.as_slice(); 3];
    let boxes = &level.ref_boxes;
    fill_extents(cands, starts, uses, &level.boxes, |axis, i| {
        (boxes[i].lo[axis], boxes[i].hi[axis])
    });
}

/// L, R and P of the plane `p` over one node's extents, by testing each of them.
#[inline]
fn count_plane(lo: &[f32], hi: &[f32], p: f32) -> Counts {
    let (mut left, mut right, mut planar) = (0u32, 0u32, 0u32);
    for (&a, &b) in lo.iter().zip(hi) {
        left += (a < p) as u32;
        right += (b > p) as u32;
        planar += ((a == p) & (b == p)) as u32;
    }
    Counts {
        left,
        right,
        planar,
    }
}

/// Phase 3: counts and prices every candidate, one parallel pass over the candidate array.
/// Returns the candidates priced.
pub(super) fn count(
    level: &Level<Span>,
    cands: &mut Candidates,
    ext: &Extents,
    cost: &CostModel,
) -> usize {
    let firsts = [0, 1, 2].map(|a| cands.ranges[a].first().map_or(0, |r| r[0]));
    // Safety: fill_extents writes every slot.
    let items = unsafe { cands.all_mut() };
    items
        .par_iter_mut()
        .enumerate()
        .with_min_len(16)
        .map(|(i, c)| {
            if c.owner == HOLE {
                return 0;
            }
            let axis = candidates::axis_in(&firsts, i);
            let k = c.owner as usize;
            let (s, e) = (
                level.ref_starts[k] as usize,
                level.ref_starts[k + 1] as usize,
            );
            let counts = count_plane(&ext.lo[axis][s..e], &ext.hi[axis][s..e], c.pos);
            *c = candidates::price(cost, &level.boxes[k], axis, c.pos, c.owner, counts);
            1
        })
        .sum()
}
