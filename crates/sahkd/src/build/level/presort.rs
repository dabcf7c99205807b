//! The one sort of a build: the root level's lists, in parallel.

use super::entries::ListEntry;
use super::Level;
use crate::build::Primitives;
use rayon::prelude::*;

/// The root level: one node over the scene box holding every primitive, slot = primitive
/// index. With `sorted`, each axis's list is every primitive's entries sorted by key: for
/// spans the lo-sort of the paper (ties by primitive index), for events the position sort of
/// Wald and Havran (which holds the lo-sort and the hi-sort in one list).
pub(super) fn root_level<E: ListEntry>(prims: &Primitives, sorted: bool) -> Level<E> {
    let n = prims.boxes.len() as u32;
    let mut level = Level::empty(sorted);
    level.boxes.push(prims.bounds);
    level.ref_starts = vec![0, n];
    level.prims = (0..n).collect();
    level.ref_boxes = prims.boxes.clone();
    if sorted {
        for axis in 0..3 {
            let mut list: Vec<E> = prims
                .boxes
                .par_iter()
                .enumerate()
                .flat_map_iter(|(i, b)| {
                    let (lo, hi) = (b.lo[axis], b.hi[axis]);
                    E::make(lo, hi, i as u32)
                        .into_iter()
                        .take(E::count(lo, hi) as usize)
                })
                .collect();
            list.par_sort_unstable_by_key(|e| e.key());
            level.list_starts[axis] = vec![0, list.len() as u32];
            level.lists[axis] = list;
        }
    }
    level
}
