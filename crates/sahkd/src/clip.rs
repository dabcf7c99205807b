//! Clipping a triangle to a box: the "perfect splits" of Wald & Havran and the overlap test
//! of `validate`.
//!
//! The clipped bounds are a pure function of the original triangle and the box (never of an
//! earlier clipped polygon), so every builder that clips gets bit-identical boxes.

use crate::geometry::{Aabb, Triangle, Vec3};
use std::mem::MaybeUninit;

/// At most 3 + 6 vertices survive clipping a triangle by six planes.
const MAX_VERTS: usize = 9;

/// Bounds of the part of `tri` inside the closed box `b`, or an empty box when the triangle
/// misses it. Computed in f64 and rounded outwards to f32, then limited to `b`; a zero bound
/// is +0 (which zero a `min` of -0 and +0 keeps is up to the compiler, and the GPU's clip must
/// give the same bits).
pub fn clipped_bounds(tri: &Triangle, b: &Aabb) -> Aabb {
    let start = Polygon::of(tri);
    let mut scratch = Polygon::scratch();
    match clip_to_axes(&start, b, 0..3, &mut scratch) {
        Some(poly) => poly.bounds(b),
        None => Aabb::EMPTY,
    }
}

/// `clipped_bounds(tri, left)` and `clipped_bounds(tri, right)` for the two halves of `node`
/// split at `pos` on `axis`, bit for bit. The planes of the axes before `axis` are the same
/// for both halves and come first in the order every clip uses, so they are cut once and
/// the polygon they leave is cut on by each half's remaining planes.
pub fn clipped_halves(tri: &Triangle, node: &Aabb, axis: usize, pos: f32) -> (Aabb, Aabb) {
    let (left, right) = node.split(axis, pos);
    let start = Polygon::of(tri);
    let mut scratch = Polygon::scratch();
    let Some(shared) = clip_to_axes(&start, node, 0..axis, &mut scratch) else {
        return (Aabb::EMPTY, Aabb::EMPTY);
    };
    let half = |b: &Aabb| {
        let mut scratch = Polygon::scratch();
        match clip_to_axes(shared, b, axis..3, &mut scratch) {
            Some(poly) => poly.bounds(b),
            None => Aabb::EMPTY,
        }
    };
    (half(&left), half(&right))
}

/// A convex polygon in f64 with the exact bounds of its vertices, which decide whether a
/// plane cuts it at all and are its clipped box at the end. Only `verts[..n]` is written:
/// the buffers are not zeroed, as a clip makes three of them per triangle and most planes
/// cut nothing.
struct Polygon {
    verts: [MaybeUninit<[f64; 3]>; MAX_VERTS],
    n: usize,
    lo: [f64; 3],
    hi: [f64; 3],
}

/// `start` cut by the low then the high plane of `b` on each of `axes`, in order: `start`
/// itself when no plane cuts it, else one of the two `scratch` polygons, which the cuts
/// write in turn (so that no plane copies a whole polygon); `None` once nothing is left.
fn clip_to_axes<'a>(
    start: &'a Polygon,
    b: &Aabb,
    axes: std::ops::Range<usize>,
    scratch: &'a mut [Polygon; 2],
) -> Option<&'a Polygon> {
    // Which scratch polygon holds the result so far; none while it is `start`.
    let mut cur: Option<usize> = None;
    for axis in axes {
        if !plane::<false>(start, scratch, &mut cur, axis, b.lo[axis] as f64)
            || !plane::<true>(start, scratch, &mut cur, axis, b.hi[axis] as f64)
        {
            return None;
        }
    }
    Some(match cur {
        None => start,
        Some(i) => &scratch[i],
    })
}

/// One plane of [`clip_to_axes`]: keeps the part of the polygon so far (`start`, or
/// `scratch[cur]`) on the inner side of `axis = bound` (below it with `KEEP_BELOW`); false
/// when nothing is left.
#[inline(always)]
fn plane<const KEEP_BELOW: bool>(
    start: &Polygon,
    scratch: &mut [Polygon; 2],
    cur: &mut Option<usize>,
    axis: usize,
    bound: f64,
) -> bool {
    let [first, second] = scratch;
    let (src, dst, to) = match *cur {
        None => (start, first, 0),
        Some(0) => (&*first, second, 1),
        Some(_) => (&*second, first, 0),
    };
    // A plane that cuts nothing leaves the polygon as it is: skip it. The bounds are the
    // vertices' extremes, so this is "every vertex inside".
    let uncut = if KEEP_BELOW {
        src.hi[axis] <= bound
    } else {
        src.lo[axis] >= bound
    };
    if uncut {
        return true;
    }
    *cur = Some(to);
    dst.cut::<KEEP_BELOW>(src, axis, bound)
}

