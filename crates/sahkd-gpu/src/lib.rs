//! GPU compute for sahkd: the level builder's data-parallel phases as portable WGSL kernels
//! on wgpu (Vulkan, Metal, DX12), tested on Mesa's software Vulkan driver (lavapipe).
//!
//! - [`Gpu`]: one adapter and device, chosen once; a missing adapter is an error that names
//!   the backends tried, and every validation error of the device is turned into an `Err`.
//! - [`scan`]: multi-pass exclusive prefix sums (no single-pass look-back, which may hang where
//!   workgroups are not guaranteed to run together).
//! - [`price`]: the SAH cost of every candidate plane, bit for bit the f32 operations of
//!   [`sahkd::CostModel::split_cost`].
//! - [`segmin`]: each node's best candidate (cheapest, then smallest position, then lowest
//!   axis), by three rounds of atomic minima.
//! - `partition` (feature `testing`): the stable split of every node's references into its two children
//!   (flags, scan, scatter).
//! - [`clip`]: triangles clipped to boxes in software f64, bit for bit the CPU's clip.
//! - [`sort`]: records sorted by a 3-word key (bitonic; steps within a tile in workgroup
//!   memory): the clipped straddlers' list entries.
//! - [`space_tree`]: the paper's counting (space trees built by height, one stack-free walk
//!   per candidate), `Counting::SpaceTree`; scan counting is the level builder's binary searches.
//! - [`level`]: the level builder itself, every option (clipping, axes, counting): the same
//!   tree as the CPU's.
//!
//! The one-off presort of the nine root lists runs on the device on a GPU (the bitonic sort of
//! [`sort`] over one record per list entry) and on the host on a CPU adapter such as lavapipe,
//! where the host's sort is faster ([`Presort`]; the report says which ran). On the host stay:
//! the reference-budget check (one comparison per level, on totals the host reads anyway to
//! size the next level), and turning the downloaded node records into `Node`s.
//! Scan counting is by binary searches in each node's sorted lists rather than the CPU's event
//! scan: the same L, R, P per candidate, with no per-node serial sweep.
//!
//! Clipping: a straddler is clipped to both children on the GPU; its list entries are rebuilt
//! from the clipped boxes, sorted on their own and merged into the children's segments by
//! rank (binary searches), so no list is ever sorted whole again.
//!
//! Ties: the segmented min orders by (cost, position, index), and the candidate array holds
//! the axes in order, so it picks what the CPU picks (cost, position, lower axis); candidates
//! equal in all three are the same plane of the same node, hence the same split. Costs differ
//! from the CPU's only if a GPU flushes subnormal intermediates (see `shaders/price.wgsl`).

pub mod clip;
mod device;
mod kernel;
pub mod level;
#[cfg(feature = "testing")]
pub mod partition;
pub mod price;
pub mod scan;
pub mod segmin;
pub mod sort;
pub mod space_tree;

pub use device::{Gpu, GpuError};
pub use kernel::{Arg, Kernel};
pub use level::{build, build_with, check_options, GpuBuild, GpuReport, Presort};

// Feature `testing` adds the host-data helpers that only the tests use (run one kernel over
// arrays held on the host and read the result back: `scan::exclusive_scan`,
// `segmin::best_candidates`, `price::price_candidates`, `clip::clip_triangles`,
// `sort::sort_records`, `space_tree::run_space_tree`, the `partition` module); the crate's
// own tests turn it on through its dev-dependency on itself.
