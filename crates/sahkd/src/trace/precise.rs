//! Double-precision ray queries: the same tree, walked and tested in f64.
//!
//! The float32 test subtracts the ray origin from each corner in float32. When a triangle is
//! far smaller than its distance to the origin (tiny triangles 1e5 away from it, under a
//! ground plane 3e5 across), those differences lose the triangle's shape and a float32 test
//! can hit the wrong triangle or miss, in any float32 library. Here rays are f64, and corners
//! (float32 in the tree) are widened to f64 before any arithmetic, so the shear, the edge
//! functions and the distance carry 29 more bits. The walk is the float32 one-ray walk
//! (`trace::walk_nodes`, generic over the precision) in f64 over the tree's own nodes (no
//! trace layout, no scene scale: f64 holds every float32 scene), the test the float32 test's
//! shear and edge functions (`triangle::Shear`) in f64.
//! It is the plain one-ray walk, about a third of the packet walk's speed (BENCHMARKS.md).

use super::triangle::Shear;
use super::Ray;
use crate::geometry::Triangle;
use crate::tree::KdTree;
use rayon::prelude::*;

type V = [f64; 3];

/// A ray `origin + t * direction` for `t` in `[t_min, t_max]`, in f64.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray64 {
    pub origin: V,
    pub direction: V,
    pub t_min: f64,
    pub t_max: f64,
}

impl Ray64 {
    /// A ray over `[0, inf)`.
    pub fn new(origin: V, direction: V) -> Ray64 {
        Ray64 {
            origin,
            direction,
            t_min: 0.0,
            t_max: f64::INFINITY,
        }
    }
    pub fn with_range(self, t_min: f64, t_max: f64) -> Ray64 {
        Ray64 {
            t_min,
            t_max,
            ..self
        }
    }
    /// Rays with a zero or non-finite direction, a NaN origin or an empty range hit nothing.
    pub fn is_valid(&self) -> bool {
        self.origin.iter().all(|c| c.is_finite())
            && self.direction.iter().all(|c| c.is_finite())
            && self.direction != [0.0; 3]
            && self.t_min <= self.t_max
    }
}

impl From<&Ray> for Ray64 {
    fn from(r: &Ray) -> Ray64 {
        Ray64 {
            origin: r.origin.0.map(f64::from),
            direction: r.direction.0.map(f64::from),
            t_min: r.t_min as f64,
            t_max: r.t_max as f64,
        }
    }
}

/// A hit in f64: the point is `(1 - u - v) * v0 + u * v1 + v * v2` of triangle `prim`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit64 {
    pub t: f64,
    pub prim: u32,
    pub u: f64,
    pub v: f64,
}

impl Hit64 {
    /// [`closer`](super::closer), the float32 queries' order: the walk's `t` is the reported one.
    fn better_than(&self, other: &Option<Hit64>) -> bool {
        super::closer(self.t, self.prim, other.map(|o| (o.t, o.prim)))
    }
}

/// Per-ray constants of the watertight test (Woop, Benthin and Wald 2013) in f64: the
/// float32 test's shear and edge functions (`triangle::Shear`), in f64.
#[derive(Clone, Copy, Debug)]
pub struct ShearedRay64 {
    origin: V,
    shear: Shear<f64>,
}

impl ShearedRay64 {
    pub fn new(ray: &Ray64) -> ShearedRay64 {
        ShearedRay64 {
            origin: ray.origin,
            shear: Shear::new(ray.direction),
        }
    }

    /// The hit with `t_min <= t <= t_max`, if any; rays parallel to the triangle's plane and
    /// zero-area triangles never hit. A distance that rounds just below `t_min` on a ray
    /// whose origin lies on the triangle (within `2^-40` of its size) counts as `t_min`.
    #[inline(always)]
    pub fn intersect(&self, tri: &Triangle, t_min: f64, t_max: f64) -> Option<(f64, f64, f64)> {
        let o = self.origin;
        let rel = [0, 1, 2].map(|i| [0, 1, 2].map(|a| tri[i][a] as f64 - o[a]));
        let crossing = self.shear.cross(rel)?;
        let ([_, ev, ew], det, z) = (crossing.e, crossing.det, crossing.z);
        let t = crossing.t_det() / det;
        let band = (z[0].abs() + z[1].abs() + z[2].abs()) * (1.0 / (1u64 << 40) as f64);
        if !(t <= t_max && t >= t_min - band) {
            return None;
        }
        Some((t.max(t_min), ev / det, ew / det))
    }
}

