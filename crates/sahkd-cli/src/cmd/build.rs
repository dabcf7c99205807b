//! `sahkd build`: build a mesh's tree, report how it went, and with `--save` keep the tree
//! for later commands.

use super::common::saved;
use super::Context;
use crate::format::{self, Table};
use crate::gpu::GpuReport;
use crate::input::{self, Loaded, MeshArg, Source};
use crate::options::{switch_name, Builder, BuilderArgs, DeviceArg, OptionsReport};
use crate::output;
use crate::progress::Progress;
use crate::resident::PeakResident;
use anyhow::{bail, Context as _, Result};
use sahkd::builders::LevelReport;
use sahkd::{Axes, TreeMeta, BINNED_REFS_PER_BIN};
use serde::Serialize;
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    pub mesh: MeshArg,

    /// Check the tree's structure and that every triangle is in every leaf it overlaps
    #[arg(long)]
    pub validate: bool,

    /// Print one JSON object on stdout instead of text
    #[arg(long)]
    pub json: bool,

    /// Save the tree (with its build options and timings) to this file, to trace, query,
    /// render or inspect later without building again; written whole or not at all
    #[arg(long, value_name = "TREE.sahkd")]
    pub save: Option<PathBuf>,

    // Last: the heading of its flattened options would carry over to any argument after it.
    #[command(flatten)]
    pub builder: BuilderArgs,
}

/// The JSON report.
#[derive(Serialize)]
pub struct Report<'a> {
    source: String,
    triangles: usize,
    /// "cpu" or "gpu".
    device: &'static str,
    /// With `--device gpu`: the adapter, upload, per-phase and download times, round trips.
    gpu: Option<&'a GpuReport>,
    #[serde(flatten)]
    options: OptionsReport,
    threads: usize,
    load_ms: f64,
    build_ms: f64,
    presort_ms: f64,
    /// The build's phases: presort_ms above, then the binned top (workers' time summed),
    /// the exact subtrees (the hybrid's level hand-over: wall time; the binned build: workers'
    /// time summed) and the layout of the finished tree.
    binned_ms: f64,
    subtrees_ms: f64,
    layout_ms: f64,
    sah_cost: f64,
    nodes: usize,
    interior: usize,
    leaves: usize,
    empty_leaves: usize,
    references: usize,
    duplication: f64,
    max_depth: u32,
    mean_leaf_size: f64,
    bytes: usize,
    peak_working_bytes: usize,
    peak_working_bytes_per_triangle: f64,
    /// The process's peak resident memory after the build (mesh, working arrays and tree);
    /// `null` where the system does not report it.
    #[serde(flatten)]
    resident: PeakResident,
    /// `null` unless `--validate` was given.
    valid: Option<bool>,
    /// The file the tree was saved to (`--save`), else `null`.
    saved: Option<String>,
    levels: &'a [LevelReport],
}

pub fn run(args: Args, context: &Context) -> Result<()> {
    let progress = Progress::new(context.quiet, args.json);
    let source = Source::resolve(&args.mesh.mesh);
    if let Source::Tree(path) = &source {
        bail!(
            "{}: is a saved tree, already built (`sahkd info` describes it; trace, query and render use it)",
            path.display()
        );
    }
    if let Some(save) = &args.save {
        output::check(save, &source.file().into_iter().collect::<Vec<_>>())?;
    }
    let mut builder = args.builder.builder()?;
    let mut built = Built::new(&args.mesh, &mut builder, &[], &progress)?;

    let validation = args.validate.then(|| {
        let spinner = progress.spinner("validating");
        let result = builder.install(|| built.build.tree.validate());
        spinner.finish_and_clear();
        result
    });

    // An invalid tree is reported below, not kept.
    let invalid = matches!(validation, Some(Err(_)));
    if let (Some(path), false) = (&args.save, invalid) {
        let meta = TreeMeta::new(
            args.builder.build_options(),
            &built.build.report,
            builder.threads(),
        );
        let spinner = progress.spinner(format!("saving {}", path.display()));
        let written = built.build.tree.save(path, &meta);
        spinner.finish_and_clear();
        written.with_context(|| format!("cannot write {}", path.display()))?;
        built.saved = Some(path.display().to_string());
    }

    if args.json {
        format::print_json(&built.report(&builder, validation.as_ref().map(Result::is_ok)))?;
    } else {
        let mut t = built.table(&builder);
        if let Some(path) = &built.saved {
            t.row("saved to", path.clone());
        }
        if let Some(result) = &validation {
            t.row(
                "validation",
                match result {
                    Ok(()) => "ok".to_string(),
                    Err(e) => format!("FAILED: {e}"),
                },
            );
        }
        format::print_text(&t.render())?;
    }
    if let Some(Err(e)) = validation {
        bail!("the tree is not valid: {e}");
    }
    Ok(())
}

/// A mesh and its tree, and how getting them went: what `build` reports, and what every
/// command that builds a tree (`render`) reports the same way.
pub struct Built {
    pub loaded: Loaded,
    pub build: sahkd::Build,
    /// Set when the tree was built on a GPU.
    pub gpu: Option<GpuReport>,
    /// Where `--save` wrote the tree.
    pub saved: Option<String>,
}

