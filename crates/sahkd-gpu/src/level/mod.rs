//! The level builder on the GPU: the same tree as the CPU level builder with the same
//! options, its data-parallel phases as WGSL kernels (`shaders/level.wgsl` and the kernels of
//! [`crate::price`], [`crate::segmin`], [`crate::scan`], [`crate::sort`]).
//!
//! The host sorts the nine lists once ([`presort`]: by lo, by hi, and the flat references,
//! per axis) and uploads them with the primitive boxes (and, with clipping, the triangles);
//! each level then runs on the GPU, one module per phase, in the CPU level builder's order:
//! - [`layout`]: axes in use and the candidate layout (a scan; it stays on the device, the
//!   candidate arrays sized by an upper bound);
//! - [`candidates`]: candidates, counting (binary searches of the node's sorted segments, or
//!   the paper's space trees) and pricing;
//! - [`decision`]: the best split (segmented min), the decision (scans), the sides of every
//!   reference (clipping straddlers) and the lists' flags; the host reads the totals;
//! - [`output`]: this level's nodes and leaf references;
//! - [`partition`]: the reference table and the lists of the next level (flags, scans,
//!   scatter; clipped straddlers' entries sorted and merged by rank).
//!
//! [`buffers`] holds the device memory as named fields; [`kernels`] loads the shaders (each
//! launch binds its buffers by the names the WGSL gives them). The finished tree comes down
//! once.

mod buffers;
mod candidates;
mod decision;
mod kernels;
mod layout;
mod output;
mod partition;
mod presort;
#[cfg(test)]
mod tests;

use crate::{Gpu, GpuError};
use buffers::{LevelBuffers, Lists};
use kernels::Kernels;
pub use presort::Presort;
use sahkd::builders::{Algorithm, Axes, BuildOptions};
use sahkd::geometry::triangle_bounds;
use sahkd::{Aabb, KdTree, Node, Triangle};
use std::time::Instant;

/// The parameters of a level's launches (`Params` in `shaders/level.wgsl`).
#[repr(C)]
#[derive(Clone, Copy, Default, bytemuck::Pod, bytemuck::Zeroable)]
struct Params {
    nodes: u32,
    entries: u32,
    refs: u32,
    depth: u32,
    max_depth: u32,
    leaf_size: u32,
    axes_all: u32,
    force_leaves: u32,
    intersection: f32,
    cands: u32,
    first1: u32,
    first2: u32,
    next_nodes: u32,
    node_base: u32,
    ref_base: u32,
    clip: u32,
    regen: u32,
    pad: [u32; 3],
}

/// Phases timed on the host around their submissions (each waits for the GPU). "sides" is
/// where straddlers are clipped; "partition" includes sorting their rebuilt list entries.
pub const PHASES: [&str; 9] = [
    "layout",
    "candidates",
    "counting",
    "pricing",
    "best split",
    "decision",
    "sides",
    "partition",
    "output",
];

/// One of the [`PHASES`]: its index in [`GpuReport::phase_ms`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Phase {
    Layout,
    Candidates,
    Counting,
    Pricing,
    BestSplit,
    Decision,
    Sides,
    Partition,
    Output,
}

impl Phase {
    pub const ALL: [Phase; 9] = [
        Phase::Layout,
        Phase::Candidates,
        Phase::Counting,
        Phase::Pricing,
        Phase::BestSplit,
        Phase::Decision,
        Phase::Sides,
        Phase::Partition,
        Phase::Output,
    ];

    /// Its name in [`PHASES`] (and in the CLI's report).
    pub fn name(self) -> &'static str {
        PHASES[self as usize]
    }
}

