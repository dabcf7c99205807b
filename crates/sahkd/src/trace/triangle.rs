//! Watertight ray/triangle intersection (Woop, Benthin and Wald 2013).
//!
//! The ray is sheared so that it runs along +z from the origin; each triangle is then tested
//! with 2-D edge functions whose signs are exact enough that a ray through a shared edge or
//! vertex hits at least one of the triangles meeting there. When an edge function comes out
//! exactly zero it is recomputed in f64, as the paper recommends.
//!
//! Its float32 distance decides which triangle is nearest; the distance a query reports is
//! then [`plane_distance`]'s, in f64 (well conditioned on needle-thin triangles, where the
//! float32 one was off by up to 2.4e-4). A hit just short of `t_min` by the float32 distance
//! (within the ray's `band`, a small fraction of the scene's size) is decided by the f64
//! one, so that a ray starting on a triangle hits it at `t = 0`.
//!
//! [`ShearedRay::intersect_block`] tests four triangles against one ray with the same operations in
//! the same order, one triangle per SSE lane (x86_64's baseline, so no run-time detection), so
//! each lane's answer is the one-triangle test's, bit for bit; elsewhere it loops over the
//! one-triangle test. [`ShearedRay::intersect_block_pair_avx`] does the same for two whole
//! blocks in the eight lanes of AVX, for the walks compiled for AVX2.

use super::Ray;
use crate::geometry::{Triangle, Vec3};
use crate::tree::layout::{block_record, BLOCK, WORDS};

/// Per-ray constants of the shear.
#[derive(Clone, Copy, Debug)]
pub struct ShearedRay {
    origin: Vec3,
    direction: Vec3,
    kx: usize,
    ky: usize,
    kz: usize,
    sx: f32,
    sy: f32,
    sz: f32,
    /// How far below `t_min` a float32 distance is checked again in f64.
    band: f32,
}

/// Distance and barycentrics of a hit: the point is `(1 - u - v) * v0 + u * v1 + v * v2`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TriangleHit {
    pub t: f32,
    pub u: f32,
    pub v: f32,
}

