//! The builder options shared by every command that builds a tree.
//!
//! Defaults are read from `sahkd::BuildOptions::default()` and `sahkd::CostModel::default()`,
//! so the library stays the one place that decides them; the command line only shows them.

use crate::gpu::GpuReport;
use anyhow::{Context, Result};
use clap::{Args, ValueEnum};
use sahkd::{Algorithm, Axes, Build, BuildOptions, CostModel, Counting, Mesh};
use std::fmt;

fn default_options() -> BuildOptions {
    BuildOptions::default()
}

fn default_cost() -> CostModel {
    CostModel::default()
}

/// How to build a tree: which builder, which candidates, the cost model and the threads.
#[derive(Args, Clone, Debug)]
#[command(next_help_heading = "Builder options")]
pub struct BuilderArgs {
    /// Where the level builder runs: the CPU, or a GPU through wgpu (Vulkan, Metal, DX12;
    /// level builder only)
    #[arg(long, value_enum, value_name = "DEVICE", default_value_t = DeviceArg::Cpu)]
    pub device: DeviceArg,

    /// Tree builder [default: hybrid; level with --device gpu]
    #[arg(long, value_enum, value_name = "NAME")]
    pub algorithm: Option<AlgorithmArg>,

    /// Axes a node's split candidates come from
    #[arg(long, value_enum, value_name = "WHICH",
          default_value_t = default_options().axes.into())]
    pub axes: AxesArg,

    /// How the level builder counts primitives on each side of a candidate
    #[arg(long, value_enum, value_name = "HOW",
          default_value_t = default_options().counting.into())]
    pub counting: CountingArg,

    /// Clip straddling triangles to each child (perfect splits)
    #[arg(long, value_enum, value_name = "ON|OFF",
          default_value_t = default_options().clip.into())]
    pub clip: Switch,

    /// Median builder: nodes with more triangles than this are split at the spatial median
    /// (or cut off empty space); smaller ones get exact SAH
    #[arg(long, value_name = "N", allow_negative_numbers = true,
          default_value_t = default_options().median_large_node)]
    pub large_node: u32,

    /// Sweep and hybrid builders: price nodes of more than 64 x N triangle references at the
    /// N - 1 boundaries of N equal bins (min-max binning), the others exactly; 0 prices every
    /// node exactly [default: 256 for hybrid, 0 for sweep]
    #[arg(long, value_name = "N", allow_negative_numbers = true, value_parser = parse_bins)]
    pub bins: Option<u32>,

    /// Worker threads for building and tracing, at most 4 per core (64 on any machine)
    /// [default: all cores]
    #[arg(long, value_name = "N", allow_negative_numbers = true, value_parser = parse_threads)]
    pub threads: Option<usize>,

    /// SAH cost of traversing an interior node (K_T)
    #[arg(long, value_name = "COST", allow_negative_numbers = true, value_parser = parse_non_negative,
          default_value_t = default_cost().traversal)]
    pub kt: f32,

    /// SAH cost of one ray/triangle test (K_I)
    #[arg(long, value_name = "COST", allow_negative_numbers = true, value_parser = parse_positive,
          default_value_t = default_cost().intersection)]
    pub ki: f32,

    /// Factor on the cost of a split that leaves one side empty (1 disables the bonus)
    #[arg(long, value_name = "FACTOR", allow_negative_numbers = true, value_parser = parse_unit_interval,
          default_value_t = default_cost().empty_bonus)]
    pub empty_bonus: f32,

    /// Nodes with this many triangles or fewer become leaves
    #[arg(long, value_name = "N", allow_negative_numbers = true,
          default_value_t = default_cost().leaf_size)]
    pub leaf_size: u32,

    /// Depth limit, or `auto` for 8 + 1.3 log2(triangles)
    #[arg(long, value_name = "DEPTH|auto", allow_negative_numbers = true, value_parser = parse_max_depth,
          default_value_t = MaxDepth(default_cost().max_depth))]
    pub max_depth: MaxDepth,

    /// Stop splitting once references reach this many times the triangle count
    #[arg(long, value_name = "FACTOR", allow_negative_numbers = true, value_parser = parse_at_least_one,
          default_value_t = default_cost().max_duplication)]
    pub max_duplication: f32,
}

