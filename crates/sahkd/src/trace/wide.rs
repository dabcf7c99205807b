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
/// (`near`) and last (`far`), its origin and the reciprocal of its direction.
struct Slabs {
    near: [usize; 3],
    far: [usize; 3],
    origin: [f32; 3],
    rd: [f32; 3],
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
        }
    }

    /// The children whose boxes the ray enters within `[t_min, limit]` (bit `i` for lane `i`)
    /// and where it enters each. A lane whose box is NaN fails (the NaN reaches the last
    /// comparison), and so does a box wholly beyond or behind a ray parallel to a slab (an
    /// infinite near distance widened is NaN).
    #[inline(always)]
    fn enter(&self, node: &WideNode, t_min: f32, limit: f32) -> (u32, [f32; WIDTH]) {
        let mut tn = [0f32; WIDTH];
        let mut hit = [0u32; WIDTH];
        for l in 0..WIDTH {
            let s = |r: usize, a: usize| (node.bounds[r][l] - self.origin[a]) * self.rd[a];
            let n = max2(
                max2(s(self.near[0], 0), s(self.near[1], 1)),
                s(self.near[2], 2),
            );
            let f = min2(
                min2(s(self.far[0], 0), s(self.far[1], 1)),
                s(self.far[2], 2),
            );
            let n = max2(t_min, n - n.abs() * WIDEN);
            let f = min2(limit, f + f.abs() * WIDEN);
            tn[l] = n;
            hit[l] = (n <= f) as u32;
        }
        let mut mask = 0;
        for (l, &h) in hit.iter().enumerate() {
            mask |= h << l;
        }
        (mask, tn)
    }

    /// [`Self::enter`] in AVX2 vector operations, with the same roundings and NaN rules (a
    /// vector max or min returns its second operand where either is NaN, as `max2` does).
    ///
    /// # Safety
    /// The CPU must have AVX2. Called only from the walk compiled for AVX2, into which it is
    /// inlined with the intrinsics it calls (a function of its own would not be).
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    unsafe fn enter_avx2(&self, node: &WideNode, t_min: f32, limit: f32) -> (u32, [f32; WIDTH]) {
        use std::arch::x86_64::*;
        let row = |r: usize| _mm256_load_ps(node.bounds[r].as_ptr());
        let slab = |r: usize, a: usize| {
            _mm256_mul_ps(
                _mm256_sub_ps(row(r), _mm256_set1_ps(self.origin[a])),
                _mm256_set1_ps(self.rd[a]),
            )
        };
        let n = _mm256_max_ps(
            _mm256_max_ps(slab(self.near[0], 0), slab(self.near[1], 1)),
            slab(self.near[2], 2),
        );
        let f = _mm256_min_ps(
            _mm256_min_ps(slab(self.far[0], 0), slab(self.far[1], 1)),
            slab(self.far[2], 2),
        );
        let abs = _mm256_castsi256_ps(_mm256_set1_epi32(0x7fff_ffff));
        let widen = _mm256_set1_ps(WIDEN);
        let n = _mm256_sub_ps(n, _mm256_mul_ps(_mm256_and_ps(n, abs), widen));
        let f = _mm256_add_ps(f, _mm256_mul_ps(_mm256_and_ps(f, abs), widen));
        let n = _mm256_max_ps(_mm256_set1_ps(t_min), n);
        let f = _mm256_min_ps(_mm256_set1_ps(limit), f);
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
        #[cfg(target_arch = "x86_64")]
        if std::is_x86_feature_detected!("avx2") {
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
                if visit_leaf(sheared, words, ray.t_min, &mut limit, counters, &mut visit) {
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

    /// The vector box test gives the scalar one's lanes and entry distances, with NaN lanes,
    /// boxes on every side of the origin and directions with zero components.
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
                rng.random_range(-1.0..1.0f32),
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
