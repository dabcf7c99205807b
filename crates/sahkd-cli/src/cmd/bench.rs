//! `sahkd bench`: the paper's experiments in one command — Table 1 (build times of every
//! builder on the paper's scenes), Fig. 1 (time of the first n levels) and Fig. 2 (speed-up
//! with threads) — plus tree quality and ray throughput. Writes results.json, table1.md and
//! three PNG charts to the output folder.

use super::Context;
use crate::bench::paper::{PaperScene, TABLE_1};
use crate::bench::{
    self, charts, cores, measure_builds, measure_rays, measured, table, BuildRow, LevelCurve,
    LevelPoint, Machine, RaySettings, Results, SceneResult, Settings,
};
use crate::input::{self, Loaded, MeshArg};
use crate::options::{named, Builder, DeviceArg, Switch};
use crate::progress::Progress;
use anyhow::{bail, Context as _, Result};
use indicatif::ProgressBar;
use sahkd::{Algorithm, BuildOptions};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Where the paper's scenes are looked for when neither --scenes-dir nor SAHKD_SCENES is given.
const SHARED_SCENES: &str = "../shared/scenes";
/// Fig. 1 covers levels 1 to 7, as the paper's does.
const FIG1_LEVELS: u32 = 7;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Meshes (.ply, .obj) or procedural scenes (spd:toys:11000); none: the paper's four
    /// scenes (Toys, Bunny, Dragon, Buddha) from the scenes folder, or procedural stand-ins
    #[arg(value_name = "MESH|SCENE")]
    pub scenes: Vec<String>,

    /// Where the paper's scenes are [default: $SAHKD_SCENES, else ../shared/scenes when
    /// present, else procedural scenes of the paper's sizes]
    #[arg(long, value_name = "DIR")]
    pub scenes_dir: Option<PathBuf>,

    /// Builders to compare, comma-separated
    #[arg(
        long,
        value_name = "LIST",
        value_delimiter = ',',
        default_value = "median,sweep,naive,level,hybrid",
        value_parser = named::<Algorithm>(Algorithm::NAMES)
    )]
    pub algorithms: Vec<Algorithm>,

    /// Thread counts, comma-separated, each at most 4 per core (64 on any machine); the
    /// serial sweep runs once, at the smallest
    #[arg(long, value_name = "LIST", value_delimiter = ',', default_value = "1,2,4,8",
          value_parser = crate::options::parse_threads)]
    pub threads: Vec<usize>,

    /// Timed builds per measurement, after one warm-up build; the median is reported
    #[arg(long, value_name = "K", allow_negative_numbers = true, default_value_t = 3,
          value_parser = clap::value_parser!(u32).range(1..=1000))]
    pub repeat: u32,

    /// The naive builder (O(n^2) per node) runs only on scenes of at most this many triangles
    #[arg(
        long,
        value_name = "TRIANGLES",
        allow_negative_numbers = true,
        default_value_t = 20_000
    )]
    pub naive_cap: usize,

    /// Width of the primary-ray picture (one ray per pixel, fixed front camera)
    #[arg(long, value_name = "PIXELS", allow_negative_numbers = true, default_value_t = 1024,
          value_parser = clap::value_parser!(u32).range(1..=16384))]
    pub width: u32,

    /// Height of the primary-ray picture
    #[arg(long, value_name = "PIXELS", allow_negative_numbers = true, default_value_t = 1024,
          value_parser = clap::value_parser!(u32).range(1..=16384))]
    pub height: u32,

    /// Side of the square ambient-occlusion picture
    #[arg(long, value_name = "PIXELS", allow_negative_numbers = true, default_value_t = 512,
          value_parser = clap::value_parser!(u32).range(1..=16384))]
    pub ao_size: u32,

    /// Ambient-occlusion rays per hit
    #[arg(long, value_name = "N", allow_negative_numbers = true, default_value_t = 16,
          value_parser = clap::value_parser!(u32).range(1..=4096))]
    pub ao_samples: u32,

    /// Where the level builder's trees are built: the CPU, or a GPU through wgpu; the other
    /// builders and all rays run on the CPU either way
    #[arg(long, value_enum, value_name = "DEVICE", default_value_t = DeviceArg::Cpu)]
    pub device: DeviceArg,

    /// Clip straddling triangles to each child (perfect splits), in every build
    #[arg(long, value_enum, value_name = "ON|OFF",
          default_value_t = BuildOptions::default().clip.into())]
    pub clip: Switch,

    /// Folder for results.json, table1.md and the charts (created if missing)
    #[arg(long, value_name = "DIR", default_value = "bench")]
    pub out: PathBuf,
}

