//! The exact closest point of a triangle to a point, in f64.
//!
//! The corners are f32, so every difference below is exact in f64 and the only rounding is
//! in the dot products and the final division. The point's Voronoi region of the triangle
//! (three corners, three edges, the face) is found from six dot products, testing the cheap
//! regions first (after Ericson, Real-Time Collision Detection, 5.1.5). A zero-area
//! triangle has no face region; the tests then always land on a corner or an edge, and a
//! rounding slip into the face is caught and answered by the edges.

use crate::geometry::Triangle;

pub(crate) type D3 = [f64; 3];

#[inline(always)]
pub(crate) fn d3(v: crate::Vec3) -> D3 {
    [v[0] as f64, v[1] as f64, v[2] as f64]
}
#[inline(always)]
pub(crate) fn sub(a: D3, b: D3) -> D3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
#[inline(always)]
pub(crate) fn dot(a: D3, b: D3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
#[inline(always)]
pub(crate) fn cross(a: D3, b: D3) -> D3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
#[inline(always)]
fn norm2(a: D3) -> f64 {
    dot(a, a)
}

/// The closest point of a triangle: squared distance and barycentric weights of the three
/// corners (summing to 1; the point is `w0 * v0 + w1 * v1 + w2 * v2`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TrianglePoint {
    pub distance2: f64,
    pub weights: [f64; 3],
}

impl TrianglePoint {
    /// The point itself, from the weights and the corners.
    pub fn point(&self, tri: &Triangle) -> D3 {
        let [w0, w1, w2] = self.weights;
        let (a, b, c) = (d3(tri[0]), d3(tri[1]), d3(tri[2]));
        std::array::from_fn(|k| w0 * a[k] + w1 * b[k] + w2 * c[k])
    }
}

/// Weights of the point `(1 - s) * a + s * b` as corner weights `i` and `j`.
#[inline(always)]
fn on_edge(i: usize, j: usize, s: f64) -> [f64; 3] {
    let mut w = [0.0; 3];
    w[i] = 1.0 - s;
    w[j] = s;
    w
}

/// `n / d` kept in [0, 1]; 0 when rounding leaves `d` zero (then `n` is too).
#[inline(always)]
fn fraction(n: f64, d: f64) -> f64 {
    if d > 0.0 {
        (n / d).clamp(0.0, 1.0)
    } else {
        0.0
    }
}

/// The closest point of segment `ab` to `p`, as the parameter along it.
#[inline(always)]
fn segment_param(p: D3, a: D3, b: D3) -> f64 {
    let ab = sub(b, a);
    let len2 = norm2(ab);
    if len2 == 0.0 {
        return 0.0;
    }
    (dot(sub(p, a), ab) / len2).clamp(0.0, 1.0)
}

/// The closest point of `tri` to `p`, exactly up to f64 rounding.
pub fn closest_on_triangle(p: D3, tri: &Triangle) -> TrianglePoint {
    let (a, b, c) = (d3(tri[0]), d3(tri[1]), d3(tri[2]));
    let weights = region_weights(p, a, b, c);
    let q: D3 = std::array::from_fn(|k| weights[0] * a[k] + weights[1] * b[k] + weights[2] * c[k]);
    TrianglePoint {
        distance2: norm2(sub(p, q)),
        weights,
    }
}

