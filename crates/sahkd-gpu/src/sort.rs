//! In-place sort of 4-word records `(k0, k1, k2, payload)`, ascending by `(k0, k1, k2)`: a
//! bitonic network (see `shaders/sort.wgsl`), deterministic for any input (a fixed network of
//! compare-exchanges; records with equal keys keep no particular order, but the same input
//! always gives the same output).
//!
//! Each thread runs up to four consecutive steps of a stage on 16 records in registers (a
//! phase). Dispatches for `n` records, `N` the next power of two (at least 512): one sorting
//! every tile of 512 in workgroup memory (15 phases), then per stage `2^s` for `s` in `10..=log2 N` its
//! `s - 9` steps of distance >= 512 in `ceil((s - 9) / 4)` global phases and one tile merge
//! for the 9 steps below. 2^20 records take 33 dispatches, not the network's 210 steps. No
//! scratch memory: past `n` the network sees virtual maxima that no comparator moves, so
//! nothing is padded.

use crate::kernel::{Kernel, GROUP};
use crate::{Gpu, GpuError};

/// Records per workgroup tile (`TILE` in the shader).
const TILE: usize = 512;

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Params {
    n: u32,
    k: u32,
    d: u32,
    r: u32,
    sets: u32,
    pad: [u32; 3],
}

/// Most steps of one phase (16 records per thread in registers).
const STEPS: u32 = 4;

/// The three kernels of the sort.
pub struct Sort {
    sort_tiles: Kernel,
    merge_tiles: Kernel,
    global_phase: Kernel,
}

impl Sort {
    pub fn new(gpu: &Gpu) -> Sort {
        let source = include_str!("shaders/sort.wgsl");
        let k = |entry| Kernel::new(gpu, source, entry);
        Sort {
            sort_tiles: k("sort_tiles"),
            merge_tiles: k("merge_tiles"),
            global_phase: k("global_phase"),
        }
    }

    /// Records the sort of the first `n` records (`4 n` words) of `data`, in place; words
    /// past them are not touched.
    pub fn record(
        &self,
        gpu: &Gpu,
        encoder: &mut wgpu::CommandEncoder,
        data: &wgpu::Buffer,
        n: usize,
    ) -> Result<(), GpuError> {
        if n <= 1 {
            return Ok(());
        }
        if (n as u64) * 16 > data.size() {
            return Err(GpuError::Runtime(format!(
                "sort of {n} records in a buffer of {} bytes",
                data.size()
            )));
        }
        // The shader indexes the network's N <= 2n records in u32 (bindings cap n far lower).
        if n > 1 << 30 {
            return Err(GpuError::Runtime(format!("sort of {n} records: too many")));
        }
        let size = n.next_power_of_two().max(TILE);
        // The tile kernels run one workgroup of 32 per tile; `dispatch` counts groups of 256.
        let tiles = n.div_ceil(TILE) as u64 * GROUP as u64;
        let params = |k: usize, d: usize, r: u32| {
            gpu.uniform(&Params {
                n: n as u32,
                k: k as u32,
                d: d as u32,
                r,
                sets: (size / 16) as u32,
                pad: [0; 3],
            })
        };
        self.sort_tiles.dispatch(
            gpu,
            encoder,
            &[("params", &params(0, 0, 0)), ("data", data)],
            tiles,
        );
        let mut k = 2 * TILE;
        while k <= size {
            // The stage's steps at distances k/2 .. 512, the short phase first.
            let mut m = (k / 2).trailing_zeros() - TILE.trailing_zeros() + 1;
            let mut r = m - STEPS * ((m - 1) / STEPS);
            let mut d = k / 2;
            while m > 0 {
                self.global_phase.dispatch(
                    gpu,
                    encoder,
                    &[("params", &params(k, d, r)), ("data", data)],
                    size as u64 / 16,
                );
                m -= r;
                d >>= r;
                r = STEPS;
            }
            self.merge_tiles.dispatch(
                gpu,
                encoder,
                &[("params", &params(k, 0, 0)), ("data", data)],
                tiles,
            );
            k *= 2;
        }
        Ok(())
    }
}

impl Sort {
    /// Sorts host records on the GPU and returns them.
    #[cfg(feature = "testing")]
    pub fn sort_records(&self, gpu: &Gpu, records: &[[u32; 4]]) -> Result<Vec<[u32; 4]>, GpuError> {
        let data = gpu.upload("sort data", records.as_flattened());
        let mut encoder = gpu.encoder();
        self.record(gpu, &mut encoder, &data, records.len())?;
        gpu.submit(encoder);
        let words = gpu.download::<u32>(&data, 4 * records.len())?;
        Ok(words
            .chunks_exact(4)
            .map(|w| [w[0], w[1], w[2], w[3]])
            .collect())
    }
}

#[cfg(feature = "testing")]
/// Sorts `records` on the GPU and returns them (a convenience for tests and callers that hold
/// the data on the host; it compiles the kernels, about 0.5 s on lavapipe, so reuse a [`Sort`]
/// for more than one sort).
pub fn sort_records(gpu: &Gpu, records: &[[u32; 4]]) -> Result<Vec<[u32; 4]>, GpuError> {
    Sort::new(gpu).sort_records(gpu, records)
}
