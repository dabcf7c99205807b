//! Watertight ray/triangle intersection (Woop, Benthin and Wald 2013).
//!
//! The ray is sheared so that it runs along +z from the origin; each triangle is then tested
//! with 2-D edge functions whose signs are exact enough that a ray through a shared edge or
//! vertex hits at least one of the triangles meeting there. When an edge function comes out
//! exactly zero it is recomputed in f64, as the paper recommends.

use super::Ray;
use crate::geometry::{Triangle, Vec3};

/// Per-ray constants of the shear.
#[derive(Clone, Copy, Debug)]
pub struct ShearedRay {
    origin: Vec3,
    kx: usize,
    ky: usize,
    kz: usize,
    sx: f32,
    sy: f32,
    sz: f32,
}

/// Distance and barycentrics of a hit: the point is `(1 - u - v) * v0 + u * v1 + v * v2`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TriangleHit {
    pub t: f32,
    pub u: f32,
    pub v: f32,
}

impl ShearedRay {
    pub fn new(ray: &Ray) -> ShearedRay {
        let d = ray.direction;
        let abs = [d[0].abs(), d[1].abs(), d[2].abs()];
        let kz = if abs[0] >= abs[1] && abs[0] >= abs[2] {
            0
        } else if abs[1] >= abs[2] {
            1
        } else {
            2
        };
        let mut kx = (kz + 1) % 3;
        let mut ky = (kx + 1) % 3;
        // Keep the winding of the triangles as seen along the ray.
        if d[kz] < 0.0 {
            std::mem::swap(&mut kx, &mut ky);
        }
        ShearedRay {
            origin: ray.origin,
            kx,
            ky,
            kz,
            sx: d[kx] / d[kz],
            sy: d[ky] / d[kz],
            sz: 1.0 / d[kz],
        }
    }

    /// The hit with `t_min <= t <= t_max`, if any. Rays parallel to the triangle's plane and
    /// zero-area triangles never hit.
    #[inline(always)]
    pub fn intersect(&self, tri: &Triangle, t_min: f32, t_max: f32) -> Option<TriangleHit> {
        let (kx, ky, kz) = (self.kx, self.ky, self.kz);
        let a = tri[0] - self.origin;
        let b = tri[1] - self.origin;
        let c = tri[2] - self.origin;
        let ax = a[kx] - self.sx * a[kz];
        let ay = a[ky] - self.sy * a[kz];
        let bx = b[kx] - self.sx * b[kz];
        let by = b[ky] - self.sy * b[kz];
        let cx = c[kx] - self.sx * c[kz];
        let cy = c[ky] - self.sy * c[kz];
        let mut eu = cx * by - cy * bx;
        let mut ev = ax * cy - ay * cx;
        let mut ew = bx * ay - by * ax;
        // `|` and `&` rather than `||` and `&&` in these tests: the same answers, one branch
        // instead of a chain of hard-to-predict ones (measured faster).
        if (eu == 0.0) | (ev == 0.0) | (ew == 0.0) {
            let f =
                |p: f32, q: f32, r: f32, s: f32| (p as f64 * q as f64 - r as f64 * s as f64) as f32;
            eu = f(cx, by, cy, bx);
            ev = f(ax, cy, ay, cx);
            ew = f(bx, ay, by, ax);
        }
        if ((eu < 0.0) | (ev < 0.0) | (ew < 0.0)) & ((eu > 0.0) | (ev > 0.0) | (ew > 0.0)) {
            return None;
        }
        let det = eu + ev + ew;
        if det == 0.0 {
            return None;
        }
        let az = self.sz * a[kz];
        let bz = self.sz * b[kz];
        let cz = self.sz * c[kz];
        let inv = 1.0 / det;
        let t = (eu * az + ev * bz + ew * cz) * inv;
        if !((t >= t_min) & (t <= t_max)) {
            return None;
        }
        Some(TriangleHit {
            t,
            u: ev * inv,
            v: ew * inv,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ray(o: [f32; 3], d: [f32; 3]) -> Ray {
        Ray::new(Vec3(o), Vec3(d))
    }

    #[test]
    fn hit_distance_and_barycentrics_match_hand_computation() {
        let tri = [
            Vec3::new(0.0, 0.0, 5.0),
            Vec3::new(1.0, 0.0, 5.0),
            Vec3::new(0.0, 1.0, 5.0),
        ];
        let r = ray([0.25, 0.5, 0.0], [0.0, 0.0, 1.0]);
        let h = ShearedRay::new(&r)
            .intersect(&tri, 0.0, f32::INFINITY)
            .unwrap();
        assert_eq!(h.t, 5.0);
        assert!(
            (h.u - 0.25).abs() < 1e-6 && (h.v - 0.5).abs() < 1e-6,
            "{h:?}"
        );
        // Backwards along the ray, and beyond t_max: no hit.
        let back = ray([0.25, 0.5, 10.0], [0.0, 0.0, 1.0]);
        assert!(ShearedRay::new(&back)
            .intersect(&tri, 0.0, f32::INFINITY)
            .is_none());
        assert!(ShearedRay::new(&r).intersect(&tri, 0.0, 4.9).is_none());
    }

    #[test]
    fn a_ray_through_a_shared_edge_hits_one_of_the_two_triangles() {
        // Two triangles sharing the diagonal of a square; rays along the diagonal.
        let p = [
            Vec3::new(0.0, 0.0, 1.0),
            Vec3::new(1.0, 0.0, 1.0),
            Vec3::new(1.0, 1.0, 1.0),
            Vec3::new(0.0, 1.0, 1.0),
        ];
        let t1 = [p[0], p[1], p[2]];
        let t2 = [p[0], p[2], p[3]];
        for i in 1..100 {
            let s = i as f32 / 100.0;
            let r = ray([s, s, 0.0], [0.0, 0.0, 1.0]);
            let sr = ShearedRay::new(&r);
            let hits = [&t1, &t2]
                .iter()
                .filter(|t| sr.intersect(t, 0.0, f32::INFINITY).is_some())
                .count();
            assert!(hits >= 1, "ray at {s} slipped through the shared edge");
        }
    }

    #[test]
    fn degenerate_triangles_and_parallel_rays_miss() {
        let line = [
            Vec3::new(0.0, 0.0, 1.0),
            Vec3::new(1.0, 0.0, 1.0),
            Vec3::new(2.0, 0.0, 1.0),
        ];
        let r = ray([0.5, 0.0, 0.0], [0.0, 0.0, 1.0]);
        assert!(ShearedRay::new(&r)
            .intersect(&line, 0.0, f32::INFINITY)
            .is_none());
        let tri = [
            Vec3::new(0.0, 0.0, 1.0),
            Vec3::new(1.0, 0.0, 1.0),
            Vec3::new(0.0, 1.0, 1.0),
        ];
        let parallel = ray([-1.0, 0.2, 1.0], [1.0, 0.0, 0.0]);
        assert!(ShearedRay::new(&parallel)
            .intersect(&tri, 0.0, f32::INFINITY)
            .is_none());
    }
}