impl BuilderArgs {
    /// The library's options for these arguments (`threads` as given, `None` for all cores).
    pub fn build_options(&self) -> BuildOptions {
        // The GPU runs the level builder only: there it is the default.
        let algorithm = match (self.algorithm, self.device) {
            (Some(a), _) => a.into(),
            (None, DeviceArg::Gpu) => Algorithm::Level,
            (None, DeviceArg::Cpu) => default_options().algorithm,
        };
        BuildOptions {
            algorithm,
            axes: self.axes.into(),
            counting: self.counting.into(),
            clip: self.clip.into(),
            threads: self.threads,
            cost: CostModel {
                traversal: self.kt,
                intersection: self.ki,
                empty_bonus: self.empty_bonus,
                leaf_size: self.leaf_size,
                max_depth: self.max_depth.0,
                max_duplication: self.max_duplication,
            },
            median_large_node: self.large_node,
            bins: self.bins,
        }
    }

    /// The options and a thread pool of the requested size, for building and tracing alike.
    pub fn builder(&self) -> Result<Builder> {
        Ok(Builder::new(self.build_options())?.on(self.device))
    }
}

/// Build options together with the thread pool every parallel step of a command runs in.
pub struct Builder {
    /// The options, with `threads` the number of threads actually used.
    pub options: BuildOptions,
    pool: rayon::ThreadPool,
    pub device: DeviceArg,
}

impl Builder {
    /// A pool of `options.threads` workers (`None`: every core, or RAYON_NUM_THREADS).
    pub fn new(mut options: BuildOptions) -> Result<Builder> {
        // Before any input is read: what the value parsers cannot see (bins with a builder
        // that has none) is refused here, by the library's rules.
        options.validate()?;
        let pool = rayon::ThreadPoolBuilder::new()
            // 0 asks rayon for its default.
            .num_threads(options.threads.unwrap_or(0))
            .build()
            .context("cannot start the worker threads")?;
        options.threads = Some(pool.current_num_threads());
        Ok(Builder {
            options,
            pool,
            device: DeviceArg::Cpu,
        })
    }

    /// The same builder, running the level builder on `device`.
    pub fn on(self, device: DeviceArg) -> Builder {
        Builder { device, ..self }
    }

    pub fn threads(&self) -> usize {
        self.pool.current_num_threads()
    }

    /// Takes over a saved tree's options (for the reports), keeping this run's threads.
    pub fn adopt(&mut self, saved: &BuildOptions) {
        self.options = BuildOptions {
            threads: self.options.threads,
            ..*saved
        };
    }

    /// Runs `f` inside the pool, so that rayon work it starts uses `threads()` threads.
    pub fn install<R: Send>(&self, f: impl FnOnce() -> R + Send) -> R {
        self.pool.install(f)
    }

    /// Builds the tree of `mesh` on the pool.
    pub fn build(&self, mesh: &Mesh) -> Result<Build> {
        // Inside the pool, `threads: None` means "the current pool" to the library.
        let options = BuildOptions {
            threads: None,
            ..self.options
        };
        self.install(|| sahkd::build(mesh, &options))
            .context("cannot build the tree")
    }

    /// Builds the tree of `mesh` on the builder's device: the CPU pool, or a GPU (the level
    /// builder only), with the GPU's report. Every command that builds goes through here.
    pub fn build_on_device(&self, mesh: &Mesh) -> Result<(Build, Option<GpuReport>)> {
        match self.device {
            DeviceArg::Cpu => Ok((self.build(mesh)?, None)),
            DeviceArg::Gpu => {
                let (build, report) = crate::gpu::build(mesh, &self.options)?;
                Ok((build, Some(report)))
            }
        }
    }

    /// [`build_on_device`](Self::build_on_device) for a command that needs the mesh no more
    /// (it leaves `mesh` empty).
    pub fn build_on_device_taking(&self, mesh: &mut Mesh) -> Result<(Build, Option<GpuReport>)> {
        if self.device == DeviceArg::Gpu {
            let built = self.build_on_device(mesh);
            *mesh = Mesh::default();
            return built;
        }
        Ok((self.build_taking(mesh)?, None))
    }

    /// [`build`](Self::build) for a command that needs the mesh no more (it leaves `mesh`
    /// empty): the mesh is freed as soon as its triangles are copied out, before the
    /// builder's working arrays exist, so the peak memory holds one copy of the geometry
    /// instead of two (18-30 bytes per triangle less).
    pub fn build_taking(&self, mesh: &mut Mesh) -> Result<Build> {
        let mesh = std::mem::take(mesh);
        let triangles = mesh
            .validate()
            .map(|()| mesh.corner_triangles())
            .map_err(sahkd::builders::BuildError::InvalidMesh)
            .context("cannot build the tree")?;
        drop(mesh);
        let options = BuildOptions {
            threads: None,
            ..self.options
        };
        self.install(|| sahkd::build_triangles(triangles, &options))
            .context("cannot build the tree")
    }
}

