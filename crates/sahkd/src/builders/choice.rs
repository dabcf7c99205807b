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