/// A scene to measure, and the paper's row it stands in for.
struct Scene {
    paper: Option<PaperScene>,
    loaded: Loaded,
}

impl Scene {
    fn label(&self) -> String {
        match &self.paper {
            Some(p) => p.name.to_string(),
            None => {
                let name = self.loaded.source.name();
                Path::new(&name)
                    .file_stem()
                    .map_or(name.clone(), |s| s.to_string_lossy().into_owned())
            }
        }
    }
}

pub fn run(args: Args, context: &Context) -> Result<()> {
    let start = Instant::now();
    let progress = Progress::new(context.quiet, false);
    let created = check_writable(&args.out)?;
    let result = measure_and_write(&args, context, &progress, start);
    if result.is_err() {
        remove_if_empty(&created);
    }
    result
}

fn measure_and_write(
    args: &Args,
    context: &Context,
    progress: &Progress,
    start: Instant,
) -> Result<()> {
    let command = std::env::args().collect::<Vec<_>>().join(" ");
    let settings = settings(args);
    if args.device == DeviceArg::Gpu {
        // Refused before any work, with the error `build --device gpu` gives.
        crate::gpu::check(&BuildOptions {
            algorithm: Algorithm::Level,
            ..settings.build_options
        })?;
    }
    let scenes = load_scenes(args, context, progress)?;
    let mut machine = Machine::describe();

    let bar = progress.bar(total_steps(&scenes, &settings), "measuring");
    let step = || bar.inc(1);
    let mut results = Vec::new();
    for scene in &scenes {
        results.push(measure_scene(scene, &settings, &bar, &step)?);
    }
    let levels = match scenes.iter().max_by_key(|s| s.loaded.mesh.triangles.len()) {
        Some(largest) => measure_levels(largest, &settings, &bar, &step)?,
        None => Vec::new(),
    };
    bar.finish_and_clear();

    machine.load_after = bench::load();
    let results = Results {
        command,
        machine,
        settings,
        scenes: results,
        levels,
        seconds: bench::seconds_since(start),
    };
    write_outputs(&args.out, &results)?;
    if !context.quiet {
        eprintln!(
            "wrote results.json, table1.md, table1.png, fig1_levels.png and fig2_speedup.png to {} in {:.0} s",
            args.out.display(),
            results.seconds
        );
    }
    Ok(())
}

/// Creates the output folder and makes sure a file can be written there before any work.
/// Returns the folders it created, deepest first, for [`remove_if_empty`].
fn check_writable(out: &Path) -> Result<Vec<PathBuf>> {
    let created: Vec<PathBuf> = out
        .ancestors()
        .filter(|p| !p.as_os_str().is_empty())
        .take_while(|p| !p.exists())
        .map(Path::to_path_buf)
        .collect();
    std::fs::create_dir_all(out)
        .with_context(|| format!("cannot create the output folder {}", out.display()))?;
    let checked = tempfile::NamedTempFile::new_in(out)
        .with_context(|| format!("cannot write to the output folder {}", out.display()));
    if let Err(e) = checked {
        remove_if_empty(&created);
        return Err(e);
    }
    Ok(created)
}

/// Removes the folders a failed run created, as long as nothing was written into them.
fn remove_if_empty(created: &[PathBuf]) {
    for folder in created {
        if std::fs::remove_dir(folder).is_err() {
            break;
        }
    }
}

fn settings(args: &Args) -> Settings {
    let mut algorithms: Vec<&'static str> = Vec::new();
    for a in &args.algorithms {
        let name = a.name();
        if !algorithms.contains(&name) {
            algorithms.push(name);
        }
    }
    let mut threads = args.threads.clone();
    threads.sort_unstable();
    threads.dedup();
    Settings {
        algorithms,
        threads,
        repeat: args.repeat as usize,
        naive_cap: args.naive_cap,
        device: match args.device {
            DeviceArg::Cpu => "cpu",
            DeviceArg::Gpu => "gpu",
        },
        build_options: BuildOptions {
            clip: args.clip.into(),
            ..BuildOptions::default()
        },
        rays: RaySettings {
            camera: "front: from +z, two scene diagonals from the centre of the scene box, \
                     looking at it, y up, 45 degree vertical field of view",
            width: args.width,
            height: args.height,
            ao_size: args.ao_size,
            ao_samples: args.ao_samples,
            threads: cores(),
        },
        fig1_levels: FIG1_LEVELS,
    }
}