/// Where a tree is built.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum DeviceArg {
    /// The CPU, on the worker threads
    Cpu,
    /// The first GPU adapter wgpu finds (high performance first)
    Gpu,
}

/// `sahkd::Algorithm` as a command-line value.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum AlgorithmArg {
    /// Level passes at the top, then each node's subtree by the sweep on one worker (the sweep's tree, on every core)
    Hybrid,
    /// Wald & Havran sweep: serial, exact SAH over sorted events
    Sweep,
    /// Li, Tan & Liao: breadth-first, every candidate of a level priced in parallel
    Level,
    /// The level framework with brute-force counting (for checking)
    Naive,
    /// Zhou et al. 2008: spatial median and empty-space cuts for large nodes, SAH below
    Median,
}

impl From<Algorithm> for AlgorithmArg {
    fn from(a: Algorithm) -> Self {
        Self::from_str(a.name(), false).expect("the library's names are the command line's")
    }
}

impl From<AlgorithmArg> for Algorithm {
    fn from(a: AlgorithmArg) -> Self {
        let value = a.to_possible_value().expect("every value is named");
        value
            .get_name()
            .parse()
            .expect("the command line's names are the library's")
    }
}

/// `sahkd::Axes` as a command-line value.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum AxesArg {
    /// The node's longest axis only
    Longest,
    /// All three axes
    All,
}

impl From<Axes> for AxesArg {
    fn from(a: Axes) -> Self {
        Self::from_str(a.name(), false).expect("the library's names are the command line's")
    }
}

impl From<AxesArg> for Axes {
    fn from(a: AxesArg) -> Self {
        let value = a.to_possible_value().expect("every value is named");
        value
            .get_name()
            .parse()
            .expect("the command line's names are the library's")
    }
}

/// `sahkd::Counting` as a command-line value.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum CountingArg {
    /// The paper's walk of an interval tree over the sorted primitives
    SpaceTree,
    /// Segmented prefix sums over sorted start/end events
    Scan,
}

impl From<Counting> for CountingArg {
    fn from(a: Counting) -> Self {
        Self::from_str(a.name(), false).expect("the library's names are the command line's")
    }
}

impl From<CountingArg> for Counting {
    fn from(a: CountingArg) -> Self {
        let value = a.to_possible_value().expect("every value is named");
        value
            .get_name()
            .parse()
            .expect("the command line's names are the library's")
    }
}

/// An on/off flag that takes a value, so that a default of `on` can be turned off.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Switch {
    On,
    Off,
}

impl From<bool> for Switch {
    fn from(b: bool) -> Self {
        if b {
            Self::On
        } else {
            Self::Off
        }
    }
}

impl From<Switch> for bool {
    fn from(s: Switch) -> Self {
        s == Switch::On
    }
}

/// The kebab-case names the command line uses, for reports.
pub fn algorithm_name(a: Algorithm) -> &'static str {
    a.name()
}

pub fn axes_name(a: Axes) -> &'static str {
    a.name()
}

pub fn counting_name(c: Counting) -> &'static str {
    c.name()
}

pub fn switch_name(b: bool) -> &'static str {
    if b {
        "on"
    } else {
        "off"
    }
}

/// A depth limit, `None` for the library's automatic one.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MaxDepth(pub Option<u32>);

impl fmt::Display for MaxDepth {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.0 {
            Some(d) => write!(f, "{d}"),
            None => f.write_str("auto"),
        }
    }
}

fn parse_max_depth(s: &str) -> Result<MaxDepth, String> {
    if s == "auto" {
        return Ok(MaxDepth(None));
    }
    s.parse::<u32>()
        .map(|d| MaxDepth(Some(d)))
        .map_err(|_| format!("expected a whole number or `auto`, found `{s}`"))
}

/// A thread count within the library's rule (`sahkd::threads`), as every command takes it.
pub fn parse_threads(s: &str) -> Result<usize, String> {
    match s.trim().parse::<usize>() {
        Ok(n) => sahkd::threads::check(n),
        Err(_) => Err(format!("expected a number of threads, found `{s}`")),
    }
}

/// A number of bins, in the range the library's `BuildOptions::validate` allows.
fn parse_bins(s: &str) -> Result<u32, String> {
    let bins = s
        .trim()
        .parse::<u32>()
        .map_err(|_| format!("expected 0 or a number of bins, found `{s}`"))?;
    let options = BuildOptions {
        algorithm: Algorithm::Sweep,
        bins: Some(bins),
        ..BuildOptions::default()
    };
    match options.validate() {
        Ok(()) => Ok(bins),
        Err(sahkd::builders::BuildError::InvalidOptions(m)) => Err(m),
        Err(e) => Err(e.to_string()),
    }
}

