//! Packets: `N` rays walked down the kd nodes together, for the batch calls' coherent rays.
//!
//! Neighbouring camera rays, and shadow rays of neighbouring hits to one light, mostly cross
//! the same nodes. Walking them together reads each node once for the packet, decides the
//! packet's way with one branch instead of one per ray, and the plane distances of the lanes
//! are computed side by side (the lane loops below are fixed length, which the compiler turns
//! into SIMD). Rays scattered around surfaces share few nodes: the batch calls walk each of
//! them alone through the wide nodes ([`PACKET_COS`] decides).
//!
//! Every lane follows the path and the intervals a walk of its ray alone down the kd nodes
//! would: a packet needs the same direction signs on every axis, so near and far children are
//! the same for all lanes; a lane is active in a node only when its own walk reaches the node
//! (the masks below) and the node starts within its own limit; its interval is cut at the
//! plane, and its leaves' triangles are tested as every walk tests them (`visit_leaf`).
//! Every triangle the ray hits in its range is offered to it, with the same test, so its
//! answer is the single-ray walk's bit for bit: the nearest hit, ties to the lower index.
//!
//! The batch calls hand out groups of [`GROUP`] neighbouring rays and sort each group by
//! direction octant before cutting it into packets: camera and shadow rays mostly share one
//! octant and keep their order. What is left of an octant's run after its full packets goes
//! in one more packet whose spare lanes hold a ray that hits nothing.

use super::{clip_to_box, visit_leaf, Closest, Hit, Ray, ShearedRay};
use crate::cost::MAX_DEPTH_CAP;
use crate::geometry::Vec3;
use crate::tree::KdTree;
use std::mem::MaybeUninit;

/// Rays per packet in the batch calls on the x86-64 baseline (SSE2).
pub(super) const WIDTH: usize = 4;

/// Rays per packet where the CPU has AVX2: the batch calls then run an instance of the packet
/// walk compiled for AVX2, whose lane loops fill 8-float registers.
#[cfg(target_arch = "x86_64")]
const WIDE: usize = 8;

/// True when this CPU runs the AVX2 instance ([`WIDE`] lanes). The standard library caches
/// the detection, so asking per group costs a load.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn has_avx2() -> bool {
    std::is_x86_feature_detected!("avx2")
}

/// Rays per group: the batch calls hand out groups of neighbouring rays, and a group's rays
/// are sorted by direction octant before they are cut into packets, so that rays of
/// scattered directions (ambient occlusion, bounces) still find partners of their octant.
/// 256 rather than 128: an octant's run fills more packets, so fewer lanes idle in the last
/// packet of each run (ambient occlusion and bounce rays 4-19 % faster); 512 gained nothing
/// more.
pub(super) const GROUP: usize = 256;

// A group's rays are numbered by `u8` in `trace_group`.
const _: () = assert!(GROUP <= 256);

/// The signs of a ray's direction as 3 bits; packets need one octant.
#[inline(always)]
fn octant(r: &Ray) -> u8 {
    (r.direction[0].is_sign_negative() as u8)
        | (r.direction[1].is_sign_negative() as u8) << 1
        | (r.direction[2].is_sign_negative() as u8) << 2
}

/// A pending far child of a packet: the lanes that go there and their intervals.
#[derive(Clone, Copy)]
struct Pending<const N: usize> {
    node: u32,
    mask: u32,
    t0: [f32; N],
    t1: [f32; N],
}

/// Bit `i` set where `f(i)`.
#[inline(always)]
fn mask_of<const N: usize>(f: impl Fn(usize) -> bool) -> u32 {
    let mut m = 0;
    for i in 0..N {
        m |= (f(i) as u32) << i;
    }
    m
}

/// Lanes where `a < b` (false for NaN, as `<` is).
#[inline(always)]
fn lt<const N: usize>(a: &[f32; N], b: &[f32; N]) -> u32 {
    #[cfg(target_arch = "x86_64")]
    if N % 4 == 0 {
        // SAFETY: SSE is part of x86_64.
        return unsafe { compare(a, b, std::arch::x86_64::_mm_cmplt_ps) };
    }
    mask_of::<N>(|i| a[i] < b[i])
}

