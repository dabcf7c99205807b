//! The builder options shared by every command that builds a tree.
//!
//! Defaults are read from `sahkd::BuildOptions::default()` and `sahkd::CostModel::default()`,
//! so the library stays the one place that decides them; the command line only shows them.

use crate::gpu::GpuReport;
use anyhow::{Context, Result};
use clap::builder::{PossibleValuesParser, TypedValueParser};
use clap::{Args, ValueEnum};
use sahkd::{Algorithm, Axes, Build, BuildOptions, CostModel, Counting, Mesh, Preset};
use std::fmt;
use std::str::FromStr;

/// A value of one of the library's named types, by the library's names (`NAMES`, `FromStr`):
/// the help lists them and a bad name is a usage error listing them.
pub fn named<T>(names: &'static [&'static str]) -> impl TypedValueParser<Value = T>
where
    T: FromStr + Clone + Send + Sync + 'static,
    T::Err: fmt::Debug,
{
    PossibleValuesParser::new(names.iter().copied()).map(|s: String| {
        s.parse::<T>()
            .expect("the parser only lets the library's own names through")
    })
}

/// How to build a tree: a preset, and any of its options overridden; the threads. Every
/// option left out takes the preset's value (`balanced` without `--preset`).
#[derive(Args, Clone, Debug)]
#[command(next_help_heading = "Builder options")]
pub struct BuilderArgs {
    /// Where the level builder runs: the CPU, or a GPU through wgpu (Vulkan, Metal, DX12;
    /// level builder only)
    #[arg(long, value_enum, value_name = "DEVICE", default_value_t = DeviceArg::Cpu)]
    pub device: DeviceArg,

    /// Named options, by how many rays the tree will trace: fast, balanced (the default),
    /// quality; paper (the paper's level builder) and sweep (the serial reference). The
    /// options below, when given, override the preset's
    #[arg(long, value_name = "NAME", value_parser = named::<Preset>(Preset::NAMES))]
    pub preset: Option<Preset>,

    /// Tree builder [default: the preset's; level with --device gpu]
    #[arg(long, value_name = "NAME", value_parser = named::<Algorithm>(Algorithm::NAMES))]
    pub algorithm: Option<Algorithm>,

    /// Axes a node's split candidates come from [default: the preset's]
    #[arg(long, value_name = "WHICH", value_parser = named::<Axes>(Axes::NAMES))]
    pub axes: Option<Axes>,

    /// How the level builder counts primitives on each side of a candidate [default: the
    /// preset's]
    #[arg(long, value_name = "HOW", value_parser = named::<Counting>(Counting::NAMES))]
    pub counting: Option<Counting>,

    /// Clip straddling triangles to each child (perfect splits) [default: the preset's]
    #[arg(long, value_enum, value_name = "ON|OFF")]
    pub clip: Option<Switch>,

    /// Median builder: nodes with more triangles than this are split at the spatial median
    /// (or cut off empty space); smaller ones get exact SAH [default: the preset's]
    #[arg(long, value_name = "N", allow_negative_numbers = true)]
    pub large_node: Option<u32>,

    /// Sweep and hybrid builders: price nodes of more than 64 x N triangle references at the
    /// N - 1 boundaries of N equal bins (min-max binning), the others exactly; 0 prices every
    /// node exactly [default: the preset's; 256 for hybrid, 0 for sweep]
    #[arg(long, value_name = "N", allow_negative_numbers = true,
          value_parser = rule(|o, v| o.bins = Some(v)))]
    pub bins: Option<u32>,

    /// Worker threads for building and tracing, at most 4 per core (64 on any machine)
    /// [default: all cores]
    #[arg(long, value_name = "N", allow_negative_numbers = true, value_parser = parse_threads)]
    pub threads: Option<usize>,

    /// SAH cost of traversing an interior node (K_T) [default: the preset's]
    #[arg(long, value_name = "COST", allow_negative_numbers = true,
          value_parser = rule(|o, v| o.cost.traversal = v))]
    pub kt: Option<f32>,

    /// SAH cost of one ray/triangle test (K_I) [default: the preset's]
    #[arg(long, value_name = "COST", allow_negative_numbers = true,
          value_parser = rule(|o, v| o.cost.intersection = v))]
    pub ki: Option<f32>,

    /// Factor on the cost of a split that leaves one side empty (1 disables the bonus)
    /// [default: the preset's]
    #[arg(long, value_name = "FACTOR", allow_negative_numbers = true,
          value_parser = rule(|o, v| o.cost.empty_bonus = v))]
    pub empty_bonus: Option<f32>,

    /// Nodes with this many triangles or fewer become leaves [default: the preset's]
    #[arg(long, value_name = "N", allow_negative_numbers = true)]
    pub leaf_size: Option<u32>,

    /// Depth limit, or `auto` for 8 + 1.3 log2(triangles) [default: the preset's]
    #[arg(long, value_name = "DEPTH|auto", allow_negative_numbers = true,
          value_parser = parse_max_depth)]
    pub max_depth: Option<MaxDepth>,

    /// Stop splitting once references reach this many times the triangle count [default:
    /// the preset's]
    #[arg(long, value_name = "FACTOR", allow_negative_numbers = true,
          value_parser = rule(|o, v| o.cost.max_duplication = v))]
    pub max_duplication: Option<f32>,
}

