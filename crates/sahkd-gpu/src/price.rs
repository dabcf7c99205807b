//! The SAH cost of every candidate plane of a level (see `shaders/price.wgsl` for how the f32
//! operations are kept identical to [`sahkd::CostModel::split_cost`]).

use crate::kernel::Kernel;
use crate::Gpu;
#[cfg(feature = "testing")]
use crate::GpuError;
use sahkd::{Aabb, CostModel};

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Params {
    traversal: f32,
    intersection: f32,
    empty_bonus: f32,
    zero: u32,
    n: u32,
    first1: u32,
    first2: u32,
    pad: u32,
}

/// Where a level's candidates lie: how many, and the first of axis 1's and axis 2's blocks.
#[derive(Clone, Copy, Debug)]
pub struct Layout {
    pub n: usize,
    pub first1: usize,
    pub first2: usize,
}

/// Where a level's candidate layout lies on the device (byte offsets, in `buffer`, of the words
/// holding the candidate count and the first of axis 1's and axis 2's blocks), when the host
/// has not read it: launches are then sized by an upper bound ([`Layout::n`]) and the real
/// values are copied into their parameters on the device.
#[derive(Clone, Copy)]
pub struct DeviceLayout<'a> {
    pub buffer: &'a wgpu::Buffer,
    pub n: u64,
    pub first1: u64,
    pub first2: u64,
}

impl DeviceLayout<'_> {
    /// Records copies of the layout's words into `uniform` at the byte offsets `[n, first1,
    /// first2]` (`None`: a word the parameters do not hold).
    pub fn patch(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        uniform: &wgpu::Buffer,
        at: [Option<u64>; 3],
    ) {
        for (from, to) in [self.n, self.first1, self.first2].into_iter().zip(at) {
            if let Some(to) = to {
                encoder.copy_buffer_to_buffer(self.buffer, from, uniform, to, 4);
            }
        }
    }
}

pub struct Price {
    kernel: Kernel,
    #[cfg(feature = "testing")]
    divide: Kernel,
}

/// The node boxes as the kernel reads them: lo.xyz, hi.xyz per node.
pub fn box_words(boxes: &[Aabb]) -> Vec<f32> {
    boxes
        .iter()
        .flat_map(|b| [b.lo[0], b.lo[1], b.lo[2], b.hi[0], b.hi[1], b.hi[2]])
        .collect()
}

impl Price {
    pub fn new(gpu: &Gpu) -> Price {
        let source = include_str!("shaders/price.wgsl");
        Price {
            kernel: Kernel::new(gpu, source, "price"),
            #[cfg(feature = "testing")]
            divide: Kernel::new(gpu, source, "divide"),
        }
    }

    /// Records the pricing of every candidate: `boxes` (6 f32 per node), `pos`, `owner`
    /// (`u32::MAX` for a hole), `counts` (L, R, P per candidate) in; `cost` (f32) and `packed`
    /// (`(L + R + P) << 1 | planar_left`) out.
    #[allow(clippy::too_many_arguments)]
    pub fn record(
        &self,
        gpu: &Gpu,
        encoder: &mut wgpu::CommandEncoder,
        model: &CostModel,
        layout: Layout,
        on_device: Option<DeviceLayout>,
        [boxes, pos, owner, counts]: [&wgpu::Buffer; 4],
        [cost, packed]: [&wgpu::Buffer; 2],
    ) {
        let params = gpu.uniform(&Params {
            traversal: model.traversal,
            intersection: model.intersection,
            empty_bonus: model.empty_bonus,
            zero: 0,
            n: layout.n as u32,
            first1: layout.first1 as u32,
            first2: layout.first2 as u32,
            pad: 0,
        });
        if let Some(d) = on_device {
            d.patch(encoder, &params, [Some(16), Some(20), Some(24)]);
        }
        self.kernel.dispatch(
            gpu,
            encoder,
            &[
                ("params", &params),
                ("boxes", boxes),
                ("pos", pos),
                ("owner", owner),
                ("counts", counts),
                ("cost", cost),
                ("packed", packed),
            ],
            layout.n as u64,
        );
    }
}

#[cfg(feature = "testing")]
/// Prices candidates held on the host; returns `(cost, packed)` per candidate.
pub fn price_candidates(
    gpu: &Gpu,
    model: &CostModel,
    boxes: &[Aabb],
    layout: Layout,
    pos: &[f32],
    owner: &[u32],
    counts: &[[u32; 3]],
) -> Result<(Vec<f32>, Vec<u32>), GpuError> {
    let n = layout.n;
    assert!(pos.len() == n && owner.len() == n && counts.len() == n);
    let price = Price::new(gpu);
    let inputs = [
        gpu.upload("boxes", &box_words(boxes)),
        gpu.upload("pos", pos),
        gpu.upload("owner", owner),
        gpu.upload("counts", counts.as_flattened()),
    ];
    let cost = gpu.storage("cost", n)?;
    let packed = gpu.storage("packed", n)?;
    let mut encoder = gpu.encoder();
    let [a, b, c, d] = &inputs;
    price.record(
        gpu,
        &mut encoder,
        model,
        layout,
        None,
        [a, b, c, d],
        [&cost, &packed],
    );
    gpu.submit(encoder);
    Ok((gpu.download(&cost, n)?, gpu.download(&packed, n)?))
}

#[cfg(feature = "testing")]
/// The shader's correctly rounded division on bit patterns `(a, b)`: the result's bits per
/// pair (for tests of the kernel's arithmetic against the CPU's `a / b`).
pub fn divide_bits(gpu: &Gpu, pairs: &[[u32; 2]]) -> Result<Vec<u32>, GpuError> {
    let n = pairs.len();
    let price = Price::new(gpu);
    let params = gpu.uniform(&Params {
        traversal: 0.0,
        intersection: 0.0,
        empty_bonus: 0.0,
        zero: 0,
        n: n as u32,
        first1: 0,
        first2: 0,
        pad: 0,
    });
    // Read-only and writable uses of one buffer may not meet in a launch.
    let unused = gpu.storage("unused", 1)?;
    let unused_out = gpu.storage("unused out", 1)?;
    let operands = gpu.upload("operands", pairs.as_flattened());
    let quotient = gpu.storage("quotient", n)?;
    let mut encoder = gpu.encoder();
    price.divide.dispatch(
        gpu,
        &mut encoder,
        &[
            ("params", &params),
            ("boxes", &unused),
            ("pos", &unused),
            ("owner", &unused),
            ("counts", &operands),
            ("cost", &quotient),
            ("packed", &unused_out),
        ],
        n as u64,
    );
    gpu.submit(encoder);
    gpu.download(&quotient, n)
}
