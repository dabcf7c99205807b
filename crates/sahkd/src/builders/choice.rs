//! What every builder decides and by which rules: the one split record ([`Split`]), the one
//! order in which candidate planes rank (the cheaper first, then the smaller position, then
//! the lower axis), and the rules around any split search ([`split_or_leaf`]).
//!
//! Because the order is total on (cost, position, axis), builders that price the same
//! candidates pick the same plane whatever order they visit them in, serially, by sweeps or
//! by parallel reductions. Each builder brings its own search (the sweep over sorted events,
//! bins, the level passes over a whole level, the median cut); the rules around it are here.

use crate::cost::CostModel;

/// A priced candidate plane, as the ranking sees it.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Ranked {
    pub cost: f32,
    pub pos: f32,
    pub axis: usize,
}

impl Ranked {
    /// Whether `self` is chosen over `other`.
    #[inline]
    pub fn precedes(self, other: Ranked) -> bool {
        self.cost < other.cost
            || (self.cost == other.cost
                && (self.pos < other.pos || (self.pos == other.pos && self.axis < other.axis)))
    }
}

/// A split plane as every builder records it (the sweep, its binned top, the median builder,
/// the level passes): where, at what cost, and how many primitives each child gets before
/// clipping.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Split {
    pub axis: usize,
    pub pos: f32,
    pub cost: f32,
    /// The primitives lying in the plane go left (else right).
    pub planar_left: bool,
    /// Primitives on each side, planar ones counted on their side.
    pub n_left: u32,
    pub n_right: u32,
}

impl Split {
    /// Whether this split is chosen over the best so far, by the builders' one order.
    #[inline]
    pub fn beats(&self, other: &Option<Split>) -> bool {
        match other {
            None => self.cost.is_finite(),
            Some(o) => self.ranked().precedes(o.ranked()),
        }
    }

    /// References the two children hold before clipping.
    #[inline]
    pub fn refs(&self) -> u32 {
        self.n_left + self.n_right
    }

    /// Whether this split pays for a node of `n` primitives: it costs strictly less than
    /// the node as a leaf.
    #[inline]
    pub fn pays(&self, n: u32, cost: &CostModel) -> bool {
        self.cost < cost.leaf_cost(n)
    }

    fn ranked(&self) -> Ranked {
        Ranked {
            cost: self.cost,
            pos: self.pos,
            axis: self.axis,
        }
    }
}

/// Whether a node of `n` primitives at `depth` is searched for a split at all: a node of at
/// most `leaf_size` primitives, or at the depth cap, is a leaf without one.
#[inline]
pub(crate) fn searched(n: u32, depth: u32, max_depth: u32, cost: &CostModel) -> bool {
    n > cost.leaf_size && depth < max_depth
}

/// The split a node of `n` primitives at `depth` gets from `search`, by the rules every
/// builder applies around its search: searched only where [`searched`] allows, kept only
/// where it [`Split::pays`]. `None` makes a leaf.
#[inline]
pub(crate) fn split_or_leaf(
    n: u32,
    depth: u32,
    max_depth: u32,
    cost: &CostModel,
    search: impl FnOnce() -> Option<Split>,
) -> Option<Split> {
    if !searched(n, depth, max_depth, cost) {
        return None;
    }
    search().filter(|s| s.pays(n, cost))
}

#[cfg(test)]
mod tests {
    use super::{split_or_leaf, Ranked, Split};
    use crate::cost::CostModel;

    #[test]
    fn the_rules_around_a_search() {
        let cost = CostModel {
            leaf_size: 4,
            ..CostModel::default()
        };
        let split = |c: f32| Split {
            axis: 0,
            pos: 0.5,
            cost: c,
            planar_left: true,
            n_left: 3,
            n_right: 3,
        };
        let searched = std::cell::Cell::new(0);
        let search = |c: f32| {
            searched.set(searched.get() + 1);
            Some(split(c))
        };
        // At the leaf size or the depth cap the search does not run.
        assert_eq!(split_or_leaf(4, 0, 10, &cost, || search(0.0)), None);
        assert_eq!(split_or_leaf(5, 10, 10, &cost, || search(0.0)), None);
        assert_eq!(searched.get(), 0);
        // Five primitives as a leaf cost 5 x 20 = 100: a split of 99 pays, one of 100 not.
        assert_eq!(
            split_or_leaf(5, 9, 10, &cost, || search(99.0)),
            Some(split(99.0))
        );
        assert_eq!(split_or_leaf(5, 9, 10, &cost, || search(100.0)), None);
        assert_eq!(split_or_leaf(5, 0, 10, &cost, || None), None);
        assert_eq!(searched.get(), 2);
    }

    fn r(cost: f32, pos: f32, axis: usize) -> Ranked {
        Ranked { cost, pos, axis }
    }

    #[test]
    fn cost_then_position_then_axis() {
        assert!(r(1.0, 5.0, 2).precedes(r(2.0, 0.0, 0)));
        assert!(r(1.0, 0.0, 2).precedes(r(1.0, 5.0, 0)));
        assert!(r(1.0, 5.0, 0).precedes(r(1.0, 5.0, 1)));
        // Strict: a candidate never precedes itself, so the first of equals is kept.
        assert!(!r(1.0, 5.0, 1).precedes(r(1.0, 5.0, 1)));
        // Unpriced candidates (infinite cost) lose to every priced one.
        assert!(!r(f32::INFINITY, 0.0, 0).precedes(r(1e30, 9.0, 2)));
    }
}