/// The distance along `ray` to the plane of `tri`, in f64, or `None` for a ray parallel to
/// it. From the corner nearest the origin, so that an origin on a corner gives exactly 0.
#[inline(never)]
pub fn plane_distance(tri: &Triangle, ray: &Ray) -> Option<f64> {
    let p = tri.map(|v| v.0.map(|c| c as f64));
    let o = ray.origin.0.map(|c| c as f64);
    let d = ray.direction.0.map(|c| c as f64);
    let sub = |a: [f64; 3], b: [f64; 3]| [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let (e1, e2) = (sub(p[1], p[0]), sub(p[2], p[0]));
    let n = [
        e1[1] * e2[2] - e1[2] * e2[1],
        e1[2] * e2[0] - e1[0] * e2[2],
        e1[0] * e2[1] - e1[1] * e2[0],
    ];
    let den = dot(n, d);
    let to = p.map(|c| sub(c, o));
    let size = |v: [f64; 3]| v[0].abs() + v[1].abs() + v[2].abs();
    let near = (0..3)
        .min_by(|&a, &b| size(to[a]).total_cmp(&size(to[b])))
        .unwrap_or(0);
    let t = dot(n, to[near]) / den;
    t.is_finite().then_some(t)
}

/// The axes of the watertight test's shear for a ray along `d` (the float32 and f64 tests
/// share them; float32 directions convert exactly): `kz` the largest component (ties to the
/// lower axis), `kx` and `ky` the next two, swapped where `d[kz]` is negative so that the
/// triangles keep their winding as seen along the ray.
#[inline(always)]
pub(crate) fn shear_axes(d: [f64; 3]) -> (usize, usize, usize) {
    let abs = d.map(f64::abs);
    let kz = if abs[0] >= abs[1] && abs[0] >= abs[2] {
        0
    } else if abs[1] >= abs[2] {
        1
    } else {
        2
    };
    let (kx, ky) = ((kz + 1) % 3, (kz + 2) % 3);
    if d[kz] < 0.0 {
        (ky, kx, kz)
    } else {
        (kx, ky, kz)
    }
}

impl ShearedRay {
    /// The test for `ray` alone: no hit short of `t_min` is checked again.
    pub fn new(ray: &Ray) -> ShearedRay {
        ShearedRay::with_reach(ray, 0.0)
    }

    /// The test for `ray` in a scene whose largest extent is `reach`: a float32 distance
    /// short of `t_min` by less than `2^-20` of the distance the ray takes to cross it (the
    /// float32 error is a few `2^-24` of that) is checked again in f64.
    pub fn with_reach(ray: &Ray, reach: f32) -> ShearedRay {
        let d = ray.direction;
        let (kx, ky, kz) = shear_axes(d.0.map(f64::from));
        ShearedRay {
            origin: ray.origin,
            direction: ray.direction,
            kx,
            ky,
            kz,
            sx: d[kx] / d[kz],
            sy: d[ky] / d[kz],
            sz: 1.0 / d[kz],
            // 2^-20, not wider: secondary rays start `render::OFFSET_SCALE` (1e-5, about
            // 2^-16.6) of the diagonal off their surface, and a band that reached their own
            // triangle sent nearly every one of them through the f64 check (10-25 % fewer
            // shadow, AO and bounce rays per second on dragon).
            band: reach * (1.0 / 1_048_576.0) / d[kz].abs(),
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
        let mut t = (eu * az + ev * bz + ew * cz) * inv;
        if !((t >= t_min) & (t <= t_max)) {
            if !((t < t_min) & (t >= t_min - self.band)) {
                return None;
            }
            // Just short of t_min (an origin on the triangle, or nearly): f64 decides.
            let ray = Ray {
                origin: self.origin,
                direction: self.direction,
                t_min,
                t_max,
            };
            match plane_distance(tri, &ray) {
                Some(d) if d >= t_min as f64 && d <= t_max as f64 => t = d as f32,
                _ => return None,
            }
        }
        Some(TriangleHit {
            t,
            u: ev * inv,
            v: ew * inv,
        })
    }
}

/// The answers of [`ShearedRay::intersect_block`]: bit `i` of `mask` is set when triangle `i` is hit,
/// and lane `i` of `t`, `u`, `v` is then its hit.
#[derive(Clone, Copy, Debug)]
pub struct Hits4 {
    pub mask: u32,
    pub t: [f32; 4],
    pub u: [f32; 4],
    pub v: [f32; 4],
}

/// The answers of [`ShearedRay::intersect_block_pair_avx`], as [`Hits4`]'s for eight lanes.
#[derive(Clone, Copy, Debug)]
pub struct Hits8 {
    pub mask: u32,
    pub t: [f32; 8],
    pub u: [f32; 8],
    pub v: [f32; 8],
}

impl Hits4 {
    /// Lane `i`'s hit, if its bit is set.
    #[inline(always)]
    pub fn get(&self, i: usize) -> Option<TriangleHit> {
        (self.mask >> i & 1 != 0).then_some(TriangleHit {
            t: self.t[i],
            u: self.u[i],
            v: self.v[i],
        })
    }
}

impl ShearedRay {
    /// [`intersect`](Self::intersect) of the `k` triangles of a block of the trace layout
    /// (`block` holds its `k * WORDS` words, `2 <= k <= 4`; see `tree::layout`), one
    /// triangle per SSE lane: each coordinate the shear needs is one vector load of a row,
    /// from the row of the axis the ray wants. Lanes `k..4` read the next row's first floats
    /// and are masked off.
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    pub fn intersect_block(&self, block: &[u32], t_min: f32, t_max: f32) -> Hits4 {
        use std::arch::x86_64::*;
        let k = block.len() / WORDS;
        // The loads below stay in the block only for `k >= 2` (a block of one is the
        // one-triangle test's); `k = len / WORDS` keeps `k * WORDS <= len`.
        assert!(k >= 2, "a block of at least 2 triangles");
        let lanes = (1u32 << k) - 1;
        let p = block.as_ptr() as *const f32;
        // SAFETY: SSE and SSE2 are part of x86_64. A row `r <= 8` starts at word `r * k` and a
        // load reads 4 words, so at most word `8 * k + 3 < 10 * k` (as `k >= 2`): inside the
        // block. The words are `f32` bits (the indices, read as floats in masked-off lanes,
        // are only computed with, never trusted).
        unsafe {
            let row = |r: usize| _mm_loadu_ps(p.add(r * k));
            let (kx, ky, kz) = (self.kx, self.ky, self.kz);
            let (ox, oy, oz) = (
                _mm_set1_ps(self.origin.0[kx]),
                _mm_set1_ps(self.origin.0[ky]),
                _mm_set1_ps(self.origin.0[kz]),
            );
            // Corner `c` relative to the origin, on the shear's three axes, as the one-triangle
            // test computes it (a subtraction per axis).
            let relative = |c: usize| {
                (
                    _mm_sub_ps(row(3 * c + kx), ox),
                    _mm_sub_ps(row(3 * c + ky), oy),
                    _mm_sub_ps(row(3 * c + kz), oz),
                )
            };
            let (a_x, a_y, a_z) = relative(0);
            let (b_x, b_y, b_z) = relative(1);
            let (c_x, c_y, c_z) = relative(2);
            let (sx, sy, sz) = (
                _mm_set1_ps(self.sx),
                _mm_set1_ps(self.sy),
                _mm_set1_ps(self.sz),
            );
            let ax = _mm_sub_ps(a_x, _mm_mul_ps(sx, a_z));
            let ay = _mm_sub_ps(a_y, _mm_mul_ps(sy, a_z));
            let bx = _mm_sub_ps(b_x, _mm_mul_ps(sx, b_z));
            let by = _mm_sub_ps(b_y, _mm_mul_ps(sy, b_z));
            let cx = _mm_sub_ps(c_x, _mm_mul_ps(sx, c_z));
            let cy = _mm_sub_ps(c_y, _mm_mul_ps(sy, c_z));
            let eu = _mm_sub_ps(_mm_mul_ps(cx, by), _mm_mul_ps(cy, bx));
            let ev = _mm_sub_ps(_mm_mul_ps(ax, cy), _mm_mul_ps(ay, cx));
            let ew = _mm_sub_ps(_mm_mul_ps(bx, ay), _mm_mul_ps(by, ax));
            let zero = _mm_setzero_ps();
            // Lanes with an edge function of exactly zero take the one-triangle test (and its
            // f64 recomputation) below.
            let mut exact = _mm_movemask_ps(_mm_or_ps(
                _mm_or_ps(_mm_cmpeq_ps(eu, zero), _mm_cmpeq_ps(ev, zero)),
                _mm_cmpeq_ps(ew, zero),
            )) as u32;
            let negative = _mm_or_ps(
                _mm_or_ps(_mm_cmplt_ps(eu, zero), _mm_cmplt_ps(ev, zero)),
                _mm_cmplt_ps(ew, zero),
            );
            let positive = _mm_or_ps(
                _mm_or_ps(_mm_cmpgt_ps(eu, zero), _mm_cmpgt_ps(ev, zero)),
                _mm_cmpgt_ps(ew, zero),
            );
            let det = _mm_add_ps(_mm_add_ps(eu, ev), ew);
            let az = _mm_mul_ps(sz, a_z);
            let bz = _mm_mul_ps(sz, b_z);
            let cz = _mm_mul_ps(sz, c_z);
            let inv = _mm_div_ps(_mm_set1_ps(1.0), det);
            let t = _mm_mul_ps(
                _mm_add_ps(
                    _mm_add_ps(_mm_mul_ps(eu, az), _mm_mul_ps(ev, bz)),
                    _mm_mul_ps(ew, cz),
                ),
                inv,
            );
            // Not (mixed signs), det != 0 (an unordered det is kept, as `det == 0.0` is false
            // for it), t_min <= t <= t_max (false for NaN).
            let rejected = _mm_or_ps(_mm_and_ps(negative, positive), _mm_cmpeq_ps(det, zero));
            let above_min = _mm_cmpge_ps(t, _mm_set1_ps(t_min));
            let keep = _mm_andnot_ps(
                rejected,
                _mm_and_ps(above_min, _mm_cmple_ps(t, _mm_set1_ps(t_max))),
            );
            // Hits just short of t_min are decided by the one-triangle test too.
            let short = _mm_andnot_ps(
                _mm_or_ps(rejected, above_min),
                _mm_cmpge_ps(t, _mm_set1_ps(t_min - self.band)),
            );
            exact = (exact | _mm_movemask_ps(short) as u32) & lanes;
            let mut hits = Hits4 {
                mask: _mm_movemask_ps(keep) as u32 & lanes & !exact,
                t: [0.0; 4],
                u: [0.0; 4],
                v: [0.0; 4],
            };
            _mm_storeu_ps(hits.t.as_mut_ptr(), t);
            _mm_storeu_ps(hits.u.as_mut_ptr(), _mm_mul_ps(ev, inv));
            _mm_storeu_ps(hits.v.as_mut_ptr(), _mm_mul_ps(ew, inv));
            let mut rest = exact;
            while rest != 0 {
                let i = rest.trailing_zeros() as usize;
                rest &= rest - 1;
                let tri = block_record(block, i).corners;
                hits.set(i, self.intersect(&tri, t_min, t_max));
            }
            hits
        }
    }

    /// [`intersect_block`](Self::intersect_block) of two whole blocks at once (`pair` holds
    /// their `2 * BLOCK * WORDS` words), one triangle per AVX lane: lanes 0-3 the first
    /// block's, 4-7 the second's. The same operations in the same order, so each lane's
    /// answer is the one-triangle test's, bit for bit.
    ///
    /// # Safety
    /// The CPU must have AVX. Called only from the walk compiled for AVX2, into which it is
    /// inlined with its intrinsics (written without closures, which would not inherit the
    /// walk's target features).
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    pub unsafe fn intersect_block_pair_avx(&self, pair: &[u32], t_min: f32, t_max: f32) -> Hits8 {
        use std::arch::x86_64::*;
        assert_eq!(pair.len(), 2 * BLOCK * WORDS, "two whole blocks");
        let p = pair.as_ptr() as *const f32;
        let second = BLOCK * WORDS;
        // Row `r` of both blocks: 4 floats at word `4 r` of each, `r <= 8`, inside the pair.
        macro_rules! row {
            ($r:expr) => {
                _mm256_loadu2_m128(p.add(second + $r * BLOCK), p.add($r * BLOCK))
            };
        }
        let (kx, ky, kz) = (self.kx, self.ky, self.kz);
        let (ox, oy, oz) = (
            _mm256_set1_ps(self.origin.0[kx]),
            _mm256_set1_ps(self.origin.0[ky]),
            _mm256_set1_ps(self.origin.0[kz]),
        );
        macro_rules! relative {
            ($c:expr) => {
                (
                    _mm256_sub_ps(row!(3 * $c + kx), ox),
                    _mm256_sub_ps(row!(3 * $c + ky), oy),
                    _mm256_sub_ps(row!(3 * $c + kz), oz),
                )
            };
        }
        let (a_x, a_y, a_z) = relative!(0);
        let (b_x, b_y, b_z) = relative!(1);
        let (c_x, c_y, c_z) = relative!(2);
        let (sx, sy, sz) = (
            _mm256_set1_ps(self.sx),
            _mm256_set1_ps(self.sy),
            _mm256_set1_ps(self.sz),
        );
        let ax = _mm256_sub_ps(a_x, _mm256_mul_ps(sx, a_z));
        let ay = _mm256_sub_ps(a_y, _mm256_mul_ps(sy, a_z));
        let bx = _mm256_sub_ps(b_x, _mm256_mul_ps(sx, b_z));
        let by = _mm256_sub_ps(b_y, _mm256_mul_ps(sy, b_z));
        let cx = _mm256_sub_ps(c_x, _mm256_mul_ps(sx, c_z));
        let cy = _mm256_sub_ps(c_y, _mm256_mul_ps(sy, c_z));
        let eu = _mm256_sub_ps(_mm256_mul_ps(cx, by), _mm256_mul_ps(cy, bx));
        let ev = _mm256_sub_ps(_mm256_mul_ps(ax, cy), _mm256_mul_ps(ay, cx));
        let ew = _mm256_sub_ps(_mm256_mul_ps(bx, ay), _mm256_mul_ps(by, ax));
        let zero = _mm256_setzero_ps();
        // The SSE comparisons' predicates: equal is ordered and quiet, the others ordered.
        let mut exact = _mm256_movemask_ps(_mm256_or_ps(
            _mm256_or_ps(
                _mm256_cmp_ps::<_CMP_EQ_OQ>(eu, zero),
                _mm256_cmp_ps::<_CMP_EQ_OQ>(ev, zero),
            ),
            _mm256_cmp_ps::<_CMP_EQ_OQ>(ew, zero),
        )) as u32;
        let negative = _mm256_or_ps(
            _mm256_or_ps(
                _mm256_cmp_ps::<_CMP_LT_OS>(eu, zero),
                _mm256_cmp_ps::<_CMP_LT_OS>(ev, zero),
            ),
            _mm256_cmp_ps::<_CMP_LT_OS>(ew, zero),
        );
        let positive = _mm256_or_ps(
            _mm256_or_ps(
                _mm256_cmp_ps::<_CMP_GT_OS>(eu, zero),
                _mm256_cmp_ps::<_CMP_GT_OS>(ev, zero),
            ),
            _mm256_cmp_ps::<_CMP_GT_OS>(ew, zero),
        );
        let det = _mm256_add_ps(_mm256_add_ps(eu, ev), ew);
        let az = _mm256_mul_ps(sz, a_z);
        let bz = _mm256_mul_ps(sz, b_z);
        let cz = _mm256_mul_ps(sz, c_z);
        let inv = _mm256_div_ps(_mm256_set1_ps(1.0), det);
        let t = _mm256_mul_ps(
            _mm256_add_ps(
                _mm256_add_ps(_mm256_mul_ps(eu, az), _mm256_mul_ps(ev, bz)),
                _mm256_mul_ps(ew, cz),
            ),
            inv,
        );
        let rejected = _mm256_or_ps(
            _mm256_and_ps(negative, positive),
            _mm256_cmp_ps::<_CMP_EQ_OQ>(det, zero),
        );
        let above_min = _mm256_cmp_ps::<_CMP_GE_OS>(t, _mm256_set1_ps(t_min));
        let keep = _mm256_andnot_ps(
            rejected,
            _mm256_and_ps(
                above_min,
                _mm256_cmp_ps::<_CMP_LE_OS>(t, _mm256_set1_ps(t_max)),
            ),
        );
        let short = _mm256_andnot_ps(
            _mm256_or_ps(rejected, above_min),
            _mm256_cmp_ps::<_CMP_GE_OS>(t, _mm256_set1_ps(t_min - self.band)),
        );
        exact |= _mm256_movemask_ps(short) as u32;
        let mut hits = Hits8 {
            mask: _mm256_movemask_ps(keep) as u32 & !exact,
            t: [0.0; 8],
            u: [0.0; 8],
            v: [0.0; 8],
        };
        _mm256_storeu_ps(hits.t.as_mut_ptr(), t);
        _mm256_storeu_ps(hits.u.as_mut_ptr(), _mm256_mul_ps(ev, inv));
        _mm256_storeu_ps(hits.v.as_mut_ptr(), _mm256_mul_ps(ew, inv));
        let mut rest = exact;
        while rest != 0 {
            let i = rest.trailing_zeros() as usize;
            rest &= rest - 1;
            let block = &pair[i / BLOCK * second..][..second];
            let tri = block_record(block, i % BLOCK).corners;
            match self.intersect(&tri, t_min, t_max) {
                Some(h) => {
                    hits.mask |= 1 << i;
                    (hits.t[i], hits.u[i], hits.v[i]) = (h.t, h.u, h.v);
                }
                None => hits.mask &= !(1 << i),
            }
        }
        hits
    }

    /// [`intersect`](Self::intersect) of the triangles of a block, one after the other.
    #[cfg(not(target_arch = "x86_64"))]
    #[inline(always)]
    pub fn intersect_block(&self, block: &[u32], t_min: f32, t_max: f32) -> Hits4 {
        let mut hits = Hits4 {
            mask: 0,
            t: [0.0; 4],
            u: [0.0; 4],
            v: [0.0; 4],
        };
        for i in 0..block.len() / WORDS {
            let tri = block_record(block, i).corners;
            hits.set(i, self.intersect(&tri, t_min, t_max));
        }
        hits
    }
}

impl Hits4 {
    #[inline(always)]
    fn set(&mut self, i: usize, hit: Option<TriangleHit>) {
        match hit {
            Some(h) => {
                self.mask |= 1 << i;
                (self.t[i], self.u[i], self.v[i]) = (h.t, h.u, h.v);
            }
            None => self.mask &= !(1 << i),
        }
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

    /// Each lane of the four-triangle test, and of the eight-triangle test of two whole
    /// blocks, answers exactly what the one-triangle test answers, bit for bit, in blocks of
    /// 4, 3 and 2: random triangles, triangles on a small integer grid (rays through
    /// their shared edges and vertices, edge functions of exactly zero), degenerate ones,
    /// and limits that cut some hits off.
    #[test]
    fn four_at_a_time_is_the_one_triangle_test_lane_by_lane() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand::rngs::StdRng::seed_from_u64(15);
        let mut point = |grid: bool| {
            let mut c = || {
                if grid {
                    rng.random_range(-2i32..=2) as f32
                } else {
                    rng.random_range(-2.0f32..2.0)
                }
            };
            Vec3::new(c(), c(), c())
        };
        let mut hits = 0;
        for case in 0..20_000 {
            let grid = case % 2 == 0;
            let tris: [Triangle; 4] = std::array::from_fn(|i| {
                let a = point(grid);
                if case % 7 == 0 && i == 3 {
                    [a, a, point(grid)] // degenerate
                } else {
                    [a, point(grid), point(grid)]
                }
            });
            // Some rays start inside another of the triangles or on its edge, where the
            // float32 distance is about 0, a little short of `t_min` or not.
            let on = &tris[(case + 1) % 4];
            let origin = match case % 5 {
                0 | 1 => (on[0] + on[1] + on[2]) * (1.0 / 3.0),
                2 => (on[1] + on[2]) * 0.5,
                _ => point(grid) + Vec3::new(0.0, 0.0, -5.0),
            };
            // At a corner, an edge's midpoint or the centre of one of the triangles.
            let [a, b, c] = tris[case % 4];
            let target = match case % 3 {
                0 => a,
                1 => (a + b) * 0.5,
                _ => (a + b + c) * (1.0 / 3.0),
            };
            let mut direction = target - origin;
            if direction == Vec3::splat(0.0) {
                direction = Vec3::new(0.0, 0.0, 1.0);
            }
            let ray = Ray::new(origin, direction);
            let sheared = if case % 2 == 0 {
                ShearedRay::new(&ray)
            } else {
                ShearedRay::with_reach(&ray, 8.0)
            };
            let t_max = if case % 5 == 0 { 0.9 } else { f32::INFINITY };
            // Blocks of 4, 3 and 2 triangles, laid out as the trace layout lays them out.
            let k = 4 - case % 3;
            let mut block = Vec::new();
            for row in 0..9 {
                block.extend(tris[..k].iter().map(|t| t[row / 3][row % 3].to_bits()));
            }
            block.extend(0..k as u32);
            let four = sheared.intersect_block(&block, 0.0, t_max);
            assert_eq!(four.mask >> k, 0, "case {case}: a lane past the block");
            for (i, tri) in tris[..k].iter().enumerate() {
                let one = sheared.intersect(tri, 0.0, t_max);
                let bits = |h: Option<TriangleHit>| h.map(|h| [h.t, h.u, h.v].map(f32::to_bits));
                assert_eq!(bits(four.get(i)), bits(one), "case {case} lane {i}");
                hits += one.is_some() as u32;
            }
            // Two whole blocks at once, the second the same triangles in reverse order.
            #[cfg(target_arch = "x86_64")]
            if k == 4 && std::is_x86_feature_detected!("avx") {
                let mut pair = block.clone();
                for row in 0..9 {
                    pair.extend(tris.iter().rev().map(|t| t[row / 3][row % 3].to_bits()));
                }
                pair.extend(4..8);
                // SAFETY: the CPU has AVX (checked above).
                let eight = unsafe { sheared.intersect_block_pair_avx(&pair, 0.0, t_max) };
                for lane in 0..8 {
                    let tri = &tris[if lane < 4 { lane } else { 7 - lane }];
                    let one = sheared
                        .intersect(tri, 0.0, t_max)
                        .map(|h| [h.t, h.u, h.v].map(f32::to_bits));
                    let got = (eight.mask >> lane & 1 != 0)
                        .then(|| [eight.t[lane], eight.u[lane], eight.v[lane]].map(f32::to_bits));
                    assert_eq!(got, one, "case {case}: lane {lane} of a pair");
                }
            }
        }
        assert!(hits > 12_000, "{hits} hits: a weak test");
    }
}
