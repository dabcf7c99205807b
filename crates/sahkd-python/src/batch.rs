//! Ray batches from numpy straight into the tree's packet walk.
//!
//! Each worker of the tree's pool takes a block of rays, converts them from the caller's
//! arrays into a buffer on its stack, traces them with the library's serial batch call (the
//! same packets and answers as `intersect_batch`) and writes the answers into the result
//! columns. No intermediate array of rays or of hits is made, and the conversion runs on every
//! core with the interpreter released: this is what keeps the Python call at the speed of the
//! Rust batch call. A row that is not finite stops the work; the serial reader
//! (`arrays::rays`) then names the first bad row, as it always did. Every float32 ray call
//! of the package comes this way: KdTree's intersect, occluded, count_hits, intersect_all
//! (through [`per_block`]) and Scene's intersect and occluded.

use numpy::ndarray::ArrayView2;
use rayon::prelude::*;
use rayon::ThreadPool;
use sahkd::{Hit, KdTree, Ray, Vec3};
use std::sync::atomic::{AtomicBool, Ordering};

use crate::arrays::{BoundView, Points, RayColumns};
use crate::columns::HitColumns;

/// Rays converted and traced by one task.
const BLOCK: usize = 256;

/// A placeholder for the stack buffers, overwritten before use.
const EMPTY: Ray = Ray {
    origin: Vec3([0.0; 3]),
    direction: Vec3([0.0; 3]),
    t_min: 0.0,
    t_max: 0.0,
};

/// An `(R, 3)` float32 or float64 array, viewed: as one slice of rows when C-contiguous (the
/// common case, read without index arithmetic), else through its strides.
#[derive(Clone, Copy)]
pub enum PointView<'a> {
    F32Rows(&'a [f32]),
    F64Rows(&'a [f64]),
    F32(ArrayView2<'a, f32>),
    F64(ArrayView2<'a, f64>),
}

impl<'a> PointView<'a> {
    pub fn of(points: &'a Points<'_>) -> Self {
        match points {
            // `to_slice` only for the standard (C) order: a Fortran-ordered array is
            // contiguous too, column by column.
            Points::F32(a) => {
                let v = a.as_array();
                v.to_slice().map_or(PointView::F32(v), PointView::F32Rows)
            }
            Points::F64(a) => {
                let v = a.as_array();
                v.to_slice().map_or(PointView::F64(v), PointView::F64Rows)
            }
        }
    }

    /// Rows `start..start + n` in float32, `set(k, row)` for the k-th; false if one of them
    /// is not finite in float32 (the rule of `arrays::rays`). One loop per layout, with the
    /// layout decided once per block rather than per row.
    #[inline(always)]
    fn read(&self, start: usize, n: usize, mut set: impl FnMut(usize, Vec3)) -> bool {
        let mut finite = true;
        let mut put = |k: usize, p: [f32; 3]| {
            finite &= p.iter().all(|c| c.is_finite());
            set(k, Vec3(p));
        };
        match self {
            PointView::F32Rows(s) => {
                for (k, r) in s[3 * start..3 * (start + n)].chunks_exact(3).enumerate() {
                    put(k, [r[0], r[1], r[2]]);
                }
            }
            PointView::F64Rows(s) => {
                for (k, r) in s[3 * start..3 * (start + n)].chunks_exact(3).enumerate() {
                    put(k, [r[0] as f32, r[1] as f32, r[2] as f32]);
                }
            }
            PointView::F32(a) => {
                for (k, i) in (start..start + n).enumerate() {
                    put(k, [a[[i, 0]], a[[i, 1]], a[[i, 2]]]);
                }
            }
            PointView::F64(a) => {
                for (k, i) in (start..start + n).enumerate() {
                    put(k, [a[[i, 0]] as f32, a[[i, 1]] as f32, a[[i, 2]] as f32]);
                }
            }
        }
        finite
    }
}

/// The rays of a call, viewed: origins, directions and their checked bounds.
pub type RayArrays<'a> = RayColumns<PointView<'a>, BoundView<'a>>;

impl RayArrays<'_> {
    /// Rays `start..start + out.len()` into `out`; false if one of them is not finite. The
    /// bounds were checked when the call began.
    fn fill(&self, start: usize, out: &mut [Ray]) -> bool {
        let n = out.len();
        let origins = self.origins.read(start, n, |k, p| out[k].origin = p);
        let directions = self.directions.read(start, n, |k, d| out[k].direction = d);
        for (k, ray) in out.iter_mut().enumerate() {
            ray.t_min = self.t_min.get(start + k) as f32;
            ray.t_max = self.t_max.get(start + k) as f32;
        }
        origins && directions
    }

    /// Block `b` of the rays converted into `buf`, or None (and `bad` set) if one of its rows
    /// is not finite or another block's was.
    fn block<'b>(&self, b: usize, buf: &'b mut [Ray], bad: &AtomicBool) -> Option<&'b [Ray]> {
        let start = b * BLOCK;
        let buf = &mut buf[..BLOCK.min(self.len - start)];
        if bad.load(Ordering::Relaxed) || !self.fill(start, buf) {
            bad.store(true, Ordering::Relaxed);
            return None;
        }
        Some(buf)
    }
}

