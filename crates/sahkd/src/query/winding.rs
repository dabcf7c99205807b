//! The generalized winding number (Jacobson, Kavan and Sorkine-Hornung 2013): the solid
//! angle the mesh subtends at a point, over 4 pi. It is 1 inside and 0 outside a closed
//! outward-wound mesh and degrades gracefully where the mesh has holes or overlaps, which
//! makes `|w| > 1/2` an inside test that needs no watertight mesh. This is the exact sum,
//! every triangle once: O(N) per point.

use super::triangle::{cross, d3, dot, sub, D3};
use crate::geometry::{Triangle, Vec3};

/// The signed solid angle of a triangle seen from `p` (Van Oosterom and Strackee's formula),
/// positive when its corners run counter-clockwise seen from `p`. Zero when `p` is a corner
/// or on the triangle's plane outside it.
#[inline(always)]
pub(crate) fn solid_angle(p: D3, tri: &Triangle) -> f64 {
    let a = sub(d3(tri[0]), p);
    let b = sub(d3(tri[1]), p);
    let c = sub(d3(tri[2]), p);
    let (la, lb, lc) = (dot(a, a).sqrt(), dot(b, b).sqrt(), dot(c, c).sqrt());
    let det = dot(a, cross(b, c));
    let den = la * lb * lc + dot(a, b) * lc + dot(a, c) * lb + dot(b, c) * la;
    2.0 * det.atan2(den)
}

/// The winding number of `triangles` around `p`; NaN for a non-finite point.
pub fn winding_number(triangles: &[Triangle], p: Vec3) -> f64 {
    if !p.is_finite() {
        return f64::NAN;
    }
    let pd = d3(p);
    let total: f64 = triangles.iter().map(|t| solid_angle(pd, t)).sum();
    total / (4.0 * std::f64::consts::PI)
}