/// Lanes where `a <= b` (false for NaN, as `<=` is).
#[inline(always)]
fn le<const N: usize>(a: &[f32; N], b: &[f32; N]) -> u32 {
    #[cfg(target_arch = "x86_64")]
    if N % 4 == 0 {
        // SAFETY: SSE is part of x86_64.
        return unsafe { compare(a, b, std::arch::x86_64::_mm_cmple_ps) };
    }
    mask_of::<N>(|i| a[i] <= b[i])
}

/// The lane mask of an SSE comparison of `a` and `b`, 4 lanes at a time (`N` a multiple of
/// 4). Hand-written because the portable loop compiled to a byte mask reassembled bit by bit
/// (measured).
///
/// # Safety
/// `N` must be a multiple of 4.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
unsafe fn compare<const N: usize>(
    a: &[f32; N],
    b: &[f32; N],
    op: unsafe fn(
        std::arch::x86_64::__m128,
        std::arch::x86_64::__m128,
    ) -> std::arch::x86_64::__m128,
) -> u32 {
    use std::arch::x86_64::{_mm_loadu_ps, _mm_movemask_ps};
    let mut mask = 0;
    for k in (0..N).step_by(4) {
        // SAFETY: lanes k..k + 4 lie within both arrays, N being a multiple of 4.
        let (x, y) = unsafe {
            (
                _mm_loadu_ps(a.as_ptr().add(k)),
                _mm_loadu_ps(b.as_ptr().add(k)),
            )
        };
        mask |= (unsafe { _mm_movemask_ps(op(x, y)) } as u32) << k;
    }
    mask
}

/// The cosine of the widest angle between two rays' directions that still go in one packet:
/// 8 degrees. Camera rays of neighbouring pixels and shadow rays to one light stay well within
/// it and run fastest in packets (one node read and one decision for the packet); rays
/// scattered around surfaces (ambient occlusion, bounces) rarely do, and each runs faster on
/// its own through the wide nodes, which take it through fewer nodes (BENCHMARKS.md, "Rays in
/// packets or one at a time").
const PACKET_COS: f32 = 0.99;

/// Whether the rays `lanes` of `rays` (one octant) are worth a packet: all within
/// [`PACKET_COS`] of the first one's direction.
#[inline(always)]
fn coherent(rays: &[Ray], lanes: &[u8]) -> bool {
    let unit = |d: Vec3| d * (1.0 / d.dot(d).sqrt());
    let first = unit(rays[lanes[0] as usize].direction);
    lanes[1..]
        .iter()
        .all(|&i| unit(rays[i as usize].direction).dot(first) >= PACKET_COS)
}

/// True when all rays have the same sign bit in each direction component, so one near/far
/// order serves the packet.
#[inline(always)]
pub(super) fn same_signs(rays: &[Ray]) -> bool {
    let first = octant(&rays[0]);
    rays.iter().all(|r| octant(r) == first)
}

