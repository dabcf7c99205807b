//! The surface area heuristic, in one place for every builder.
//!
//! Every builder prices a split with [`CostModel::split_cost`] and a leaf with
//! [`CostModel::leaf_cost`]; the same inputs give bit-identical costs in every builder, which
//! is what lets the level builder and the sweep builder agree on the tree they pick.

use crate::geometry::Aabb;
use serde::{Deserialize, Serialize};

/// The deepest any tree may go; traversal stacks are sized from it.
pub const MAX_DEPTH_CAP: u32 = 60;

/// SAH constants and termination rules.
///
/// The default prices a node step at `K_T = 60` against `K_I = 20` for a triangle, with a
/// bonus factor of 0.8 on a split that leaves one side empty. Wald & Havran's 2006 constants
/// (`K_T = 15`, [`CostModel::wald_havran`]) assume a triangle test costs more than a node
/// step; this traversal tests a leaf's triangles four at a time, and the wide nodes rays walk
/// open a large leaf into boxed blocks of four, so a triangle costs less and a node step
/// relatively more. With the default build (`balanced`, BENCHMARKS.md "Choosing `balanced`")
/// K_T 60 builds in less time than 45, with a third fewer nodes, for rays within a few percent
/// either way; against 15, 45 already traced dragon's and bunny's rays 5-11 % faster ("The
/// cost constants").
///
/// The greedy cost of splitting node `V` at `p` is
/// `lambda * (K_T + K_I * (SA(V_L) * N_L + SA(V_R) * N_R) / SA(V))`, against `K_I * N` for
/// keeping `V` a leaf.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct CostModel {
    /// `K_T`: the cost of stepping through one interior node.
    pub traversal: f32,
    /// `K_I`: the cost of one ray/triangle test.
    pub intersection: f32,
    /// `lambda` applied when one side of a split holds no primitive (1 disables the bonus).
    pub empty_bonus: f32,
    /// A node with this many primitives or fewer becomes a leaf without being priced.
    pub leaf_size: u32,
    /// Depth limit; `None` means `8 + 1.3 * log2(N)`, rounded. Always capped at
    /// [`MAX_DEPTH_CAP`].
    pub max_depth: Option<u32>,
    /// Reference budget: a build stops splitting once the references reach this many times
    /// the triangle count (plus a small constant), so that heavily overlapping input cannot
    /// exhaust memory.
    pub max_duplication: f32,
}

impl Default for CostModel {
    fn default() -> Self {
        CostModel {
            traversal: 60.0,
            intersection: 20.0,
            empty_bonus: 0.8,
            leaf_size: 1,
            max_depth: None,
            max_duplication: 16.0,
        }
    }
}

impl CostModel {
    /// Wald & Havran's (2006) constants, `K_T = 15` and `K_I = 20`, the default before this
    /// traversal was timed against them; otherwise the defaults.
    pub fn wald_havran() -> CostModel {
        CostModel {
            traversal: 15.0,
            intersection: 20.0,
            ..CostModel::default()
        }
    }

    /// The depth limit for a scene of `n` triangles.
    pub fn max_depth_for(&self, n: usize) -> u32 {
        let default = || (8.0 + 1.3 * (n.max(1) as f64).log2()).round() as u32;
        self.max_depth.unwrap_or_else(default).min(MAX_DEPTH_CAP)
    }

    /// The most references a build of `n` triangles may produce.
    pub fn reference_budget(&self, n: usize) -> usize {
        (n as f64 * self.max_duplication.max(1.0) as f64) as usize + 1024
    }

    /// The cost of keeping `n` primitives in a leaf.
    #[inline]
    pub fn leaf_cost(&self, n: u32) -> f32 {
        self.intersection * n as f32
    }

    /// The cost of splitting `node` at `axis = pos` with `nl` primitives left and `nr` right.
    ///
    /// Only planes strictly inside the node are meaningful; for any other plane, or a node
    /// without area, the cost is infinite so that no builder ever picks it.
    #[inline]
    pub fn split_cost(&self, node: &Aabb, axis: usize, pos: f32, nl: u32, nr: u32) -> f32 {
        self.splits_of(node, axis).cost(pos, nl, nr)
    }

