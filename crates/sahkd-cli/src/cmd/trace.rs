//! `sahkd trace`: trace rays from a `.npy` file against a mesh and write the hits to `.npz`.

use super::common::{self, write_array, RunReport};
use super::Context;
use crate::format;
use crate::input::MeshArg;
use crate::options::BuilderArgs;
use crate::progress::Progress;
use crate::rays;
use crate::resident::PeakResident;
use anyhow::Result;
use sahkd::{Hit, Hit64, KdTree, Ray, Ray64};
use serde::Serialize;
use std::path::{Path, PathBuf};

#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    pub mesh: MeshArg,

    /// Rays: float32 array of shape (R, 6) with origin xyz and direction xyz, traced over
    /// t in [0, inf), or (R, 8) with t_min and t_max appended
    #[arg(long, value_name = "RAYS.npy")]
    pub rays: PathBuf,

    /// Where to write the hits: arrays `t` (float32, inf on a miss), `prim` (int64, -1 on a
    /// miss), `u` and `v` (float32, 0 on a miss); with --any-hit, `hit` (bool) only
    #[arg(long, short, value_name = "HITS.npz")]
    pub output: PathBuf,

    /// Only ask whether each ray hits anything (shadow rays)
    #[arg(long)]
    pub any_hit: bool,

    /// Arithmetic of the walk and the triangle tests: f32 (fast), or f64 for scenes beyond
    /// float32 (tiny triangles far from the origin); with f64, `t`, `u` and `v` are written
    /// as float64 (the rays are read as float32 either way)
    #[arg(long, value_enum, default_value_t = Precision::F32)]
    pub precision: Precision,

    /// Print one JSON object on stdout instead of the summary on stderr
    #[arg(long)]
    pub json: bool,

    // Last: the heading of its flattened options would carry over to any argument after it.
    #[command(flatten)]
    pub builder: BuilderArgs,
}

#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Precision {
    F32,
    F64,
}

#[derive(Serialize)]
struct Report {
    #[serde(flatten)]
    run: RunReport,
    rays: usize,
    any_hit: bool,
    precision: Precision,
    trace_ms: f64,
    mrays_per_s: f64,
    hits: usize,
    /// The process's peak resident memory: mesh, build, tree, trace layout, rays and answers.
    #[serde(flatten)]
    resident: PeakResident,
}

/// The answers of a batch of rays.
enum Hits {
    Closest(Vec<Option<Hit>>),
    Closest64(Vec<Option<Hit64>>),
    Any(Vec<bool>),
}

impl Hits {
    fn count(&self) -> usize {
        match self {
            Hits::Closest(h) => h.iter().filter(|h| h.is_some()).count(),
            Hits::Closest64(h) => h.iter().filter(|h| h.is_some()).count(),
            Hits::Any(h) => h.iter().filter(|&&h| h).count(),
        }
    }
}

pub fn run(args: Args, context: &Context) -> Result<()> {
    let progress = Progress::new(context.quiet, args.json);
    let inputs = common::Inputs {
        mesh: &args.mesh,
        builder: &args.builder,
        data: &args.rays,
        output: &args.output,
    };
    let (any_hit, precision) = (args.any_hit, args.precision);
    let ran = common::run(
        inputs,
        context,
        &progress,
        rays::read,
        |tree, rays, progress| trace(tree, rays, any_hit, precision, progress),
        |output, _, hits| write_hits(output, hits),
    )?;
    let rays = &ran.prepared.data;
    let report = Report {
        run: ran.report(),
        rays: rays.len(),
        any_hit,
        precision,
        trace_ms: ran.work_ms,
        mrays_per_s: ran.rate(rays.len()),
        hits: ran.answers.count(),
        resident: PeakResident::now(ran.prepared.built.tree.triangles().len()),
    };
    if args.json {
        format::print_json(&report)?;
    } else if !context.quiet {
        eprintln!(
            "{} rays on {} triangles of {}: {} hit; build {}, trace layout {}, trace {}, {:.2} Mrays/s on {} threads; wrote {}",
            format::count(report.rays as u64),
            format::count(report.run.triangles as u64),
            report.run.source,
            format::count(report.hits as u64),
            format::ms(report.run.build_ms),
            format::ms(report.run.layout_ms),
            format::ms(report.trace_ms),
            report.mrays_per_s,
            report.run.threads,
            args.output.display()
        );
    }
    Ok(())
}

/// Traces in one batch, or in slices when a progress bar is shown so that it can move.
fn trace(
    tree: &KdTree,
    rays: &[Ray],
    any_hit: bool,
    precision: Precision,
    progress: &Progress,
) -> Hits {
    let slice = if progress.enabled() {
        (rays.len() / 100).max(1 << 14)
    } else {
        rays.len().max(1)
    };
    let bar = progress.bar(rays.len() as u64, "tracing");
    let sliced = |f: &mut dyn FnMut(&[Ray])| {
        for chunk in rays.chunks(slice) {
            f(chunk);
            bar.inc(chunk.len() as u64);
        }
    };
    let wide = |chunk: &[Ray]| chunk.iter().map(Ray64::from).collect::<Vec<_>>();
    let mut any = Vec::new();
    let mut closest = Vec::new();
    let mut closest64 = Vec::new();
    let hits = match (any_hit, precision) {
        (true, Precision::F32) => {
            sliced(&mut |c| any.extend(tree.occluded_batch(c)));
            Hits::Any(any)
        }
        (true, Precision::F64) => {
            sliced(&mut |c| any.extend(tree.occluded_batch_f64(&wide(c))));
            Hits::Any(any)
        }
        (false, Precision::F32) => {
            sliced(&mut |c| closest.extend(tree.intersect_batch(c)));
            Hits::Closest(closest)
        }
        (false, Precision::F64) => {
            sliced(&mut |c| closest64.extend(tree.intersect_batch_f64(&wide(c))));
            Hits::Closest64(closest64)
        }
    };
    bar.finish_and_clear();
    hits
}

fn write_hits(path: &Path, hits: &Hits) -> Result<()> {
    common::write_npz(path, |npz| match hits {
        Hits::Closest(h) => write_closest(npz, h, f32::INFINITY, |h| (h.t, h.prim, h.u, h.v)),
        Hits::Closest64(h) => write_closest(npz, h, f64::INFINITY, |h| (h.t, h.prim, h.u, h.v)),
        Hits::Any(h) => write_array(npz, "hit", &[h.len() as u64], h.iter().copied()),
    })
}

/// The arrays `t`, `prim`, `u`, `v` of closest hits in either precision; `row` gives a hit's
/// (t, prim, u, v), and a miss is (`miss`, -1, 0, 0).
fn write_closest<H, F: npyz::AutoSerialize + Default + Copy>(
    npz: &mut common::Npz,
    hits: &[Option<H>],
    miss: F,
    row: impl Fn(&H) -> (F, u32, F, F),
) -> std::io::Result<()> {
    let shape = [hits.len() as u64];
    let rows = || hits.iter().map(|h| h.as_ref().map(&row));
    write_array(npz, "t", &shape, rows().map(|h| h.map_or(miss, |h| h.0)))?;
    let prim = rows().map(|h| h.map_or(-1, |h| i64::from(h.1)));
    write_array(npz, "prim", &shape, prim)?;
    write_array(
        npz,
        "u",
        &shape,
        rows().map(|h| h.map_or(F::default(), |h| h.2)),
    )?;
    write_array(
        npz,
        "v",
        &shape,
        rows().map(|h| h.map_or(F::default(), |h| h.3)),
    )
}
