//! # sahkd: SAH kd-trees for ray tracing, built fast
//!
//! ```
//! use sahkd::{build, BuildOptions, Mesh, Ray, Vec3};
//!
//! // Two triangles forming the unit square in the plane z = 1.
//! let mesh = Mesh {
//!     vertices: vec![[0., 0., 1.], [1., 0., 1.], [1., 1., 1.], [0., 1., 1.]],
//!     triangles: vec![[0, 1, 2], [0, 2, 3]],
//! };
//! let built = build(&mesh, &BuildOptions::default()).unwrap();
//! let tree = built.tree;
//! let hit = tree.intersect(&Ray::new(Vec3::new(0.25, 0.5, 0.), Vec3::new(0., 0., 1.))).unwrap();
//! assert_eq!((hit.t, hit.prim), (1.0, 1));
//! assert!(!tree.occluded(&Ray::new(Vec3::new(2., 2., 0.), Vec3::new(0., 0., 1.))));
//! tree.validate().unwrap();
//! ```

pub mod builders;
pub mod clip;
pub mod cost;
pub mod geometry;
pub mod mesh;
pub mod output;
pub mod query;
pub mod render;
pub mod saved;
pub mod scene;
pub mod scenes;
pub mod threads;
pub mod trace;
pub mod tree;

pub use builders::{
    build, build_triangles, Algorithm, Axes, Build, BuildOptions, BuildReport, Counting, Preset,
    BINNED_REFS_PER_BIN, HYBRID_BINS, MAX_BINS,
};
pub use cost::CostModel;
pub use geometry::{Aabb, Triangle, Vec3};
pub use mesh::{Mesh, MeshError};
pub use query::{ClosestPoint, InsideTest};
pub use saved::{LoadError, TreeMeta};
pub use scene::{Scene, SceneClosestPoint, SceneError, SceneHit, SceneTree, Transform};
pub use trace::{Hit, Hit64, Ray, Ray64, RayPart, TraceStats};
pub use tree::{KdTree, Node, TreeStats};

/// Hands memory freed by a step of many allocations back to the system: glibc keeps it for
/// reuse, so without this the process stays as large as that step's peak and whatever comes
/// next adds to it. Called after a build (its working arrays, per node and per worker) and
/// after the wide nodes are made (the boxes they are made from), so that the trace layout's
/// words take the place of what was freed instead of adding to it. Other allocators return
/// memory on their own.
///
/// Only for meshes of [`KEEP_FREED_BELOW`] triangles or more: a smaller one's step freed a few
/// tens of MB at most, which the next build or layout reuses without the page faults of fresh
/// memory (a tenth of a small mesh's build from Python, where builds follow each other).
pub(crate) fn give_back_freed_memory(triangles: usize) {
    if triangles < KEEP_FREED_BELOW {
        return;
    }
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: malloc_trim only releases free pages of the allocator's own heaps.
    unsafe {
        libc::malloc_trim(0);
    }
}

/// Meshes smaller than this keep the memory a build or layout freed for the next one (see
/// [`give_back_freed_memory`]).
pub(crate) const KEEP_FREED_BELOW: usize = 1 << 18;
