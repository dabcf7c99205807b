//! Candidates, counting and pricing: every candidate plane of the level with its node, its
//! counts (L, R, P) and its SAH cost.

use super::buffers::ListHandles;
use super::{Builder, Params};
use crate::price::Layout;
use crate::space_tree;
use crate::GpuError;
use sahkd::builders::Counting;

impl Builder<'_> {
    /// Sizes the candidate arrays for `layout` (an upper bound of the candidates).
    pub(super) fn candidate_buffers(&mut self, layout: Layout) -> Result<(), GpuError> {
        let (gpu, c, b) = (self.gpu, layout.n, &mut self.bufs);
        for g in [
            &mut b.cand_pos,
            &mut b.cand_owner,
            &mut b.cand_cost,
            &mut b.packed,
        ] {
            g.ensure(gpu, c, false)?;
        }
        b.counts.ensure(gpu, 3 * c, false)?;
        Ok(())
    }

    /// Per (axis, reference of the lo list): its lo and hi as candidates of its node, or holes.
    pub(super) fn candidates(
        &mut self,
        level: &ListHandles,
        p: &Params,
        params: &wgpu::Buffer,
    ) -> Result<(), GpuError> {
        let b = &self.bufs;
        self.run(|enc| {
            self.kernels.candidates.dispatch(
                self.gpu,
                enc,
                &[
                    ("params", params),
                    ("ref_boxes", &level.ref_boxes),
                    ("boxes", &level.boxes),
                    ("starts", &level.starts),
                    ("entries", &level.entries),
                    ("ref_node", &level.ref_node),
                    ("uses", b.uses.get()),
                    ("caps", b.caps.get()),
                    ("cand_pos", b.cand_pos.get()),
                    ("cand_owner", b.cand_owner.get()),
                ],
                3 * p.refs as u64,
            );
            Ok(())
        })
    }

    /// Counting: the paper's space trees and walks, or binary searches of the sorted segments
    /// (the same L, R, P as the CPU's event scan).
    pub(super) fn count(
        &mut self,
        level: &ListHandles,
        p: &Params,
        params: &wgpu::Buffer,
        layout: Layout,
    ) -> Result<(), GpuError> {
        let (gpu, nodes, refs) = (self.gpu, p.nodes as usize, p.refs as usize);
        if self.options.counting == Counting::SpaceTree {
            self.bufs.space_trees.ensure(gpu, 9 * refs, false)?;
            self.bufs
                .walk_stats
                .ensure(gpu, space_tree::STATS_WORDS, false)?;
        }
        let b = &self.bufs;
        self.run(|enc| {
            if self.options.counting == Counting::SpaceTree {
                let trees = b.space_trees.get();
                let st = &self.kernels.space_tree;
                st.record_build(
                    gpu,
                    enc,
                    nodes,
                    refs,
                    [&level.ref_boxes, &level.entries, &level.starts],
                    trees,
                )?;
                st.record_count(
                    gpu,
                    enc,
                    nodes,
                    refs,
                    layout,
                    Some(self.device_layout(nodes)),
                    [&level.starts, trees, b.cand_pos.get(), b.cand_owner.get()],
                    b.counts.get(),
                    b.walk_stats.get(),
                );
            } else {
                self.kernels.count.dispatch(
                    gpu,
                    enc,
                    &[
                        ("params", params),
                        ("ref_boxes", &level.ref_boxes),
                        ("starts", &level.starts),
                        ("entries", &level.entries),
                        ("cand_pos", b.cand_pos.get()),
                        ("cand_owner", b.cand_owner.get()),
                        ("counts", b.counts.get()),
                    ],
                    layout.n as u64,
                );
            }
            Ok(())
        })
    }

    /// Pricing: each candidate's cost (and its planar side), as the CPU's cost model.
    pub(super) fn price(
        &mut self,
        level: &ListHandles,
        p: &Params,
        layout: Layout,
    ) -> Result<(), GpuError> {
        let b = &self.bufs;
        self.run(|enc| {
            self.kernels.price.record(
                self.gpu,
                enc,
                &self.options.cost,
                layout,
                Some(self.device_layout(p.nodes as usize)),
                [
                    &level.boxes,
                    b.cand_pos.get(),
                    b.cand_owner.get(),
                    b.counts.get(),
                ],
                [b.cand_cost.get(), b.packed.get()],
            );
            Ok(())
        })
    }
}
