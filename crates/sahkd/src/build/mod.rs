//! Builders: from triangles to a [`KdTree`].
//!
//! All build parameters live in [`BuildOptions`], with their defaults in one place. Every
//! builder takes the same [`Primitives`] and returns the same [`BuiltTree`]; [`build`] picks
//! the builder, runs it on a thread pool of the requested size, and times it.

mod level;
mod median;
mod report;
mod sweep;

pub use report::{BuildReport, LevelReport, PhaseTimes};

use crate::cost::CostModel;
use crate::geometry::{triangle_bounds, Aabb, Triangle};
use crate::mesh::{Mesh, MeshError};
use crate::tree::{KdTree, Node};
use serde::{Deserialize, Serialize};
use std::fmt;
use std::time::Instant;

/// Which builder to run.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Algorithm {
    /// Wald & Havran 2006: serial, exact SAH over sorted events, O(N log N).
    Sweep,
    /// Li, Tan & Liao: breadth-first, every candidate of a level priced in parallel.
    #[default]
    Level,
    /// The level framework with brute-force counting, O(n) per candidate.
    Naive,
    /// The paper's reference [14]: Zhou, Hou, Wang & Guo 2008 as implemented by Chang, Seo &
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

/// Everything that decides a build. Same options and input give the same tree, whatever the
/// number of threads. Fields missing from serialized options take their defaults, so options
/// saved before a field existed still load.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct BuildOptions {
    pub algorithm: Algorithm,
    pub axes: Axes,
    pub counting: Counting,
    /// Clip straddling triangles to each child ("perfect splits"); off uses the triangles'
    /// boxes, as the paper does.
    pub clip: bool,
    /// Worker threads; `None` uses rayon's global pool (every core).
    pub threads: Option<usize>,
    pub cost: CostModel,
    /// Median builder only: nodes with more primitives than this are "large" (empty-space
    /// cut or spatial median split); the others get exact SAH.
    pub median_large_node: u32,
}

impl Default for BuildOptions {
    fn default() -> Self {
        BuildOptions {
            algorithm: Algorithm::default(),
            axes: Axes::default(),
            counting: Counting::default(),
            clip: true,
            threads: None,
            cost: CostModel::default(),
            median_large_node: 64,
        }
    }
}

impl BuildOptions {
    /// The paper's builder with its own choices: longest axis, triangle boxes.
    pub fn paper() -> Self {
        BuildOptions {
            algorithm: Algorithm::Level,
            axes: Axes::Longest,
            clip: false,
            ..Self::default()
        }
    }
    /// The best trees: exact SAH over all three axes with perfect splits.
    pub fn quality() -> Self {
        BuildOptions {
            axes: Axes::All,
            clip: true,
            ..Self::default()
        }
    }
    /// The serial reference builder.
    pub fn sweep() -> Self {
        BuildOptions {
            algorithm: Algorithm::Sweep,
            ..Self::default()
        }
    }
}

/// Why a build could not run.
#[derive(Debug)]
pub enum BuildError {
    InvalidMesh(MeshError),
    InvalidOptions(String),
}

impl fmt::Display for BuildError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            BuildError::InvalidMesh(e) => write!(f, "invalid mesh: {e}"),
            BuildError::InvalidOptions(m) => write!(f, "invalid build options: {m}"),
        }
    }
}

impl std::error::Error for BuildError {}

/// The input every builder sees: triangles, their boxes and the scene box.
pub(crate) struct Primitives<'a> {
    pub triangles: &'a [Triangle],
    pub boxes: Vec<Aabb>,
    pub bounds: Aabb,
}

/// What every builder returns: nodes with node 0 the root, and the leaves' references.
#[derive(Default)]
pub(crate) struct BuiltTree {
    pub nodes: Vec<Node>,
    pub refs: Vec<u32>,
    pub report: BuildReport,
}

/// A tree and how its build went.
pub struct Build {
    pub tree: KdTree,
    pub report: BuildReport,
}

/// Validates the mesh and builds its tree.
pub fn build(mesh: &Mesh, options: &BuildOptions) -> Result<Build, BuildError> {
    mesh.validate().map_err(BuildError::InvalidMesh)?;
    build_triangles(mesh.corner_triangles(), options)
}

/// Builds the tree of a triangle list (corners must be finite).
pub fn build_triangles(
    triangles: Vec<Triangle>,
    options: &BuildOptions,
) -> Result<Build, BuildError> {
    if let Some((i, _)) = triangles
        .iter()
        .enumerate()
        .find(|(_, t)| !t.iter().all(|v| v.is_finite()))
    {
        return Err(BuildError::InvalidOptions(format!(
            "triangle {i} has a non-finite corner"
        )));
    }
    if triangles.len() > Node::MAX_INDEX as usize {
        return Err(BuildError::InvalidOptions(format!(
            "{} triangles is more than the {} a tree can hold",
            triangles.len(),
            Node::MAX_INDEX
        )));
    }
    match options.threads {
        Some(0) => Err(BuildError::InvalidOptions(
            "threads must be at least 1".into(),
        )),
        Some(n) => {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(n)
                .build()
                .map_err(|e| {
                    BuildError::InvalidOptions(format!("cannot start {n} threads: {e}"))
                })?;
            Ok(pool.install(|| run(triangles, options)))
        }
        None => Ok(run(triangles, options)),
    }
}

fn run(triangles: Vec<Triangle>, options: &BuildOptions) -> Build {
    let start = Instant::now();
    if triangles.is_empty() {
        return Build {
            tree: KdTree::empty(),
            report: BuildReport::default(),
        };
    }
    let boxes: Vec<Aabb> = triangles.iter().map(triangle_bounds).collect();
    let bounds = boxes.iter().fold(Aabb::EMPTY, |b, &t| b.union(t));
    let prims = Primitives {
        triangles: &triangles,
        boxes,
        bounds,
    };
    let built = match options.algorithm {
        Algorithm::Sweep => sweep::build(&prims, options),
        Algorithm::Level | Algorithm::Naive => level::build(&prims, options),
        Algorithm::Median => median::build(&prims, options),
    };
    let mut report = built.report;
    report.build_ms = start.elapsed().as_secs_f64() * 1e3;
    Build {
        tree: KdTree::from_parts(triangles, bounds, built.nodes, built.refs),
        report,
    }
}