/// Every triangle tested against the ray, in triangle order: the oracle the f64 walk is
/// checked against. Calls `f` with each hit in `[t_min, t_max]`.
pub fn brute_for_each_hit(triangles: &[Triangle], ray: &Ray64, mut f: impl FnMut(Hit64)) {
    if !ray.is_valid() {
        return;
    }
    let sheared = ShearedRay64::new(ray);
    for (i, tri) in triangles.iter().enumerate() {
        if let Some((t, u, v)) = sheared.intersect(tri, ray.t_min, ray.t_max) {
            f(Hit64 {
                t,
                prim: i as u32,
                u,
                v,
            });
        }
    }
}

/// The closest hit by testing every triangle.
pub fn brute_intersect(triangles: &[Triangle], ray: &Ray64) -> Option<Hit64> {
    let mut best = None;
    brute_for_each_hit(triangles, ray, |h| {
        if h.better_than(&best) {
            best = Some(h);
        }
    });
    best
}

impl KdTree {
    /// The closest hit in `[ray.t_min, ray.t_max]`, walked and tested in f64.
    pub fn intersect_f64(&self, ray: &Ray64) -> Option<Hit64> {
        let mut best: Option<Hit64> = None;
        self.walk_f64(ray, |hit, limit| {
            if hit.better_than(&best) {
                *limit = hit.t;
                best = Some(hit);
            }
            false
        });
        best
    }

    /// True when anything is hit in `[ray.t_min, ray.t_max]`, in f64.
    pub fn occluded_f64(&self, ray: &Ray64) -> bool {
        let mut found = false;
        self.walk_f64(ray, |_, _| {
            found = true;
            true
        });
        found
    }

    /// [`intersect_f64`](Self::intersect_f64) for many rays on every core of the current
    /// rayon pool.
    pub fn intersect_batch_f64(&self, rays: &[Ray64]) -> Vec<Option<Hit64>> {
        rays.par_iter()
            .with_min_len(64)
            .map(|r| self.intersect_f64(r))
            .collect()
    }

    /// [`occluded_f64`](Self::occluded_f64) for many rays on every core of the current pool.
    pub fn occluded_batch_f64(&self, rays: &[Ray64]) -> Vec<bool> {
        rays.par_iter()
            .with_min_len(64)
            .map(|r| self.occluded_f64(r))
            .collect()
    }

    /// The float32 walk (`trace::walk`) in f64 over the tree's own nodes and references.
    fn walk_f64(&self, ray: &Ray64, mut visit: impl FnMut(Hit64, &mut f64) -> bool) {
        if !ray.is_valid() || self.triangles.is_empty() {
            return;
        }
        let inv = ray.direction.map(|c| 1.0 / c);
        let (lo, hi) = (
            self.bounds.lo.0.map(f64::from),
            self.bounds.hi.0.map(f64::from),
        );
        let range = (ray.t_min, ray.t_max);
        let Some(interval) = super::clip(lo, hi, ray.origin, inv, range) else {
            return;
        };
        let sheared = ShearedRay64::new(ray);
        let nodes = &self.nodes;
        super::walk_nodes(
            nodes,
            ray.origin,
            inv,
            interval,
            ray.t_max,
            &mut (),
            |node, limit, _| {
                for &prim in self.leaf_refs(node) {
                    let tri = &self.triangles[prim as usize];
                    if let Some((t, u, v)) = sheared.intersect(tri, ray.t_min, *limit) {
                        if visit(Hit64 { t, prim, u, v }, limit) {
                            return true;
                        }
                    }
                }
                false
            },
        );
    }
}
