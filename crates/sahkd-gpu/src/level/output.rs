//! Output: this level's node records and its leaves' references, appended to the tree.

use super::buffers::ListHandles;
use super::{Builder, Params, Totals};
use crate::GpuError;

impl Builder<'_> {
    /// Writes the level's nodes and leaf references; returns the ends of the tree's nodes and
    /// references so far.
    pub(super) fn output(
        &mut self,
        level: &ListHandles,
        p: &Params,
        totals: &Totals,
    ) -> Result<(usize, usize), GpuError> {
        let gpu = self.gpu;
        let node_end = p.node_base as usize + p.nodes as usize;
        let ref_end = p.ref_base as usize + totals.leaf_refs;
        self.bufs.nodes_out.ensure(gpu, 3 * node_end, true)?;
        self.bufs.refs_out.ensure(gpu, ref_end.max(1), true)?;
        let params = gpu.uniform(p);
        let b = &self.bufs;
        self.run(|enc| {
            self.kernels.emit_nodes.dispatch(
                gpu,
                enc,
                &[
                    ("params", &params),
                    ("starts", &level.starts),
                    ("split", b.split.get()),
                    ("split_scan", b.split_scan.get()),
                    ("leaf_scan", b.leaf_scan.get()),
                    ("out_nodes", b.nodes_out.get()),
                ],
                p.nodes as u64,
            );
            self.kernels.emit_refs.dispatch(
                gpu,
                enc,
                &[
                    ("params", &params),
                    ("starts", &level.starts),
                    ("ref_prim", &level.ref_prim),
                    ("ref_node", &level.ref_node),
                    ("split", b.split.get()),
                    ("leaf_scan", b.leaf_scan.get()),
                    ("out_refs", b.refs_out.get()),
                ],
                p.refs as u64,
            );
            Ok(())
        })?;
        Ok((node_end, ref_end))
    }
}