fn parse_finite(s: &str) -> Result<f32, String> {
    match s.parse::<f32>() {
        Ok(x) if x.is_finite() => Ok(x),
        _ => Err(format!("expected a finite number, found `{s}`")),
    }
}

fn parse_non_negative(s: &str) -> Result<f32, String> {
    let x = parse_finite(s)?;
    if x >= 0.0 {
        Ok(x)
    } else {
        Err(format!("must not be negative, found {x}"))
    }
}

fn parse_positive(s: &str) -> Result<f32, String> {
    let x = parse_finite(s)?;
    if x > 0.0 {
        Ok(x)
    } else {
        Err(format!("must be greater than 0, found {x}"))
    }
}

fn parse_unit_interval(s: &str) -> Result<f32, String> {
    let x = parse_finite(s)?;
    if x > 0.0 && x <= 1.0 {
        Ok(x)
    } else {
        Err(format!("must be in (0, 1], found {x}"))
    }
}

fn parse_at_least_one(s: &str) -> Result<f32, String> {
    let x = parse_finite(s)?;
    if x >= 1.0 {
        Ok(x)
    } else {
        Err(format!("must be at least 1, found {x}"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    /// The value enums only add help texts: their names are the library's, all of them.
    #[test]
    fn value_names_are_the_librarys() {
        let names = |values: &[clap::builder::PossibleValue]| -> Vec<String> {
            values.iter().map(|v| v.get_name().to_string()).collect()
        };
        let cli: Vec<_> = AlgorithmArg::value_variants()
            .iter()
            .map(|v| v.to_possible_value().unwrap())
            .collect();
        assert_eq!(names(&cli), Algorithm::NAMES);
        let cli: Vec<_> = AxesArg::value_variants()
            .iter()
            .map(|v| v.to_possible_value().unwrap())
            .collect();
        assert_eq!(names(&cli), Axes::NAMES);
        let cli: Vec<_> = CountingArg::value_variants()
            .iter()
            .map(|v| v.to_possible_value().unwrap())
            .collect();
        assert_eq!(names(&cli), Counting::NAMES);
    }

    #[derive(Parser)]
    struct Wrapper {
        #[command(flatten)]
        builder: BuilderArgs,
    }

    fn parse(args: &[&str]) -> Result<BuildOptions, clap::Error> {
        let argv = std::iter::once("test").chain(args.iter().copied());
        Wrapper::try_parse_from(argv).map(|w| w.builder.build_options())
    }

    #[test]
    fn no_flags_give_the_library_defaults() {
        assert_eq!(parse(&[]).unwrap(), BuildOptions::default());
    }

    #[test]
    fn every_flag_reaches_the_options() {
        let o = parse(&[
            "--algorithm=sweep",
            "--axes=all",
            "--counting=space-tree",
            "--clip=off",
            "--threads=3",
            "--kt=1.5",
            "--ki=2.5",
            "--empty-bonus=1",
            "--leaf-size=4",
            "--max-depth=12",
            "--max-duplication=2",
            "--large-node=16",
            "--bins=64",
        ])
        .unwrap();
        let expected = BuildOptions {
            algorithm: Algorithm::Sweep,
            axes: Axes::All,
            counting: Counting::SpaceTree,
            clip: false,
            threads: Some(3),
            cost: CostModel {
                traversal: 1.5,
                intersection: 2.5,
                empty_bonus: 1.0,
                leaf_size: 4,
                max_depth: Some(12),
                max_duplication: 2.0,
            },
            median_large_node: 16,
            bins: Some(64),
        };
        assert_eq!(o, expected);
        assert_eq!(
            parse(&["--max-depth", "auto"]).unwrap().cost.max_depth,
            None
        );
    }

    #[test]
    fn bad_values_are_usage_errors() {
        for bad in [
            &["--threads", "0"][..],
            &["--threads", "many"],
            &["--threads", "100000"],
            &["--algorithm", "quick"],
            &["--clip", "yes"],
            &["--kt", "-1"],
            &["--ki", "0"],
            &["--ki", "nan"],
            &["--empty-bonus", "1.5"],
            &["--max-duplication", "0.5"],
            &["--max-depth", "deep"],
            &["--leaf-size", "-2"],
            &["--large-node", "-1"],
            &["--bins", "1"],
            &["--bins", "-4"],
            &["--bins", "1025"],
            &["--bins", "many"],
        ] {
            assert!(parse(bad).is_err(), "{bad:?} was accepted");
        }
    }
}
