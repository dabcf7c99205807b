//! Every hit along a ray, in one walk of the tree.
//!
//! The core answers closest-hit and any-hit queries. Asking it again and again with `t_min`
//! moved past the last hit would lose hits that share a distance (a ray through an edge hits
//! both triangles at the same `t`), so this module walks the tree once per ray instead: it
//! visits every leaf the ray's range passes through, in the same way the core's traversal
//! routes a ray, tests every triangle of those leaves against the whole range with the core's
//! watertight test, and reports each triangle hit once, sorted by distance then index. The
//! result is exactly the set the brute-force oracle [`brute_all_hits`] finds.

use sahkd::cost::MAX_DEPTH_CAP;
use sahkd::trace::ShearedRay;
use sahkd::{Aabb, Hit, KdTree, Ray, Vec3};

/// The ray's parameter range inside `b`, if it meets it (a zero direction component checks
/// the origin instead, as the core's traversal does).
fn clip_to_box(b: &Aabb, ray: &Ray, inv: &Vec3) -> Option<(f32, f32)> {
    let (mut t0, mut t1) = (ray.t_min, ray.t_max);
    for a in 0..3 {
        if inv[a].is_finite() {
            let near = (b.lo[a] - ray.origin[a]) * inv[a];
            let far = (b.hi[a] - ray.origin[a]) * inv[a];
            t0 = t0.max(near.min(far));
            t1 = t1.min(near.max(far));
        } else if !(ray.origin[a] >= b.lo[a] && ray.origin[a] <= b.hi[a]) {
            return None;
        }
    }
    (t0 <= t1).then_some((t0, t1))
}

/// Sorts hits by distance then triangle and drops repeats of a triangle (one referenced by
/// several leaves is found once per leaf, always with the same result).
fn finish(hits: &mut Vec<Hit>) {
    hits.sort_unstable_by(|a, b| a.t.total_cmp(&b.t).then(a.prim.cmp(&b.prim)));
    hits.dedup_by_key(|h| h.prim);
}

/// Every triangle the ray hits within `[t_min, t_max]`, nearest first, into `out`.
pub fn all_hits(tree: &KdTree, ray: &Ray, out: &mut Vec<Hit>) {
    out.clear();
    let (nodes, triangles) = (tree.nodes(), tree.triangles());
    if !ray.is_valid() || triangles.is_empty() {
        return;
    }
    let d = ray.direction;
    let inv = Vec3([1.0 / d[0], 1.0 / d[1], 1.0 / d[2]]);
    let Some((mut t0, mut t1)) = clip_to_box(&tree.bounds(), ray, &inv) else {
        return;
    };
    let sheared = ShearedRay::new(ray);
    // Far children waiting, with the ray's range inside them; a tree is at most
    // MAX_DEPTH_CAP deep, and loading checks that of trees read from files.
    let mut stack = [(0u32, 0f32, 0f32); MAX_DEPTH_CAP as usize + 4];
    let mut top = 0usize;
    let mut index = 0u32;
    loop {
        let node = &nodes[index as usize];
        if !node.is_leaf() {
            let (axis, split, left) = (node.axis(), node.split(), node.left());
            let o = ray.origin[axis];
            if inv[axis].is_finite() {
                let t_plane = (split - o) * inv[axis];
                let (near, far) = if d[axis] > 0.0 {
                    (left, left + 1)
                } else {
                    (left + 1, left)
                };
                if t_plane > t1 {
                    index = near;
                } else if t_plane < t0 {
                    index = far;
                } else {
                    stack[top] = (far, t_plane, t1);
                    top += 1;
                    index = near;
                    t1 = t_plane;
                }
            } else if o < split {
                index = left;
            } else if o > split {
                index = left + 1;
            } else {
                stack[top] = (left + 1, t0, t1);
                top += 1;
                index = left;
            }
            continue;
        }
        for &prim in tree.leaf_refs(node) {
            let tri = &triangles[prim as usize];
            if let Some(h) = sheared.intersect(tri, ray.t_min, ray.t_max) {
                out.push(Hit {
                    t: h.t,
                    prim,
                    u: h.u,
                    v: h.v,
                });
            }
        }
        if top == 0 {
            break;
        }
        top -= 1;
        (index, t0, t1) = stack[top];
    }
    finish(out);
}

/// The oracle: every triangle tested, no tree. Shares only the ray/triangle test with
/// [`all_hits`] and the core's queries.
pub fn brute_all_hits(tree: &KdTree, ray: &Ray, out: &mut Vec<Hit>) {
    out.clear();
    if !ray.is_valid() {
        return;
    }
    let sheared = ShearedRay::new(ray);
    for (prim, tri) in tree.triangles().iter().enumerate() {
        if let Some(h) = sheared.intersect(tri, ray.t_min, ray.t_max) {
            out.push(Hit {
                t: h.t,
                prim: prim as u32,
                u: h.u,
                v: h.v,
            });
        }
    }
    finish(out);
}