impl Built {
    /// Loads the mesh and builds its tree on the builder's threads, with spinners; or opens
    /// a saved tree (refused when `builder_flags` name any builder option), whose options the
    /// builder then takes over for the reports.
    pub fn new(
        mesh: &MeshArg,
        builder: &mut Builder,
        builder_flags: &[String],
        progress: &Progress,
    ) -> Result<Built> {
        let mut loaded = builder.install(|| input::open(mesh, builder_flags, progress))?;
        if let Some(build) = saved(builder, &mut loaded) {
            return Ok(Built {
                loaded,
                build,
                gpu: None,
                saved: None,
            });
        }
        let spinner = progress.spinner(format!(
            "building {} triangles",
            format::count(loaded.mesh.triangles.len() as u64)
        ));
        let built = builder.build_on_device_taking(&mut loaded.mesh);
        spinner.finish_and_clear();
        let (build, gpu) = built?;
        Ok(Built {
            loaded,
            build,
            gpu,
            saved: None,
        })
    }

    /// The JSON report; `valid` is `None` when the tree was not validated.
    pub fn report(&self, builder: &Builder, valid: Option<bool>) -> Report<'_> {
        let options = &builder.options;
        let stats = self.build.tree.stats(&options.cost);
        let report = &self.build.report;
        Report {
            source: self.loaded.source.name(),
            triangles: self.build.tree.triangles().len(),
            device: match builder.device {
                DeviceArg::Cpu => "cpu",
                DeviceArg::Gpu => "gpu",
            },
            gpu: self.gpu.as_ref(),
            options: OptionsReport::of(options),
            threads: builder.threads(),
            load_ms: self.loaded.load_ms,
            build_ms: report.build_ms,
            presort_ms: report.presort_ms,
            binned_ms: report.binned_ms,
            subtrees_ms: report.subtrees_ms,
            layout_ms: report.layout_ms,
            sah_cost: stats.sah_cost,
            nodes: stats.nodes,
            interior: stats.interior,
            leaves: stats.leaves,
            empty_leaves: stats.empty_leaves,
            references: stats.references,
            duplication: stats.duplication,
            max_depth: stats.max_depth,
            mean_leaf_size: stats.mean_leaf_size,
            bytes: stats.bytes,
            peak_working_bytes: report.peak_working_bytes,
            peak_working_bytes_per_triangle: report.peak_working_bytes as f64
                / self.build.tree.triangles().len().max(1) as f64,
            resident: PeakResident::now(self.build.tree.triangles().len()),
            valid,
            saved: self.saved.clone(),
            levels: &report.levels,
        }
    }

    /// The text report, one row per statistic.
    pub fn table(&self, builder: &Builder) -> Table {
        let options = &builder.options;
        let stats = self.build.tree.stats(&options.cost);
        let report = &self.build.report;
        let mut t = Table::default();
        t.row("mesh", self.loaded.source.describe())
            .row(
                "triangles",
                format::count(self.build.tree.triangles().len() as u64),
            )
            .row(
                "builder",
                format!(
                    "{}{}, {}, {} counting, clip {}{}, {} threads",
                    options
                        .preset
                        .map_or(String::new(), |p| format!("preset {p}: ")),
                    options.algorithm.name(),
                    match options.axes {
                        Axes::Longest => "longest axis",
                        Axes::All => "all axes",
                    },
                    options.counting.name(),
                    switch_name(options.clip),
                    match options.resolved_bins() {
                        0 => String::new(),
                        n => format!(
                            ", {n} bins above {} references",
                            n as usize * BINNED_REFS_PER_BIN
                        ),
                    },
                    builder.threads()
                ),
            )
            .row("load time", format::ms(self.loaded.load_ms))
            .row("build time", format::ms(report.build_ms));
        if let Some(gpu) = &self.gpu {
            let phases: Vec<String> = gpu
                .phases_ms
                .iter()
                .map(|(name, ms)| format!("{name} {}", format::ms(*ms)))
                .collect();
            t.row("GPU adapter", gpu.adapter.clone())
                .row("GPU upload", format::ms(gpu.upload_ms))
                .row("GPU phases", phases.join(", "))
                .row("GPU download", format::ms(gpu.download_ms))
                .row(
                    "host round trips",
                    format!(
                        "{} ({} levels, {:.0} per level)",
                        gpu.round_trips, gpu.levels, gpu.round_trips_per_level
                    ),
                );
        }
        t.row("pre-sort time", format::ms(report.presort_ms));
        if report.binned_ms > 0.0 || report.subtrees_ms > 0.0 {
            t.row(
                "phases",
                format!(
                    "binned top {}, exact subtrees {} (workers' time), layout {}",
                    format::ms(report.binned_ms),
                    format::ms(report.subtrees_ms),
                    format::ms(report.layout_ms)
                ),
            );
        }
        t.row("SAH cost", format!("{:.3}", stats.sah_cost))
            .row("nodes", format::count(stats.nodes as u64))
            .row("interior nodes", format::count(stats.interior as u64))
            .row("leaves", format::count(stats.leaves as u64))
            .row("empty leaves", format::count(stats.empty_leaves as u64))
            .row("references", format::count(stats.references as u64))
            .row(
                "duplication",
                format!("{:.3} per triangle", stats.duplication),
            )
            .row("max depth", stats.max_depth.to_string())
            .row(
                "mean leaf size",
                format!("{:.2} triangles", stats.mean_leaf_size),
            )
            .row("tree size", format::bytes(stats.bytes as u64))
            .row(
                "peak working memory",
                format!(
                    "{} ({:.0} bytes per triangle)",
                    format::bytes(report.peak_working_bytes as u64),
                    report.peak_working_bytes as f64
                        / self.build.tree.triangles().len().max(1) as f64
                ),
            );
        let resident = PeakResident::now(self.build.tree.triangles().len());
        if let Some(bytes) = resident.peak_resident_bytes {
            let per = resident.peak_resident_bytes_per_triangle.unwrap_or(0.0);
            t.row(
                "peak resident memory",
                format!("{} ({per:.0} bytes per triangle)", format::bytes(bytes)),
            );
        }
        t
    }
}
