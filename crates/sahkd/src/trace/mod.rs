//! Ray queries: closest hit and any hit, one ray or a batch on every core.
//!
//! The traversal is the classic stack-based front-to-back kd-tree walk. A ray enters each
//! node over a parameter interval `[t0, t1]`; an interior node's plane cuts that interval at
//! `t_plane`, and the child on the ray's incoming side is visited first. Rays parallel to a
//! split plane are routed by their origin: `t_plane` is then +-infinity, or NaN when the
//! origin lies in the plane, which sends the ray to both children. Leaves test their
//! triangles against the whole remaining ray `[t_min, best]`, and pending nodes that start
//! beyond the best hit are dropped. One walk ([`KdTree::for_each_hit`] and the private `walk`)
//! serves closest hit, any hit and all hits; it runs over the tree's `layout` copy, made on
//! the first query: nodes depth first, leaves' triangles stored in leaf order. The batch calls
//! walk neighbouring rays in packets of 4 or 8 (`packet`), with the same answers.
//!
//! Ties: the closest hit is the least (reported `t`, triangle index) of all the ray's hits,
//! so two triangles at one distance (coplanar ones, or neighbours sharing the edge the ray
//! crosses) give the lower index, whatever leaf or order they are found in. Every
//! closest-hit query, float32 or f64, one ray or a batch, tree or brute force, compares by
//! [`closer`] alone. The float32 walk compares the reported (f64 plane) distance, not its
//! own float32 one, and keeps looking a little beyond its best hit (`Closest`), since a
//! tied triangle may sit in a later leaf.

mod all_hits;
pub mod brute;
mod packet;
pub mod precise;
mod triangle;
#[doc(hidden)]
pub mod wide;

use crate::tree::layout;

pub use precise::{Hit64, Ray64};
pub use triangle::{ShearedRay, TriangleHit};

use crate::geometry::{Aabb, Triangle, Vec3};
use crate::tree::KdTree;
use rayon::prelude::*;

/// Tests a leaf's triangles against one ray and calls `visit(hit, limit)` for each hit with
/// `t` in `[t_min, *limit]`, in the leaf's order, exactly as testing them one at a time
/// against the limit of the moment would: a block of the layout at a time against the limit
/// at the start of the block (`ShearedRay::intersect_block`), or two whole blocks at once in
/// the walks compiled for AVX2 (`AVX`: `ShearedRay::intersect_block_pair_avx`), each hit
/// checked again against the limit the hits before it in the leaf may have lowered. A last
/// block of one triangle takes the one-triangle test. `words` are the leaf's words in the
/// layout. Returns true when `visit` ends the walk.
#[inline(always)]
fn visit_leaf<const AVX: bool>(
    sheared: &ShearedRay,
    words: &[u32],
    t_min: f32,
    limit: &mut f32,
    counters: &mut impl TraceCounters,
    visit: &mut impl FnMut(Hit, &mut f32) -> bool,
) -> bool {
    // The hits of `mask` in lane order; lane `i` is triangle `i % BLOCK` of block
    // `i / BLOCK` of `words` (whole blocks of `BLOCK` each, or one shorter block alone).
    let mut offer = |words: &[u32], mask: u32, t: &[f32], u: &[f32], v: &[f32], limit: &mut f32| {
        let size = (words.len() / layout::WORDS).min(layout::BLOCK) * layout::WORDS;
        let mut bits = mask;
        while bits != 0 {
            let i = bits.trailing_zeros() as usize;
            bits &= bits - 1;
            if t[i] <= *limit {
                let block = &words[i / layout::BLOCK * size..][..size];
                let hit = Hit {
                    t: t[i],
                    prim: layout::block_prim(block, i % layout::BLOCK),
                    u: u[i],
                    v: v[i],
                };
                if visit(hit, limit) {
                    return true;
                }
            }
        }
        false
    };
    let whole = layout::BLOCK * layout::WORDS;
    #[cfg_attr(not(target_arch = "x86_64"), allow(unused_mut))]
    let mut rest = words;
    // Two whole blocks at a time in AVX lanes where the walk was compiled for AVX2.
    #[cfg(target_arch = "x86_64")]
    if AVX {
        let mut pairs = rest.chunks_exact(2 * whole);
        for pair in &mut pairs {
            for _ in 0..2 * layout::BLOCK {
                counters.triangle();
            }
            // SAFETY: `AVX` is set only in the walks compiled for AVX2, which run where the
            // CPU has it.
            let hits = unsafe { sheared.intersect_block_pair_avx(pair, t_min, *limit) };
            if hits.mask != 0 && offer(pair, hits.mask, &hits.t, &hits.u, &hits.v, limit) {
                return true;
            }
        }
        rest = pairs.remainder();
    }
    // Whole blocks, then the leaf's last, shorter block (a block of one triangle takes the
    // one-triangle test).
    for block in rest.chunks(whole) {
        let k = block.len() / layout::WORDS;
        for _ in 0..k {
            counters.triangle();
        }
        let ended = if k > 1 {
            let hits = sheared.intersect_block(block, t_min, *limit);
            hits.mask != 0 && offer(block, hits.mask, &hits.t, &hits.u, &hits.v, limit)
        } else {
            let corners = layout::block_record(block, 0).corners;
            sheared
                .intersect(&corners, t_min, *limit)
                .is_some_and(|h| offer(block, 1, &[h.t], &[h.u], &[h.v], limit))
        };
        if ended {
            return true;
        }
    }
    false
}

