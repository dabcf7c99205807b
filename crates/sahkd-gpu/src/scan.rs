//! Exclusive prefix sums over u32 buffers, in several passes (see `shaders/scan.wgsl`).

use crate::kernel::{Kernel, GROUP};

/// Elements per workgroup (`BLOCK` in the shader: 4 per thread).
const BLOCK: usize = 4 * GROUP as usize;
use crate::{Gpu, GpuError};

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Params {
    n: u32,
    pad: [u32; 3],
}

/// The two kernels of the scan.
pub struct Scan {
    blocks: Kernel,
    add: Kernel,
}

impl Scan {
    pub fn new(gpu: &Gpu) -> Scan {
        let source = include_str!("shaders/scan.wgsl");
        Scan {
            blocks: Kernel::new(gpu, source, "scan_blocks"),
            add: Kernel::new(gpu, source, "add_block_sums"),
        }
    }

    /// Records the in-place exclusive scan of the first `n` elements of `data` (wrapping
    /// sums). To get the total as well, scan `n + 1` elements whose last is 0.
    pub fn record(
        &self,
        gpu: &Gpu,
        encoder: &mut wgpu::CommandEncoder,
        data: &wgpu::Buffer,
        n: usize,
    ) -> Result<(), GpuError> {
        if n == 0 {
            return Ok(());
        }
        let blocks = n.div_ceil(BLOCK);
        let threads = (blocks * GROUP as usize) as u64;
        let sums = gpu.storage("scan sums", blocks)?;
        let params = gpu.uniform(&Params {
            n: n as u32,
            pad: [0; 3],
        });
        self.blocks.dispatch(
            gpu,
            encoder,
            &[("params", &params), ("data", data), ("sums", &sums)],
            threads,
        );
        if blocks > 1 {
            self.record(gpu, encoder, &sums, blocks)?;
            self.add.dispatch(
                gpu,
                encoder,
                &[("params", &params), ("data", data), ("sums", &sums)],
                threads,
            );
        }
        Ok(())
    }
}

#[cfg(feature = "testing")]
/// Scans `values` on the GPU and returns the result (a convenience for tests and callers
/// that hold the data on the host).
pub fn exclusive_scan(gpu: &Gpu, values: &[u32]) -> Result<Vec<u32>, GpuError> {
    let scan = Scan::new(gpu);
    let data = gpu.upload("scan data", values);
    let mut encoder = gpu.encoder();
    scan.record(gpu, &mut encoder, &data, values.len())?;
    gpu.submit(encoder);
    gpu.download(&data, values.len())
}
