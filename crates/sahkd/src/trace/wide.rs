//! The walk of the trace layout's 8-wide nodes (`tree::wide`), one ray at a time with the
//! slab tests of a node's eight children at once (AVX2 where the CPU has it): the walk of
//! every ray query, closest, any and every hit. Its leaves are runs of the trace layout's
//! words, tested four triangles at a time by `visit_leaf`; a closest-hit walk keeps the
//! pending children sorted by entry distance, nearest on top, and an any-hit walk does not
//! (it ends at any hit).

use super::{visit_leaf, Hit, Ray, ShearedRay, TraceCounters};
use crate::cost::MAX_DEPTH_CAP;
use crate::tree::layout::WORDS;
use crate::tree::wide::{push_children, WideNode, LEAF, WIDEN, WIDTH};
use crate::tree::KdTree;
use std::mem::MaybeUninit;

/// What a ray needs to test a node's boxes: per axis, the row of the face it meets first
/// (`near`) and last (`far`), its origin and the reciprocal of its direction, and that
/// reciprocal rounded down (`rd_near`) and up (`rd_far`) by `WIDEN`.
///
/// Slab distances are widened by `WIDEN` of their size so that no rounding loses a hit.
/// For `t_min >= 0` the widening is folded into the reciprocals: an entry distance `n >= 0`
/// times `1 - WIDEN` shrinks as `n - |n| WIDEN` does, and a negative one stays below
/// `t_min` either way (the same for exits with `1 + WIDEN`), so a node's test is three
/// operations shorter on the chain every step of the walk waits on. Rays reaching behind
/// their origin (`t_min < 0`) widen after the product.
struct Slabs {
    near: [usize; 3],
    far: [usize; 3],
    origin: [f32; 3],
    rd: [f32; 3],
    rd_near: [f32; 3],
    rd_far: [f32; 3],
}

/// `a` if greater, else `b`: a NaN in either gives `b`, as a vector max does.
#[inline(always)]
fn max2(a: f32, b: f32) -> f32 {
    if a > b {
        a
    } else {
        b
    }
}

/// `a` if less, else `b`: a NaN in either gives `b`.
#[inline(always)]
fn min2(a: f32, b: f32) -> f32 {
    if a < b {
        a
    } else {
        b
    }
}

impl Slabs {
    /// The ray's reciprocal direction and the rows of the faces it meets first and last.
    #[inline(always)]
    fn of(ray: &Ray) -> Slabs {
        let d = ray.direction;
        // A zero (or subnormal) component gets the smallest normal float as a stand-in: its
        // reciprocal stays finite, so slab distances are never NaN (an infinite one times
        // a zero difference would be), and a ray parallel to a slab is kept or not by its
        // origin, as with an infinite reciprocal.
        let rd = [0, 1, 2].map(|a| {
            let x = d[a];
            let x = if x.abs() < f32::MIN_POSITIVE {
                f32::MIN_POSITIVE.copysign(x)
            } else {
                x
            };
            1.0 / x
        });
        Slabs {
            near: [0, 1, 2].map(|a| if rd[a] < 0.0 { 3 + a } else { a }),
            far: [0, 1, 2].map(|a| if rd[a] < 0.0 { a } else { 3 + a }),
            origin: ray.origin.0,
            rd,
            rd_near: rd.map(|r| r * (1.0 - WIDEN)),
            rd_far: rd.map(|r| r * (1.0 + WIDEN)),
        }
    }

    /// The children whose boxes the ray enters within `[t_min, limit]` (bit `i` for lane `i`)
    /// and where it enters each. A lane whose box is NaN fails (the NaN reaches the last
    /// comparison: `t_min` and `limit` are the first operands of their max and min), and so
    /// does a box wholly beyond or behind a ray parallel to a slab (its infinite entry
    /// distance is beyond every exit, or widened after the product, NaN).
    #[inline(always)]
    fn enter(&self, node: &WideNode, t_min: f32, limit: f32) -> (u32, [f32; WIDTH]) {
        let mut tn = [0f32; WIDTH];
        let mut hit = [0u32; WIDTH];
        let folded = t_min >= 0.0;
        for l in 0..WIDTH {
            let (n, f) = if folded {
                let s = |r: usize, a: usize, rd: &[f32; 3]| {
                    (node.bounds[r][l] - self.origin[a]) * rd[a]
                };
                let near = |a: usize| s(self.near[a], a, &self.rd_near);
                let far = |a: usize| s(self.far[a], a, &self.rd_far);
                (
                    max2(max2(near(0), near(1)), max2(t_min, near(2))),
                    min2(min2(far(0), far(1)), min2(limit, far(2))),
                )
            } else {
                let s = |r: usize, a: usize| (node.bounds[r][l] - self.origin[a]) * self.rd[a];
                let n = max2(
                    max2(s(self.near[0], 0), s(self.near[1], 1)),
                    s(self.near[2], 2),
                );
                let f = min2(
                    min2(s(self.far[0], 0), s(self.far[1], 1)),
                    s(self.far[2], 2),
                );
                (
                    max2(t_min, n - n.abs() * WIDEN),
                    min2(limit, f + f.abs() * WIDEN),
                )
            };
            tn[l] = n;
            hit[l] = (n <= f) as u32;
        }
        let mut mask = 0;
        for (l, &h) in hit.iter().enumerate() {
            mask |= h << l;
        }
        (mask, tn)
    }