/// The hit `hit` of the float32 test (its `t` in a scene scaled by `1 / inv_scale`) as
/// queries report it: `t` recomputed in f64 from the plane of `tri` (the caller's triangle)
/// and kept within the ray's range; the float32 one only if the plane gives none.
#[inline(always)]
fn finish_hit(tri: &Triangle, ray: &Ray, hit: Hit, inv_scale: f32) -> Hit {
    let t = match triangle::plane_distance(tri, ray) {
        Some(t) => t as f32,
        None => hit.t * inv_scale,
    };
    Hit {
        t: t.max(ray.t_min).min(ray.t_max),
        ..hit
    }
}

/// A ray `origin + t * direction` for `t` in `[t_min, t_max]`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    pub origin: Vec3,
    pub direction: Vec3,
    pub t_min: f32,
    pub t_max: f32,
}

impl Ray {
    /// A ray over `[0, inf)`.
    pub fn new(origin: Vec3, direction: Vec3) -> Ray {
        Ray {
            origin,
            direction,
            t_min: 0.0,
            t_max: f32::INFINITY,
        }
    }
    pub fn with_range(self, t_min: f32, t_max: f32) -> Ray {
        Ray {
            t_min,
            t_max,
            ..self
        }
    }
    /// Rays with a zero or non-finite direction, a NaN origin or an empty range hit nothing.
    pub fn is_valid(&self) -> bool {
        self.origin.is_finite()
            && self.direction.is_finite()
            && self.direction != Vec3::splat(0.0)
            && self.t_min <= self.t_max
    }
    /// The first part of this ray that [`RayPart::problem`] refuses, and why.
    pub fn input_problem(&self) -> Option<(RayPart, &'static str)> {
        let coordinates = |part: RayPart, v: &Vec3| {
            v.0.iter()
                .find_map(|&c| part.problem(c as f64))
                .map(|why| (part, why))
        };
        coordinates(RayPart::Origin, &self.origin)
            .or_else(|| coordinates(RayPart::Direction, &self.direction))
            .or_else(|| {
                [(RayPart::TMin, self.t_min), (RayPart::TMax, self.t_max)]
                    .into_iter()
                    .find_map(|(part, v)| part.problem(v as f64).map(|why| (part, why)))
            })
    }
    pub fn at(&self, t: f32) -> Vec3 {
        self.origin + self.direction * t
    }
    /// The ray in a scene scaled by `s`: the origin moves, the direction stays, so
    /// distances scale by `s`.
    #[inline(always)]
    fn scaled(&self, s: f32) -> Ray {
        Ray {
            origin: self.origin * s,
            direction: self.direction,
            t_min: self.t_min * s,
            t_max: self.t_max * s,
        }
    }
}

/// A part of a ray given as input (a file's rows, a caller's arrays).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RayPart {
    Origin,
    Direction,
    TMin,
    TMax,
}

impl RayPart {
    pub fn name(self) -> &'static str {
        match self {
            RayPart::Origin => "origin",
            RayPart::Direction => "direction",
            RayPart::TMin => "t_min",
            RayPart::TMax => "t_max",
        }
    }

    /// The rule for rays given as input, one for every front end: why `v` (a coordinate of
    /// the origin or the direction, or a bound) cannot be this part, or `None`. Coordinates
    /// and `t_min` must be finite; `t_max` must not be NaN (`+inf` leaves the ray open). A
    /// zero direction or `t_min > t_max` is a ray that hits nothing, not an error.
    pub fn problem(self, v: f64) -> Option<&'static str> {
        match self {
            RayPart::TMax => v.is_nan().then_some("NaN"),
            _ => (!v.is_finite()).then_some("not finite"),
        }
    }
}

