//! Every parameter of a build, with its defaults, its names and its valid ranges, in one
//! place: the command line and Python take names and ranges from here.

use super::BuildError;
use crate::cost::{CostModel, MAX_DEPTH_CAP};
use serde::{Deserialize, Serialize};
use std::fmt;
use std::str::FromStr;

/// Which builder to run.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Algorithm {
    /// Parallel at the top of the tree, then each node's subtree by the sweep on one worker:
    /// the sweep's tree with the same bins, on every core. With bins (256 unless set) the top
    /// is the binned search, the two children of each node built at once; with `bins` 0 it
    /// is the paper's level passes.
    #[default]
    Hybrid,
    /// Wald & Havran 2006: serial, exact SAH over sorted events, O(N log N).
    Sweep,
    /// Li, Tan & Liao: breadth-first, every candidate of a level priced in parallel.
    Level,
    /// The level framework with brute-force counting, O(n) per candidate.
    Naive,
    /// The paper's reference \[14\]: Zhou, Hou, Wang & Guo 2008 as implemented by Chang, Seo &
    /// Ihm 2015. Breadth-first; large nodes cut off empty space or split at the spatial
    /// median, small nodes get exact SAH.
    Median,
}

/// Which axes a node's candidates come from.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Axes {
    /// The node's longest axis only (the paper's choice).
    #[default]
    Longest,
    /// All three axes, as exact SAH builders do.
    All,
}

/// How the level builder counts the primitives on each side of a candidate.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Counting {
    /// The paper's walk of the implicit interval tree over the lo-sorted list.
    SpaceTree,
    /// Segmented prefix sums over sorted start/end events.
    #[default]
    Scan,
}

/// A named starting point for [`BuildOptions`], chosen by how many rays the tree will trace:
/// options given beside a preset override its own. [`Preset::options`] gives its options,
/// which remember the preset they came from (`BuildOptions::preset`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Preset {
    /// The quickest build of a tree that still traces well: few rays per build.
    Fast,
    /// The default: the least build time plus the time of a million rays of a mixed set
    /// (primary, shadow, AO, bounce) on the meshes measured: triangle boxes, K_T 60, 256
    /// bins.
    #[default]
    Balanced,
    /// Exact SAH over all three axes with perfect splits: many rays per build.
    Quality,
    /// The paper's own configuration: the level builder, longest axis, triangle boxes.
    Paper,
    /// The serial Wald–Havran sweep, exact SAH: the reference the other builders are
    /// checked against.
    Sweep,
}

impl Preset {
    /// The preset's options (threads unset: every core).
    pub fn options(self) -> BuildOptions {
        let balanced = BuildOptions::default();
        let options = match self {
            Preset::Balanced => balanced,
            Preset::Fast => BuildOptions {
                bins: Some(FAST_BINS),
                cost: CostModel {
                    leaf_size: FAST_LEAF_SIZE,
                    traversal: FAST_TRAVERSAL,
                    ..balanced.cost
                },
                ..balanced
            },
            Preset::Quality => BuildOptions {
                axes: Axes::All,
                clip: true,
                bins: Some(0),
                ..balanced
            },
            Preset::Paper => BuildOptions {
                algorithm: Algorithm::Level,
                axes: Axes::Longest,
                ..balanced
            },
            Preset::Sweep => BuildOptions {
                algorithm: Algorithm::Sweep,
                ..balanced
            },
        };
        BuildOptions {
            preset: Some(self),
            ..options
        }
    }
}

/// The `fast` preset's bins: binned down to `BINNED_REFS_PER_BIN * FAST_BINS` references.
pub const FAST_BINS: u32 = 64;
/// The `fast` preset's leaf size: nodes this small become leaves unpriced.
pub const FAST_LEAF_SIZE: u32 = 2;
/// The `fast` preset's `K_T`: a dearer node step gives a shallower tree with fuller leaves,
/// which the wide nodes rays walk open into boxed blocks of four. Against `balanced`'s 60
/// (BENCHMARKS.md, "The fast preset"): half the nodes, 0.69-0.85x the build time, rays
/// 0.86-1.09x `balanced`'s.
pub const FAST_TRAVERSAL: f32 = 120.0;

