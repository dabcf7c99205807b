//! The paper's counting on the GPU (see `shaders/space_tree.wgsl`): the space tree of every
//! node's segment of the three lo-sorted lists, built bottom-up by height, then one stack-free
//! walk per candidate. Same counts as the level builder's binary-search `count` kernel
//! (`L = #(lo < p)`, `R = #(hi > p)`, `P = #(lo == p == hi)`, zeros for holes), plus the
//! CPU's counters (walk steps, cut primitives).
//!
//! Buffers (words of 4 bytes), for a level of `nodes` nodes and `refs` references per list:
//! - `ref_boxes`: 6 f32 per reference id, lo.xyz then hi.xyz;
//! - `entries`: the nine lists of reference ids, `starts`: `9 (nodes + 1)` segment starts
//!   (node k's segment of list j begins at `starts[j (nodes + 1) + k]`);
//! - `cand_pos` (f32), `cand_owner` (node or `u32::MAX` for a hole): one per candidate, laid
//!   out by a [`Layout`] (axis blocks 0, 1, 2);
//! - `trees`: `3 refs` [`TreeNode`]s (`9 refs` words), axis a's block at `a refs`, aligned with
//!   list `3a`'s entries;
//! - `counts`: 3 words per candidate; `stats`: [`STATS_WORDS`] words, see [`WalkStats`].
//!
//! Cost: one dispatch for the slots (a binary search over the node starts each, to find its
//! segment), then one per height `1..=log2(refs)` with one thread per window of `2^h` slots
//! (about one thread per slot over all heights together); the count is one dispatch.
//!
//! The walk does O(NP + log n) steps per candidate where the binary searches of the `count`
//! kernel do three of log n: at the bunny's root (about 600 spans cut per plane) that is 640
//! steps per candidate against about 50 reads, so this pays only where planes cut few spans.

use crate::kernel::Kernel;
use crate::price::{DeviceLayout, Layout};
use crate::{Gpu, GpuError};
#[cfg(feature = "testing")]
use {crate::price::box_words, sahkd::Aabb};

#[repr(C)]
#[derive(Clone, Copy, Default, bytemuck::Pod, bytemuck::Zeroable)]
struct Params {
    nodes: u32,
    refs: u32,
    cands: u32,
    first1: u32,
    first2: u32,
    height: u32,
    windows: u32,
    pad: u32,
}

/// One slot of a space tree: a span and the largest `hi` of its subtree.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct TreeNode {
    pub lo: f32,
    pub hi: f32,
    pub max: f32,
}

/// Words of the `stats` buffer: walk steps (low, high word), cut primitives (low, high word),
/// candidates walked.
pub const STATS_WORDS: usize = 5;

/// The counters of one count, as the CPU's space-tree counting reports them.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct WalkStats {
    /// Tree slots visited, over all candidates.
    pub walk_steps: u64,
    /// Primitives with `lo < p < hi`, summed over candidates (the paper's NP).
    pub cut_primitives: u64,
    /// Candidates that were not holes.
    pub walks: u32,
}

impl WalkStats {
    pub fn from_words(w: &[u32]) -> WalkStats {
        WalkStats {
            walk_steps: w[0] as u64 | (w[1] as u64) << 32,
            cut_primitives: w[2] as u64 | (w[3] as u64) << 32,
            walks: w[4],
        }
    }
}

/// The three kernels: slots, heights, count.
pub struct SpaceTree {
    leaves: Kernel,
    heights: Kernel,
    count: Kernel,
}

impl SpaceTree {
    pub fn new(gpu: &Gpu) -> SpaceTree {
        let source = include_str!("shaders/space_tree.wgsl");
        let header = source.split("//! kernel ").next().unwrap_or_default();
        let kernel = |name: &str| {
            let body = section(source, name);
            Kernel::new(gpu, &format!("{header}{body}"), name)
        };
        SpaceTree {
            leaves: kernel("leaves"),
            heights: kernel("heights"),
            count: kernel("count"),
        }
    }

    /// Records the build of the space trees of every node on all three axes into `trees`
    /// (`3 refs` [`TreeNode`]s). Allocates a scratch of `3 refs` words (each slot's node).
    pub fn record_build(
        &self,
        gpu: &Gpu,
        encoder: &mut wgpu::CommandEncoder,
        nodes: usize,
        refs: usize,
        [ref_boxes, entries, starts]: [&wgpu::Buffer; 3],
        trees: &wgpu::Buffer,
    ) -> Result<(), GpuError> {
        if refs == 0 {
            return Ok(());
        }
        let slot_node = gpu.storage("space tree slot nodes", 3 * refs)?;
        let mut p = Params {
            nodes: nodes as u32,
            refs: refs as u32,
            ..Params::default()
        };
        self.leaves.dispatch(
            gpu,
            encoder,
            &[
                ("params", &gpu.uniform(&p)),
                ("ref_boxes", ref_boxes),
                ("entries", entries),
                ("starts", starts),
                ("trees", trees),
                ("slot_node", &slot_node),
            ],
            3 * refs as u64,
        );
        // No segment is longer than the list: its tallest slot has height log2(refs).
        for h in 1..=refs.ilog2() {
            p.height = h;
            p.windows = refs.div_ceil(1 << h) as u32;
            self.heights.dispatch(
                gpu,
                encoder,
                &[
                    ("params", &gpu.uniform(&p)),
                    ("starts", starts),
                    ("slot_node", &slot_node),
                    ("trees", trees),
                ],
                3 * p.windows as u64,
            );
        }
        Ok(())
    }