/// Where a ray's interval `[t0, t1]` goes at an interior node whose plane it meets at
/// `t_plane`: the near child only, the far child only, or both, the far child from
/// `far_t0` and the near child up to `near_t1`. A ray running inside the plane (NaN) keeps
/// its interval for both, since either may hold what it touches. One rule for the float32
/// and the f64 walks.
#[derive(Clone, Copy)]
pub(crate) enum Cut<T> {
    Near,
    Far,
    Both { far_t0: T, near_t1: T },
}

// `t_plane != t_plane` is the NaN test of a generic `PartialOrd` (a ray in the plane).
#[allow(clippy::eq_op)]
#[inline(always)]
pub(crate) fn cut<T: PartialOrd + Copy>(t_plane: T, t0: T, t1: T) -> Cut<T> {
    if t_plane > t1 {
        Cut::Near
    } else if t_plane < t0 {
        Cut::Far
    } else if t_plane != t_plane {
        Cut::Both {
            far_t0: t0,
            near_t1: t1,
        }
    } else {
        Cut::Both {
            far_t0: t_plane,
            near_t1: t_plane,
        }
    }
}

/// The closest hit of a ray: distance, triangle and barycentrics `(u, v)` of corners 1 and 2.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    pub t: f32,
    pub prim: u32,
    pub u: f32,
    pub v: f32,
}

/// The order of closest hits, the one rule every closest-hit query follows (the float32 and
/// f64 walks, one ray or a batch, the scene's tree and the brute force): nearer first, then
/// the lower triangle index. `t` is the distance the query reports.
#[inline(always)]
pub fn closer<T: PartialOrd>(t: T, prim: u32, best: Option<(T, u32)>) -> bool {
    match best {
        None => true,
        Some((best_t, best_prim)) => t < best_t || (t == best_t && prim < best_prim),
    }
}

/// How far beyond a hit (relative to its distance plus the ray's crossing of the scene) the
/// float32 walk keeps looking for another hit at the same reported distance: those differ
/// from the reported one by a few float32 roundings (`2^-22` or so), so this leaves a wide
/// margin and costs a walk almost nothing beyond the hit.
const TIE_SLACK: f32 = 1.0 / 65536.0;

/// The closest hit of one ray so far in a float32 walk, by [`closer`] on the reported hit.
///
/// The walk finds hits by their float32 distance in the scaled scene, but a query reports the
/// f64 plane distance (`finish_hit`), and two triangles at one reported distance (coplanar
/// ones, or neighbours sharing the edge the ray crosses) can come out of the float32 test a
/// rounding apart, in either order. So every hit is finished before it is compared, and the
/// walk's limit is set a little beyond the best hit (`TIE_SLACK`), not at it: a triangle at
/// the same reported distance in a later leaf or later in the leaf is still tested.
pub(crate) struct Closest<'a> {
    triangles: &'a [Triangle],
    ray: &'a Ray,
    /// The walk's scale and its inverse (distances in the walk are `scale` times the ray's).
    scale: f32,
    inv_scale: f32,
    /// The walk's distance for crossing the scene, in scaled units.
    cross: f32,
    /// The ray's `t_max` in the walk's units.
    t_max: f32,
    best: Option<Hit>,
}

impl<'a> Closest<'a> {
    /// For `ray` in a walk at `scale` over `triangles` (the caller's), whose scaled bounds
    /// have the largest extent `reach`.
    #[inline(always)]
    pub(crate) fn new(triangles: &'a [Triangle], ray: &'a Ray, scale: f32, reach: f32) -> Self {
        let d = ray.direction;
        let longest = d[0].abs().max(d[1].abs()).max(d[2].abs());
        Closest {
            triangles,
            ray,
            scale,
            inv_scale: 1.0 / scale,
            cross: reach / longest,
            t_max: ray.t_max * scale,
            best: None,
        }
    }

    /// Offers a hit of the walk (its `t` in the walk's units); when it comes first, keeps it
    /// and sets `limit` just beyond it.
    #[inline(always)]
    pub(crate) fn offer(&mut self, hit: Hit, limit: &mut f32) {
        let hit = finish_hit(
            &self.triangles[hit.prim as usize],
            self.ray,
            hit,
            self.inv_scale,
        );
        if closer(hit.t, hit.prim, self.best.map(|b| (b.t, b.prim))) {
            let t = hit.t * self.scale;
            *limit = (t + (t.abs() + self.cross) * TIE_SLACK).min(self.t_max);
            self.best = Some(hit);
        }
    }