/// How a GPU build went.
#[derive(Clone, Debug, Default)]
pub struct GpuReport {
    /// "name (backend, device type)".
    pub adapter: String,
    pub upload_ms: f64,
    /// Milliseconds per phase, in the order of [`PHASES`], summed over levels.
    pub phase_ms: Vec<f64>,
    pub download_ms: f64,
    /// Presorting the nine root lists (on the host, or on the device with the records'
    /// upload), see [`Presort`].
    pub presort_ms: f64,
    /// Whether the presort ran on the device (else on the host).
    pub presort_on_device: bool,
    pub levels: usize,
    /// Reads of GPU results by the host during the build (one per level: the decision's
    /// totals; the candidate layout stays on the device).
    pub round_trips: usize,
    pub total_ms: f64,
    /// Bytes of the level buffers on the device at the end (they only grow, so the peak).
    pub device_bytes: usize,
}

/// A tree built on the GPU and its report.
pub struct GpuBuild {
    pub tree: KdTree,
    pub report: GpuReport,
}

/// Whether `options` can run on the GPU: the level builder, with any of its options.
pub fn check_options(options: &BuildOptions) -> Result<(), String> {
    if options.algorithm != Algorithm::Level {
        return Err(format!(
            "--device gpu runs the level builder only, not {:?}",
            options.algorithm
        ));
    }
    Ok(())
}

fn ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

/// What a level's decision leaves: the totals the host reads once per level.
#[derive(Clone, Copy, Debug)]
struct Totals {
    /// Nodes split (each has two children in the next level).
    splits: usize,
    /// References in this level's leaves.
    leaf_refs: usize,
    /// References of the next level before clipping (the budget's count).
    next_refs: usize,
    /// The next level's list entries and table length.
    next_entries: usize,
    next_table: usize,
    /// Rebuilt list entries of clipped straddlers.
    regen: usize,
}

/// A build in progress: the device, its kernels and buffers, and the report.
struct Builder<'a> {
    gpu: &'a Gpu,
    options: &'a BuildOptions,
    kernels: Kernels,
    bufs: LevelBuffers,
    /// This level's arrays and the next level's, alternating.
    lists: [Lists; 2],
    /// The triangles' corners (9 f32 each), read only to clip straddlers.
    corners: wgpu::Buffer,
    report: GpuReport,
}

impl Builder<'_> {
    /// Runs `f` and adds its time to `phase` (whatever `f` submits, it waits for).
    fn timed<T>(
        &mut self,
        phase: Phase,
        f: impl FnOnce(&mut Self) -> Result<T, GpuError>,
    ) -> Result<T, GpuError> {
        let t = Instant::now();
        let out = f(self)?;
        self.report.phase_ms[phase as usize] += ms(t);
        Ok(out)
    }

    /// Records launches with `record`, submits them and waits for the GPU.
    fn run(
        &self,
        record: impl FnOnce(&mut wgpu::CommandEncoder) -> Result<(), GpuError>,
    ) -> Result<(), GpuError> {
        let mut encoder = self.gpu.encoder();
        record(&mut encoder)?;
        self.gpu.submit(encoder);
        self.gpu.finish()
    }

    /// Copies word `at` of each `(buffer, at)` into `totals`, in order, and reads them back
    /// (one round trip).
    fn read_totals(
        &mut self,
        mut encoder: wgpu::CommandEncoder,
        words: &[(&wgpu::Buffer, usize)],
    ) -> Result<Vec<u32>, GpuError> {
        let totals = self.bufs.totals.get();
        for (i, (buffer, at)) in words.iter().enumerate() {
            encoder.copy_buffer_to_buffer(buffer, *at as u64 * 4, totals, i as u64 * 4, 4);
        }
        self.gpu.submit(encoder);
        let words = self.gpu.download::<u32>(totals, words.len())?;
        self.report.round_trips += 1;
        Ok(words)
    }
}

/// Builds the tree of `triangles` on `gpu`; the options must pass [`check_options`]. The
/// root lists are presorted where [`Presort::Auto`] says.
pub fn build(
    gpu: &Gpu,
    triangles: Vec<Triangle>,
    options: &BuildOptions,
) -> Result<GpuBuild, GpuError> {
    build_with(gpu, triangles, options, Presort::Auto)
}

