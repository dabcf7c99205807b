//! The oracle: every query answered by testing every triangle.
//!
//! It shares only the ray/triangle test and the scene's scale ([`scene_scale`]) with the tree
//! traversal, so a tree that loses, misplaces or mis-orders a triangle shows up as a
//! disagreement with it.

use super::{finish_hit, Closest, Hit, Ray, ShearedRay};
use crate::geometry::{scene_scale, triangle_bounds, Aabb, Triangle};
use crate::tree::layout::reach_of;

/// The scale the tree of these triangles is traced at, the largest extent of the scaled
/// scene, the test and the ray scaled.
fn prepare(triangles: &[Triangle], ray: &Ray) -> Option<(f32, f32, ShearedRay, Ray)> {
    if !ray.is_valid() {
        return None;
    }
    let bounds = triangles
        .iter()
        .fold(Aabb::EMPTY, |b, t| b.union(triangle_bounds(t)));
    let scale = scene_scale(&bounds);
    let scaled = ray.scaled(scale);
    let reach = reach_of(&bounds.scaled(scale));
    scaled
        .origin
        .is_finite()
        .then(|| (scale, reach, ShearedRay::with_reach(&scaled, reach), scaled))
}

/// Calls `f` with the hit of every triangle hit in `[ray.t_min, ray.t_max]`, in triangle
/// order, each as [`KdTree::for_each_hit`](crate::KdTree::for_each_hit) reports it.
pub fn for_each_hit(triangles: &[Triangle], ray: &Ray, mut f: impl FnMut(Hit)) {
    let Some((scale, _, sheared, scaled)) = prepare(triangles, ray) else {
        return;
    };
    for (i, tri) in triangles.iter().enumerate() {
        if let Some(h) = sheared.intersect(&tri.map(|v| v * scale), scaled.t_min, scaled.t_max) {
            let hit = Hit {
                t: h.t,
                prim: i as u32,
                u: h.u,
                v: h.v,
            };
            f(finish_hit(tri, ray, hit, 1.0 / scale));
        }
    }
}

/// The closest hit over all triangles, by [`closer`](super::closer) on the reported hits
/// (ties go to the lower triangle index).
pub fn intersect(triangles: &[Triangle], ray: &Ray) -> Option<Hit> {
    let (scale, reach, sheared, scaled) = prepare(triangles, ray)?;
    let mut closest = Closest::new(triangles, ray, scale, reach);
    let mut limit = scaled.t_max;
    for (i, tri) in triangles.iter().enumerate() {
        let tri = tri.map(|v| v * scale);
        if let Some(h) = sheared.intersect(&tri, scaled.t_min, limit) {
            let hit = Hit {
                t: h.t,
                prim: i as u32,
                u: h.u,
                v: h.v,
            };
            closest.offer(hit, &mut limit);
        }
    }
    closest.best()
}

/// Whether any triangle is hit.
pub fn occluded(triangles: &[Triangle], ray: &Ray) -> bool {
    let Some((scale, _, sheared, scaled)) = prepare(triangles, ray) else {
        return false;
    };
    triangles.iter().any(|t| {
        sheared
            .intersect(&t.map(|v| v * scale), scaled.t_min, scaled.t_max)
            .is_some()
    })
}
