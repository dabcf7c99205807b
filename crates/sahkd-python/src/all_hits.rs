//! Every hit along a ray, in one walk of the tree.
//!
//! Asking the core for closest hits again and again with `t_min` moved past the last hit
//! would lose hits that share a distance (a ray through an edge hits both triangles at the
//! same `t`), so this module walks the tree once per ray with the core's
//! [`KdTree::for_each_hit`], which visits every leaf the ray's range passes through and tests
//! every triangle there against the whole range with the core's watertight test; each
//! triangle hit is reported once, sorted by distance then index. The result is exactly the
//! set the brute-force oracle [`brute_all_hits`] finds.

use sahkd::{Hit, KdTree, Ray};

/// Sorts hits by distance then triangle and drops repeats of a triangle (one referenced by
/// several leaves is found once per leaf, always with the same result).
fn finish(hits: &mut Vec<Hit>) {
    hits.sort_unstable_by(|a, b| a.t.total_cmp(&b.t).then(a.prim.cmp(&b.prim)));
    hits.dedup_by_key(|h| h.prim);
}

/// Every triangle the ray hits within `[t_min, t_max]`, nearest first, into `out`.
pub fn all_hits(tree: &KdTree, ray: &Ray, out: &mut Vec<Hit>) {
    out.clear();
    tree.for_each_hit(ray, |hit| out.push(hit));
    finish(out);
}

/// The oracle: every triangle tested, no tree. Shares only the ray/triangle test with
/// [`all_hits`] and the core's queries.
pub fn brute_all_hits(tree: &KdTree, ray: &Ray, out: &mut Vec<Hit>) {
    out.clear();
    sahkd::trace::brute::for_each_hit(tree.triangles(), ray, |h| out.push(h));
    finish(out);
}
