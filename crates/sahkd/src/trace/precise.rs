//! Double-precision ray queries: the same tree, walked and tested in f64.
//!
//! The float32 test subtracts the ray origin from each corner in float32. When a triangle is
//! far smaller than its distance to the origin (tiny triangles 1e5 away from it, under a
//! ground plane 3e5 across), those differences lose the triangle's shape and a float32 test
//! can hit the wrong triangle or miss, in any float32 library. Here rays are f64, and corners
//! (float32 in the tree) are widened to f64 before any arithmetic, so the shear, the edge
//! functions and the distance carry 29 more bits. The walk is the float32 walk's in f64 over
//! the tree's own nodes (no trace layout, no scene scale: f64 holds every float32 scene).
//! It is the plain one-ray walk, about a third of the packet walk's speed (BENCHMARKS.md).

use super::Ray;
use crate::cost::MAX_DEPTH_CAP;
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
/// float32 test's shear axes, with the shear factors held as one array so that a corner is
/// sheared by one expression.
#[derive(Clone, Copy, Debug)]
pub struct ShearedRay64 {
    origin: V,
    /// `kx`, `ky`, `kz` of [`shear_axes`](super::triangle::shear_axes).
    axes: [usize; 3],
    /// `d[kx] / d[kz]`, `d[ky] / d[kz]`, `1 / d[kz]`.
    factors: V,
}

impl ShearedRay64 {
    pub fn new(ray: &Ray64) -> ShearedRay64 {
        let d = ray.direction;
        let (kx, ky, kz) = super::triangle::shear_axes(d);
        let factors = [d[kx], d[ky], 1.0].map(|n| n / d[kz]);
        ShearedRay64 {
            origin: ray.origin,
            axes: [kx, ky, kz],
            factors,
        }
    }

    /// A corner relative to the origin, sheared so that the ray runs along +z: its x, y and
    /// its scaled z.
    #[inline(always)]
    fn shear(&self, corner: [f32; 3]) -> V {
        let [kx, ky, kz] = self.axes;
        let [sx, sy, sz] = self.factors;
        let p = [0, 1, 2].map(|a| corner[a] as f64 - self.origin[a]);
        [p[kx] - sx * p[kz], p[ky] - sy * p[kz], sz * p[kz]]
    }

    /// The hit with `t_min <= t <= t_max`, if any; rays parallel to the triangle's plane and
    /// zero-area triangles never hit. A distance that rounds just below `t_min` on a ray
    /// whose origin lies on the triangle (within `2^-40` of its size) counts as `t_min`.
    #[inline(always)]
    pub fn intersect(&self, tri: &Triangle, t_min: f64, t_max: f64) -> Option<(f64, f64, f64)> {
        let [ax, ay, az] = self.shear(tri[0].0);
        let [bx, by, bz] = self.shear(tri[1].0);
        let [cx, cy, cz] = self.shear(tri[2].0);
        let eu = cx * by - cy * bx;
        let ev = ax * cy - ay * cx;
        let ew = bx * ay - by * ax;
        if (eu < 0.0 || ev < 0.0 || ew < 0.0) && (eu > 0.0 || ev > 0.0 || ew > 0.0) {
            return None;
        }
        let det = eu + ev + ew;
        if det == 0.0 {
            return None;
        }
        let t = (eu * az + ev * bz + ew * cz) / det;
        let band = (az.abs() + bz.abs() + cz.abs()) * (1.0 / (1u64 << 40) as f64);
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
        let (o, d) = (ray.origin, ray.direction);
        let inv = d.map(|c| 1.0 / c);
        let (mut t0, mut t1) = (ray.t_min, ray.t_max);
        for a in 0..3 {
            let (lo, hi) = (self.bounds.lo[a] as f64, self.bounds.hi[a] as f64);
            if inv[a].is_finite() {
                let (p, q) = ((lo - o[a]) * inv[a], (hi - o[a]) * inv[a]);
                t0 = t0.max(p.min(q));
                t1 = t1.min(p.max(q));
            } else if !(o[a] >= lo && o[a] <= hi) {
                return;
            }
        }
        if t0 > t1 {
            return;
        }
        let near_is_right = [0, 1, 2].map(|a| d[a].is_sign_negative() as u32);
        let sheared = ShearedRay64::new(ray);
        let mut stack = Vec::with_capacity(MAX_DEPTH_CAP as usize + 4);
        let mut node_index = 0u32;
        let mut limit = ray.t_max;
        loop {
            if t0 <= limit {
                let node = &self.nodes[node_index as usize];
                if !node.is_leaf() {
                    let axis = node.axis();
                    let t_plane = (node.split() as f64 - o[axis]) * inv[axis];
                    let near = node.left() + near_is_right[axis];
                    let far = node.left() + 1 - near_is_right[axis];
                    match super::cut(t_plane, t0, t1) {
                        super::Cut::Near => node_index = near,
                        super::Cut::Far => node_index = far,
                        super::Cut::Both { far_t0, near_t1 } => {
                            stack.push((far, far_t0, t1));
                            node_index = near;
                            t1 = near_t1;
                        }
                    }
                    continue;
                }
                for &prim in self.leaf_refs(node) {
                    let tri = &self.triangles[prim as usize];
                    if let Some((t, u, v)) = sheared.intersect(tri, ray.t_min, limit) {
                        if visit(Hit64 { t, prim, u, v }, &mut limit) {
                            return;
                        }
                    }
                }
            }
            let Some((n, a, b)) = stack.pop() else {
                return;
            };
            (node_index, t0, t1) = (n, a, b);
        }
    }
}