impl KdTree {
    /// The front-to-back walk of the kd nodes for `N` rays with the same direction signs
    /// (see [`same_signs`]). `visit(lane, hit, limit)` sees each hit of a lane's ray, may lower
    /// that lane's limit and returns true to end that lane's walk.
    #[inline(always)]
    pub(super) fn walk_packet<const N: usize, const AVX: bool>(
        &self,
        rays: &[Ray; N],
        mut visit: impl FnMut(usize, Hit, &mut f32) -> bool,
    ) {
        debug_assert!(N <= 32 && same_signs(rays));
        if self.triangles.is_empty() {
            return;
        }
        let layout = self.trace_layout();
        let nodes = layout.nodes(self);
        let rays: [Ray; N] = std::array::from_fn(|i| rays[i].scaled(layout.scale));
        let rays = &rays;
        let mut origin = [[0.0f32; N]; 3];
        let mut inv = [[0.0f32; N]; 3];
        let mut t0 = [0.0f32; N];
        let mut t1 = [0.0f32; N];
        let mut t_min = [0.0f32; N];
        let mut limit = [0.0f32; N];
        let mut mask = 0u32;
        for (i, ray) in rays.iter().enumerate() {
            let d = ray.direction;
            let lane_inv = Vec3([1.0 / d[0], 1.0 / d[1], 1.0 / d[2]]);
            for a in 0..3 {
                origin[a][i] = ray.origin[a];
                inv[a][i] = lane_inv[a];
            }
            t_min[i] = ray.t_min;
            limit[i] = ray.t_max;
            if ray.is_valid() && ray.origin.is_finite() {
                if let Some((a, b)) = clip_to_box(&layout.bounds, ray, &lane_inv) {
                    (t0[i], t1[i]) = (a, b);
                    mask |= 1 << i;
                }
            }
        }
        if mask == 0 {
            return;
        }
        let near_is_right = [0, 1, 2].map(|a| rays[0].direction[a].is_sign_negative() as u32);
        let mut sheared: Option<[ShearedRay; N]> = None;
        // Lanes whose walk has ended; when all of `live` are done, the packet is.
        let live = mask;
        let mut done = 0u32;
        // Only entries below `top` are read, and each was written first.
        let mut stack = [MaybeUninit::<Pending<N>>::uninit(); MAX_DEPTH_CAP as usize + 4];
        let mut top = 0usize;
        let mut node_index = 0u32;
        loop {
            // The lanes that reach this node and start within their limit.
            let m = mask & !done & le(&t0, &limit);
            if m != 0 {
                let node = &nodes[node_index as usize];
                if !node.is_leaf() {
                    let axis = node.axis();
                    let left = node.left();
                    let split = node.split();
                    let (o, ia) = (&origin[axis], &inv[axis]);
                    let tp: [f32; N] = std::array::from_fn(|i| (split - o[i]) * ia[i]);
                    // As in the single walk: `tp > t1` near only, `tp < t0` far only, else
                    // (NaN included) both.
                    let near_m = m & !lt(&tp, &t0);
                    let far_m = m & !lt(&t1, &tp);
                    let near = left + near_is_right[axis];
                    let far = left + 1 - near_is_right[axis];
                    if far_m == 0 {
                        node_index = near;
                        mask = m;
                    } else if near_m == 0 {
                        node_index = far;
                        mask = m;
                    } else {
                        // Lanes going to both sides are cut at the plane; near-only lanes
                        // (`tp > t1`), far-only lanes (`tp < t0`) and NaN lanes keep their
                        // interval.
                        stack[top] = MaybeUninit::new(Pending {
                            node: far,
                            mask: far_m,
                            t0: std::array::from_fn(|i| if tp[i] > t0[i] { tp[i] } else { t0[i] }),
                            t1,
                        });
                        top += 1;
                        t1 = std::array::from_fn(|i| if tp[i] < t1[i] { tp[i] } else { t1[i] });
                        node_index = near;
                        mask = near_m;
                    }
                    continue;
                }
                let words = layout.leaf_words(node);
                if !words.is_empty() {
                    let sheared = sheared.get_or_insert_with(|| {
                        std::array::from_fn(|i| ShearedRay::with_reach(&rays[i], layout.reach))
                    });
                    // Lane after lane: each lane sees its hits in the leaf's order.
                    let mut bits = m;
                    while bits != 0 {
                        let i = bits.trailing_zeros() as usize;
                        bits &= bits - 1;
                        let mut visit_lane = |hit: Hit, limit: &mut f32| visit(i, hit, limit);
                        if visit_leaf::<AVX>(
                            &sheared[i],
                            words,
                            t_min[i],
                            &mut limit[i],
                            &mut (),
                            &mut visit_lane,
                        ) {
                            done |= 1 << i;
                        }
                    }
                    if done == live {
                        return;
                    }
                }
            }
            if top == 0 {
                return;
            }
            top -= 1;
            // SAFETY: entries below `top` were all written by a push.
            let p = unsafe { stack[top].assume_init() };
            (node_index, mask, t0, t1) = (p.node, p.mask, p.t0, p.t1);
        }
    }

