//! The one split event type that every builder shares (the sweep, the level passes on the
//! CPU, the hand-over between them): [`Event`], packed in one `u64`, so that sorting and
//! merging events is integer work.
//!
//! Layout, high to low bits: 32 bits of the position (its [`ordered`] image), 2 bits of kind
//! (end < planar < start), 30 bits of id (the sweep's primitive index, a level's reference
//! slot; both keep the primitives' order). Integer order is therefore the total order
//! (position, kind, id) of Wald and Havran's sweep. Each axis keeps its own list, so the axis
//! is implicit. A position of -0 is stored as +0 (the same plane), so that equal positions
//! have equal bits.

/// The box ends here.
pub(crate) const END: u32 = 0;
/// The box is flat on this axis and lies in this plane.
pub(crate) const PLANAR: u32 = 1;
/// The box starts here.
pub(crate) const START: u32 = 2;

/// Bits of an id; the two bits above them hold the kind.
pub(crate) const ID_BITS: u32 = 30;
/// The largest id, and so the most primitives (or a level's references) a list may number.
pub(crate) const MAX_ID: usize = (1 << ID_BITS) - 1;
const ID_MASK: u64 = (1 << ID_BITS) - 1;

/// Maps an `f32` to a `u32` whose integer order is the float order (with -0 just below +0),
/// so that sort keys are plain integers.
#[inline(always)]
pub(crate) fn ordered(x: f32) -> u32 {
    let b = x.to_bits();
    if b >> 31 == 1 {
        !b
    } else {
        b | 0x8000_0000
    }
}

/// The inverse of [`ordered`].
#[inline(always)]
pub(crate) fn unordered(u: u32) -> f32 {
    f32::from_bits(if u >> 31 == 1 { u & 0x7fff_ffff } else { !u })
}

/// The position bits of a plane at `pos` ([`ordered`], with -0 taken as +0 as `==` does).
#[inline(always)]
pub(crate) fn plane_bits(pos: f32) -> u32 {
    ordered(pos + 0.0)
}

/// A split event: one `u64` whose integer order is the event order, so sorting and merging
/// events is integer work. `Default` is the all-zero event (a scratch value for buffers).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash)]
#[repr(transparent)]
pub(crate) struct Event(pub u64);

impl Event {
    /// The event of kind `kind` at `pos` for id `id`.
    #[inline(always)]
    pub fn new(pos: f32, kind: u32, id: u32) -> Event {
        Event((plane_bits(pos) as u64) << 32 | (kind as u64) << ID_BITS | id as u64)
    }

    /// The position's bits: equal exactly for equal positions.
    #[inline(always)]
    pub fn pos_bits(self) -> u32 {
        (self.0 >> 32) as u32
    }

    #[inline(always)]
    pub fn pos(self) -> f32 {
        unordered(self.pos_bits())
    }

    #[inline(always)]
    pub fn kind(self) -> u32 {
        ((self.0 >> ID_BITS) & 3) as u32
    }

    #[inline(always)]
    pub fn id(self) -> u32 {
        (self.0 & ID_MASK) as u32
    }

    /// The same event with another id.
    #[inline(always)]
    pub fn with_id(self, id: u32) -> Event {
        Event(self.0 & !ID_MASK | id as u64)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ordered_bits_follow_float_order_and_round_trip() {
        let xs = [
            f32::NEG_INFINITY,
            -1e30,
            -1.5,
            -f32::MIN_POSITIVE,
            -1e-45,
            -0.0,
            0.0,
            1e-45,
            1.0,
            3e38,
            f32::INFINITY,
        ];
        for w in xs.windows(2) {
            assert!(ordered(w[0]) < ordered(w[1]), "{} vs {}", w[0], w[1]);
        }
        for x in xs {
            assert_eq!(unordered(ordered(x)).to_bits(), x.to_bits());
        }
        assert_eq!(plane_bits(-0.0), plane_bits(0.0));
    }

    #[test]
    fn events_order_by_position_then_end_planar_start_then_id() {
        let mut evs = [
            Event::new(1.0, START, 0),
            Event::new(1.0, END, 5),
            Event::new(0.5, START, 9),
            Event::new(1.0, PLANAR, 3),
            Event::new(-0.0, END, MAX_ID as u32),
            Event::new(1.0, END, 2),
        ];
        evs.sort_unstable();
        let got: Vec<(f32, u32, u32)> = evs.iter().map(|e| (e.pos(), e.kind(), e.id())).collect();
        assert_eq!(
            got,
            vec![
                (0.0, END, MAX_ID as u32),
                (0.5, START, 9),
                (1.0, END, 2),
                (1.0, END, 5),
                (1.0, PLANAR, 3),
                (1.0, START, 0)
            ]
        );
        let moved = evs[1].with_id(7);
        assert_eq!((moved.pos(), moved.kind(), moved.id()), (0.5, START, 7));
    }
}
