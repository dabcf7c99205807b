//! The host's presort: the nine lists of the root, before the upload.

use sahkd::Aabb;

/// The nine lists of the root (per axis: all primitives by lo, all by hi, the flat ones by
/// their value; ties by primitive index), concatenated, and each list's start and end.
pub(super) fn root_lists(boxes: &[Aabb]) -> (Vec<u32>, Vec<u32>) {
    let n = boxes.len() as u32;
    let mut entries = Vec::new();
    let mut starts = Vec::new();
    for a in 0..3 {
        let by = |value: &dyn Fn(u32) -> f32, filter: &dyn Fn(u32) -> bool| {
            let mut list: Vec<u32> = (0..n).filter(|&p| filter(p)).collect();
            list.sort_unstable_by(|&x, &y| value(x).total_cmp(&value(y)).then(x.cmp(&y)));
            list
        };
        let lo = |p: u32| boxes[p as usize].lo[a];
        let hi = |p: u32| boxes[p as usize].hi[a];
        for list in [
            by(&lo, &|_| true),
            by(&hi, &|_| true),
            by(&lo, &|p| lo(p) == hi(p)),
        ] {
            starts.push(entries.len() as u32);
            starts.push((entries.len() + list.len()) as u32);
            entries.extend(list);
        }
    }
    (entries, starts)
}
