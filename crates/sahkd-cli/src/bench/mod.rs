//! `sahkd bench`: the paper's experiments on this machine. This module holds what is measured
//! and how; `table` writes the Markdown table, `charts` the PNG figures, `paper` holds the
//! paper's own numbers.

pub mod charts;
pub mod paper;
pub mod table;

use crate::gpu::GpuReport;
use crate::options::Builder;
use anyhow::Result;
use paper::PaperScene;
use sahkd::render::{
    render, Camera, Query, RayCounts, RaySet, RaySets, RenderOptions, Shading, COUNT_STRIDE,
};
use sahkd::TraceStats;
use sahkd::{BuildOptions, KdTree, Mesh};
use serde::Serialize;
use std::time::Instant;

/// Median, minimum and maximum of repeated measurements (the samples are kept too).
#[derive(Clone, Debug, Serialize)]
pub struct Spread {
    pub median: f64,
    pub min: f64,
    pub max: f64,
    pub samples: Vec<f64>,
}

impl Spread {
    /// `samples` must not be empty.
    pub fn of(samples: Vec<f64>) -> Spread {
        let mut sorted = samples.clone();
        sorted.sort_by(f64::total_cmp);
        let n = sorted.len();
        let median = if n % 2 == 1 {
            sorted[n / 2]
        } else {
            (sorted[n / 2 - 1] + sorted[n / 2]) / 2.0
        };
        Spread {
            median,
            min: sorted[0],
            max: sorted[n - 1],
            samples,
        }
    }
}

/// Everything one `sahkd bench` run measured, as written to results.json.
#[derive(Serialize)]
pub struct Results {
    /// The command line, as typed.
    pub command: String,
    pub machine: Machine,
    pub settings: Settings,
    pub scenes: Vec<SceneResult>,
    /// Fig. 1: time to build the first n levels, on the largest scene.
    pub levels: Vec<LevelCurve>,
    /// Wall time of the whole run.
    pub seconds: f64,
}

/// What the numbers were measured on.
#[derive(Serialize)]
pub struct Machine {
    pub cpu: String,
    /// Hardware threads the process may use.
    pub cores: usize,
    pub memory: String,
    pub os: String,
    /// /proc/loadavg (1, 5, 15 minutes) before and after the run.
    pub load_before: String,
    pub load_after: String,
}

impl Machine {
    pub fn describe() -> Machine {
        let read = |path: &str| std::fs::read_to_string(path).unwrap_or_default();
        let field = |text: &str, key: &str| {
            text.lines()
                .find(|l| l.starts_with(key))
                .and_then(|l| l.split_once([':', '=']))
                .map(|(_, v)| v.trim().trim_matches('"').to_string())
        };
        Machine {
            cpu: field(&read("/proc/cpuinfo"), "model name").unwrap_or_else(|| "unknown".into()),
            cores: cores(),
            memory: field(&read("/proc/meminfo"), "MemTotal")
                .and_then(|kb| kb.trim_end_matches("kB").trim().parse::<u64>().ok())
                .map_or_else(|| "unknown".into(), |kb| crate::format::bytes(kb * 1024)),
            os: field(&read("/etc/os-release"), "PRETTY_NAME")
                .unwrap_or_else(|| std::env::consts::OS.to_string()),
            load_before: load(),
            load_after: String::new(),
        }
    }
}

pub fn cores() -> usize {
    std::thread::available_parallelism().map_or(1, |n| n.get())
}

/// The load averages of /proc/loadavg, or "unknown".
pub fn load() -> String {
    std::fs::read_to_string("/proc/loadavg")
        .ok()
        .map(|s| s.split_whitespace().take(3).collect::<Vec<_>>().join(" "))
        .unwrap_or_else(|| "unknown".into())
}

/// The settings of the run, defaults included.
#[derive(Clone, Serialize)]
pub struct Settings {
    pub algorithms: Vec<&'static str>,
    pub threads: Vec<usize>,
    pub repeat: usize,
    pub naive_cap: usize,
    /// Where the level builder's trees are built, "cpu" or "gpu"; every other builder, and
    /// every ray, runs on the CPU.
    pub device: &'static str,
    /// Options of every build; only `algorithm`, `threads` and, for Fig. 1, the depth limit
    /// change between builds.
    pub build_options: BuildOptions,
    pub rays: RaySettings,
    /// Fig. 1 covers levels 1 ..= this.
    pub fig1_levels: u32,
}

impl Settings {
    /// The thread count Table 1 and Fig. 1 show a builder at: the serial sweep at the
    /// smallest, the parallel builders at the largest the machine has cores for.
    pub fn table_threads(&self, algorithm: &str) -> usize {
        if algorithm == "sweep" {
            return self.threads[0];
        }
        self.threads
            .iter()
            .copied()
            .filter(|&t| t <= cores())
            .max()
            .unwrap_or(self.threads[0])
    }
}