impl Polygon {
    /// Two polygons to clip into. Made at run time, not copied from a constant: a constant
    /// is copied whole, its unwritten vertices as zeros.
    #[inline(always)]
    fn scratch() -> [Polygon; 2] {
        [Polygon::blank(), Polygon::blank()]
    }

    #[inline(always)]
    fn blank() -> Polygon {
        Polygon {
            verts: [const { MaybeUninit::uninit() }; MAX_VERTS],
            n: 0,
            lo: [0.0; 3],
            hi: [0.0; 3],
        }
    }

    #[inline(always)]
    fn of(tri: &Triangle) -> Polygon {
        let mut poly = Polygon::blank();
        for (k, v) in tri.iter().enumerate() {
            poly.verts[k].write(v.0.map(|c| c as f64));
        }
        poly.n = 3;
        poly.measure();
        poly
    }

    /// The vertices.
    #[inline(always)]
    fn verts(&self) -> &[[f64; 3]] {
        debug_assert!(self.n <= MAX_VERTS);
        // SAFETY: every writer of `n` has written `verts[..n]` first; MaybeUninit<T> has the
        // layout of T.
        unsafe { std::slice::from_raw_parts(self.verts.as_ptr().cast(), self.n) }
    }

    /// Sets `lo` and `hi` to the extremes of the (at least one) vertices. Compared, not
    /// `f64::min`: the values are finite, and a -0 kept for a +0 is made +0 by `bounds`.
    #[inline(always)]
    fn measure(&mut self) {
        let verts = self.verts();
        let (mut lo, mut hi) = (verts[0], verts[0]);
        for p in &verts[1..] {
            for a in 0..3 {
                if p[a] < lo[a] {
                    lo[a] = p[a];
                }
                if p[a] > hi[a] {
                    hi[a] = p[a];
                }
            }
        }
        (self.lo, self.hi) = (lo, hi);
    }

    /// Becomes the part of `src` on the inner side of the plane `axis = bound` (below it
    /// with `KEEP_BELOW`); false when nothing is left.
    #[inline(always)]
    fn cut<const KEEP_BELOW: bool>(&mut self, src: &Polygon, axis: usize, bound: f64) -> bool {
        let inside = |p: &[f64; 3]| {
            if KEEP_BELOW {
                p[axis] <= bound
            } else {
                p[axis] >= bound
            }
        };
        let poly = src.verts();
        let n = poly.len();
        let mut m = 0;
        let mut pin = inside(&poly[0]);
        for i in 0..n {
            let p = &poly[i];
            let q = &poly[if i + 1 == n { 0 } else { i + 1 }];
            let qin = inside(q);
            // Rounding can bend a clipped polygon very slightly; the caps keep a pathological
            // one inside the buffers (as the GPU's clip does) instead of panicking.
            if pin && m < MAX_VERTS {
                self.verts[m].write(*p);
                m += 1;
            }
            if pin != qin && m < MAX_VERTS {
                let t = (bound - p[axis]) / (q[axis] - p[axis]);
                let mut x = [0f64; 3];
                for a in 0..3 {
                    x[a] = p[a] + t * (q[a] - p[a]);
                }
                x[axis] = bound;
                self.verts[m].write(x);
                m += 1;
            }
            pin = qin;
        }
        self.n = m;
        if m > 0 {
            self.measure();
        }
        m > 0
    }

    /// The polygon's bounds rounded outwards to f32 and limited to `b`, zeros as +0.
    fn bounds(&self, b: &Aabb) -> Aabb {
        let out =
            Aabb::new(Vec3(self.lo.map(round_down)), Vec3(self.hi.map(round_up))).intersection(*b);
        // x + 0.0 is x, except that -0 becomes +0.
        Aabb::new(
            Vec3(out.lo.0.map(|x| x + 0.0)),
            Vec3(out.hi.0.map(|x| x + 0.0)),
        )
    }
}

/// The largest f32 at most `x` (the lower bound of a clipped box).
pub fn round_down(x: f64) -> f32 {
    let f = x as f32;
    if (f as f64) > x {
        f.next_down()
    } else {
        f
    }
}

/// The smallest f32 at least `x` (the upper bound of a clipped box).
pub fn round_up(x: f64) -> f32 {
    let f = x as f32;
    if (f as f64) < x {
        f.next_up()
    } else {
        f
    }
}

