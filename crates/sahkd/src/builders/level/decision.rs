//! Phase 4: each node's best candidate (a segmented min over the level's candidate array) and
//! the leaf rules.

use super::candidates::{Candidate, Candidates};
use super::entries::ListEntry;
use super::{Context, Level};
use crate::builders::choice::Split;
use rayon::prelude::*;

/// Candidates of one node on one axis above which the min is itself parallel.
const PARALLEL_MIN: usize = 1 << 15;

/// Whether candidate `a` (on its axis) is chosen over `b`: the builders' one order.
#[inline]
fn better((a, a_axis): (&Candidate, usize), (b, b_axis): (&Candidate, usize)) -> bool {
    a.ranked(a_axis).precedes(b.ranked(b_axis))
}

fn min_of<'a>(
    a: Option<(&'a Candidate, usize)>,
    b: Option<(&'a Candidate, usize)>,
) -> Option<(&'a Candidate, usize)> {
    match (a, b) {
        (Some(x), Some(y)) => Some(if better(y, x) { y } else { x }),
        (x, None) => x,
        (None, y) => y,
    }
}

/// Sets, per node, the split to make, or `None` for a leaf: a node with nothing to price (`uses`
/// 0), no candidate, or whose best candidate does not cost strictly less than the leaf.
pub(super) fn decide<E: ListEntry>(
    level: &Level<E>,
    uses: &[u8],
    cands: &Candidates,
    ctx: &Context,
    splits: &mut Vec<Option<Split>>,
) {
    (0..level.nodes())
        .into_par_iter()
        .with_min_len(64)
        .map(|k| {
            if uses[k] == 0 {
                return None;
            }
            let mut best = None;
            for axis in 0..3 {
                if uses[k] & (1 << axis) == 0 {
                    continue;
                }
                let mine = cands.of(axis, k);
                let local = if mine.len() >= PARALLEL_MIN {
                    mine.par_iter()
                        .with_min_len(4096)
                        .map(|c| Some((c, axis)))
                        .reduce(|| None, min_of)
                } else {
                    mine.iter()
                        .map(|c| (c, axis))
                        .reduce(|x, y| if better(y, x) { y } else { x })
                };
                best = min_of(best, local);
            }
            let (c, axis) = best?;
            Some(c.split(axis)).filter(|s| s.pays(level.refs(k), &ctx.cost))
        })
        .collect_into_vec(splits);
}
