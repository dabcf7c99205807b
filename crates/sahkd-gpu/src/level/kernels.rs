//! The level builder's kernels: those of `shaders/level.wgsl`, one module per section, and
//! the shared ones (pricing, segmented min, scan, sort, space trees).

use crate::kernel::Kernel;
use crate::price::Price;
use crate::scan::Scan;
use crate::segmin::SegMin;
use crate::sort::Sort;
use crate::space_tree::SpaceTree;
use crate::Gpu;

/// The source: a header, then one section per kernel, opened by a line `//! kernel NAME`
/// (`with clip.wgsl` after the name puts the clip library between header and body).
pub(super) const LEVEL_WGSL: &str = include_str!("../shaders/level.wgsl");

pub(super) struct Kernels {
    pub(super) axes_in_use: Kernel,
    pub(super) candidates: Kernel,
    pub(super) count: Kernel,
    pub(super) fill: Kernel,
    pub(super) decide: Kernel,
    pub(super) sides: Kernel,
    pub(super) classify: Kernel,
    pub(super) emit_nodes: Kernel,
    pub(super) emit_refs: Kernel,
    pub(super) scatter_refs: Kernel,
    pub(super) regen_emit: Kernel,
    pub(super) next_level: Kernel,
    pub(super) scatter: Kernel,
    pub(super) regen_place: Kernel,
    pub(super) payloads: Kernel,
    pub(super) price: Price,
    pub(super) segmin: SegMin,
    pub(super) scan: Scan,
    pub(super) sort: Sort,
    pub(super) space_tree: SpaceTree,
}

/// Each kernel's name and full source (header, library, body), in file order.
pub(super) fn level_sources() -> Vec<(String, String)> {
    let mut sections = LEVEL_WGSL.split("//! kernel ");
    let header = sections.next().unwrap_or_default();
    sections
        .map(|section| {
            let (line, body) = section.split_once('\n').unwrap_or((section, ""));
            let name = line.split_whitespace().next().unwrap_or_default();
            let library = if line.contains("with clip.wgsl") {
                crate::clip::CLIP_WGSL
            } else {
                ""
            };
            (name.to_string(), format!("{header}{library}{body}"))
        })
        .collect()
}

impl Kernels {
    pub(super) fn new(gpu: &Gpu) -> Kernels {
        let mut kernels: std::collections::HashMap<String, Kernel> = level_sources()
            .into_iter()
            .map(|(name, source)| {
                let kernel = Kernel::new(gpu, &source, &name);
                (name, kernel)
            })
            .collect();
        let mut take = |name: &str| {
            kernels
                .remove(name)
                .unwrap_or_else(|| panic!("kernel {name} missing from level.wgsl"))
        };
        Kernels {
            axes_in_use: take("axes_in_use"),
            candidates: take("candidates"),
            count: take("count"),
            fill: take("fill"),
            decide: take("decide"),
            sides: take("sides"),
            classify: take("classify"),
            emit_nodes: take("emit_nodes"),
            emit_refs: take("emit_refs"),
            scatter_refs: take("scatter_refs"),
            regen_emit: take("regen_emit"),
            next_level: take("next_level"),
            scatter: take("scatter"),
            regen_place: take("regen_place"),
            payloads: take("payloads"),
            price: Price::new(gpu),
            segmin: SegMin::new(gpu),
            scan: Scan::new(gpu),
            sort: Sort::new(gpu),
            space_tree: SpaceTree::new(gpu),
        }
    }
}
