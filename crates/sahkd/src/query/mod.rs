//! Point queries: closest point, distance, signed distance and the inside test, one point
//! or a batch on every core.
//!
//! - [`KdTree::closest_point`] walks the tree nearest child first and skips nodes farther
//!   than the best triangle so far (`nearest`); each triangle's closest point is computed
//!   exactly in f64 (`triangle`). The answer equals the brute force's ([`brute`]) to the
//!   bit, ties going to the lower triangle index.
//! - The inside test has two methods ([`InsideTest`]). [`InsideTest::Parity`], the default,
//!   casts one ray, trusted when its crossings lie clear of triangle edges, else three
//!   that vote (`parity`): one tree walk for most points, and exact for closed meshes.
//!   [`InsideTest::Winding`] sums the generalized winding number over every triangle
//!   (`winding`): robust where the mesh has holes, overlaps or stray pieces, but O(N) per
//!   point, too slow for large meshes and many points; hence not the default.
//! - The signed distance is the distance, negative inside.
//!
//! Batches run on the current rayon pool; each point's answer is the single-point answer,
//! whatever the number of threads.

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

/// Points handed to a worker at a time: enough to amortise the scheduling.
const MIN_BATCH: usize = 64;

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
        nearest::closest_point(self, p)
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
        points
            .par_iter()
            .with_min_len(MIN_BATCH)
            .map(|&p| self.closest_point(p))
            .collect()
    }

    /// [`distance`](Self::distance) of every point, on every core.
    pub fn distance_batch(&self, points: &[Vec3]) -> Vec<f64> {
        points
            .par_iter()
            .with_min_len(MIN_BATCH)
            .map(|&p| self.distance(p))
            .collect()
    }

    /// [`contains`](Self::contains) of every point, on every core.
    pub fn contains_batch(&self, points: &[Vec3], test: InsideTest) -> Vec<bool> {
        points
            .par_iter()
            .with_min_len(MIN_BATCH)
            .map_init(Vec::new, |buf, &p| self.contains_with(p, test, buf))
            .collect()
    }

    /// [`signed_distance`](Self::signed_distance) of every point, on every core.
    pub fn signed_distance_batch(&self, points: &[Vec3], test: InsideTest) -> Vec<f64> {
        points
            .par_iter()
            .with_min_len(MIN_BATCH)
            .map_init(Vec::new, |buf, &p| self.signed_distance_with(p, test, buf))
            .collect()
    }

    /// Closest point and inside flag of every point in one pass, on every core (what
    /// `signed_distance_batch` computes, with the closest point kept).
    pub fn closest_point_signed_batch(
        &self,
        points: &[Vec3],
        test: InsideTest,
    ) -> Vec<(Option<ClosestPoint>, bool)> {
        points
            .par_iter()
            .with_min_len(MIN_BATCH)
            .map_init(Vec::new, |buf, &p| {
                (self.closest_point(p), self.contains_with(p, test, buf))
            })
            .collect()
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
        let d = self.distance(p);
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