/// Everything that decides a build. Same options and input give the same tree, whatever the
/// number of threads. Fields missing from serialized options take their defaults, so options
/// saved before a field existed still load.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct BuildOptions {
    pub algorithm: Algorithm,
    pub axes: Axes,
    pub counting: Counting,
    /// Clip straddling triangles to each child ("perfect splits"); off (the default) uses
    /// the triangles' boxes, as the paper does. The wide nodes rays walk hold the triangles
    /// clipped to their cells either way, so clipping in the build buys rays little for its
    /// time (BENCHMARKS.md, "Choosing `balanced`").
    pub clip: bool,
    /// Worker threads; `None` uses rayon's global pool (every core).
    pub threads: Option<usize>,
    pub cost: CostModel,
    /// Median builder only: nodes with more primitives than this are "large" (empty-space
    /// cut or spatial median split); the others get exact SAH.
    pub median_large_node: u32,
    /// Min-max binning, for the sweep and hybrid builders: `Some(0)` prices every candidate
    /// exactly; `Some(N)` (2 to [`MAX_BINS`]) prices only the `N - 1` bin boundaries of nodes
    /// holding more than [`BINNED_REFS_PER_BIN`]` * N` references, and exactly below that;
    /// `None` takes the builder's default ([`BuildOptions::resolved_bins`]). Left out of
    /// saved options when `None`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub bins: Option<u32>,
    /// The preset these options started from, before any option given beside it: a label for
    /// reports and saved trees, which decides nothing itself. `None` in options saved before
    /// presets existed, and left out of saved options then.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub preset: Option<Preset>,
}

/// The bins of a hybrid build whose options leave `bins` unset. Measured on bunny,
/// dragon_res2 and dragon (BENCHMARKS.md, "Binned SAH for the big nodes"): 0-23 % less build time,
/// a third of the working memory, SAH cost within 0.35 % of exact and a modelled ray cost
/// within 0.3 %; the exact sweep still prices every node of 16,384 references or fewer.
pub const HYBRID_BINS: u32 = 256;

/// The most bins `BuildOptions::bins` takes. Beyond it the binned threshold
/// (`BINNED_REFS_PER_BIN * bins`, 65,536 here) leaves only the very top of a tree to the
/// binning, and the exact sweep does better there.
pub const MAX_BINS: u32 = 1024;

/// A node is binned when it holds more than this many references per bin: then each bin
/// holds many references' ends on average, so the cost between two boundaries varies little
/// and the best boundary prices close to the best exact plane, while below it the exact sweep
/// is cheap anyway (at 64 bins: binned above 4,096 references).
pub const BINNED_REFS_PER_BIN: usize = 64;

impl Default for BuildOptions {
    fn default() -> Self {
        BuildOptions {
            algorithm: Algorithm::default(),
            axes: Axes::default(),
            counting: Counting::default(),
            clip: false,
            threads: None,
            cost: CostModel::default(),
            median_large_node: 64,
            bins: None,
            preset: Some(Preset::Balanced),
        }
    }
}

impl BuildOptions {
    /// The bins this build uses: `bins` when set, else [`HYBRID_BINS`] for the hybrid and
    /// 0 (exact SAH) for every other builder, so the sweep stays the exact reference.
    pub fn resolved_bins(&self) -> u32 {
        match (self.bins, self.algorithm) {
            (Some(bins), _) => bins,
            (None, Algorithm::Hybrid) => HYBRID_BINS,
            (None, _) => 0,
        }
    }

    /// The `fast` preset ([`Preset::Fast`]).
    pub fn fast() -> Self {
        Preset::Fast.options()
    }
    /// The `balanced` preset, the default ([`Preset::Balanced`]).
    pub fn balanced() -> Self {
        Preset::Balanced.options()
    }
    /// The `quality` preset: exact SAH over all three axes with perfect splits.
    pub fn quality() -> Self {
        Preset::Quality.options()
    }
    /// The `paper` preset: the paper's builder with its own choices (longest axis, triangle
    /// boxes).
    pub fn paper() -> Self {
        Preset::Paper.options()
    }
    /// The `sweep` preset: the serial reference builder.
    pub fn sweep() -> Self {
        Preset::Sweep.options()
    }
}

/// The names of an option's values: `Display` writes them, `FromStr` reads them (case and
/// `_`/`-` insensitive), and `NAMES` lists them for help texts and errors.
macro_rules! named_values {
    ($ty:ident, $what:literal, $($variant:ident => $name:literal),+ $(,)?) => {
        impl $ty {
            /// Every value, in the order of `NAMES`.
            pub const ALL: &'static [$ty] = &[$($ty::$variant),+];
            /// The names of the values, as the command line and Python spell them.
            pub const NAMES: &'static [&'static str] = &[$($name),+];
            pub fn name(self) -> &'static str {
                match self {
                    $($ty::$variant => $name),+
                }
            }
        }
        impl fmt::Display for $ty {
            fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                f.write_str(self.name())
            }
        }
        impl FromStr for $ty {
            type Err = String;
            fn from_str(s: &str) -> Result<Self, String> {
                let key = s.trim().to_ascii_lowercase().replace('_', "-");
                $ty::ALL.iter().copied().find(|v| v.name() == key).ok_or_else(|| {
                    format!(
                        "unknown {} `{s}`: expected one of {}",
                        $what,
                        $ty::NAMES.join(", ")
                    )
                })
            }
        }
    };
}

named_values!(Algorithm, "algorithm",
    Hybrid => "hybrid", Sweep => "sweep", Level => "level", Naive => "naive", Median => "median");
