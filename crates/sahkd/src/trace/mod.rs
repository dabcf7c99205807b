//! Ray queries: closest hit and any hit, one ray or a batch on every core.
//!
//! The traversal is the classic stack-based front-to-back kd-tree walk. A ray enters each
//! node over a parameter interval `[t0, t1]`; an interior node's plane cuts that interval at
//! `t_plane`, and the child on the ray's incoming side is visited first. Rays parallel to a
//! split plane are routed by their origin (both children when the origin lies in the plane),
//! so zero direction components never produce NaNs. Leaves test their triangles against the
//! whole remaining ray `[t_min, best]`, and pending nodes that start beyond the best hit are
//! dropped.

pub mod brute;
mod triangle;

pub use triangle::{ShearedRay, TriangleHit};

use crate::cost::MAX_DEPTH_CAP;
use crate::geometry::Vec3;
use crate::tree::KdTree;
use rayon::prelude::*;

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
    pub fn at(&self, t: f32) -> Vec3 {
        self.origin + self.direction * t
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

impl Hit {
    /// The order of hits: nearer first, then the lower triangle index, so that the result of
    /// a query does not depend on the order triangles are tested in.
    #[inline(always)]
    fn better_than(&self, other: &Option<Hit>) -> bool {
        match other {
            None => true,
            Some(o) => self.t < o.t || (self.t == o.t && self.prim < o.prim),
        }
    }
}

/// Counters for a traversal. The `()` implementation does nothing and compiles away, so the
/// plain queries pay nothing for them.
pub trait TraceCounters {
    fn node(&mut self) {}
    fn triangle(&mut self) {}
}

impl TraceCounters for () {}

/// Nodes visited and triangles tested, summed over rays.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct TraceStats {
    pub rays: u64,
    pub nodes: u64,
    pub triangles: u64,
}

impl TraceCounters for TraceStats {
    fn node(&mut self) {
        self.nodes += 1;
    }
    fn triangle(&mut self) {
        self.triangles += 1;
    }
}

impl std::ops::AddAssign for TraceStats {
    fn add_assign(&mut self, o: TraceStats) {
        self.rays += o.rays;
        self.nodes += o.nodes;
        self.triangles += o.triangles;
    }
}

/// What a query wants from a leaf: the closest hit, or any hit at all.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Query {
    Closest,
    Any,
}

/// Pending far child: node index and the ray interval inside it.
#[derive(Clone, Copy, Default)]
struct Pending {
    node: u32,
    t0: f32,
    t1: f32,
}

/// Slab test against the tree's box; a zero direction component checks the origin instead.
fn clip_to_box(tree: &KdTree, ray: &Ray, inv: &Vec3) -> Option<(f32, f32)> {
    let b = tree.bounds;
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
        self.traverse(ray, Query::Closest, &mut ())
    }

    /// True when anything is hit in `[ray.t_min, ray.t_max]`; stops at the first hit found.
    pub fn occluded(&self, ray: &Ray) -> bool {
        self.traverse(ray, Query::Any, &mut ()).is_some()
    }

    /// [`intersect`](Self::intersect) that also counts nodes visited and triangles tested.
    pub fn intersect_counted(&self, ray: &Ray, counters: &mut impl TraceCounters) -> Option<Hit> {
        self.traverse(ray, Query::Closest, counters)
    }

    /// [`occluded`](Self::occluded) that also counts nodes visited and triangles tested.
    pub fn occluded_counted(&self, ray: &Ray, counters: &mut impl TraceCounters) -> bool {
        self.traverse(ray, Query::Any, counters).is_some()
    }

    /// Closest hits of many rays on every core of the current rayon pool. The result of each
    /// ray does not depend on the number of threads.
    pub fn intersect_batch(&self, rays: &[Ray]) -> Vec<Option<Hit>> {
        rays.par_iter()
            .with_min_len(256)
            .map(|r| self.intersect(r))
            .collect()
    }

    /// Any-hit answers for many rays on every core of the current rayon pool.
    pub fn occluded_batch(&self, rays: &[Ray]) -> Vec<bool> {
        rays.par_iter()
            .with_min_len(256)
            .map(|r| self.occluded(r))
            .collect()
    }

    fn traverse(&self, ray: &Ray, query: Query, counters: &mut impl TraceCounters) -> Option<Hit> {
        if !ray.is_valid() || self.triangles.is_empty() {
            return None;
        }
        let d = ray.direction;
        let inv = Vec3([1.0 / d[0], 1.0 / d[1], 1.0 / d[2]]);
        let (mut t0, mut t1) = clip_to_box(self, ray, &inv)?;
        let sheared = ShearedRay::new(ray);
        let mut stack = [Pending::default(); MAX_DEPTH_CAP as usize + 4];
        let mut top = 0usize;
        let mut node_index = 0u32;
        let mut best: Option<Hit> = None;
        let mut best_t = ray.t_max;
        loop {
            // A node that starts beyond the best hit is skipped, not a reason to stop: a ray
            // lying in a split plane pushes a sibling over its whole interval, so the stack
            // is not always ordered by entry distance.
            if t0 > best_t {
                if top == 0 {
                    break;
                }
                top -= 1;
                let p = stack[top];
                (node_index, t0, t1) = (p.node, p.t0, p.t1);
                continue;
            }
            counters.node();
            let node = &self.nodes[node_index as usize];
            if !node.is_leaf() {
                let axis = node.axis();
                let split = node.split();
                let left = node.left();
                let o = ray.origin[axis];
                if inv[axis].is_finite() {
                    let t_plane = (split - o) * inv[axis];
                    // The child the ray comes from is "near", the one it goes into "far".
                    let (near, far) = if d[axis] > 0.0 {
                        (left, left + 1)
                    } else {
                        (left + 1, left)
                    };
                    if t_plane > t1 {
                        node_index = near;
                    } else if t_plane < t0 {
                        node_index = far;
                    } else {
                        stack[top] = Pending {
                            node: far,
                            t0: t_plane,
                            t1,
                        };
                        top += 1;
                        node_index = near;
                        t1 = t_plane;
                    }
                } else if o < split {
                    node_index = left;
                } else if o > split {
                    node_index = left + 1;
                } else {
                    // Running inside the plane: both sides may hold what it touches.
                    stack[top] = Pending {
                        node: left + 1,
                        t0,
                        t1,
                    };
                    top += 1;
                    node_index = left;
                }
                continue;
            }
            for &prim in self.leaf_refs(node) {
                counters.triangle();
                let tri = &self.triangles[prim as usize];
                if let Some(h) = sheared.intersect(tri, ray.t_min, best_t) {
                    let hit = Hit {
                        t: h.t,
                        prim,
                        u: h.u,
                        v: h.v,
                    };
                    if query == Query::Any {
                        return Some(hit);
                    }
                    if hit.better_than(&best) {
                        best_t = hit.t;
                        best = Some(hit);
                    }
                }
            }
            if top == 0 {
                break;
            }
            top -= 1;
            let p = stack[top];
            (node_index, t0, t1) = (p.node, p.t0, p.t1);
        }
        best
    }
}