    /// Answers of a group of at most [`GROUP`] rays into `out`: the rays are ordered by the
    /// signs of their directions (stable, so coherent rays keep their neighbours) and each
    /// run of one octant is cut into packets of `W` rays, walked by `packet` where they are
    /// [`coherent`] (or `packets_only`, for tests), else one at a time by `single`; the last
    /// packet of a run fills its spare lanes with a ray that hits nothing (an empty range, so
    /// its lane is never active). Every ray gets its single-ray answer whichever way it is
    /// walked, so the grouping changes nothing in the results.
    #[inline(always)]
    fn trace_group<const W: usize, T: Copy>(
        &self,
        rays: &[Ray],
        out: &mut [T],
        packets_only: bool,
        mut packet: impl FnMut(&[Ray; W]) -> [T; W],
        mut single: impl FnMut(&Ray) -> T,
    ) {
        debug_assert!(rays.len() <= GROUP && rays.len() == out.len());
        // Counting sort of the ray indices by octant.
        let octants: [u8; GROUP] = std::array::from_fn(|i| rays.get(i).map_or(0, octant));
        let mut starts = [0usize; 9];
        for &o in &octants[..rays.len()] {
            starts[o as usize + 1] += 1;
        }
        for k in 0..8 {
            starts[k + 1] += starts[k];
        }
        let runs = starts;
        let mut order = [0u8; GROUP];
        for (i, &o) in octants[..rays.len()].iter().enumerate() {
            order[starts[o as usize]] = i as u8;
            starts[o as usize] += 1;
        }
        for k in 0..8 {
            let run = &order[runs[k]..runs[k + 1]];
            for lanes in run.chunks(W) {
                if !packets_only && !coherent(rays, lanes) {
                    for &i in lanes {
                        out[i as usize] = single(&rays[i as usize]);
                    }
                    continue;
                }
                let idle = rays[lanes[0] as usize].with_range(1.0, 0.0);
                let answers = packet(&std::array::from_fn(|j| {
                    lanes.get(j).map_or(idle, |&i| rays[i as usize])
                }));
                for (j, &i) in lanes.iter().enumerate() {
                    out[i as usize] = answers[j];
                }
            }
        }
    }

    /// Closest hits of a group of at most [`GROUP`] rays into `out`.
    pub(super) fn closest_group(&self, rays: &[Ray], out: &mut [Option<Hit>]) {
        #[cfg(target_arch = "x86_64")]
        if has_avx2() {
            // SAFETY: the CPU has AVX2 (checked just above).
            return unsafe { self.closest_group_avx2(rays, out) };
        }
        self.closest_group_of::<WIDTH, false>(rays, out, false);
    }

    /// Any-hit answers of a group of at most [`GROUP`] rays into `out`.
    pub(super) fn any_group(&self, rays: &[Ray], out: &mut [bool]) {
        #[cfg(target_arch = "x86_64")]
        if has_avx2() {
            // SAFETY: the CPU has AVX2 (checked just above).
            return unsafe { self.any_group_avx2(rays, out) };
        }
        self.any_group_of::<WIDTH, false>(rays, out, false);
    }

