//! The presort: the nine lists of the root, sorted on the host before the upload, or on the
//! device (the bitonic sort of [`crate::sort`] over one record per list entry).

use super::buffers::Grow;
use super::kernels::Kernels;
use super::Params;
use crate::{Gpu, GpuError};
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

/// Where the nine root lists are sorted.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Presort {
    /// On the device when it is a GPU (the bitonic sort is expected to beat the host there:
    /// not measured, no GPU was available), on the host when it is a CPU (lavapipe: the host's
    /// sort is several times faster than a software driver's).
    #[default]
    Auto,
    Host,
    Device,
}

/// A key ordered like `f32::total_cmp` (so -0 sorts before +0, as on the host).
fn total_key(v: f32) -> u32 {
    let bits = v.to_bits();
    if bits >> 31 == 1 {
        !bits
    } else {
        bits | 0x8000_0000
    }
}

/// The records the device sorts into the nine root lists: `(list, value key, primitive,
/// primitive)` per entry (sorted by the first three words: list by list, by value, ties by
/// primitive, the host's order), and each list's start and end.
pub(super) fn root_records(boxes: &[Aabb]) -> (Vec<[u32; 4]>, Vec<u32>) {
    let mut records = Vec::new();
    let mut starts = Vec::new();
    for a in 0..3 {
        for j in 0..3 {
            let list = (3 * a + j) as u32;
            starts.push(records.len() as u32);
            for (p, b) in boxes.iter().enumerate() {
                let value = match j {
                    0 => b.lo[a],
                    1 => b.hi[a],
                    _ if b.lo[a] == b.hi[a] => b.lo[a],
                    _ => continue,
                };
                records.push([list, total_key(value), p as u32, p as u32]);
            }
            starts.push(records.len() as u32);
        }
    }
    (records, starts)
}

/// Sorts the root lists on the device into `entries` (the records of [`root_records`] sorted
/// by [`crate::sort`], then their primitives gathered); returns the lists' total length and
/// starts.
pub(super) fn on_device(
    gpu: &Gpu,
    kernels: &Kernels,
    boxes: &[Aabb],
    entries: &mut Grow,
) -> Result<(usize, Vec<u32>), GpuError> {
    let (records, starts) = root_records(boxes);
    let n = records.len();
    let data = gpu.upload("presort records", records.as_flattened());
    let out = entries.ensure(gpu, n, false)?;
    let params = gpu.uniform(&Params {
        entries: n as u32,
        ..Params::default()
    });
    let mut enc = gpu.encoder();
    kernels.sort.record(gpu, &mut enc, &data, n)?;
    kernels.payloads.dispatch(
        gpu,
        &mut enc,
        &[
            ("params", &params),
            ("records", &data),
            ("out_entries", out),
        ],
        n as u64,
    );
    gpu.submit(enc);
    gpu.finish()?;
    Ok((n, starts))
}