/// The scenes named on the command line, or the paper's four.
fn load_scenes(args: &Args, context: &Context, progress: &Progress) -> Result<Vec<Scene>> {
    let named: Vec<(Option<PaperScene>, String)> = if !args.scenes.is_empty() {
        args.scenes.iter().map(|s| (None, s.clone())).collect()
    } else if let Some(dir) = scenes_dir(args)? {
        TABLE_1
            .iter()
            .map(|p| (Some(*p), dir.join(p.stand_in).display().to_string()))
            .collect()
    } else {
        if !context.quiet {
            eprintln!(
                "note: no scenes folder (--scenes-dir, SAHKD_SCENES or {SHARED_SCENES}); \
                 using procedural scenes of the paper's sizes"
            );
        }
        TABLE_1
            .iter()
            .map(|p| (Some(*p), p.procedural.to_string()))
            .collect()
    };
    named
        .into_iter()
        .map(|(paper, mesh)| {
            let loaded = input::load(&MeshArg { mesh }, progress)?;
            Ok(Scene { paper, loaded })
        })
        .collect()
}

/// --scenes-dir, else SAHKD_SCENES (each must exist), else ../shared/scenes if present.
fn scenes_dir(args: &Args) -> Result<Option<PathBuf>> {
    let given = match (&args.scenes_dir, std::env::var_os("SAHKD_SCENES")) {
        (Some(dir), _) => Some((dir.clone(), "--scenes-dir")),
        (None, Some(dir)) => Some((PathBuf::from(dir), "SAHKD_SCENES")),
        (None, None) => None,
    };
    match given {
        Some((dir, from)) if !dir.is_dir() => {
            bail!("{from} {}: no such folder", dir.display())
        }
        Some((dir, _)) => Ok(Some(dir)),
        None => Ok(Some(PathBuf::from(SHARED_SCENES)).filter(|d| d.is_dir())),
    }
}

/// Thread counts a builder runs at: the serial sweep only at the smallest.
fn thread_counts(algorithm: &str, settings: &Settings) -> Vec<usize> {
    if algorithm == "sweep" {
        settings.threads.iter().take(1).copied().collect()
    } else {
        settings.threads.clone()
    }
}

fn skips_naive(scene: &Scene, settings: &Settings) -> bool {
    scene.loaded.mesh.triangles.len() > settings.naive_cap
}

/// Fig. 1's builders: the sweep and the level builder, at their Table 1 thread counts.
fn level_runs(settings: &Settings) -> Vec<(&'static str, usize)> {
    ["sweep", "level"]
        .into_iter()
        .filter(|a| settings.algorithms.contains(a))
        .map(|a| (a, settings.table_threads(a)))
        .collect()
}

/// Builds and ray measurements (warm-ups included) of the whole run, for the progress bar.
fn total_steps(scenes: &[Scene], settings: &Settings) -> u64 {
    let per_measurement = 1 + settings.repeat as u64;
    let mut total = 0;
    for scene in scenes {
        for &a in &settings.algorithms {
            if a == "naive" && skips_naive(scene, settings) {
                continue;
            }
            total += thread_counts(a, settings).len() as u64 * per_measurement + 1;
        }
    }
    total + level_runs(settings).len() as u64 * FIG1_LEVELS as u64 * per_measurement
}

/// The device a builder runs on: the level builder on the chosen one, the rest on the CPU.
fn device(name: &str, settings: &Settings) -> DeviceArg {
    if name == "level" && settings.device == "gpu" {
        DeviceArg::Gpu
    } else {
        DeviceArg::Cpu
    }
}

/// The builder of a name in `Settings::algorithms` (the library's own names, so parsing
/// cannot fail).
fn algorithm(name: &str) -> Algorithm {
    name.parse()
        .expect("Settings::algorithms holds the library's names")
}