/// How ray throughput is measured.
#[derive(Clone, Serialize)]
pub struct RaySettings {
    pub camera: &'static str,
    /// Primary rays: one per pixel of a width x height picture.
    pub width: u32,
    pub height: u32,
    /// Ambient occlusion: a picture of ao_size x ao_size pixels, ao_samples rays per hit.
    /// Shadow and bounce rays: one of each per primary hit (`sahkd::render::RaySets`).
    pub ao_size: u32,
    pub ao_samples: u32,
    pub threads: usize,
}

/// A scene's measurements.
#[derive(Serialize)]
pub struct SceneResult {
    /// The paper's name for the scene, or the file's or spec's name.
    pub label: String,
    pub source: String,
    pub triangles: usize,
    /// The paper's row this scene stands in for.
    pub paper: Option<PaperScene>,
    pub builds: Vec<BuildRow>,
    pub rays: Vec<RayRow>,
}

impl SceneResult {
    /// The row of `algorithm` at `threads`, if it was measured.
    pub fn build(&self, algorithm: &str, threads: usize) -> Option<&BuildRow> {
        self.builds
            .iter()
            .find(|b| b.algorithm == algorithm && b.threads == threads)
    }
}

/// One builder at one thread count on one scene.
#[derive(Serialize)]
pub struct BuildRow {
    pub algorithm: &'static str,
    pub threads: usize,
    /// Why it was not run, when it was not.
    pub skipped: Option<String>,
    pub measured: Option<Measured>,
}

/// Build times over the repeats, and the tree.
#[derive(Serialize)]
pub struct Measured {
    /// Whole build, pre-sort included.
    pub build_ms: Spread,
    pub presort_ms: Spread,
    pub sah_cost: f64,
    pub nodes: usize,
    pub leaves: usize,
    pub references: usize,
    pub depth: u32,
    /// Nodes, references and triangle data of the finished tree.
    pub tree_bytes: usize,
    /// The builder's working arrays at their peak.
    pub peak_working_bytes: usize,
    /// Built on a GPU: the adapter, upload, per-phase and download times and host round
    /// trips of the last timed build.
    pub gpu: Option<GpuReport>,
}

/// Ray throughput through one builder's tree.
#[derive(Serialize)]
pub struct RayRow {
    pub algorithm: &'static str,
    /// Mrays/s of each of the `repeat` renders (after a warm-up render).
    pub primary_mrays: Spread,
    pub ao_mrays: Spread,
    /// Mrays/s of each of the `repeat` batch calls on the shadow rays (any hit, to a point
    /// light) and the bounce rays (closest hit, cosine-weighted) of the primary hits.
    pub shadow_mrays: Spread,
    pub bounce_mrays: Spread,
    /// Counts of the last render or batch (rays, nodes and triangles per ray are the same
    /// every time).
    pub primary: RayCounts,
    pub ao: RayCounts,
    pub shadow: RayCounts,
    pub bounce: RayCounts,
}

/// Fig. 1 for one builder: T_n for n = 1 ..= levels.
#[derive(Serialize)]
pub struct LevelCurve {
    pub scene: String,
    pub algorithm: &'static str,
    pub threads: usize,
    pub points: Vec<LevelPoint>,
}

#[derive(Serialize)]
pub struct LevelPoint {
    pub level: u32,
    /// T_n: build time with the depth limited to `level`.
    pub t_ms: Spread,
    /// T_sort: the pre-sort part of those builds.
    pub presort_ms: Spread,
    /// T_n - T_sort of each build (taken within a build, so the sort's noise cancels).
    pub after_sort_ms: Spread,
    /// P_n = median(T_n - T_sort) / median(T_1 - T_sort).
    pub p: f64,
}

/// Build times over the repeats: whole builds and their pre-sort parts.
pub struct BuildTimes {
    pub total: Spread,
    pub presort: Spread,
    /// Whole build minus pre-sort, build by build.
    pub after_sort: Spread,
}

/// The last of repeated builds, and its GPU report when it was built on a GPU.
pub struct LastBuild {
    pub build: sahkd::Build,
    pub gpu: Option<GpuReport>,
}

/// Builds once to warm up, then `repeat` times, on the builder's device; `step` is called
/// after every build. Returns the times and the last build.
pub fn measure_builds(
    builder: &Builder,
    mesh: &Mesh,
    repeat: usize,
    step: &dyn Fn(),
) -> Result<(BuildTimes, LastBuild)> {
    let (mut last, mut gpu) = builder.build_on_device(mesh)?;
    step();
    let (mut total, mut presort, mut after_sort) = (Vec::new(), Vec::new(), Vec::new());
    for _ in 0..repeat {
        (last, gpu) = builder.build_on_device(mesh)?;
        total.push(last.report.build_ms);
        presort.push(last.report.presort_ms);
        after_sort.push(last.report.build_ms - last.report.presort_ms);
        step();
    }
    let times = BuildTimes {
        total: Spread::of(total),
        presort: Spread::of(presort),
        after_sort: Spread::of(after_sort),
    };
    Ok((times, LastBuild { build: last, gpu }))
}