    /// The closest hit, as the query reports it.
    #[inline(always)]
    pub(crate) fn best(&self) -> Option<Hit> {
        self.best
    }
}

/// Counters for a traversal. The `()` implementation does nothing and compiles away, so the
/// plain queries pay nothing for them.
pub trait TraceCounters {
    fn node(&mut self) {}
    fn leaf(&mut self) {}
    fn triangle(&mut self) {}
}

impl TraceCounters for () {}

/// Nodes visited (leaves included), non-empty leaves entered and triangles tested, summed
/// over rays.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct TraceStats {
    pub rays: u64,
    pub nodes: u64,
    pub leaves: u64,
    pub triangles: u64,
}

impl TraceCounters for TraceStats {
    fn node(&mut self) {
        self.nodes += 1;
    }
    fn leaf(&mut self) {
        self.leaves += 1;
    }
    fn triangle(&mut self) {
        self.triangles += 1;
    }
}

impl std::ops::AddAssign for TraceStats {
    fn add_assign(&mut self, o: TraceStats) {
        self.rays += o.rays;
        self.nodes += o.nodes;
        self.leaves += o.leaves;
        self.triangles += o.triangles;
    }
}

/// Slab test against the (scaled) tree's box; a zero direction component checks the origin
/// instead.
#[inline(always)]
fn clip_to_box(b: &Aabb, ray: &Ray, inv: &Vec3) -> Option<(f32, f32)> {
    let (mut t0, mut t1) = (ray.t_min, ray.t_max);
    for a in 0..3 {
        if inv[a].is_finite() {
            let near = (b.lo[a] - ray.origin[a]) * inv[a];
            let far = (b.hi[a] - ray.origin[a]) * inv[a];
            let (near, far) = if near <= far {
                (near, far)
            } else {
                (far, near)
            };
            t0 = t0.max(near);
            t1 = t1.min(far);
        } else if !(ray.origin[a] >= b.lo[a] && ray.origin[a] <= b.hi[a]) {
            return None;
        }
    }
    (t0 <= t1).then_some((t0, t1))
}

impl KdTree {
    /// The closest hit in `[ray.t_min, ray.t_max]`.
    pub fn intersect(&self, ray: &Ray) -> Option<Hit> {
        self.closest(ray, &mut ())
    }

    /// True when anything is hit in `[ray.t_min, ray.t_max]`; stops at the first hit found.
    pub fn occluded(&self, ray: &Ray) -> bool {
        self.any(ray, &mut ())
    }

    /// [`intersect`](Self::intersect) that also counts nodes visited and triangles tested.
    pub fn intersect_counted(&self, ray: &Ray, counters: &mut impl TraceCounters) -> Option<Hit> {
        self.closest(ray, counters)
    }

    /// [`occluded`](Self::occluded) that also counts nodes visited and triangles tested.
    pub fn occluded_counted(&self, ray: &Ray, counters: &mut impl TraceCounters) -> bool {
        self.any(ray, counters)
    }

    /// Calls `f` with every hit of a triangle in `[ray.t_min, ray.t_max]`, walking every leaf
    /// the ray passes through, front to back. A triangle referenced by several of those leaves
    /// is reported once per leaf, each time with the same hit; the order of the calls is not
    /// sorted by distance.
    pub fn for_each_hit(&self, ray: &Ray, mut f: impl FnMut(Hit)) {
        self.walk::<false>(ray, &mut (), |hit, _| {
            f(self.finish(ray, hit));
            false
        });
    }

    /// [`for_each_hit`](Self::for_each_hit) without each hit's distance refined: the same
    /// triangles and barycentrics, `t` left as the walk's float32 estimate in the layout's
    /// scale. For callers that only count crossings (the parity inside test): refining reads
    /// each hit triangle's corners from the unscaled mesh, a cache miss apiece.
    pub(crate) fn for_each_crossing(&self, ray: &Ray, mut f: impl FnMut(Hit)) {
        self.walk::<false>(ray, &mut (), |hit, _| {
            f(hit);
            false
        });
    }

