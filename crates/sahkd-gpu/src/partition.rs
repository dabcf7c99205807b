//! Stable split of every segment's elements into its left and right outputs: flags, one
//! multi-pass scan, scatter (see `shaders/partition.wgsl`).

use crate::kernel::Kernel;
use crate::scan::Scan;
use crate::{Gpu, GpuError};

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Params {
    n: u32,
    pad: [u32; 3],
}

/// Side bits of an element: to the left output, to the right output (both for a straddler).
pub const LEFT: u32 = 1;
pub const RIGHT: u32 = 2;

/// One segment: its first element and the first output slots of its two sides.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct Segment {
    pub first: u32,
    pub left_out: u32,
    pub right_out: u32,
    pub pad: u32,
}

pub struct Partition {
    flags: Kernel,
    scatter: Kernel,
    scan: Scan,
}

impl Partition {
    pub fn new(gpu: &Gpu) -> Partition {
        Partition {
            flags: Kernel::new(gpu, include_str!("shaders/partition.wgsl"), "set_flags"),
            scatter: Kernel::new(gpu, include_str!("shaders/scatter.wgsl"), "scatter"),
            scan: Scan::new(gpu),
        }
    }

    /// Records the split of `n` elements (`values`, their segment `owner`, their `side` bits)
    /// into `out`, laid out by `segments`.
    #[allow(clippy::too_many_arguments)]
    pub fn record(
        &self,
        gpu: &Gpu,
        encoder: &mut wgpu::CommandEncoder,
        n: usize,
        [side, values, owner, segments]: [&wgpu::Buffer; 4],
        out: &wgpu::Buffer,
    ) -> Result<(), GpuError> {
        let params = gpu.uniform(&Params {
            n: n as u32,
            pad: [0; 3],
        });
        let flags = gpu.storage("partition flags", 2 * n + 2)?;
        self.flags.dispatch(
            gpu,
            encoder,
            &[("params", &params), ("side", side), ("flags", &flags)],
            n as u64 + 1,
        );
        self.scan.record(gpu, encoder, &flags, 2 * n + 2)?;
        self.scatter.dispatch(
            gpu,
            encoder,
            &[
                ("params", &params),
                ("side", side),
                ("flags", &flags),
                ("values", values),
                ("owner", owner),
                ("segments", segments),
                ("out", out),
            ],
            n as u64,
        );
        Ok(())
    }
}

/// Splits host data on the GPU into an output of `out_len` elements.
pub fn split_segments(
    gpu: &Gpu,
    values: &[u32],
    owner: &[u32],
    side: &[u32],
    segments: &[Segment],
    out_len: usize,
) -> Result<Vec<u32>, GpuError> {
    let n = values.len();
    assert!(owner.len() == n && side.len() == n);
    let partition = Partition::new(gpu);
    let inputs = [
        gpu.upload("side", side),
        gpu.upload("values", values),
        gpu.upload("owner", owner),
        gpu.upload("segments", segments),
    ];
    let out = gpu.storage("split", out_len)?;
    let mut encoder = gpu.encoder();
    let [a, b, c, d] = &inputs;
    partition.record(gpu, &mut encoder, n, [a, b, c, d], &out)?;
    gpu.submit(encoder);
    gpu.download(&out, out_len)
}