    /// [`Self::enter`] for `t_min >= 0` in AVX2 vector operations, with the same roundings
    /// and NaN rules (a vector max or min returns its second operand where either is NaN, as
    /// `max2` does).
    ///
    /// # Safety
    /// The CPU must have AVX2. Called only from the walk compiled for AVX2, into which it is
    /// inlined with the intrinsics it calls (a function of its own would not be).
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    unsafe fn enter_avx2(&self, node: &WideNode, t_min: f32, limit: f32) -> (u32, [f32; WIDTH]) {
        use std::arch::x86_64::*;
        debug_assert!(t_min >= 0.0, "the folded widening needs t_min >= 0");
        let slab = |r: usize, a: usize, rd: &[f32; 3]| {
            _mm256_mul_ps(
                _mm256_sub_ps(
                    _mm256_load_ps(node.bounds[r].as_ptr()),
                    _mm256_set1_ps(self.origin[a]),
                ),
                _mm256_set1_ps(rd[a]),
            )
        };
        let near = |a: usize| slab(self.near[a], a, &self.rd_near);
        let far = |a: usize| slab(self.far[a], a, &self.rd_far);
        let n = _mm256_max_ps(
            _mm256_max_ps(near(0), near(1)),
            _mm256_max_ps(_mm256_set1_ps(t_min), near(2)),
        );
        let f = _mm256_min_ps(
            _mm256_min_ps(far(0), far(1)),
            _mm256_min_ps(_mm256_set1_ps(limit), far(2)),
        );
        let mask = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(n, f)) as u32;
        let mut tn = [0f32; WIDTH];
        _mm256_storeu_ps(tn.as_mut_ptr(), n);
        (mask, tn)
    }
}

/// A pending child: what it is and where the ray enters its box.
#[derive(Clone, Copy)]
struct Entry {
    child: u32,
    count: u32,
    t: f32,
}