fn measure_scene(
    scene: &Scene,
    settings: &Settings,
    bar: &ProgressBar,
    step: &dyn Fn(),
) -> Result<SceneResult> {
    let mesh = &scene.loaded.mesh;
    let label = scene.label();
    let ray_pool = Builder::new(BuildOptions {
        threads: Some(settings.rays.threads),
        ..settings.build_options
    })?;
    let mut builds = Vec::new();
    let mut rays = Vec::new();
    for &name in &settings.algorithms {
        if name == "naive" && skips_naive(scene, settings) {
            for &threads in &settings.threads {
                builds.push(BuildRow {
                    algorithm: name,
                    threads,
                    skipped: Some(format!(
                        "skipped (n > cap: {} > {} triangles)",
                        mesh.triangles.len(),
                        settings.naive_cap
                    )),
                    measured: None,
                });
            }
            continue;
        }
        let mut last_tree = None;
        for threads in thread_counts(name, settings) {
            bar.set_message(format!("{label}: {name}, {threads} threads"));
            let builder = Builder::new(BuildOptions {
                algorithm: algorithm(name),
                threads: Some(threads),
                ..settings.build_options
            })?
            .on(device(name, settings));
            let (times, last) = measure_builds(&builder, mesh, settings.repeat, step)?;
            builds.push(BuildRow {
                algorithm: name,
                threads,
                skipped: None,
                measured: Some(measured(&last, &builder.options, times)),
            });
            last_tree = Some(last.build.tree);
        }
        if let Some(tree) = last_tree {
            bar.set_message(format!("{label}: {name}, rays"));
            rays.push(measure_rays(
                &ray_pool,
                &tree,
                &settings.rays,
                settings.repeat,
                name,
            ));
            step();
        }
    }
    Ok(SceneResult {
        label,
        source: scene.loaded.source.name(),
        triangles: mesh.triangles.len(),
        paper: scene.paper,
        builds,
        rays,
    })
}

/// Fig. 1: T_n is the build time of the same builder with the depth limited to n (the sweep
/// is depth-first, so this is the only common way to stop both after n levels).
fn measure_levels(
    scene: &Scene,
    settings: &Settings,
    bar: &ProgressBar,
    step: &dyn Fn(),
) -> Result<Vec<LevelCurve>> {
    let mut curves = Vec::new();
    for (name, threads) in level_runs(settings) {
        let mut points: Vec<LevelPoint> = Vec::new();
        for level in 1..=FIG1_LEVELS {
            bar.set_message(format!("Fig. 1: {name}, {level} levels"));
            let mut options = BuildOptions {
                algorithm: algorithm(name),
                threads: Some(threads),
                ..settings.build_options
            };
            options.cost.max_depth = Some(level);
            let builder = Builder::new(options)?.on(device(name, settings));
            let (times, _) = measure_builds(&builder, &scene.loaded.mesh, settings.repeat, step)?;
            points.push(LevelPoint {
                level,
                t_ms: times.total,
                presort_ms: times.presort,
                after_sort_ms: times.after_sort,
                p: 0.0,
            });
        }
        let base = points[0].after_sort_ms.median;
        for p in &mut points {
            p.p = p.after_sort_ms.median / base;
        }
        curves.push(LevelCurve {
            scene: scene.label(),
            algorithm: name,
            threads,
            points,
        });
    }
    Ok(curves)
}

/// Every file whole or not at all (`crate::output`).
/// The files a run writes into its folder.
const OUTPUTS: [&str; 5] = [
    "results.json",
    "table1.md",
    "table1.png",
    "fig1_levels.png",
    "fig2_speedup.png",
];

/// Everything is made in memory first, then written into a hidden folder inside `out` and
/// moved into place file by file: a failure part way (a full disk at a chart) leaves none of
/// this run's files (the caller then removes the folders it created), and an earlier run's
/// files are only replaced once all of these are written.
fn write_outputs(out: &Path, results: &Results) -> Result<()> {
    let json = serde_json::to_string_pretty(results).context("cannot encode results.json")?;
    let contents: [Vec<u8>; 5] = [
        json.into_bytes(),
        table::markdown(results).into_bytes(),
        charts::table1(&out.join(OUTPUTS[2]), results)?,
        charts::fig1(&out.join(OUTPUTS[3]), results)?,
        charts::fig2(&out.join(OUTPUTS[4]), results)?,
    ];
    let cannot = |name: &str| format!("cannot write {}", out.join(name).display());
    let staging = tempfile::Builder::new()
        .prefix(".sahkd-bench-")
        .tempdir_in(out)
        .with_context(|| cannot(OUTPUTS[0]))?;
    for (name, bytes) in OUTPUTS.iter().zip(&contents) {
        let write = || -> std::io::Result<()> {
            let mut file = std::fs::File::create(staging.path().join(name))?;
            std::io::Write::write_all(&mut file, bytes)?;
            file.sync_all()
        };
        write().with_context(|| cannot(name))?;
    }
    for (i, name) in OUTPUTS.iter().enumerate() {
        if let Err(e) = std::fs::rename(staging.path().join(name), out.join(name)) {
            // None of the set stays: the ones already moved go too.
            for moved in &OUTPUTS[..i] {
                let _ = std::fs::remove_file(out.join(moved));
            }
            return Err(anyhow::Error::new(e).context(cannot(name)));
        }
    }
    Ok(())
}