    /// Closest hits of many rays on every core of the current rayon pool, each the answer of
    /// [`intersect`](Self::intersect): neighbouring rays within a narrow cone (a camera's,
    /// shadow rays to one light) are walked together in packets over the kd nodes
    /// (`trace::packet`), the others one at a time over the wide nodes; the way changes
    /// nothing in the results. The result of each ray does
    /// not depend on the number of threads.
    pub fn intersect_batch(&self, rays: &[Ray]) -> Vec<Option<Hit>> {
        let mut out = vec![None; rays.len()];
        out.par_chunks_mut(packet::GROUP)
            .zip(rays.par_chunks(packet::GROUP))
            .with_min_len(8)
            .for_each(|(out, rays)| self.closest_group(rays, out));
        out
    }

    /// Any-hit answers for many rays on every core of the current rayon pool, each the answer
    /// of [`occluded`](Self::occluded), walked in packets like
    /// [`intersect_batch`](Self::intersect_batch).
    pub fn occluded_batch(&self, rays: &[Ray]) -> Vec<bool> {
        let mut out = vec![false; rays.len()];
        out.par_chunks_mut(packet::GROUP)
            .zip(rays.par_chunks(packet::GROUP))
            .with_min_len(8)
            .for_each(|(out, rays)| self.any_group(rays, out));
        out
    }

    /// The answers of [`intersect_batch`](Self::intersect_batch) written into `out`, on the
    /// calling thread only, for callers that already run in parallel (the renderer's tiles,
    /// the Python door converting and tracing a group of rays per worker). `out` must be as
    /// long as `rays`.
    pub fn intersect_into(&self, rays: &[Ray], out: &mut [Option<Hit>]) {
        assert_eq!(rays.len(), out.len(), "one answer per ray");
        for (out, rays) in out
            .chunks_mut(packet::GROUP)
            .zip(rays.chunks(packet::GROUP))
        {
            self.closest_group(rays, out);
        }
    }

    /// The answers of [`occluded_batch`](Self::occluded_batch) written into `out`, on the
    /// calling thread only, as [`intersect_into`](Self::intersect_into).
    pub fn occluded_into(&self, rays: &[Ray], out: &mut [bool]) {
        assert_eq!(rays.len(), out.len(), "one answer per ray");
        for (out, rays) in out
            .chunks_mut(packet::GROUP)
            .zip(rays.chunks(packet::GROUP))
        {
            self.any_group(rays, out);
        }
    }

    /// [`intersect_into`](Self::intersect_into) into a new vector.
    pub(crate) fn intersect_serial(&self, rays: &[Ray]) -> Vec<Option<Hit>> {
        let mut out = vec![None; rays.len()];
        self.intersect_into(rays, &mut out);
        out
    }

    /// [`occluded_into`](Self::occluded_into) into a new vector.
    pub(crate) fn occluded_serial(&self, rays: &[Ray]) -> Vec<bool> {
        let mut out = vec![false; rays.len()];
        self.occluded_into(rays, &mut out);
        out
    }

    #[inline(always)]
    fn closest(&self, ray: &Ray, counters: &mut impl TraceCounters) -> Option<Hit> {
        let mut closest = self.closest_of(ray);
        self.walk::<true>(ray, counters, |hit, limit| {
            closest.offer(hit, limit);
            false
        });
        closest.best()
    }

    /// The search for the closest hit of `ray` in this tree's walk.
    #[inline(always)]
    fn closest_of<'a>(&'a self, ray: &'a Ray) -> Closest<'a> {
        let layout = self.trace_layout();
        Closest::new(&self.triangles, ray, layout.scale, layout.reach)
    }

    /// A hit of the walk (its `t` in the layout's scaled units) as the query reports it.
    #[inline(always)]
    fn finish(&self, ray: &Ray, hit: Hit) -> Hit {
        let tri = &self.triangles[hit.prim as usize];
        finish_hit(tri, ray, hit, self.trace_layout().inv_scale)
    }

    #[inline(always)]
    fn any(&self, ray: &Ray, counters: &mut impl TraceCounters) -> bool {
        let mut found = false;
        self.walk::<false>(ray, counters, |_, _| {
            found = true;
            true
        });
        found
    }

    /// Makes the trace layout now if no query has made it yet (queries make it on first
    /// use), so that a caller can time it apart from the queries.
    pub fn prepare_trace(&self) {
        self.trace_layout();
    }

    /// Bytes of the trace layout (making it if no query has yet): the leaves' triangle
    /// blocks, the wide nodes, and the renumbered kd nodes where the tree's own are not in
    /// walk order.
    pub fn trace_bytes(&self) -> usize {
        self.trace_layout().bytes()
    }
}
