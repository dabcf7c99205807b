//! Point queries: closest point, distance, signed distance and the inside test, one point
//! or a batch on every core.
//!
//! - [`KdTree::closest_point`] walks the tree's 8-wide nodes nearest child first and skips
//!   children farther than the best triangle so far (`nearest`); each triangle's closest
//!   point is computed exactly in f64 (`triangle`). The answer equals the brute force's
//!   ([`brute`]) to the bit, ties going to the lower triangle index.
//! - The inside test has two methods ([`InsideTest`]). [`InsideTest::Parity`], the default,
//!   casts one ray, trusted when its crossings lie clear of triangle edges, else three
//!   that vote (`parity`): one tree walk for most points, and exact for closed meshes.
//!   [`InsideTest::Winding`] sums the generalized winding number over every triangle
//!   (`winding`): robust where the mesh has holes, overlaps or stray pieces, but O(N) per
//!   point, too slow for large meshes and many points; hence not the default.
//! - The signed distance is the distance, negative inside.
//!
//! Batches run on the current rayon pool, over the points sorted along a Morton curve:
//! neighbours walk the same nodes while they are cached, and each closest-point walk starts
//! bounded by its predecessors' triangles, so most of the tree is never entered. Each
//! point's answer is the single-point answer, whatever the order and the number of threads.

pub mod brute;
mod nearest;
mod parity;
mod triangle;
mod winding;

pub use parity::DIRECTIONS as PARITY_DIRECTIONS;
pub use triangle::{closest_on_triangle, TrianglePoint};
pub use winding::winding_number;

use crate::geometry::{Triangle, Vec3};
use crate::tree::KdTree;
use rayon::prelude::*;
use std::sync::atomic::{AtomicU32, Ordering::Relaxed};

/// Points handed to a worker at a time, in spatial order: the run's first closest point
/// walks without a hint, so runs must be long; and there must be enough of them for every
/// core.
const RUN: usize = 256;

/// The answers of the last few points (distinct triangles) that bound a batch's next walk:
/// 3 rather than 1 gave the far points of dragon +4 % (the Morton curve's neighbours are
/// not always the nearest points), near ones -3 %.
const HINTS: usize = 3;

/// `answer(state, point)` of every point, in the points' order, computed on every core in
/// their spatial order (`spatial_order`): neighbours walk the same nodes while they are in
/// the cache. Each run of [`RUN`] points shares one `state`, made by `start`. A point that
/// `trivial` answers (one outside the mesh's box, say) is neither sorted nor walked.
fn in_spatial_order<S, T: Copy + Send + Sync>(
    points: &[Vec3],
    trivial: impl Fn(Vec3) -> Option<T> + Sync,
    start: impl Fn() -> S + Sync,
    answer: impl Fn(&mut S, Vec3) -> T + Sync,
) -> Vec<T> {
    let quick: Vec<Option<T>> = points.par_iter().map(|&p| trivial(p)).collect();
    let walked: Vec<u32> = (0..points.len() as u32)
        .into_par_iter()
        .filter(|&i| quick[i as usize].is_none())
        .collect();
    let order = sort_spatially(points, walked);
    let (start, answer) = (&start, &answer);
    let in_order: Vec<T> = order
        .par_chunks(RUN)
        .flat_map_iter(|run| {
            let mut state = start();
            run.iter()
                .map(move |&i| answer(&mut state, points[i as usize]))
        })
        .collect();
    // Where each walked point's answer is in `in_order` (disjoint stores, in parallel).
    let rank: Vec<AtomicU32> = points.par_iter().map(|_| AtomicU32::new(0)).collect();
    order
        .par_iter()
        .enumerate()
        .for_each(|(k, &i)| rank[i as usize].store(k as u32, Relaxed));
    quick
        .par_iter()
        .zip(&rank)
        .map(|(q, k)| q.unwrap_or_else(|| in_order[k.load(Relaxed) as usize]))
        .collect()
}

/// The indices of `points` sorted along a Morton curve of their box (21 bits per axis),
/// ties by index: near points become near in the order (non-finite ones anywhere). The
/// batch calls use it; a caller that cuts a large batch into slices (to show progress, say)
/// keeps their speed by slicing the points in this order.
pub fn spatial_order(points: &[Vec3]) -> Vec<u32> {
    sort_spatially(points, (0..points.len() as u32).collect())
}

