//! Builders: from triangles to a [`KdTree`].
//!
//! All build parameters live in [`BuildOptions`], with their defaults in one place. Every
//! builder takes the same `Primitives` and returns the same `BuiltTree`; [`build`] picks
//! the builder, runs it on a thread pool of the requested size, and times it.

mod choice;
mod driver;
mod event;
mod hybrid;
mod level;
mod median;
mod options;
mod report;
mod stitch;
mod sweep;

pub use options::{
    Algorithm, Axes, BuildOptions, Counting, Preset, BINNED_REFS_PER_BIN, FAST_BINS,
    FAST_LEAF_SIZE, FAST_TRAVERSAL, HYBRID_BINS, MAX_BINS,
};
pub use report::{BuildReport, LevelReport, PhaseTimes};

use crate::geometry::{scene_scale, triangle_bounds, Aabb, Triangle};
use crate::mesh::{Mesh, MeshError};
use crate::tree::{KdTree, Node};
use rayon::prelude::*;
use std::fmt;
use std::time::Instant;

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
    options.validate()?;
    if triangles.len() > Node::MAX_INDEX as usize {
        return Err(BuildError::InvalidOptions(format!(
            "{} triangles is more than the {} a tree can hold",
            triangles.len(),
            Node::MAX_INDEX
        )));
    }
    // The build's time is all the caller waits for on the workers: the check of the corners,
    // the tree, the working arrays freed and handed back.
    let timed = || {
        let start = Instant::now();
        let n = triangles.len();
        // On the workers: serially, this pass was as long as a small mesh's serial start.
        let bad = triangles
            .par_chunks(CHECK_CHUNK)
            .enumerate()
            .find_map_first(|(c, chunk)| {
                let bad = chunk.iter().position(|t| !t.iter().all(|v| v.is_finite()));
                bad.map(|i| c * CHECK_CHUNK + i)
            });
        if let Some(i) = bad {
            return Err(BuildError::InvalidOptions(format!(
                "triangle {i} has a non-finite corner"
            )));
        }
        let mut built = run(triangles, options);
        crate::give_back_freed_memory(n);
        built.report.build_ms = start.elapsed().as_secs_f64() * 1e3;
        Ok(built)
    };
    match options.threads {
        Some(n) => {
            // `validate` checked `n` against the thread rule.
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(n)
                .build()
                .map_err(|e| {
                    BuildError::InvalidOptions(format!("cannot start {n} threads: {e}"))
                })?;
            pool.install(timed)
        }
        None => timed(),
    }
}

/// Triangles per task of the check of their corners (per triangle, the check's bookkeeping
/// took longer than the check).
const CHECK_CHUNK: usize = 4096;

/// The box of all `boxes`, from the unions of fixed chunks joined in order, so that the
/// result is the same bits on any thread count (`min` and `max` of -0 and 0 depend on the
/// order).
fn bounds_of(boxes: &[Aabb]) -> Aabb {
    const CHUNK: usize = 1 << 14;
    let chunks: Vec<Aabb> = boxes
        .par_chunks(CHUNK)
        .map(|c| c.iter().fold(Aabb::EMPTY, |b, &x| b.union(x)))
        .collect();
    chunks.into_iter().fold(Aabb::EMPTY, Aabb::union)
}

/// The triangles' boxes, on the workers.
fn boxes_of(triangles: &[Triangle]) -> Vec<Aabb> {
    triangles.par_iter().map(triangle_bounds).collect()
}

/// The build of checked `triangles` (its report's `build_ms` is set by the caller).
fn run(triangles: Vec<Triangle>, options: &BuildOptions) -> Build {
    if triangles.is_empty() {
        return Build {
            tree: KdTree::empty(),
            report: BuildReport::default(),
        };
    }
    // Every pass over all triangles runs on the workers: on small meshes these passes, and
    // the page faults of the arrays they fill, are a fair part of a build's serial start.
    // The scene box comes from the boxes, which most scenes (those not scaled) build with.
    let boxes = boxes_of(&triangles);
    let bounds = bounds_of(&boxes);
    // Scenes too large or too small for float32 products of their coordinates are built
    // scaled by a power of two (exact), and the planes scaled back; others as they are.
    let scale = scene_scale(&bounds);
    let scaled: Vec<Triangle>;
    let (build_triangles, boxes) = if scale == 1.0 {
        (&triangles, boxes)
    } else {
        scaled = triangles.par_iter().map(|t| t.map(|v| v * scale)).collect();
        (&scaled, boxes_of(&scaled))
    };
    let prims = Primitives {
        triangles: build_triangles,
        boxes,
        bounds: bounds.scaled(scale),
    };
    let mut built = match options.algorithm {
        Algorithm::Sweep => sweep::build(&prims, options),
        Algorithm::Level | Algorithm::Naive => level::build(&prims, options),
        Algorithm::Median => median::build(&prims, options),
        Algorithm::Hybrid => hybrid::build(&prims, options),
    };
    if scale != 1.0 {
        let back = 1.0 / scale;
        for node in built.nodes.iter_mut().filter(|n| !n.is_leaf()) {
            *node = Node::interior(node.axis(), node.split() * back, node.left());
        }
    }
    let mut report = built.report;
    let layout = Instant::now();
    let tree = KdTree::from_parts(triangles, bounds, built.nodes, built.refs);
    report.layout_ms += layout.elapsed().as_secs_f64() * 1e3;
    Build { tree, report }
}