named_values!(Axes, "axes", Longest => "longest", All => "all");
named_values!(Counting, "counting", SpaceTree => "space-tree", Scan => "scan");
named_values!(Preset, "preset",
    Fast => "fast", Balanced => "balanced", Quality => "quality", Paper => "paper", Sweep => "sweep");

impl BuildOptions {
    /// What [`validate`](Self::validate) says of a `bins` out of range; front ends whose
    /// numbers can be negative say the same of values a `u32` cannot hold.
    pub fn bins_out_of_range(got: impl std::fmt::Display) -> String {
        format!("bins must be 0 (exact SAH) or from 2 to {MAX_BINS}, got {got}")
    }

    /// Checks every parameter's range, naming the first one out of it. `build` and
    /// `build_triangles` call it; front ends may call it early.
    pub fn validate(&self) -> Result<(), BuildError> {
        let bad = |m: String| Err(BuildError::InvalidOptions(m));
        let c = &self.cost;
        if !(c.traversal.is_finite() && c.traversal >= 0.0) {
            return bad(format!(
                "traversal cost (K_T) must be a finite number of at least 0, got {}",
                c.traversal
            ));
        }
        if !(c.intersection.is_finite() && c.intersection > 0.0) {
            return bad(format!(
                "intersection cost (K_I) must be a finite number above 0, got {}",
                c.intersection
            ));
        }
        if !(c.empty_bonus > 0.0 && c.empty_bonus <= 1.0) {
            return bad(format!(
                "empty_bonus must be in (0, 1] (1 disables the bonus), got {}",
                c.empty_bonus
            ));
        }
        if !(c.max_duplication.is_finite() && c.max_duplication >= 1.0) {
            return bad(format!(
                "max_duplication must be a finite number of at least 1, got {}",
                c.max_duplication
            ));
        }
        if let Some(d) = c.max_depth.filter(|&d| d > MAX_DEPTH_CAP) {
            return bad(format!(
                "max_depth must be at most {MAX_DEPTH_CAP}, got {d}"
            ));
        }
        if let Some(n) = self.threads {
            crate::threads::check(n)
                .map_err(|e| BuildError::InvalidOptions(format!("threads: {e}")))?;
        }
        if let Some(bins) = self.bins.filter(|&b| b != 0) {
            if bins == 1 || bins > MAX_BINS {
                return bad(Self::bins_out_of_range(bins));
            }
            if !matches!(self.algorithm, Algorithm::Sweep | Algorithm::Hybrid) {
                return bad(format!(
                    "bins works with the sweep and hybrid builders only, not {} (use bins 0)",
                    self.algorithm
                ));
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_read_back_and_bad_names_list_the_good_ones() {
        for &a in Algorithm::ALL {
            assert_eq!(a.to_string().parse::<Algorithm>(), Ok(a));
        }
        for &a in Axes::ALL {
            assert_eq!(a.to_string().parse::<Axes>(), Ok(a));
        }
        assert_eq!("SPACE_TREE".parse::<Counting>(), Ok(Counting::SpaceTree));
        let err = "quick".parse::<Algorithm>().unwrap_err();
        assert!(err.contains("quick") && err.contains("hybrid, sweep, level, naive, median"));
    }

    #[test]
    fn validate_names_the_parameter_out_of_range() {
        assert!(BuildOptions::default().validate().is_ok());
        let with = |cost: CostModel| BuildOptions {
            cost,
            ..BuildOptions::default()
        };
        let base = CostModel::default();
        for (options, word) in [
            (
                with(CostModel {
                    empty_bonus: 5.0,
                    ..base
                }),
                "empty_bonus",
            ),
            (
                with(CostModel {
                    empty_bonus: 0.0,
                    ..base
                }),
                "empty_bonus",
            ),
            (
                with(CostModel {
                    traversal: -1.0,
                    ..base
                }),
                "K_T",
            ),
            (
                with(CostModel {
                    intersection: 0.0,
                    ..base
                }),
                "K_I",
            ),
            (
                with(CostModel {
                    intersection: f32::NAN,
                    ..base
                }),
                "K_I",
            ),
            (
                with(CostModel {
                    max_duplication: 0.5,
                    ..base
                }),
                "max_duplication",
            ),
            (
                with(CostModel {
                    max_depth: Some(61),
                    ..base
                }),
                "max_depth",
            ),
            (
                BuildOptions {
                    threads: Some(0),
                    ..BuildOptions::default()
                },
                "threads",
            ),
            (
                BuildOptions {
                    bins: Some(1),
                    ..BuildOptions::default()
                },
                "bins",
            ),
            (
                BuildOptions {
                    bins: Some(MAX_BINS + 1),
                    ..BuildOptions::default()
                },
                "bins",
            ),
            (
                BuildOptions {
                    algorithm: Algorithm::Level,
                    bins: Some(16),
                    ..BuildOptions::default()
                },
                "bins",
            ),
        ] {
            let err = options.validate().unwrap_err().to_string();
            assert!(err.contains(word), "{err} should name {word}");
        }
    }
}
