//! The sorted per-axis lists a level carries from one level to the next, in the two forms the
//! counting modes read: spans (one per reference, sorted by lo, for the space tree) and events
//! (start/end/planar, sorted by position, for the scan).
//!
//! Both store the reference's level slot (its index in the level's canonical arrays) so that a
//! partition can look up where the reference goes. Slots keep the primitives' relative order
//! (every partition is stable), so ordering ties by slot is ordering them by primitive index.

use crate::builders::event;
pub(super) use crate::builders::event::{ordered, Event, END, PLANAR, START};

/// Bits of a slot: the shared event encoding's id bits.
pub(super) const SLOT_BITS: u32 = event::ID_BITS;
/// The most references one level may hold.
pub(super) const MAX_SLOTS: usize = event::MAX_ID;

/// What the level machinery needs from a list entry.
pub(super) trait ListEntry: Copy + Send + Sync + 'static {
    fn slot(self) -> u32;
    fn with_slot(self, slot: u32) -> Self;
    /// A total order, equal to the list order: no two entries of one level share a key.
    fn key(self) -> u64;
    /// The key's low bits that only order entries of one reference by slot (below them the
    /// key is position, and kind for events).
    const SLOT_KEY_BITS: u32;
    /// Entries of a reference whose extent on the list's axis is `[lo, hi]`.
    #[inline(always)]
    fn count(lo: f32, hi: f32) -> u32 {
        Self::count_flat(lo == hi)
    }
    /// Entries of a reference that is flat (`lo == hi`) on the list's axis, or not.
    fn count_flat(flat: bool) -> u32;
    /// What this entry tells of the children its reference goes to at the plane `p`
    /// (left, right), by the shared rule (see `partition::sides`), where it tells it.
    fn sides(self, p: f32, planar_left: bool) -> [Option<bool>; 2];
    /// Those entries (the first `count` of the array).
    fn make(lo: f32, hi: f32, slot: u32) -> [Self; 2];
}

/// A reference's extent on one axis, in the lo-sorted list of the space tree.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[repr(C)]
pub(super) struct Span {
    pub lo: f32,
    pub hi: f32,
    pub slot: u32,
}

impl ListEntry for Span {
    #[inline(always)]
    fn slot(self) -> u32 {
        self.slot
    }
    #[inline(always)]
    fn with_slot(self, slot: u32) -> Self {
        Span { slot, ..self }
    }
    #[inline(always)]
    fn key(self) -> u64 {
        (ordered(self.lo) as u64) << 32 | self.slot as u64
    }
    const SLOT_KEY_BITS: u32 = 32;
    #[inline(always)]
    fn count_flat(_flat: bool) -> u32 {
        1
    }
    #[inline(always)]
    fn sides(self, p: f32, planar_left: bool) -> [Option<bool>; 2] {
        let in_plane = (self.lo == p) & (self.hi == p);
        [
            Some((self.lo < p) | (in_plane & planar_left)),
            Some((self.hi > p) | (in_plane & !planar_left)),
        ]
    }
    #[inline(always)]
    fn make(lo: f32, hi: f32, slot: u32) -> [Self; 2] {
        let s = Span { lo, hi, slot };
        [s, s]
    }
}

impl ListEntry for Event {
    #[inline(always)]
    fn slot(self) -> u32 {
        self.id()
    }
    #[inline(always)]
    fn with_slot(self, slot: u32) -> Self {
        self.with_id(slot)
    }
    #[inline(always)]
    fn key(self) -> u64 {
        self.0
    }
    const SLOT_KEY_BITS: u32 = SLOT_BITS;
    #[inline(always)]
    fn count_flat(flat: bool) -> u32 {
        2 - flat as u32
    }
    /// A start tells whether `lo < p` (left), an end whether `hi > p` (right), a planar event
    /// both.
    #[inline(always)]
    fn sides(self, p: f32, planar_left: bool) -> [Option<bool>; 2] {
        let x = self.pos();
        match self.kind() {
            START => [Some(x < p), None],
            END => [None, Some(x > p)],
            _ => {
                let in_plane = x == p;
                [
                    Some((x < p) | (in_plane & planar_left)),
                    Some((x > p) | (in_plane & !planar_left)),
                ]
            }
        }
    }
    #[inline(always)]
    fn make(lo: f32, hi: f32, slot: u32) -> [Self; 2] {
        if lo == hi {
            let e = Event::new(lo, PLANAR, slot);
            [e, e]
        } else {
            [Event::new(lo, START, slot), Event::new(hi, END, slot)]
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn events_sort_by_position_then_end_planar_start_then_slot() {
        let mut evs = [
            Event::new(1.0, START, 0),
            Event::new(1.0, END, 5),
            Event::new(0.5, START, 9),
            Event::new(1.0, PLANAR, 3),
            Event::new(1.0, END, 2),
        ];
        evs.sort_by_key(|e| e.key());
        let got: Vec<(f32, u32, u32)> = evs.iter().map(|e| (e.pos(), e.kind(), e.slot())).collect();
        assert_eq!(
            got,
            vec![
                (0.5, START, 9),
                (1.0, END, 2),
                (1.0, END, 5),
                (1.0, PLANAR, 3),
                (1.0, START, 0)
            ]
        );
        assert_eq!(evs[0].with_slot(7).slot(), 7);
        assert_eq!(evs[0].with_slot(7).pos(), 0.5);
        assert_eq!(evs[0].with_slot(7).kind(), START);
    }
}
