//! Every triangle a ray hits, each once, nearest first: the all-hits query of every front end
//! (Python's `intersect_all` and `count_hits`, the C API, scenes).
//!
//! Asking for closest hits again and again with `t_min` moved past the last hit would lose
//! hits that share a distance (a ray through an edge hits both triangles at the same `t`), so
//! the tree is walked once with [`KdTree::for_each_hit`], which tests every triangle of every
//! leaf the ray's range passes through against the whole range.

use super::{brute, Hit, Ray};
use crate::tree::KdTree;

/// Sorts hits by distance then triangle and drops repeats of a triangle (one referenced by
/// several leaves is found once per leaf, always with the same result).
fn finish(hits: &mut Vec<Hit>) {
    hits.sort_unstable_by(|a, b| a.t.total_cmp(&b.t).then(a.prim.cmp(&b.prim)));
    hits.dedup_by_key(|h| h.prim);
}

impl KdTree {
    /// Every triangle the ray hits within `[t_min, t_max]`, each once, nearest first (ties
    /// to the lower index), into `out` (cleared first, so one buffer serves many rays).
    pub fn all_hits_into(&self, ray: &Ray, out: &mut Vec<Hit>) {
        out.clear();
        self.for_each_hit(ray, |hit| out.push(hit));
        finish(out);
    }

    /// [`all_hits_into`](Self::all_hits_into) into a new vector.
    pub fn all_hits(&self, ray: &Ray) -> Vec<Hit> {
        let mut out = Vec::new();
        self.all_hits_into(ray, &mut out);
        out
    }

    /// The oracle of [`all_hits_into`](Self::all_hits_into): every triangle tested, no tree;
    /// it shares only the ray/triangle test with the tree's queries.
    pub fn brute_all_hits_into(&self, ray: &Ray, out: &mut Vec<Hit>) {
        out.clear();
        brute::for_each_hit(self.triangles(), ray, |hit| out.push(hit));
        finish(out);
    }
}