/// True when the triangle has a point inside the closed box.
pub fn overlaps(tri: &Triangle, b: &Aabb) -> bool {
    !b.is_empty() && !clipped_bounds(tri, b).is_empty()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tri(a: [f32; 3], b: [f32; 3], c: [f32; 3]) -> Triangle {
        [Vec3(a), Vec3(b), Vec3(c)]
    }

    #[test]
    fn clipping_a_diagonal_triangle_to_a_half_box() {
        // The triangle (0,0,0) (2,0,0) (0,2,0) clipped to x <= 1 spans x 0..1, y 0..2.
        let t = tri([0.0; 3], [2.0, 0.0, 0.0], [0.0, 2.0, 0.0]);
        let b = Aabb::new(Vec3::splat(-1.0), Vec3::new(1.0, 3.0, 1.0));
        let c = clipped_bounds(&t, &b);
        assert_eq!(c, Aabb::new(Vec3::splat(0.0), Vec3::new(1.0, 2.0, 0.0)));
        // Clipped to x >= 1.5 it spans x 1.5..2, y 0..0.5.
        let b = Aabb::new(Vec3::new(1.5, -1.0, -1.0), Vec3::splat(3.0));
        let c = clipped_bounds(&t, &b);
        assert_eq!(c.lo, Vec3::new(1.5, 0.0, 0.0));
        assert_eq!(c.hi, Vec3::new(2.0, 0.5, 0.0));
    }

    #[test]
    fn halves_are_the_clips_to_each_half_bit_for_bit() {
        let mut seed = 777u64;
        let mut rnd = move || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((seed >> 40) as f32 / (1u64 << 24) as f32) * 2.0 - 1.0
        };
        for round in 0..3000 {
            let t = tri(
                [rnd(), rnd(), rnd()],
                [rnd(), rnd(), rnd()],
                [rnd(), rnd(), rnd()],
            );
            let (p, q) = (Vec3([rnd(), rnd(), rnd()]), Vec3([rnd(), rnd(), rnd()]));
            let node = Aabb::new(p.min(q), p.max(q));
            let axis = round % 3;
            let pos = node.lo[axis] + (node.hi[axis] - node.lo[axis]) * (rnd() * 0.5 + 0.5);
            let (left, right) = node.split(axis, pos);
            let bits = |b: Aabb| [b.lo.0, b.hi.0].map(|v| v.map(f32::to_bits));
            let (l, r) = clipped_halves(&t, &node, axis, pos);
            assert_eq!(bits(l), bits(clipped_bounds(&t, &left)), "round {round}");
            assert_eq!(bits(r), bits(clipped_bounds(&t, &right)), "round {round}");
        }
    }

    #[test]
    fn a_triangle_beside_the_box_is_clipped_away() {
        let t = tri([0.0; 3], [2.0, 0.0, 0.0], [0.0, 2.0, 0.0]);
        // The box's corner (1.5, 1.5) lies beyond the hypotenuse x + y = 2.
        let b = Aabb::new(Vec3::new(1.5, 1.5, -1.0), Vec3::new(3.0, 3.0, 1.0));
        assert!(clipped_bounds(&t, &b).is_empty());
        assert!(!overlaps(&t, &b));
        let b = Aabb::new(Vec3::new(0.9, 0.9, -1.0), Vec3::new(3.0, 3.0, 1.0));
        assert!(overlaps(&t, &b));
    }

    #[test]
    fn clipped_bounds_always_contain_the_exact_part_inside() {
        // Random triangles against random boxes: sample points of the triangle inside the box
        // must lie inside the clipped bounds.
        let mut seed = 12345u64;
        let mut rnd = move || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((seed >> 40) as f32 / (1u64 << 24) as f32) * 2.0 - 1.0
        };
        for _ in 0..2000 {
            let t = tri(
                [rnd(), rnd(), rnd()],
                [rnd(), rnd(), rnd()],
                [rnd(), rnd(), rnd()],
            );
            let (p, q) = (Vec3([rnd(), rnd(), rnd()]), Vec3([rnd(), rnd(), rnd()]));
            let b = Aabb::new(p.min(q), p.max(q));
            let c = clipped_bounds(&t, &b);
            for i in 0..=10 {
                for j in 0..=(10 - i) {
                    let (u, v) = (i as f32 / 10.0, j as f32 / 10.0);
                    let x = t[0] * (1.0 - u - v) + t[1] * u + t[2] * v;
                    let inside = (0..3).all(|a| x[a] >= b.lo[a] && x[a] <= b.hi[a]);
                    if inside {
                        let slack = 1e-5;
                        assert!(
                            (0..3).all(|a| x[a] >= c.lo[a] - slack && x[a] <= c.hi[a] + slack),
                            "{x:?} outside {c:?}"
                        );
                    }
                }
            }
        }
    }
}