    /// [`Self::closest_group`] with packets of [`WIDE`] rays, compiled for AVX2. Only AVX2 is
    /// enabled, not FMA: the triangle test's products and sums stay separate operations, as
    /// in the single-ray walk, so the answers keep their bits.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn closest_group_avx2(&self, rays: &[Ray], out: &mut [Option<Hit>]) {
        self.closest_group_of::<WIDE, true>(rays, out, false);
    }

    /// [`Self::any_group`] with packets of [`WIDE`] rays, compiled for AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn any_group_avx2(&self, rays: &[Ray], out: &mut [bool]) {
        self.any_group_of::<WIDE, true>(rays, out, false);
    }

    /// Every coherent or not ray of a group in packets of [`WIDE`], compiled for AVX2 (tests).
    #[cfg(all(test, target_arch = "x86_64"))]
    #[target_feature(enable = "avx2")]
    unsafe fn closest_packets_avx2(&self, rays: &[Ray], out: &mut [Option<Hit>]) {
        self.closest_group_of::<WIDE, true>(rays, out, true);
    }

    /// Every ray of a group in packets of [`WIDE`], compiled for AVX2 (tests).
    #[cfg(all(test, target_arch = "x86_64"))]
    #[target_feature(enable = "avx2")]
    unsafe fn any_packets_avx2(&self, rays: &[Ray], out: &mut [bool]) {
        self.any_group_of::<WIDE, true>(rays, out, true);
    }

    #[inline(always)]
    fn closest_group_of<const W: usize, const AVX: bool>(
        &self,
        rays: &[Ray],
        out: &mut [Option<Hit>],
        packets_only: bool,
    ) {
        self.trace_group::<W, _>(
            rays,
            out,
            packets_only,
            #[inline(always)]
            |packet| {
                let mut closest: [Closest; W] =
                    std::array::from_fn(|i| self.closest_of(&packet[i]));
                self.walk_packet::<W, AVX>(packet, |i, hit, limit| {
                    closest[i].offer(hit, limit);
                    false
                });
                std::array::from_fn(|i| closest[i].best())
            },
            |ray| self.intersect(ray),
        );
    }

    #[inline(always)]
    fn any_group_of<const W: usize, const AVX: bool>(
        &self,
        rays: &[Ray],
        out: &mut [bool],
        packets_only: bool,
    ) {
        self.trace_group::<W, _>(
            rays,
            out,
            packets_only,
            #[inline(always)]
            |packet| {
                let mut found = [false; W];
                self.walk_packet::<W, AVX>(packet, |i, _, _| {
                    found[i] = true;
                    true
                });
                found
            },
            |ray| self.occluded(ray),
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{build_triangles, BuildOptions};
    use rand::rngs::StdRng;
    use rand::{Rng, SeedableRng};

    /// Packets of every width the batch calls may pick (4 on the x86-64 baseline, 8 where the
    /// CPU has AVX2) answer each ray as its single-ray walk does, bit for bit: coherent rays
    /// from one eye, scattered rays from points in the scene (most octants mixed in a
    /// group), and short rays whose limits end inside the scene.
    #[test]
    fn packets_of_each_width_answer_as_single_rays() {
        let mut rng = StdRng::seed_from_u64(8);
        let mut point = |r: f32| Vec3(std::array::from_fn(|_| rng.random_range(-r..r)));
        let tris: Vec<_> = (0..2000)
            .map(|_| {
                let c = point(1.0);
                [c + point(0.15), c + point(0.15), c + point(0.15)]
            })
            .collect();
        let tree = build_triangles(tris, &BuildOptions::default())
            .unwrap()
            .tree;
        let mut rays: Vec<Ray> = (0..GROUP * 3)
            .map(|i| {
                let target = point(1.0);
                let eye = Vec3::new(0.3, 0.2, 3.0);
                match i % 3 {
                    0 => Ray::new(eye, target - eye),
                    1 => Ray::new(point(1.0), point(1.0)),
                    _ => {
                        let mut r = Ray::new(point(1.0), point(1.0));
                        r.t_max = 0.3;
                        r
                    }
                }
            })
            .collect();
        rays.sort_by_key(|r| octant(r));
        let closest: Vec<Option<Hit>> = rays.iter().map(|r| tree.intersect(r)).collect();
        let any: Vec<bool> = rays.iter().map(|r| tree.occluded(r)).collect();
        assert!(closest.iter().filter(|h| h.is_some()).count() > rays.len() / 4);
        assert!(any.iter().any(|&b| !b));
        let check = |width: usize, got: (Vec<Option<Hit>>, Vec<bool>)| {
            assert_eq!(got.0, closest, "closest hits, packets of {width}");
            assert_eq!(got.1, any, "any hits, packets of {width}");
        };
        let run = |closest_of: &dyn Fn(&[Ray], &mut [Option<Hit>]),
                   any_of: &dyn Fn(&[Ray], &mut [bool])| {
            let mut c = vec![None; rays.len()];
            let mut a = vec![false; rays.len()];
            for (rays, (c, a)) in rays
                .chunks(GROUP)
                .zip(c.chunks_mut(GROUP).zip(a.chunks_mut(GROUP)))
            {
                closest_of(rays, c);
                any_of(rays, a);
            }
            (c, a)
        };
        check(
            4,
            run(
                &|r, o| tree.closest_group_of::<4, false>(r, o, true),
                &|r, o| tree.any_group_of::<4, false>(r, o, true),
            ),
        );
        check(
            8,
            run(
                &|r, o| tree.closest_group_of::<8, false>(r, o, true),
                &|r, o| tree.any_group_of::<8, false>(r, o, true),
            ),
        );
        // The width the AVX2 instance walks, its leaves tested two blocks at once.
        #[cfg(target_arch = "x86_64")]
        if has_avx2() {
            check(
                8,
                // SAFETY: the CPU has AVX2 (checked just above).
                run(
                    &|r, o| unsafe { tree.closest_packets_avx2(r, o) },
                    &|r, o| unsafe { tree.any_packets_avx2(r, o) },
                ),
            );
        }
        // What the batch calls run on this CPU: the eye's rays in packets, the others alone.
        check(
            0,
            run(&|r, o| tree.closest_group(r, o), &|r, o| {
                tree.any_group(r, o)
            }),
        );
    }
}