    /// Records the count of every candidate into `counts` (3 words each) and the walk's
    /// counters into `stats` ([`STATS_WORDS`] words, cleared first, so it needs `COPY_DST`);
    /// `trees` must hold this level's trees ([`SpaceTree::record_build`]).
    #[allow(clippy::too_many_arguments)]
    pub fn record_count(
        &self,
        gpu: &Gpu,
        encoder: &mut wgpu::CommandEncoder,
        nodes: usize,
        refs: usize,
        cands: Layout,
        on_device: Option<DeviceLayout>,
        [starts, trees, cand_pos, cand_owner]: [&wgpu::Buffer; 4],
        counts: &wgpu::Buffer,
        stats: &wgpu::Buffer,
    ) {
        encoder.clear_buffer(stats, 0, Some(4 * STATS_WORDS as u64));
        if cands.n == 0 {
            return;
        }
        let p = Params {
            nodes: nodes as u32,
            refs: refs as u32,
            cands: cands.n as u32,
            first1: cands.first1 as u32,
            first2: cands.first2 as u32,
            ..Params::default()
        };
        let params = gpu.uniform(&p);
        if let Some(d) = on_device {
            d.patch(encoder, &params, [Some(8), Some(12), Some(16)]);
        }
        self.count.dispatch(
            gpu,
            encoder,
            &[
                ("params", &params),
                ("starts", starts),
                ("trees", trees),
                ("cand_pos", cand_pos),
                ("cand_owner", cand_owner),
                ("counts", counts),
                ("stats", stats),
            ],
            cands.n as u64,
        );
    }
}

/// The body of the section of `name` in a kernel file (after its marker line).
fn section<'a>(source: &'a str, name: &str) -> &'a str {
    source
        .split("//! kernel ")
        .skip(1)
        .find_map(|s| {
            let (first, body) = s.split_once('\n').unwrap_or((s, ""));
            (first.trim() == name).then_some(body)
        })
        .unwrap_or_else(|| panic!("kernel {name} in space_tree.wgsl"))
}

#[cfg(feature = "testing")]
/// What a whole run on host data gives: the trees, the counts, the counters.
pub struct HostRun {
    pub trees: Vec<TreeNode>,
    pub counts: Vec<[u32; 3]>,
    pub stats: WalkStats,
}

#[cfg(feature = "testing")]
/// Builds the trees and counts `cands` (position, owner; holes owned by `u32::MAX`, axis
/// blocks starting at `first1` and `first2`) on the GPU, from host data laid out as the
/// buffers of this module (`ref_boxes` indexed by the reference ids of `entries`).
#[allow(clippy::too_many_arguments)]
pub fn run_space_tree(
    gpu: &Gpu,
    ref_boxes: &[Aabb],
    entries: &[u32],
    starts: &[u32],
    nodes: usize,
    cands: &[(f32, u32)],
    first1: usize,
    first2: usize,
) -> Result<HostRun, GpuError> {
    assert_eq!(starts.len(), 9 * (nodes + 1), "nine lists of node starts");
    let refs = (starts[nodes] - starts[0]) as usize;
    let layout = Layout {
        n: cands.len(),
        first1,
        first2,
    };
    let kernels = SpaceTree::new(gpu);
    let boxes = gpu.upload("ref boxes", &box_words(ref_boxes));
    let entries = gpu.upload("entries", entries);
    let starts = gpu.upload("starts", starts);
    let pos: Vec<f32> = cands.iter().map(|c| c.0).collect();
    let owner: Vec<u32> = cands.iter().map(|c| c.1).collect();
    let (pos, owner) = (
        gpu.upload("cand pos", &pos),
        gpu.upload("cand owner", &owner),
    );
    let trees = gpu.storage("trees", 9 * refs)?;
    let counts = gpu.storage("counts", 3 * cands.len())?;
    let stats = gpu.storage("stats", STATS_WORDS)?;
    let mut encoder = gpu.encoder();
    kernels.record_build(
        gpu,
        &mut encoder,
        nodes,
        refs,
        [&boxes, &entries, &starts],
        &trees,
    )?;
    kernels.record_count(
        gpu,
        &mut encoder,
        nodes,
        refs,
        layout,
        None,
        [&starts, &trees, &pos, &owner],
        &counts,
        &stats,
    );
    gpu.submit(encoder);
    let counts = gpu.download::<u32>(&counts, 3 * cands.len())?;
    Ok(HostRun {
        trees: gpu.download(&trees, 3 * refs)?,
        counts: counts.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect(),
        stats: WalkStats::from_words(&gpu.download::<u32>(&stats, STATS_WORDS)?),
    })
}

#[cfg(feature = "testing")]
/// The counts of [`run_space_tree`] alone.
#[allow(clippy::too_many_arguments)]
pub fn count_space_tree(
    gpu: &Gpu,
    ref_boxes: &[Aabb],
    entries: &[u32],
    starts: &[u32],
    nodes: usize,
    cands: &[(f32, u32)],
    first1: usize,
    first2: usize,
) -> Result<Vec<[u32; 3]>, GpuError> {
    let run = run_space_tree(
        gpu, ref_boxes, entries, starts, nodes, cands, first1, first2,
    )?;
    Ok(run.counts)
}