impl BuilderArgs {
    /// The library's options for these arguments: the preset's, with every option given
    /// beside it in its place (`threads` as given, `None` for all cores).
    pub fn build_options(&self) -> BuildOptions {
        let base = self.preset.unwrap_or_default().options();
        // The GPU runs the level builder only: there it is the default.
        let algorithm = match (self.algorithm, self.device) {
            (Some(a), _) => a,
            (None, DeviceArg::Gpu) => Algorithm::Level,
            (None, DeviceArg::Cpu) => base.algorithm,
        };
        let c = base.cost;
        BuildOptions {
            algorithm,
            axes: self.axes.unwrap_or(base.axes),
            counting: self.counting.unwrap_or(base.counting),
            clip: self.clip.map_or(base.clip, bool::from),
            threads: self.threads,
            cost: CostModel {
                traversal: self.kt.unwrap_or(c.traversal),
                intersection: self.ki.unwrap_or(c.intersection),
                empty_bonus: self.empty_bonus.unwrap_or(c.empty_bonus),
                leaf_size: self.leaf_size.unwrap_or(c.leaf_size),
                max_depth: self.max_depth.map_or(c.max_depth, |d| d.0),
                max_duplication: self.max_duplication.unwrap_or(c.max_duplication),
            },
            median_large_node: self.large_node.unwrap_or(base.median_large_node),
            bins: self.bins.or(base.bins),
            preset: base.preset,
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
    let depth = s
        .parse::<u32>()
        .map_err(|_| format!("expected a whole number or `auto`, found `{s}`"))?;
    rule(|o, d| o.cost.max_depth = Some(d))(s).map(|_: u32| MaxDepth(Some(depth)))
}

/// A thread count within the library's rule (`sahkd::threads`), as every command takes it.
pub fn parse_threads(s: &str) -> Result<usize, String> {
    match s.trim().parse::<usize>() {
        Ok(n) => sahkd::threads::check(n),
        Err(_) => Err(format!("expected a number of threads, found `{s}`")),
    }
}

/// A number for one option, checked by the library's own rule for it (`BuildOptions::validate`
/// of the default options with this one value set), so that a value out of range is a usage
/// error naming the flag, in the library's words.
fn rule<T>(set: fn(&mut BuildOptions, T)) -> impl Fn(&str) -> Result<T, String> + Clone
where
    T: FromStr + Copy,
{
    move |s: &str| {
        let v = s
            .trim()
            .parse::<T>()
            .map_err(|_| format!("expected a number, found `{s}`"))?;
        let mut options = BuildOptions {
            // The builder that takes every option's range (bins too).
            algorithm: Algorithm::Sweep,
            ..BuildOptions::default()
        };
        set(&mut options, v);
        match options.validate() {
            Ok(()) => Ok(v),
            Err(sahkd::builders::BuildError::InvalidOptions(m)) => Err(m),
            Err(e) => Err(e.to_string()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    /// The command line's names are the library's, all of them.
    #[test]
    fn value_names_are_the_librarys() {
        let names = |arg: &str| -> Vec<String> {
            let command = <Wrapper as clap::CommandFactory>::command();
            let a = command.get_arguments().find(|a| a.get_id() == arg).unwrap();
            a.get_possible_values()
                .iter()
                .map(|v| v.get_name().to_string())
                .collect()
        };
        assert_eq!(names("algorithm"), Algorithm::NAMES);
        assert_eq!(names("axes"), Axes::NAMES);
        assert_eq!(names("counting"), Counting::NAMES);
        assert_eq!(names("preset"), Preset::NAMES);
    }

    #[test]
    fn presets_are_the_librarys_and_options_beside_them_override() {
        for &p in Preset::ALL {
            assert_eq!(parse(&["--preset", p.name()]).unwrap(), p.options());
        }
        let o = parse(&["--preset", "fast", "--clip", "on", "--kt", "7"]).unwrap();
        let fast = BuildOptions::fast();
        let want = BuildOptions {
            clip: true,
            cost: CostModel {
                traversal: 7.0,
                ..fast.cost
            },
            ..fast
        };
        assert_eq!(o, want);
        let err = parse(&["--preset", "fastest"]).unwrap_err().to_string();
        assert!(
            err.contains("fastest") && err.contains("fast, balanced, quality, paper, sweep"),
            "{err}"
        );
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
            preset: Some(Preset::Balanced),
        };
        assert_eq!(o, expected);
        assert_eq!(
            parse(&["--max-depth", "auto"]).unwrap().cost.max_depth,
            None
        );
    }

    /// Each option at the library's edges: the command line accepts exactly what the
    /// library's `validate` accepts.
    #[test]
    fn options_at_their_edges_get_the_librarys_answer() {
        type Set = fn(&mut BuildOptions);
        let cases: [(&[&str], Set); 18] = [
            (&["--kt", "0"], |o| o.cost.traversal = 0.0),
            (&["--kt", "-0.000001"], |o| o.cost.traversal = -0.000001),
            (&["--ki", "0.000001"], |o| o.cost.intersection = 0.000001),
            (&["--ki", "0"], |o| o.cost.intersection = 0.0),
            (&["--empty-bonus", "1"], |o| o.cost.empty_bonus = 1.0),
            (&["--empty-bonus", "0"], |o| o.cost.empty_bonus = 0.0),
            (&["--max-duplication", "1"], |o| {
                o.cost.max_duplication = 1.0
            }),
            (&["--max-duplication", "0.999"], |o| {
                o.cost.max_duplication = 0.999
            }),
            (&["--max-depth", "60"], |o| o.cost.max_depth = Some(60)),
            (&["--max-depth", "61"], |o| o.cost.max_depth = Some(61)),
            (&["--threads", "1"], |o| o.threads = Some(1)),
            (&["--threads", "0"], |o| o.threads = Some(0)),
            (&["--bins", "0"], |o| o.bins = Some(0)),
            (&["--bins", "1"], |o| o.bins = Some(1)),
            (&["--bins", "1024"], |o| o.bins = Some(1024)),
            (&["--bins", "1025"], |o| o.bins = Some(1025)),
            (&["--algorithm", "level", "--bins", "0"], |o| {
                o.algorithm = Algorithm::Level;
                o.bins = Some(0)
            }),
            (&["--algorithm", "level", "--bins", "2"], |o| {
                o.algorithm = Algorithm::Level;
                o.bins = Some(2)
            }),
        ];
        for (args, set) in cases {
            let mut library = BuildOptions::default();
            set(&mut library);
            let want = library.validate().is_ok();
            // What a command does with them: parse, then the builder's check before any input.
            let got = parse(args).is_ok_and(|o| Builder::new(o).is_ok());
            assert_eq!(
                got, want,
                "{args:?}: the command line and the library disagree"
            );
        }
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

/// The build options as the JSON reports of `build` and `info` show them (flattened into
/// each): names from the library, the bins the build used.
#[derive(serde::Serialize, Debug)]
pub struct OptionsReport {
    /// The preset the options started from (options given beside it override it; none in
    /// files from before presets).
    pub preset: Option<&'static str>,
    pub algorithm: &'static str,
    pub axes: &'static str,
    pub counting: &'static str,
    pub clip: bool,
    /// Bins of the binned SAH for big nodes; 0: exact SAH everywhere.
    pub bins: u32,
}

impl OptionsReport {
    pub fn of(o: &BuildOptions) -> OptionsReport {
        OptionsReport {
            preset: o.preset.map(|p| p.name()),
            algorithm: o.algorithm.name(),
            axes: o.axes.name(),
            counting: o.counting.name(),
            clip: o.clip,
            bins: o.resolved_bins(),
        }
    }
}