/// [`build`], with the presort on the host or on the device as `presort` says. Three phases:
/// the root level presorted and uploaded ([`upload`]), the level loop on the device
/// ([`Builder::build_levels`]), the finished tree brought down ([`Builder::download`]).
pub fn build_with(
    gpu: &Gpu,
    triangles: Vec<Triangle>,
    options: &BuildOptions,
    presort: Presort,
) -> Result<GpuBuild, GpuError> {
    check_options(options).map_err(GpuError::Runtime)?;
    let start = Instant::now();
    let report = GpuReport {
        adapter: gpu.describe(),
        phase_ms: vec![0.0; PHASES.len()],
        ..GpuReport::default()
    };
    if triangles.is_empty() {
        return Ok(GpuBuild {
            tree: KdTree::empty(),
            report,
        });
    }
    let prim_boxes: Vec<Aabb> = triangles.iter().map(triangle_bounds).collect();
    let bounds = prim_boxes.iter().fold(Aabb::EMPTY, |b, &t| b.union(t));
    let (mut b, root) = upload(
        gpu,
        options,
        &triangles,
        &prim_boxes,
        bounds,
        presort,
        report,
    )?;
    let end = b.build_levels(root)?;
    let (nodes, refs, mut report) = b.download(&end)?;
    report.total_ms = ms(start);
    Ok(GpuBuild {
        tree: KdTree::from_parts(triangles, bounds, nodes, refs),
        report,
    })
}

/// The first phase: the root's nine lists presorted (on the host or the device, as `presort`
/// says) and uploaded with the primitive boxes and, with clipping, the triangles. Returns the
/// builder and the root level's parameters.
fn upload<'a>(
    gpu: &'a Gpu,
    options: &'a BuildOptions,
    triangles: &[Triangle],
    prim_boxes: &[Aabb],
    bounds: Aabb,
    presort: Presort,
    mut report: GpuReport,
) -> Result<(Builder<'a>, Params), GpuError> {
    let n = triangles.len();
    let kernels = Kernels::new(gpu);
    report.presort_on_device = match presort {
        Presort::Auto => gpu.adapter.device_type != wgpu::DeviceType::Cpu,
        Presort::Host => false,
        Presort::Device => true,
    };
    let mut root = Lists::new();
    let t = Instant::now();
    let (host_entries, starts, root_entries) = if report.presort_on_device {
        let (len, starts) = presort::on_device(gpu, &kernels, prim_boxes, &mut root.entries)?;
        (None, starts, len)
    } else {
        let (entries, starts) = presort::root_lists(prim_boxes);
        let len = entries.len();
        (Some(entries), starts, len)
    };
    report.presort_ms = ms(t);

    let t = Instant::now();
    let corners: Vec<f32> = if options.clip {
        triangles
            .iter()
            .flat_map(|t| t.iter().flat_map(|v| v.0))
            .collect()
    } else {
        Vec::new()
    };
    let corners = gpu.upload("triangles", &corners);
    let bits = |boxes: &[Aabb]| -> Vec<u32> {
        crate::price::box_words(boxes)
            .iter()
            .map(|f| f.to_bits())
            .collect()
    };
    if let Some(entries) = host_entries {
        root.entries.write(gpu, &entries)?;
    }
    root.starts.write(gpu, &starts)?;
    root.boxes.write(gpu, &bits(&[bounds]))?;
    root.ref_prim
        .write(gpu, &(0..n as u32).collect::<Vec<u32>>())?;
    root.ref_node.write(gpu, &vec![0u32; n])?;
    root.ref_boxes.write(gpu, &bits(prim_boxes))?;
    gpu.finish()?;
    report.upload_ms = ms(t);

    let mut b = Builder {
        gpu,
        options,
        kernels,
        bufs: LevelBuffers::new(),
        lists: [root, Lists::new()],
        corners,
        report,
    };
    b.bufs.totals.ensure(gpu, 8, false)?;
    let cost = options.cost;
    let root = Params {
        nodes: 1,
        entries: root_entries as u32,
        refs: n as u32,
        max_depth: cost.max_depth_for(n),
        leaf_size: cost.leaf_size,
        axes_all: (options.axes == Axes::All) as u32,
        intersection: cost.intersection,
        clip: options.clip as u32,
        ..Params::default()
    };
    Ok((b, root))
}