/// Closest hits of every ray as the Python columns (t, prim, u, v), or None if a row is not
/// finite.
pub fn closest(tree: &KdTree, rays: &RayArrays<'_>, pool: &ThreadPool) -> Option<HitColumns<f32>> {
    let n = rays.len;
    let (mut t, mut prim) = (vec![0f32; n], vec![0i64; n]);
    let (mut u, mut v) = (vec![0f32; n], vec![0f32; n]);
    let bad = AtomicBool::new(false);
    pool.install(|| {
        t.par_chunks_mut(BLOCK)
            .zip(prim.par_chunks_mut(BLOCK))
            .zip(u.par_chunks_mut(BLOCK))
            .zip(v.par_chunks_mut(BLOCK))
            .enumerate()
            .for_each(|(b, (((t, prim), u), v))| {
                let mut buf = [EMPTY; BLOCK];
                let Some(block) = rays.block(b, &mut buf, &bad) else {
                    return;
                };
                let mut hits = [None::<Hit>; BLOCK];
                let hits = &mut hits[..block.len()];
                tree.intersect_into(block, hits);
                let columns = t.iter_mut().zip(prim).zip(u).zip(v);
                for ((((t, prim), u), v), h) in columns.zip(hits.iter()) {
                    (*t, *prim, *u, *v) = match h {
                        Some(h) => (h.t, h.prim as i64, h.u, h.v),
                        None => (f32::INFINITY, -1, 0.0, 0.0),
                    };
                }
            })
    });
    (!bad.into_inner()).then(|| HitColumns::from_columns(t, prim, u, v))
}

/// Whether each ray hits anything, or None if a row is not finite.
pub fn occluded(tree: &KdTree, rays: &RayArrays<'_>, pool: &ThreadPool) -> Option<Vec<bool>> {
    let mut out = vec![false; rays.len];
    let bad = AtomicBool::new(false);
    pool.install(|| {
        out.par_chunks_mut(BLOCK).enumerate().for_each(|(b, out)| {
            let mut buf = [EMPTY; BLOCK];
            if let Some(block) = rays.block(b, &mut buf, &bad) {
                tree.occluded_into(block, out);
            }
        })
    });
    (!bad.into_inner()).then_some(out)
}

/// How many faces each ray hits, each face once (the walk of `intersect_all`), or None if a
/// row is not finite.
pub fn count_hits(tree: &KdTree, rays: &RayArrays<'_>, pool: &ThreadPool) -> Option<Vec<i64>> {
    let mut out = vec![0i64; rays.len];
    let bad = AtomicBool::new(false);
    pool.install(|| {
        out.par_chunks_mut(BLOCK)
            .enumerate()
            .for_each_init(Vec::new, |hits, (b, out)| {
                let mut buf = [EMPTY; BLOCK];
                if let Some(block) = rays.block(b, &mut buf, &bad) {
                    for (count, ray) in out.iter_mut().zip(block) {
                        tree.all_hits_into(ray, hits);
                        *count = hits.len() as i64;
                    }
                }
            })
    });
    (!bad.into_inner()).then_some(out)
}

/// `answer` of each block of rays, in order, or None if a row is not finite: for the calls
/// whose answers vary in size from ray to ray (every hit of each ray).
pub fn per_block<T: Send>(
    rays: &RayArrays<'_>,
    pool: &ThreadPool,
    answer: impl Fn(&[Ray]) -> T + Sync,
) -> Option<Vec<T>> {
    let bad = AtomicBool::new(false);
    let answers: Vec<Option<T>> = pool.install(|| {
        (0..rays.len.div_ceil(BLOCK))
            .into_par_iter()
            .map(|b| {
                let mut buf = [EMPTY; BLOCK];
                rays.block(b, &mut buf, &bad).map(&answer)
            })
            .collect()
    });
    answers.into_iter().collect()
}