/// A build's times, tree statistics and GPU report.
pub fn measured(last: &LastBuild, options: &BuildOptions, times: BuildTimes) -> Measured {
    let build = &last.build;
    let stats = build.tree.stats(&options.cost);
    Measured {
        build_ms: times.total,
        presort_ms: times.presort,
        sah_cost: stats.sah_cost,
        nodes: stats.nodes,
        leaves: stats.leaves,
        references: stats.references,
        depth: stats.max_depth,
        tree_bytes: stats.bytes,
        peak_working_bytes: build.report.peak_working_bytes,
        gpu: last.gpu.clone(),
    }
}

/// Primary rays (normal shading, `width` x `height`) and AO rays (`ao_size` squared pixels,
/// `ao_samples` per hit) through `tree`, from the fixed front camera, on `pool`'s threads:
/// one warm-up render of each, then `repeat`.
pub fn measure_rays(
    pool: &Builder,
    tree: &KdTree,
    rays: &RaySettings,
    repeat: usize,
    algorithm: &'static str,
) -> RayRow {
    let camera = Camera::front(tree.bounds());
    let primary = RenderOptions::new(rays.width, rays.height, camera);
    let ao = RenderOptions {
        shading: Shading::Ao,
        ao_samples: rays.ao_samples,
        ..RenderOptions::new(rays.ao_size, rays.ao_size, camera)
    };
    pool.install(|| {
        let once = || {
            let (_, p) = render(tree, &primary, &|_, _| {});
            let (_, a) = render(tree, &ao, &|_, _| {});
            (p.primary, a.occlusion)
        };
        let mut last = once();
        let (mut p, mut a) = (Vec::new(), Vec::new());
        for _ in 0..repeat {
            last = once();
            p.push(last.0.mrays_per_s);
            a.push(last.1.mrays_per_s);
        }
        let sets = RaySets::new(tree, camera, rays.width, rays.height);
        let [_, shadow, _, bounce] = &sets.sets;
        let (shadow_mrays, shadow) = time_batches(tree, shadow, repeat);
        let (bounce_mrays, bounce) = time_batches(tree, bounce, repeat);
        RayRow {
            algorithm,
            primary_mrays: Spread::of(p),
            ao_mrays: Spread::of(a),
            shadow_mrays,
            bounce_mrays,
            primary: last.0,
            ao: last.1,
            shadow,
            bounce,
        }
    })
}

/// Times the batch call of `set` `repeat` times after a warm-up (in the current pool), and
/// counts nodes and triangles per ray over every `COUNT_STRIDE`-th ray, as `render` does.
fn time_batches(tree: &KdTree, set: &RaySet, repeat: usize) -> (Spread, RayCounts) {
    let trace = || {
        let start = Instant::now();
        match set.query {
            Query::Closest => drop(std::hint::black_box(tree.intersect_batch(&set.rays))),
            Query::Any => drop(std::hint::black_box(tree.occluded_batch(&set.rays))),
        }
        start.elapsed().as_secs_f64()
    };
    trace();
    let seconds: Vec<f64> = (0..repeat.max(1)).map(|_| trace()).collect();
    let mut stats = TraceStats::default();
    for ray in set.rays.iter().step_by(COUNT_STRIDE as usize) {
        match set.query {
            Query::Closest => drop(tree.intersect_counted(ray, &mut stats)),
            Query::Any => drop(tree.occluded_counted(ray, &mut stats)),
        }
    }
    let rays = set.rays.len() as u64;
    let rate = |s: f64| if s > 0.0 { rays as f64 / s / 1e6 } else { 0.0 };
    let last = seconds[seconds.len() - 1];
    let counted = set.rays.len().div_ceil(COUNT_STRIDE as usize).max(1) as f64;
    let counts = RayCounts {
        rays,
        seconds: last,
        mrays_per_s: rate(last),
        nodes_per_ray: stats.nodes as f64 / counted,
        triangles_per_ray: stats.triangles as f64 / counted,
    };
    (Spread::of(seconds.into_iter().map(rate).collect()), counts)
}

/// Seconds since `start`.
pub fn seconds_since(start: Instant) -> f64 {
    start.elapsed().as_secs_f64()
}

#[cfg(test)]
mod tests {
    use super::Spread;

    #[test]
    fn spread_takes_median_min_and_max() {
        let s = Spread::of(vec![5.0, 1.0, 3.0]);
        assert_eq!((s.median, s.min, s.max), (3.0, 1.0, 5.0));
        assert_eq!(Spread::of(vec![4.0, 2.0]).median, 3.0);
        assert_eq!(Spread::of(vec![7.0]).median, 7.0);
    }
}