impl Builder<'_> {
    /// The second phase: level after level on the device, from the root's parameters `p`,
    /// each level's phases in the CPU level builder's order, until a level splits no node.
    /// Returns the last level's parameters, whose bases are the tree's node and reference
    /// counts.
    fn build_levels(&mut self, mut p: Params) -> Result<Params, GpuError> {
        let gpu = self.gpu;
        // The root level's references are the triangles.
        let budget = self.options.cost.reference_budget(p.refs as usize);
        let mut cur = 0;
        loop {
            self.report.levels += 1;
            let level = self.lists[cur].handles();
            // The level's parameters; the layout phase copies the candidate layout in.
            let params = gpu.uniform(&p);
            let layout = self.timed(Phase::Layout, |b| b.layout(&level, &p, &params))?;
            self.bufs.best.ensure(gpu, 3 * p.nodes as usize, false)?;
            if layout.n > 0 {
                self.candidate_buffers(layout)?;
                self.timed(Phase::Candidates, |b| b.candidates(&level, &p, &params))?;
                self.timed(Phase::Counting, |b| b.count(&level, &p, &params, layout))?;
                self.timed(Phase::Pricing, |b| b.price(&level, &p, layout))?;
            }
            self.timed(Phase::BestSplit, |b| b.best_split(&p, &params, layout))?;
            self.timed(Phase::Decision, |b| b.decide(&level, &p, &params))?;
            let totals = self.timed(Phase::Sides, |b| b.sides(&level, &mut p, &params, budget))?;
            let (node_end, ref_end) =
                self.timed(Phase::Output, |b| b.output(&level, &p, &totals))?;
            if totals.splits == 0 {
                p.node_base = node_end as u32;
                p.ref_base = ref_end as u32;
                return Ok(p);
            }
            let next = 1 - cur;
            self.timed(Phase::Partition, |b| {
                b.partition(&level, next, &mut p, &totals)
            })?;
            p = Params {
                nodes: 2 * totals.splits as u32,
                entries: totals.next_entries as u32,
                refs: totals.next_table as u32,
                depth: p.depth + 1,
                node_base: node_end as u32,
                ref_base: ref_end as u32,
                force_leaves: 0,
                next_nodes: 0,
                regen: 0,
                ..p
            };
            cur = next;
        }
    }

    /// The third phase: the finished tree's nodes and references brought down once (`end`
    /// from [`Builder::build_levels`]), with the report.
    fn download(self, end: &Params) -> Result<(Vec<Node>, Vec<u32>, GpuReport), GpuError> {
        let mut report = self.report;
        report.device_bytes = 4
            * (self.bufs.words() + self.lists.iter().map(Lists::words).sum::<usize>())
            + self.corners.size() as usize;
        let t = Instant::now();
        let words = self
            .gpu
            .download::<u32>(self.bufs.nodes_out.get(), 3 * end.node_base as usize)?;
        let refs = self
            .gpu
            .download::<u32>(self.bufs.refs_out.get(), end.ref_base as usize)?;
        report.download_ms = ms(t);
        let nodes = words
            .chunks(3)
            .map(|w| match w[0] {
                3 => Node::leaf(w[1], w[2]),
                axis => Node::interior(axis as usize, f32::from_bits(w[1]), w[2]),
            })
            .collect();
        Ok((nodes, refs, report))
    }
}
