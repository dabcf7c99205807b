//! The level builder on the GPU: the same tree as the CPU level builder with the same
//! options, its data-parallel phases as WGSL kernels (`shaders/level.wgsl` and the kernels of
//! [`crate::price`], [`crate::segmin`], [`crate::scan`], [`crate::sort`]).
//!
//! The host sorts the nine lists once (by lo, by hi, and the flat references, per axis) and
//! uploads them with the primitive boxes (and, with clipping, the triangles); each level then
//! runs on the GPU: axes in use and candidate layout (scan) -> candidates -> counting (binary
//! searches of the node's sorted segments, or the paper's space trees) -> pricing -> best split (segmented min) ->
//! decision (scans) -> sides of every reference, clipping straddlers -> partition of the
//! reference table and the lists (flags, scans, scatter; clipped straddlers' entries sorted
//! and merged by rank) -> output nodes and leaf references. Per level the host reads back two
//! small records: the candidate layout (to size the candidate arrays) and the decision's
//! totals (the reference budget, and the next level's sizes). The finished tree comes down
//! once.

use crate::kernel::{Arg, Kernel};
use crate::price::{Layout, Price};
use crate::scan::Scan;
use crate::segmin::SegMin;
use crate::sort::Sort;
use crate::space_tree::{self, SpaceTree};
use crate::{Gpu, GpuError};
use sahkd::build::{Algorithm, Axes, BuildOptions, Counting};
use sahkd::geometry::triangle_bounds;
use sahkd::{Aabb, KdTree, Node, Triangle};
use std::time::Instant;

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