#[inline(always)]
fn region_weights(p: D3, a: D3, b: D3, c: D3) -> [f64; 3] {
    let ab = sub(b, a);
    let ac = sub(c, a);
    // Corner a: p lies behind both edges leaving a.
    let ap = sub(p, a);
    let d1 = dot(ab, ap);
    let d2 = dot(ac, ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return [1.0, 0.0, 0.0];
    }
    // The region tests below assume a proper triangle; a flat one (exactly zero normal: the
    // differences are exact, the products nearly so) is answered by its edges.
    if cross(ab, ac) == [0.0; 3] {
        return nearest_edge(p, a, b, c);
    }
    // Corner b.
    let bp = sub(p, b);
    let d3 = dot(ab, bp);
    let d4 = dot(ac, bp);
    if d3 >= 0.0 && d4 <= d3 {
        return [0.0, 1.0, 0.0];
    }
    // Edge ab: p projects inside it and lies outside the face across it. `vc` is (up to the
    // factor |ab x ac|^2) the face barycentric of c.
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return on_edge(0, 1, fraction(d1, d1 - d3));
    }
    // Corner c.
    let cp = sub(p, c);
    let d5 = dot(ab, cp);
    let d6 = dot(ac, cp);
    if d6 >= 0.0 && d5 <= d6 {
        return [0.0, 0.0, 1.0];
    }
    // Edge ac.
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return on_edge(0, 2, fraction(d2, d2 - d6));
    }
    // Edge bc.
    let va = d3 * d6 - d5 * d4;
    let (e, f) = (d4 - d3, d5 - d6);
    if va <= 0.0 && e >= 0.0 && f >= 0.0 {
        return on_edge(1, 2, fraction(e, e + f));
    }
    // The face. Positive for a proper triangle; zero or a rounding artefact for a flat one,
    // which has no face region: its nearest point is then on one of its edges.
    let sum = va + vb + vc;
    if sum > 0.0 && va >= 0.0 && vb >= 0.0 && vc >= 0.0 {
        let inv = 1.0 / sum;
        let (v, w) = (vb * inv, vc * inv);
        let weights = [1.0 - v - w, v, w];
        if weights.iter().all(|x| x.is_finite()) {
            return weights;
        }
    }
    nearest_edge(p, a, b, c)
}

/// The nearest of the three edges' closest points; ties keep the first edge (ab, bc, ca).
#[cold]
fn nearest_edge(p: D3, a: D3, b: D3, c: D3) -> [f64; 3] {
    let mut best = ([1.0, 0.0, 0.0], f64::INFINITY);
    for (i, j, u, v) in [(0, 1, a, b), (1, 2, b, c), (2, 0, c, a)] {
        let s = segment_param(p, u, v);
        let q: D3 = std::array::from_fn(|k| u[k] + s * (v[k] - u[k]));
        let d = norm2(sub(p, q));
        if d < best.1 {
            best = (on_edge(i, j, s), d);
        }
    }
    best.0
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Vec3;

    fn tri() -> Triangle {
        [
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
        ]
    }

    #[test]
    fn each_region_gives_its_point() {
        let t = tri();
        let cases: [(D3, D3, f64); 7] = [
            ([0.25, 0.25, 2.0], [0.25, 0.25, 0.0], 4.0), // face
            ([-1.0, -1.0, 0.0], [0.0, 0.0, 0.0], 2.0),   // corner a
            ([2.0, -1.0, 0.0], [1.0, 0.0, 0.0], 2.0),    // corner b
            ([-1.0, 3.0, 1.0], [0.0, 1.0, 0.0], 6.0),    // corner c
            ([0.5, -2.0, 0.0], [0.5, 0.0, 0.0], 4.0),    // edge ab
            ([-3.0, 0.5, 0.0], [0.0, 0.5, 0.0], 9.0),    // edge ac
            ([1.0, 1.0, 0.0], [0.5, 0.5, 0.0], 0.5),     // edge bc
        ];
        for (p, want, d2) in cases {
            let got = closest_on_triangle(p, &t);
            let q = got.point(&t);
            for k in 0..3 {
                assert!((q[k] - want[k]).abs() < 1e-12, "{p:?}: {q:?} vs {want:?}");
            }
            assert!(
                (got.distance2 - d2).abs() < 1e-12,
                "{p:?}: {}",
                got.distance2
            );
            assert!((got.weights.iter().sum::<f64>() - 1.0).abs() < 1e-12);
        }
    }

    #[test]
    fn flat_triangles_answer_from_their_edges() {
        // Collinear corners, and all three corners equal.
        let line = [
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(2.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
        ];
        let got = closest_on_triangle([1.5, 1.0, 0.0], &line);
        assert!((got.distance2 - 1.0).abs() < 1e-12, "{got:?}");
        let q = got.point(&line);
        assert!((q[0] - 1.5).abs() < 1e-12 && q[1].abs() < 1e-12, "{q:?}");
        let dot = [Vec3::new(1.0, 2.0, 3.0); 3];
        let got = closest_on_triangle([1.0, 2.0, 5.0], &dot);
        assert_eq!(got.distance2, 4.0);
    }
}