    /// [`split_cost`](Self::split_cost) for many planes of one node and axis: what depends
    /// only on the node is computed once (bit-identical costs).
    #[inline]
    pub fn splits_of(&self, node: &Aabb, axis: usize) -> SplitPricer {
        let lo = node.lo[axis];
        let hi = node.hi[axis];
        let (b, c) = ((axis + 1) % 3, (axis + 2) % 3);
        // Extents are scaled by the largest one, so that scenes near 1e30 do not overflow
        // the products to infinity (and the ratio to NaN).
        let d = [hi - lo, node.hi[b] - node.lo[b], node.hi[c] - node.lo[c]];
        let scale = d[0].max(d[1]).max(d[2]);
        let inv = 1.0 / scale;
        let (db, dc) = (d[1] * inv, d[2] * inv);
        // Half surface areas: the factor 2 cancels in the ratio.
        let face = db * dc;
        let perimeter = db + dc;
        let area = face + d[0] * inv * perimeter;
        SplitPricer {
            lo,
            hi,
            inv,
            face,
            perimeter,
            area,
            valid: scale > 0.0 && scale.is_finite() && area > 0.0,
            model: *self,
        }
    }
}

/// The split costs of one node along one axis (see [`CostModel::splits_of`]).
#[derive(Clone, Copy, Debug)]
pub struct SplitPricer {
    lo: f32,
    hi: f32,
    inv: f32,
    face: f32,
    perimeter: f32,
    area: f32,
    /// False for a node without area (or with non-finite extents): every split is infinite.
    valid: bool,
    model: CostModel,
}

impl SplitPricer {
    /// The cost of the plane at `pos` with `nl` primitives left and `nr` right.
    #[inline]
    pub fn cost(&self, pos: f32, nl: u32, nr: u32) -> f32 {
        if !(pos > self.lo && pos < self.hi && self.valid) {
            return f32::INFINITY;
        }
        let area_l = self.face + (pos - self.lo) * self.inv * self.perimeter;
        let area_r = self.face + (self.hi - pos) * self.inv * self.perimeter;
        let bonus = if nl == 0 || nr == 0 {
            self.model.empty_bonus
        } else {
            1.0
        };
        bonus
            * (self.model.traversal
                + self.model.intersection * (area_l * nl as f32 + area_r * nr as f32) / self.area)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Vec3;

    fn unit_cube() -> Aabb {
        Aabb::new(Vec3::splat(0.0), Vec3::splat(1.0))
    }

    #[test]
    fn split_cost_matches_hand_computation() {
        // Unit cube split at x = 0.25: half-areas 1 + 0.25*2 = 1.5, 1 + 0.75*2 = 2.5, 3.
        let c = CostModel::wald_havran();
        let cost = c.split_cost(&unit_cube(), 0, 0.25, 4, 6);
        let expected = 15.0 + 20.0 * (1.5 * 4.0 + 2.5 * 6.0) / 3.0;
        assert!((cost - expected).abs() < 1e-4, "{cost} vs {expected}");
        let empty = c.split_cost(&unit_cube(), 1, 0.5, 0, 3);
        let expected = 0.8 * (15.0 + 20.0 * (2.0 * 3.0) / 3.0);
        assert!((empty - expected).abs() < 1e-4, "{empty} vs {expected}");
    }

    #[test]
    fn planes_on_or_outside_the_boundary_are_never_chosen() {
        let c = CostModel::default();
        for pos in [0.0, 1.0, -0.5, 2.0, f32::NAN] {
            assert_eq!(c.split_cost(&unit_cube(), 2, pos, 1, 1), f32::INFINITY);
        }
        let line = Aabb::new(Vec3::splat(0.0), Vec3::new(1.0, 0.0, 0.0));
        assert_eq!(c.split_cost(&line, 0, 0.5, 1, 1), f32::INFINITY);
    }

    #[test]
    fn huge_nodes_do_not_overflow() {
        let c = CostModel::wald_havran();
        let huge = Aabb::new(Vec3::splat(-1e30), Vec3::splat(1e30));
        let cost = c.split_cost(&huge, 0, 0.0, 5, 5);
        // Halving a cube: each side has half-area 1 + 0.5 * 2 = 2 of 3.
        let expected = 15.0 + 20.0 * (2.0 * 5.0 + 2.0 * 5.0) / 3.0;
        assert!((cost - expected).abs() < 1e-3, "{cost} vs {expected}");
    }

    #[test]
    fn default_depth_follows_pbrt_rule_and_is_capped() {
        let c = CostModel::default();
        assert_eq!(c.max_depth_for(1024), 21); // 8 + 1.3 * 10 = 21
        assert_eq!(c.max_depth_for(0), 8);
        let deep = CostModel {
            max_depth: Some(1000),
            ..c
        };
        assert_eq!(deep.max_depth_for(10), MAX_DEPTH_CAP);
    }
}