impl KdTree {
    /// The walk; `ORDERED` keeps the pending children sorted by entry distance, which a
    /// closest hit needs to stop early and an any hit does not (it stops at any hit).
    /// `visit(hit, limit)` sees each triangle hit with `t` in `[ray.t_min, limit]`; it may
    /// lower `limit` (children entered beyond it are skipped and triangles are tested against
    /// it) and returns true to end the walk.
    #[inline(always)]
    pub(super) fn walk<const ORDERED: bool>(
        &self,
        ray: &Ray,
        counters: &mut impl TraceCounters,
        visit: impl FnMut(Hit, &mut f32) -> bool,
    ) {
        if !ray.is_valid() || self.triangles.is_empty() || self.trace_layout().wide.is_empty() {
            return;
        }
        // The vector test folds its widening into the reciprocals, which needs `t_min >= 0`
        // (see `Slabs`); rays reaching behind their origin take the portable walk.
        #[cfg(target_arch = "x86_64")]
        if ray.t_min >= 0.0 && std::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU has AVX2 (checked just above).
            return unsafe { self.walk_avx2::<ORDERED>(ray, counters, visit) };
        }
        self.walk_any::<false, ORDERED>(ray, counters, visit)
    }

    /// The walk compiled for AVX2: a node's eight slab tests become vector operations.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn walk_avx2<const ORDERED: bool>(
        &self,
        ray: &Ray,
        counters: &mut impl TraceCounters,
        visit: impl FnMut(Hit, &mut f32) -> bool,
    ) {
        self.walk_any::<true, ORDERED>(ray, counters, visit)
    }

    /// The walk; `AVX2` (only from [`Self::walk_avx2`]) tests a node's boxes in AVX2
    /// vector operations, `ORDERED` as in [`Self::walk`].
    #[inline(always)]
    fn walk_any<const AVX2: bool, const ORDERED: bool>(
        &self,
        ray: &Ray,
        counters: &mut impl TraceCounters,
        mut visit: impl FnMut(Hit, &mut f32) -> bool,
    ) {
        let layout = self.trace_layout();
        let nodes = &layout.wide[..];
        let ray = &ray.scaled(layout.scale);
        if !ray.origin.is_finite() {
            return;
        }
        let slabs = Slabs::of(ray);
        let mut sheared: Option<ShearedRay> = None;
        let mut stack = [MaybeUninit::<Entry>::uninit(); 7 * MAX_DEPTH_CAP as usize + 8];
        let mut top = 0usize;
        let mut limit = ray.t_max;
        let mut cur = Entry {
            child: 0,
            count: 0,
            t: ray.t_min,
        };
        loop {
            if cur.child & LEAF == 0 {
                counters.node();
                let node = &nodes[cur.child as usize];
                let (mask, ts) = match AVX2 {
                    #[cfg(target_arch = "x86_64")]
                    // SAFETY: `AVX2` is set only in the walk compiled for AVX2, which runs
                    // where the CPU has it.
                    true => unsafe { slabs.enter_avx2(node, ray.t_min, limit) },
                    _ => slabs.enter(node, ray.t_min, limit),
                };
                if mask != 0 {
                    let entry = |lane: usize| Entry {
                        child: node.child[lane],
                        count: node.count[lane],
                        t: ts[lane],
                    };
                    // The nearest child is walked next straight from registers; the others
                    // are pushed, sorted for a closest hit so that the nearest pops first.
                    cur = push_children::<_, ORDERED>(mask, entry, |e| e.t, &mut stack, &mut top);
                    continue;
                }
            } else {
                counters.leaf();
                let first = (cur.child & !LEAF) as usize * WORDS;
                let words = &layout.words[first..first + cur.count as usize * WORDS];
                let sheared =
                    sheared.get_or_insert_with(|| ShearedRay::with_reach(ray, layout.reach));
                if visit_leaf::<AVX2>(sheared, words, ray.t_min, &mut limit, counters, &mut visit) {
                    return;
                }
            }
            loop {
                if top == 0 {
                    return;
                }
                top -= 1;
                // SAFETY: entries below `top` were all written by a push.
                let e = unsafe { stack[top].assume_init() };
                if e.t <= limit {
                    cur = e;
                    break;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Vec3;
    use crate::trace::Closest;
    use crate::{build_triangles, BuildOptions};
    use rand::rngs::StdRng;
    use rand::{Rng, SeedableRng};

    /// The vector box test gives the scalar one's lanes and entry distances (for `t_min >= 0`,
    /// the rays it is used for), with NaN lanes, boxes on every side of the origin and
    /// directions with zero components.
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn vector_box_test_equals_scalar() {
        if !std::is_x86_feature_detected!("avx2") {
            eprintln!("skipped: this CPU has no AVX2");
            return;
        }
        let mut rng = StdRng::seed_from_u64(5);
        for round in 0..20_000 {
            let mut node = WideNode::empty();
            for lane in 0..rng.random_range(0..=WIDTH) {
                for a in 0..3 {
                    let (x, y) = (
                        rng.random_range(-4.0..4.0f32),
                        rng.random_range(-4.0..4.0f32),
                    );
                    node.bounds[a][lane] = x.min(y);
                    node.bounds[3 + a][lane] = x.max(y);
                }
            }
            let mut d = [0f32; 3].map(|_| rng.random_range(-1.0..1.0f32));
            if round % 3 == 0 {
                d[round % 9 / 3] = 0.0;
            }
            let origin = [0f32; 3].map(|_| rng.random_range(-5.0..5.0f32));
            let ray = Ray::new(Vec3(origin), Vec3(d));
            let slabs = Slabs::of(&ray);
            let (t_min, limit) = (
                if round % 5 == 0 {
                    0.0
                } else {
                    rng.random_range(0.0..1.0f32)
                },
                rng.random_range(0.0..20.0f32),
            );
            let (mask, tn) = slabs.enter(&node, t_min, limit);
            // SAFETY: the CPU has AVX2 (checked above).
            let (vmask, vtn) = unsafe { slabs.enter_avx2(&node, t_min, limit) };
            assert_eq!(mask, vmask, "round {round}");
            for lane in (0..WIDTH).filter(|l| mask >> l & 1 == 1) {
                assert_eq!(tn[lane].to_bits(), vtn[lane].to_bits(), "round {round}");
            }
        }
    }

    /// Every box the ray meets within `[t_min, limit]`, by an exact test in f64 (the box's
    /// faces, the origin and the direction are all exact there), passes the float32 test, on
    /// both sides of `t_min = 0`, with the entry no later than the exact one: widening
    /// before or after the product loses no box. The boxes are met by rays aimed at a point
    /// inside them, and at a point on a face or an edge, where the roundings decide.
    #[test]
    fn box_test_keeps_every_box_the_ray_meets() {
        let mut rng = StdRng::seed_from_u64(17);
        let exact = |node: &WideNode, lane: usize, o: [f32; 3], d: [f32; 3], t0: f64, t1: f64| {
            let (mut n, mut f) = (t0, t1);
            for a in 0..3 {
                let (lo, hi) = (node.bounds[a][lane] as f64, node.bounds[3 + a][lane] as f64);
                let (o, d) = (o[a] as f64, d[a] as f64);
                if d == 0.0 {
                    if o < lo || o > hi {
                        return None;
                    }
                } else {
                    let (p, q) = ((lo - o) / d, (hi - o) / d);
                    n = n.max(p.min(q));
                    f = f.min(p.max(q));
                }
            }
            (n <= f).then_some(n)
        };
        let mut met = 0;
        for round in 0..20_000 {
            let mut node = WideNode::empty();
            let scale = [1e-3f32, 1.0, 1e3][round % 3];
            for lane in 0..WIDTH {
                for a in 0..3 {
                    let c = rng.random_range(-4.0..4.0f32) * scale;
                    let w = [0.0, rng.random_range(0.0..1.0f32) * scale][rng.random_range(0..2)];
                    node.bounds[a][lane] = c;
                    node.bounds[3 + a][lane] = c + w;
                }
            }
            let origin = [0f32; 3].map(|_| rng.random_range(-8.0..8.0f32) * scale);
            // Aim at a point of lane 0's box: inside it, or on its lower corner's faces.
            let target = [0, 1, 2].map(|a| {
                let (lo, hi) = (node.bounds[a][0], node.bounds[3 + a][0]);
                if round % 2 == 0 {
                    lo
                } else {
                    lo + (hi - lo) * rng.random_range(0.0..1.0f32)
                }
            });
            let mut d = [0, 1, 2].map(|a| target[a] - origin[a]);
            if round % 7 == 0 {
                d[round % 3] = 0.0;
            }
            if d == [0.0; 3] {
                continue;
            }
            let ray = Ray::new(Vec3(origin), Vec3(d));
            let slabs = Slabs::of(&ray);
            let t_min = [0.0, 0.25, -0.5, -3.0][round % 4];
            let limit = [f32::INFINITY, 1.0, 2.0][round % 3];
            let (mask, tn) = slabs.enter(&node, t_min, limit);
            #[cfg(target_arch = "x86_64")]
            let vector = (t_min >= 0.0 && std::is_x86_feature_detected!("avx2"))
                // SAFETY: the CPU has AVX2 (checked just above).
                .then(|| unsafe { slabs.enter_avx2(&node, t_min, limit) });
            #[cfg(not(target_arch = "x86_64"))]
            let vector: Option<(u32, [f32; WIDTH])> = None;
            for lane in 0..WIDTH {
                let Some(entry) = exact(&node, lane, origin, d, t_min as f64, limit as f64) else {
                    continue;
                };
                met += 1;
                for (mask, tn) in std::iter::once((mask, tn)).chain(vector) {
                    assert_eq!(mask >> lane & 1, 1, "round {round}, lane {lane}");
                    assert!(tn[lane] as f64 <= entry, "round {round}, lane {lane}");
                }
            }
        }
        assert!(met > 10_000, "only {met} boxes met");
    }

    /// The walk without AVX2 answers as the brute force does.
    #[test]
    fn portable_walk_matches_brute_force() {
        let mut rng = StdRng::seed_from_u64(9);
        let tris: Vec<[Vec3; 3]> = (0..500)
            .map(|_| {
                let c = Vec3([0f32; 3].map(|_| rng.random_range(0.0..10.0f32)));
                [0, 1, 2].map(|_| c + Vec3([0f32; 3].map(|_| rng.random_range(-1.0..1.0f32))))
            })
            .collect();
        let tree = build_triangles(tris, &BuildOptions::default())
            .unwrap()
            .tree;
        for i in 0..2000 {
            let o = Vec3([0f32; 3].map(|_| rng.random_range(-2.0..12.0f32)));
            let mut d = Vec3([0f32; 3].map(|_| rng.random_range(-1.0..1.0f32)));
            if i % 4 == 0 {
                d[i % 3] = 0.0;
            }
            let ray = Ray::new(o, d);
            let layout = tree.trace_layout();
            let mut closest = Closest::new(tree.triangles(), &ray, layout.scale, layout.reach);
            tree.walk_any::<false, true>(&ray, &mut (), |hit, limit| {
                closest.offer(hit, limit);
                false
            });
            assert_eq!(
                closest.best(),
                crate::trace::brute::intersect(tree.triangles(), &ray),
                "ray {i}"
            );
        }
    }
}
