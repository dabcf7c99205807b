//! Layout: per node, the axes it prices and its candidate capacity per axis, scanned into the
//! level's candidate layout; the host reads the layout's totals to size the candidate arrays.

use super::buffers::ListHandles;
use super::{Builder, Params};
use crate::price::Layout;
use crate::GpuError;

impl Builder<'_> {
    /// Sets `p.first1`, `p.first2`, `p.cands` (one round trip) and returns the layout.
    pub(super) fn layout(
        &mut self,
        level: &ListHandles,
        p: &mut Params,
    ) -> Result<Layout, GpuError> {
        let gpu = self.gpu;
        let nodes = p.nodes as usize;
        self.bufs.uses.ensure(gpu, nodes, false)?;
        self.bufs.caps.ensure(gpu, 3 * nodes + 1, false)?;
        let params = gpu.uniform(&*p);
        let (uses, caps) = (self.bufs.uses.get(), self.bufs.caps.get());
        let mut enc = gpu.encoder();
        self.kernels.axes_in_use.dispatch(
            gpu,
            &mut enc,
            &[
                ("params", &params),
                ("boxes", &level.boxes),
                ("starts", &level.starts),
                ("uses", uses),
                ("caps", caps),
            ],
            nodes as u64,
        );
        self.kernels
            .scan
            .record(gpu, &mut enc, caps, 3 * nodes + 1)?;
        let caps = caps.clone();
        let words = self.read_totals(
            enc,
            &[(&caps, nodes), (&caps, 2 * nodes), (&caps, 3 * nodes)],
        )?;
        p.first1 = words[0];
        p.first2 = words[1];
        p.cands = words[2];
        Ok(Layout {
            n: p.cands as usize,
            first1: p.first1 as usize,
            first2: p.first2 as usize,
        })
    }
}