/// `indices` of `points` sorted as [`spatial_order`] sorts all of them, in the box of these.
fn sort_spatially(points: &[Vec3], indices: Vec<u32>) -> Vec<u32> {
    const CELLS: f64 = (1u64 << 21) as f64;
    let finite = indices
        .iter()
        .map(|&i| &points[i as usize])
        .filter(|p| p.is_finite());
    let (lo, hi) = finite.fold(([f64::MAX; 3], [f64::MIN; 3]), |(lo, hi), p| {
        (
            std::array::from_fn(|a| lo[a].min(p.0[a] as f64)),
            std::array::from_fn(|a| hi[a].max(p.0[a] as f64)),
        )
    });
    let cell = |p: &Vec3, a: usize| {
        let t = (p.0[a] as f64 - lo[a]) / (hi[a] - lo[a]).max(f64::MIN_POSITIVE);
        ((t * CELLS) as u64).min(CELLS as u64 - 1)
    };
    let mut keyed: Vec<(u64, u32)> = indices
        .into_par_iter()
        .map(|i| {
            let p = &points[i as usize];
            let code = if p.is_finite() {
                spread(cell(p, 0)) | spread(cell(p, 1)) << 1 | spread(cell(p, 2)) << 2
            } else {
                0
            };
            (code, i)
        })
        .collect();
    keyed.par_sort_unstable();
    keyed.into_iter().map(|(_, i)| i).collect()
}

/// The low 21 bits of `x`, two zero bits after each.
fn spread(x: u64) -> u64 {
    let mut x = x & 0x1f_ffff;
    x = (x | x << 32) & 0x1f_0000_0000_ffff;
    x = (x | x << 16) & 0x1f_0000_ff00_00ff;
    x = (x | x << 8) & 0x100f_00f0_0f00_f00f;
    x = (x | x << 4) & 0x10c3_0c30_c30c_30c3;
    (x | x << 2) & 0x1249_2492_4924_9249
}

/// The closest point of a mesh to a query point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ClosestPoint {
    /// The point on the mesh, in f64 (from the barycentrics and the f32 corners).
    pub point: [f64; 3],
    /// Euclidean distance from the query point, in f64.
    pub distance: f64,
    /// The triangle the point lies on (the lowest index among equally near ones).
    pub prim: u32,
    /// Weights of the triangle's corners 0, 1, 2 (non-negative, summing to 1).
    pub barycentrics: [f64; 3],
}

impl ClosestPoint {
    pub(crate) fn new(distance2: f64, prim: u32, weights: [f64; 3], tri: &Triangle) -> Self {
        let point = TrianglePoint { distance2, weights }.point(tri);
        ClosestPoint {
            point,
            distance: distance2.sqrt(),
            prim,
            barycentrics: weights,
        }
    }
}

/// How [`KdTree::contains`] and [`KdTree::signed_distance`] decide inside from outside.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum InsideTest {
    /// One ray's crossing parity, or where it passes near an edge, the majority of three
    /// rays': fast, for closed (watertight) meshes.
    #[default]
    Parity,
    /// |generalized winding number| > 1/2, summed over every triangle: robust for meshes
    /// with holes and either consistent orientation, O(N) per point.
    Winding,
}

impl std::str::FromStr for InsideTest {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "parity" => Ok(InsideTest::Parity),
            "winding" => Ok(InsideTest::Winding),
            _ => Err(format!(
                "unknown inside test '{s}' (expected 'parity' or 'winding')"
            )),
        }
    }
}

impl KdTree {
    /// The closest point of the mesh to `p`; `None` for an empty mesh or a point with a
    /// non-finite coordinate.
    pub fn closest_point(&self, p: Vec3) -> Option<ClosestPoint> {
        nearest::closest_point(self, p, &[])
    }

    /// Distance from `p` to the mesh: infinite for an empty mesh, NaN for a non-finite point.
    pub fn distance(&self, p: Vec3) -> f64 {
        distance_of(self, p, self.closest_point(p))
    }

    /// Whether `p` lies inside the mesh under `test`; false for a non-finite point.
    pub fn contains(&self, p: Vec3, test: InsideTest) -> bool {
        self.contains_with(p, test, &mut Vec::new())
    }

    /// The distance, negative inside (under `test`); infinite for an empty mesh, NaN for a
    /// non-finite point. A point on the surface has distance 0 whatever its side.
    pub fn signed_distance(&self, p: Vec3, test: InsideTest) -> f64 {
        self.signed_distance_with(p, test, &mut Vec::new())
    }

    /// The generalized winding number of the mesh around `p` (exact sum over all triangles).
    pub fn winding_number(&self, p: Vec3) -> f64 {
        winding::winding_number(&self.triangles, p)
    }

    /// [`closest_point`](Self::closest_point) of every point, on every core.
    pub fn closest_point_batch(&self, points: &[Vec3]) -> Vec<Option<ClosestPoint>> {
        self.nearest_batch(points, |_, _, c, _| c)
    }

    /// [`distance`](Self::distance) of every point, on every core.
    pub fn distance_batch(&self, points: &[Vec3]) -> Vec<f64> {
        self.nearest_batch(points, |tree, p, c, _| distance_of(tree, p, c))
    }

