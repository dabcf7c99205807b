//! The oracle: the closest point and the winding number from every triangle, no tree.
//!
//! The closest point shares only the point-triangle routine with the tree walk, so a walk
//! that prunes a node it should have entered shows up as a disagreement with it.

use super::triangle::{closest_on_triangle, d3};
use super::ClosestPoint;
use crate::geometry::{Triangle, Vec3};

/// The closest point over all triangles (ties go to the lower triangle index); `None` when
/// there are no triangles or the point is not finite.
pub fn closest_point(triangles: &[Triangle], p: Vec3) -> Option<ClosestPoint> {
    if !p.is_finite() {
        return None;
    }
    let pd = d3(p);
    let mut best: Option<(f64, u32, [f64; 3])> = None;
    for (i, tri) in triangles.iter().enumerate() {
        let found = closest_on_triangle(pd, tri);
        if best.is_none_or(|(d2, _, _)| found.distance2 < d2) {
            best = Some((found.distance2, i as u32, found.weights));
        }
    }
    best.map(|(d2, prim, w)| ClosestPoint::new(d2, prim, w, &triangles[prim as usize]))
}
