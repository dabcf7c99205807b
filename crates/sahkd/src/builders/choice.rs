//! The one order in which every builder ranks candidate planes: the cheaper first, then the
//! smaller position, then the lower axis. Because it is a total order on (cost, position,
//! axis), builders that price the same candidates pick the same plane whatever order they
//! visit them in, serially, by sweeps or by parallel reductions.

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

    fn ranked(&self) -> Ranked {
        Ranked {
            cost: self.cost,
            pos: self.pos,
            axis: self.axis,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::Ranked;

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
