//! Each node's best candidate over the level's flat candidate array (see
//! `shaders/segmin.wgsl`): a segmented minimum keyed by (cost, position, index).

use crate::kernel::Kernel;
use crate::price::DeviceLayout;
use crate::Gpu;
#[cfg(feature = "testing")]
use crate::GpuError;

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Params {
    n: u32,
    pad: [u32; 3],
}

/// No candidate (an empty node, or an index in `best` of a node without candidates).
pub const NONE: u32 = u32::MAX;

pub struct SegMin {
    rounds: [Kernel; 3],
}

impl SegMin {
    pub fn new(gpu: &Gpu) -> SegMin {
        let source = include_str!("shaders/segmin.wgsl");
        let k = |entry| Kernel::new(gpu, source, entry);
        SegMin {
            rounds: [k("min_cost"), k("min_pos"), k("min_index")],
        }
    }

    /// Records the three rounds over `n` candidates (with `on_device`, `n` is an upper bound
    /// and the real count is copied in on the device) (`cost` as f32 >= 0 or +inf, `pos` as
    /// f32, `owner` the node or `u32::MAX` for a hole). `best` holds 3 words per node, filled
    /// with `u32::MAX` beforehand; word 2 ends as the best candidate's index.
    #[allow(clippy::too_many_arguments)]
    pub fn record(
        &self,
        gpu: &Gpu,
        encoder: &mut wgpu::CommandEncoder,
        cost: &wgpu::Buffer,
        pos: &wgpu::Buffer,
        owner: &wgpu::Buffer,
        n: usize,
        on_device: Option<DeviceLayout>,
        best: &wgpu::Buffer,
    ) {
        let params = gpu.uniform(&Params {
            n: n as u32,
            pad: [0; 3],
        });
        if let Some(d) = on_device {
            d.patch(encoder, &params, [Some(0), None, None]);
        }
        for round in &self.rounds {
            round.dispatch(
                gpu,
                encoder,
                &[
                    ("params", &params),
                    ("cost", cost),
                    ("pos", pos),
                    ("owner", owner),
                    ("best", best),
                ],
                n as u64,
            );
        }
    }
}

#[cfg(feature = "testing")]
/// The index of each of `nodes` nodes' best candidate ([`NONE`] for none), computed on the GPU.
pub fn best_candidates(
    gpu: &Gpu,
    cost: &[f32],
    pos: &[f32],
    owner: &[u32],
    nodes: usize,
) -> Result<Vec<u32>, GpuError> {
    let n = cost.len();
    assert!(pos.len() == n && owner.len() == n);
    let kernel = SegMin::new(gpu);
    let best = gpu.upload("best", &vec![u32::MAX; 3 * nodes]);
    let (cost, pos, owner) = (
        gpu.upload("cost", cost),
        gpu.upload("pos", pos),
        gpu.upload("owner", owner),
    );
    let mut encoder = gpu.encoder();
    kernel.record(gpu, &mut encoder, &cost, &pos, &owner, n, None, &best);
    gpu.submit(encoder);
    let words = gpu.download::<u32>(&best, 3 * nodes)?;
    Ok(words.chunks(3).map(|w| w[2]).collect())
}
