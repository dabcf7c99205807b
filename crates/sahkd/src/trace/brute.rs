//! The oracle: every query answered by testing every triangle.
//!
//! It shares only the ray/triangle test with the tree traversal, so a tree that loses,
//! misplaces or mis-orders a triangle shows up as a disagreement with it.

use super::{Hit, Ray, ShearedRay};
use crate::geometry::Triangle;

/// The closest hit over all triangles (ties go to the lower triangle index).
pub fn intersect(triangles: &[Triangle], ray: &Ray) -> Option<Hit> {
    if !ray.is_valid() {
        return None;
    }
    let sheared = ShearedRay::new(ray);
    let mut best: Option<Hit> = None;
    let mut best_t = ray.t_max;
    for (i, tri) in triangles.iter().enumerate() {
        if let Some(h) = sheared.intersect(tri, ray.t_min, best_t) {
            let hit = Hit {
                t: h.t,
                prim: i as u32,
                u: h.u,
                v: h.v,
            };
            if hit.better_than(&best) {
                best_t = hit.t;
                best = Some(hit);
            }
        }
    }
    best
}

/// Whether any triangle is hit.
pub fn occluded(triangles: &[Triangle], ray: &Ray) -> bool {
    if !ray.is_valid() {
        return false;
    }
    let sheared = ShearedRay::new(ray);
    triangles
        .iter()
        .any(|t| sheared.intersect(t, ray.t_min, ray.t_max).is_some())
}