    /// [`contains`](Self::contains) of every point, on every core.
    pub fn contains_batch(&self, points: &[Vec3], test: InsideTest) -> Vec<bool> {
        // Parity answers a point outside the mesh's box (or not finite) without a walk.
        let trivial = |p: Vec3| {
            (test == InsideTest::Parity && !parity::within(&self.bounds, p)).then_some(false)
        };
        in_spatial_order(points, trivial, Vec::new, |buf, p| {
            self.contains_with(p, test, buf)
        })
    }

    /// [`signed_distance`](Self::signed_distance) of every point, on every core.
    pub fn signed_distance_batch(&self, points: &[Vec3], test: InsideTest) -> Vec<f64> {
        self.nearest_batch(points, |tree, p, c, buf| {
            tree.signed(p, distance_of(tree, p, c), test, buf)
        })
    }

    /// Closest point and inside flag of every point in one pass, on every core (what
    /// `signed_distance_batch` computes, with the closest point kept).
    pub fn closest_point_signed_batch(
        &self,
        points: &[Vec3],
        test: InsideTest,
    ) -> Vec<(Option<ClosestPoint>, bool)> {
        self.nearest_batch(points, |tree, p, c, buf| {
            (c, tree.contains_with(p, test, buf))
        })
    }

    /// `answer(tree, point, closest point, buffer)` of every point, on every core, in the
    /// points' order. The closest points are found in the spatial order of the points, each
    /// walk bounded from the start by the nearest of the last [`HINTS`] points' triangles:
    /// neighbours share their nearest triangles, so most walks start with a near-final bound. The answers are those
    /// of single queries, whatever the order and threads.
    fn nearest_batch<T: Copy + Send + Sync>(
        &self,
        points: &[Vec3],
        answer: impl Fn(&KdTree, Vec3, Option<ClosestPoint>, &mut Vec<u32>) -> T + Sync,
    ) -> Vec<T> {
        let start = || ([u32::MAX; HINTS], Vec::new());
        in_spatial_order(
            points,
            |_| None,
            start,
            |(hints, buf), p| {
                let c = nearest::closest_point(self, p, hints);
                if let Some(c) = c {
                    if !hints.contains(&c.prim) {
                        hints.rotate_right(1);
                        hints[0] = c.prim;
                    }
                }
                answer(self, p, c, buf)
            },
        )
    }

    /// [`winding_number`](Self::winding_number) of every point, on every core.
    pub fn winding_number_batch(&self, points: &[Vec3]) -> Vec<f64> {
        points
            .par_iter()
            .with_min_len(1)
            .map(|&p| self.winding_number(p))
            .collect()
    }

    fn contains_with(&self, p: Vec3, test: InsideTest, buf: &mut Vec<u32>) -> bool {
        match test {
            InsideTest::Parity => parity::inside(self, p, buf),
            InsideTest::Winding => self.winding_number(p).abs() > 0.5,
        }
    }

    fn signed_distance_with(&self, p: Vec3, test: InsideTest, buf: &mut Vec<u32>) -> f64 {
        self.signed(p, self.distance(p), test, buf)
    }

    /// The distance `d` of `p`, negated when `p` lies inside.
    fn signed(&self, p: Vec3, d: f64, test: InsideTest, buf: &mut Vec<u32>) -> f64 {
        // On the surface the side is moot, and an empty mesh has no inside.
        if d == 0.0 || !d.is_finite() {
            return d;
        }
        if self.contains_with(p, test, buf) {
            -d
        } else {
            d
        }
    }
}

fn distance_of(tree: &KdTree, p: Vec3, c: Option<ClosestPoint>) -> f64 {
    match c {
        Some(c) => c.distance,
        None if tree.triangles.is_empty() && p.is_finite() => f64::INFINITY,
        None => f64::NAN,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spread_puts_two_zero_bits_after_each_bit() {
        assert_eq!(spread(0b111), 0b1001001);
        assert_eq!(spread(0x1f_ffff), 0x1249_2492_4924_9249);
        assert_eq!(spread(1 << 20), 1 << 60);
    }

    #[test]
    fn spatial_order_is_a_permutation_with_neighbours_adjacent() {
        // Two clusters far apart, interleaved in the input: the order keeps each together.
        let points: Vec<Vec3> = (0..64)
            .map(|i| {
                let base = if i % 2 == 0 { 0.0 } else { 100.0 };
                Vec3::new(base + (i / 2) as f32 * 0.01, base, base)
            })
            .chain([Vec3::new(f32::NAN, 0.0, 0.0)])
            .collect();
        let order = spatial_order(&points);
        let mut sorted = order.clone();
        sorted.sort_unstable();
        assert_eq!(sorted, (0..points.len() as u32).collect::<Vec<_>>());
        let clusters: Vec<u32> = order.iter().filter(|&&i| i < 64).map(|&i| i % 2).collect();
        assert!(clusters[..32].iter().all(|&c| c == clusters[0]));
        assert!(clusters[32..].iter().all(|&c| c != clusters[0]));
    }
}