/// How a GPU build went.
#[derive(Clone, Debug, Default)]
pub struct GpuReport {
    /// "name (backend, device type)".
    pub adapter: String,
    pub upload_ms: f64,
    /// Milliseconds per phase, in the order of [`PHASES`], summed over levels.
    pub phase_ms: Vec<f64>,
    pub download_ms: f64,
    /// Presorting the lists on the host, before the upload.
    pub presort_ms: f64,
    pub levels: usize,
    /// Reads of GPU results by the host during the build (per level: layout, decision).
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

/// A storage buffer that grows geometrically (by at least half) when a level outgrows it.
struct Grow {
    label: &'static str,
    buffer: Option<wgpu::Buffer>,
    len: usize,
}

impl Grow {
    fn new(label: &'static str) -> Grow {
        Grow {
            label,
            buffer: None,
            len: 0,
        }
    }
    /// At least `len` words; `keep` copies the old contents over when growing.
    fn ensure(&mut self, gpu: &Gpu, len: usize, keep: bool) -> Result<&wgpu::Buffer, GpuError> {
        if self.buffer.is_none() || len > self.len {
            let grown = len.max(self.len + self.len / 2).max(64);
            let max_words = (gpu.max_binding / 4) as usize;
            let size = if len <= max_words {
                grown.min(max_words)
            } else {
                len
            };
            let buffer = gpu.storage(self.label, size)?;
            if keep {
                if let Some(old) = &self.buffer {
                    let mut encoder = gpu.encoder();
                    encoder.copy_buffer_to_buffer(old, 0, &buffer, 0, (self.len * 4) as u64);
                    gpu.submit(encoder);
                }
            }
            self.buffer = Some(buffer);
            self.len = size;
        }
        Ok(self.buffer.as_ref().unwrap())
    }
    fn get(&self) -> &wgpu::Buffer {
        self.buffer.as_ref().expect("buffer sized before use")
    }
}

struct Kernels {
    axes_in_use: Kernel,
    candidates: Kernel,
    count: Kernel,
    fill: Kernel,
    decide: Kernel,
    sides: Kernel,
    classify: Kernel,
    emit_nodes: Kernel,
    emit_refs: Kernel,
    scatter_refs: Kernel,
    regen_emit: Kernel,
    next_level: Kernel,
    scatter: Kernel,
    regen_place: Kernel,
    price: Price,
    segmin: SegMin,
    scan: Scan,
    sort: Sort,
    space_tree: SpaceTree,
}

impl Kernels {
    fn new(gpu: &Gpu) -> Kernels {
        let source = include_str!("shaders/level.wgsl");
        let mut sections = source.split("//! kernel ");
        let header = sections.next().unwrap_or_default();
        let mut kernels = std::collections::HashMap::new();
        for section in sections {
            let (line, body) = section.split_once('\n').unwrap_or((section, ""));
            let name = line.split_whitespace().next().unwrap_or_default();
            let library = if line.contains("with clip.wgsl") {
                crate::clip::CLIP_WGSL
            } else {
                ""
            };
            // Binding 0 is the uniform; the others are storage, in order.
            let bindings = body.matches("@binding(").count();
            let mut args = vec![Arg::Uniform];
            args.resize(bindings, Arg::Write);
            let module = gpu.module(name, &format!("{header}{library}{body}"));
            kernels.insert(name.to_string(), Kernel::new(gpu, &module, name, &args));
        }
        let mut take = |name: &str| kernels.remove(name).expect("kernel in level.wgsl");
        Kernels {
            axes_in_use: take("axes_in_use"),
            candidates: take("candidates"),
            count: take("count"),
            fill: take("fill"),
            decide: take("decide"),
            sides: take("sides"),
            classify: take("classify"),
            emit_nodes: take("emit_nodes"),
            emit_refs: take("emit_refs"),
            scatter_refs: take("scatter_refs"),
            regen_emit: take("regen_emit"),
            next_level: take("next_level"),
            scatter: take("scatter"),
            regen_place: take("regen_place"),
            price: Price::new(gpu),
            segmin: SegMin::new(gpu),
            scan: Scan::new(gpu),
            sort: Sort::new(gpu),
            space_tree: SpaceTree::new(gpu),
        }
    }
}

/// The host's presort: the nine lists of the root, concatenated, and their starts.
fn root_lists(boxes: &[Aabb]) -> (Vec<u32>, Vec<u32>) {
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

fn ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

/// Builds the tree of `triangles` on `gpu`; the options must pass [`check_options`].
pub fn build(
    gpu: &Gpu,
    triangles: Vec<Triangle>,
    options: &BuildOptions,
) -> Result<GpuBuild, GpuError> {
    check_options(options).map_err(GpuError::Runtime)?;
    let start = Instant::now();
    let mut report = GpuReport {
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
    let n = triangles.len();
    let cost = options.cost;
    let prim_boxes: Vec<Aabb> = triangles.iter().map(triangle_bounds).collect();
    let bounds = prim_boxes.iter().fold(Aabb::EMPTY, |b, &t| b.union(t));
    let budget = cost.reference_budget(n);

    let t = Instant::now();
    let (entries, starts) = root_lists(&prim_boxes);
    report.presort_ms = ms(t);

    let k = Kernels::new(gpu);
    let t = Instant::now();
    // The corners are read only to clip straddlers.
    let corners: Vec<f32> = if options.clip {
        triangles
            .iter()
            .flat_map(|t| t.iter().flat_map(|v| v.0))
            .collect()
    } else {
        Vec::new()
    };
    let corners = gpu.upload("triangles", &corners);
    // Per level, double-buffered: the lists, their starts, the node boxes and the reference
    // table (primitive, node, box).
    let pair = |label| [Grow::new(label), Grow::new(label)];
    let mut entries_buf = pair("entries");
    let mut starts_buf = pair("starts");
    let mut boxes_buf = pair("boxes");
    let mut prim_buf = pair("ref prim");
    let mut node_buf = pair("ref node");
    let mut ref_box_buf = pair("ref boxes");
    let root_entries = entries.len();
    let write = |g: &mut Grow, data: &[u32]| -> Result<(), GpuError> {
        let buffer = g.ensure(gpu, data.len(), false)?;
        gpu.queue
            .write_buffer(buffer, 0, bytemuck::cast_slice(data));
        Ok(())
    };
    let bits = |boxes: &[Aabb]| -> Vec<u32> {
        crate::price::box_words(boxes)
            .iter()
            .map(|f| f.to_bits())
            .collect()
    };
    write(&mut entries_buf[0], &entries)?;
    write(&mut starts_buf[0], &starts)?;
    write(&mut boxes_buf[0], &bits(&[bounds]))?;
    write(&mut prim_buf[0], &(0..n as u32).collect::<Vec<u32>>())?;
    write(&mut node_buf[0], &vec![0u32; n])?;
    write(&mut ref_box_buf[0], &bits(&prim_boxes))?;
    gpu.finish()?;
    report.upload_ms = ms(t);

    let names = [
        "uses",
        "caps",
        "cand pos",
        "cand owner",
        "counts",
        "cost",
        "packed",
        "best",
        "split",
        "split scan",
        "leaf scan",
        "next scan",
        "lflags",
        "rflags",
        "nodes out",
        "refs out",
        "totals",
        "go left",
        "go right",
        "moved",
        "regen scan",
        "clipped boxes",
        "new ids",
        "records",
        "parents",
        "space trees",
        "walk stats",
    ];
    let mut g: Vec<Grow> = names.iter().map(|&name| Grow::new(name)).collect();
    let (uses, caps, cand_pos, cand_owner, counts, cand_cost, packed, best) =
        (0, 1, 2, 3, 4, 5, 6, 7);
    let (split, split_scan, leaf_scan, next_scan, lflags, rflags, nodes_out, refs_out, totals) =
        (8, 9, 10, 11, 12, 13, 14, 15, 16);
    let (go_l, go_r, moved, regen_scan, clipped, new_id, records, parents) =
        (17, 18, 19, 20, 21, 22, 23, 24);
    let (space_trees, walk_stats) = (25, 26);
    g[totals].ensure(gpu, 8, false)?;

    let mut p = Params {
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
    let mut cur = 0;
    loop {
        let nodes = p.nodes as usize;
        let e = p.entries as usize;
        let refs = p.refs as usize;
        report.levels += 1;
        // Handles (shared references to the GPU buffers), so the other side can grow.
        let [ent, sta, box_, prim, node, ref_box] = &[
            entries_buf[cur].get().clone(),
            starts_buf[cur].get().clone(),
            boxes_buf[cur].get().clone(),
            prim_buf[cur].get().clone(),
            node_buf[cur].get().clone(),
            ref_box_buf[cur].get().clone(),
        ];
        // Layout: axes in use, candidate capacities, their scan; the host reads the totals.
        let t = Instant::now();
        g[uses].ensure(gpu, nodes, false)?;
        g[caps].ensure(gpu, 3 * nodes + 1, false)?;
        let params = gpu.uniform(&p);
        let mut enc = gpu.encoder();
        k.axes_in_use.dispatch(
            gpu,
            &mut enc,
            &[&params, box_, sta, g[uses].get(), g[caps].get()],
            nodes as u64,
        );
        k.scan.record(gpu, &mut enc, g[caps].get(), 3 * nodes + 1)?;
        for (i, at) in [nodes, 2 * nodes, 3 * nodes].into_iter().enumerate() {
            enc.copy_buffer_to_buffer(
                g[caps].get(),
                at as u64 * 4,
                g[totals].get(),
                i as u64 * 4,
                4,
            );
        }
        gpu.submit(enc);
        let layout_words = gpu.download::<u32>(g[totals].get(), 3)?;
        report.round_trips += 1;
        let (first1, first2, cands) = (layout_words[0], layout_words[1], layout_words[2]);
        p.first1 = first1;
        p.first2 = first2;
        p.cands = cands;
        report.phase_ms[0] += ms(t);

        g[best].ensure(gpu, 3 * nodes, false)?;
        let params = gpu.uniform(&p);
        if cands > 0 {
            let c = cands as usize;
            for i in [cand_pos, cand_owner, cand_cost, packed] {
                g[i].ensure(gpu, c, false)?;
            }
            g[counts].ensure(gpu, 3 * c, false)?;
            let t = Instant::now();
            let mut enc = gpu.encoder();
            k.candidates.dispatch(
                gpu,
                &mut enc,
                &[
                    &params,
                    ref_box,
                    box_,
                    sta,
                    ent,
                    node,
                    g[uses].get(),
                    g[caps].get(),
                    g[cand_pos].get(),
                    g[cand_owner].get(),
                ],
                3 * refs as u64,
            );
            gpu.submit(enc);
            gpu.finish()?;
            report.phase_ms[1] += ms(t);

            // Counting: the paper's space trees and walks, or binary searches of the sorted
            // segments (the same L, R, P as the CPU's event scan).
            let t = Instant::now();
            let mut enc = gpu.encoder();
            if options.counting == Counting::SpaceTree {
                g[space_trees].ensure(gpu, 9 * refs, false)?;
                g[walk_stats].ensure(gpu, space_tree::STATS_WORDS, false)?;
                k.space_tree.record_build(
                    gpu,
                    &mut enc,
                    nodes,
                    refs,
                    [ref_box, ent, sta],
                    g[space_trees].get(),
                )?;
                let layout = Layout {
                    n: c,
                    first1: first1 as usize,
                    first2: first2 as usize,
                };
                k.space_tree.record_count(
                    gpu,
                    &mut enc,
                    nodes,
                    refs,
                    layout,
                    [
                        sta,
                        g[space_trees].get(),
                        g[cand_pos].get(),
                        g[cand_owner].get(),
                    ],
                    g[counts].get(),
                    g[walk_stats].get(),
                );
            } else {
                k.count.dispatch(
                    gpu,
                    &mut enc,
                    &[
                        &params,
                        ref_box,
                        sta,
                        ent,
                        g[cand_pos].get(),
                        g[cand_owner].get(),
                        g[counts].get(),
                    ],
                    c as u64,
                );
            }
            gpu.submit(enc);
            gpu.finish()?;
            report.phase_ms[2] += ms(t);

            let t = Instant::now();
            let mut enc = gpu.encoder();
            k.price.record(
                gpu,
                &mut enc,
                &cost,
                Layout {
                    n: c,
                    first1: first1 as usize,
                    first2: first2 as usize,
                },
                [
                    box_,
                    g[cand_pos].get(),
                    g[cand_owner].get(),
                    g[counts].get(),
                ],
                [g[cand_cost].get(), g[packed].get()],
            );
            gpu.submit(enc);
            gpu.finish()?;
            report.phase_ms[3] += ms(t);
        }

        let t = Instant::now();
        let mut enc = gpu.encoder();
        k.fill
            .dispatch(gpu, &mut enc, &[&params, g[best].get()], 3 * nodes as u64);
        if cands > 0 {
            k.segmin.record(
                gpu,
                &mut enc,
                g[cand_cost].get(),
                g[cand_pos].get(),
                g[cand_owner].get(),
                cands as usize,
                g[best].get(),
            );
        }
        gpu.submit(enc);
        gpu.finish()?;
        report.phase_ms[4] += ms(t);

        // Decision, the references' sides (clipping straddlers) and the lists' flags, so that
        // one read gives the host every total.
        let t = Instant::now();
        for i in [split_scan, leaf_scan, next_scan] {
            g[i].ensure(gpu, nodes + 1, false)?;
        }
        g[split].ensure(gpu, 4 * nodes, false)?;
        g[lflags].ensure(gpu, e + 1, false)?;
        g[rflags].ensure(gpu, e + 1, false)?;
        for i in [go_l, go_r, regen_scan] {
            g[i].ensure(gpu, refs + 1, false)?;
        }
        g[moved].ensure(gpu, refs, false)?;
        g[clipped].ensure(gpu, if options.clip { 12 * refs } else { 1 }, false)?;
        // Candidate buffers must exist to bind, even on a level without candidates.
        for i in [cand_pos, cand_cost, packed] {
            g[i].ensure(gpu, 1, false)?;
        }
        let decide = |enc: &mut wgpu::CommandEncoder, params: &wgpu::Buffer| {
            k.decide.dispatch(
                gpu,
                enc,
                &[
                    params,
                    g[uses].get(),
                    sta,
                    g[best].get(),
                    g[cand_cost].get(),
                    g[packed].get(),
                    g[cand_pos].get(),
                    g[split].get(),
                    g[split_scan].get(),
                    g[leaf_scan].get(),
                    g[next_scan].get(),
                ],
                nodes as u64,
            );
            for i in [split_scan, leaf_scan, next_scan] {
                k.scan.record(gpu, enc, g[i].get(), nodes + 1)?;
            }
            Ok::<(), GpuError>(())
        };
        let mut enc = gpu.encoder();
        decide(&mut enc, &params)?;
        gpu.submit(enc);
        gpu.finish()?;
        report.phase_ms[5] += ms(t);
        let t = Instant::now();
        let mut enc = gpu.encoder();
        k.sides.dispatch(
            gpu,
            &mut enc,
            &[
                &params,
                ref_box,
                prim,
                node,
                &corners,
                box_,
                g[split].get(),
                g[go_l].get(),
                g[go_r].get(),
                g[moved].get(),
                g[regen_scan].get(),
                g[clipped].get(),
            ],
            refs as u64 + 1,
        );
        for i in [go_l, go_r, regen_scan] {
            k.scan.record(gpu, &mut enc, g[i].get(), refs + 1)?;
        }
        k.classify.dispatch(
            gpu,
            &mut enc,
            &[
                &params,
                ent,
                g[moved].get(),
                g[go_l].get(),
                g[go_r].get(),
                g[lflags].get(),
                g[rflags].get(),
            ],
            e as u64 + 1,
        );
        k.scan.record(gpu, &mut enc, g[lflags].get(), e + 1)?;
        k.scan.record(gpu, &mut enc, g[rflags].get(), e + 1)?;
        for (i, (buf, at)) in [
            (split_scan, nodes),
            (leaf_scan, nodes),
            (next_scan, nodes),
            (lflags, e),
            (rflags, e),
            (go_l, refs),
            (go_r, refs),
            (regen_scan, refs),
        ]
        .into_iter()
        .enumerate()
        {
            enc.copy_buffer_to_buffer(
                g[buf].get(),
                at as u64 * 4,
                g[totals].get(),
                i as u64 * 4,
                4,
            );
        }
        gpu.submit(enc);
        let sums = gpu.download::<u32>(g[totals].get(), 8)?;
        report.round_trips += 1;
        let (mut splits, mut leaf_refs, next_refs) =
            (sums[0] as usize, sums[1] as usize, sums[2] as usize);
        let regen = sums[7] as usize;
        let next_entries = (sums[3] + sums[4]) as usize + regen;
        let next_table = (sums[5] + sums[6]) as usize;
        // The reference budget, as the CPU checks it: the references already in leaves, this
        // level's leaves and the next level's (before clipping, which only removes) must fit,
        // or the whole level becomes leaves.
        if p.ref_base as usize + leaf_refs + next_refs > budget && splits > 0 {
            p.force_leaves = 1;
            let forced = gpu.uniform(&p);
            let mut enc = gpu.encoder();
            decide(&mut enc, &forced)?;
            gpu.submit(enc);
            splits = 0;
            leaf_refs = refs;
        }
        gpu.finish()?;
        report.phase_ms[6] += ms(t);

        // Output: this level's nodes and leaf references.
        let t = Instant::now();
        let node_end = p.node_base as usize + nodes;
        let ref_end = p.ref_base as usize + leaf_refs;
        g[nodes_out].ensure(gpu, 3 * node_end, true)?;
        g[refs_out].ensure(gpu, ref_end.max(1), true)?;
        let params = gpu.uniform(&p);
        let mut enc = gpu.encoder();
        k.emit_nodes.dispatch(
            gpu,
            &mut enc,
            &[
                &params,
                sta,
                g[split].get(),
                g[split_scan].get(),
                g[leaf_scan].get(),
                g[nodes_out].get(),
            ],
            nodes as u64,
        );
        k.emit_refs.dispatch(
            gpu,
            &mut enc,
            &[
                &params,
                sta,
                prim,
                node,
                g[split].get(),
                g[leaf_scan].get(),
                g[refs_out].get(),
            ],
            refs as u64,
        );
        gpu.submit(enc);
        gpu.finish()?;
        report.phase_ms[8] += ms(t);
        if splits == 0 {
            p.node_base = node_end as u32;
            p.ref_base = ref_end as u32;
            break;
        }

        // Partition: the reference table, the clipped straddlers' records (sorted), then the
        // next level's list starts, boxes and lists.
        let t = Instant::now();
        let next = 1 - cur;
        let next_nodes = 2 * splits;
        p.next_nodes = next_nodes as u32;
        p.regen = regen as u32;
        let params = gpu.uniform(&p);
        entries_buf[next].ensure(gpu, next_entries, false)?;
        starts_buf[next].ensure(gpu, 9 * (next_nodes + 1), false)?;
        boxes_buf[next].ensure(gpu, 6 * next_nodes, false)?;
        prim_buf[next].ensure(gpu, next_table, false)?;
        node_buf[next].ensure(gpu, next_table, false)?;
        ref_box_buf[next].ensure(gpu, 6 * next_table, false)?;
        g[new_id].ensure(gpu, 2 * refs, false)?;
        g[records].ensure(gpu, 4 * regen, false)?;
        g[parents].ensure(gpu, next_nodes, false)?;
        let mut enc = gpu.encoder();
        k.scatter_refs.dispatch(
            gpu,
            &mut enc,
            &[
                &params,
                sta,
                prim,
                node,
                ref_box,
                g[moved].get(),
                g[clipped].get(),
                g[go_l].get(),
                g[go_r].get(),
                g[split_scan].get(),
                prim_buf[next].get(),
                node_buf[next].get(),
                ref_box_buf[next].get(),
                g[new_id].get(),
            ],
            refs as u64,
        );
        if regen > 0 {
            k.regen_emit.dispatch(
                gpu,
                &mut enc,
                &[
                    &params,
                    node,
                    g[moved].get(),
                    g[clipped].get(),
                    g[go_l].get(),
                    g[go_r].get(),
                    g[regen_scan].get(),
                    g[split_scan].get(),
                    g[new_id].get(),
                    g[records].get(),
                ],
                refs as u64,
            );
            k.sort.record(gpu, &mut enc, g[records].get(), regen)?;
        }
        k.next_level.dispatch(
            gpu,
            &mut enc,
            &[
                &params,
                box_,
                sta,
                g[split].get(),
                g[split_scan].get(),
                g[lflags].get(),
                g[rflags].get(),
                g[records].get(),
                starts_buf[next].get(),
                boxes_buf[next].get(),
                g[parents].get(),
            ],
            9 * (nodes as u64 + 1),
        );
        k.scatter.dispatch(
            gpu,
            &mut enc,
            &[
                &params,
                sta,
                ent,
                node,
                ref_box,
                g[split_scan].get(),
                g[lflags].get(),
                g[rflags].get(),
                g[records].get(),
                g[new_id].get(),
                entries_buf[next].get(),
            ],
            e as u64,
        );
        if regen > 0 {
            k.regen_place.dispatch(
                gpu,
                &mut enc,
                &[
                    &params,
                    sta,
                    ent,
                    ref_box,
                    g[lflags].get(),
                    g[rflags].get(),
                    g[records].get(),
                    g[parents].get(),
                    entries_buf[next].get(),
                ],
                regen as u64,
            );
        }
        gpu.submit(enc);
        gpu.finish()?;
        report.phase_ms[7] += ms(t);

        p = Params {
            nodes: next_nodes as u32,
            entries: next_entries as u32,
            refs: next_table as u32,
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

    report.device_bytes = 4
        * (g.iter().map(|b| b.len).sum::<usize>()
            + [
                &entries_buf,
                &starts_buf,
                &boxes_buf,
                &prim_buf,
                &node_buf,
                &ref_box_buf,
            ]
            .iter()
            .flat_map(|pair| pair.iter().map(|b| b.len))
            .sum::<usize>())
        + corners.size() as usize;
    let t = Instant::now();
    let words = gpu.download::<u32>(g[nodes_out].get(), 3 * p.node_base as usize)?;
    let refs = gpu.download::<u32>(g[refs_out].get(), p.ref_base as usize)?;
    report.download_ms = ms(t);
    let nodes = words
        .chunks(3)
        .map(|w| match w[0] {
            3 => Node::leaf(w[1], w[2]),
            axis => Node::interior(axis as usize, f32::from_bits(w[1]), w[2]),
        })
        .collect();
    report.total_ms = ms(start);
    Ok(GpuBuild {
        tree: KdTree::from_parts(triangles, bounds, nodes, refs),
        report,
    })
}
