//! Layout: per node, the axes it prices and its candidate capacity per axis, scanned into the
//! level's candidate layout. The host does not read it: the candidate arrays are sized by an
//! upper bound (two candidates per reference and axis priced), and the layout's words are
//! copied into the launches' parameters on the device.

use super::buffers::ListHandles;
use super::{Builder, Params};
use crate::price::{DeviceLayout, Layout};
use crate::GpuError;
use sahkd::builders::Axes;

/// Byte offsets of `cands`, `first1`, `first2` in the level's `Params`.
pub(super) const PARAMS_LAYOUT: [Option<u64>; 3] = [Some(36), Some(40), Some(44)];

impl Builder<'_> {
    /// Records the layout into `caps` and copies it into `params`; returns the upper bound of
    /// the candidates that sizes the candidate arrays and launches.
    pub(super) fn layout(
        &mut self,
        level: &ListHandles,
        p: &Params,
        params: &wgpu::Buffer,
    ) -> Result<Layout, GpuError> {
        let gpu = self.gpu;
        let nodes = p.nodes as usize;
        self.bufs.uses.ensure(gpu, nodes, false)?;
        self.bufs.caps.ensure(gpu, 3 * nodes + 1, false)?;
        let node_params = gpu.uniform(p);
        let (uses, caps) = (self.bufs.uses.get(), self.bufs.caps.get());
        self.run(|enc| {
            self.kernels.axes_in_use.dispatch(
                gpu,
                enc,
                &[
                    ("params", &node_params),
                    ("boxes", &level.boxes),
                    ("starts", &level.starts),
                    ("uses", uses),
                    ("caps", caps),
                ],
                nodes as u64,
            );
            self.kernels.scan.record(gpu, enc, caps, 3 * nodes + 1)?;
            self.device_layout(nodes).patch(enc, params, PARAMS_LAYOUT);
            Ok(())
        })?;
        let axes = if self.options.axes == Axes::All { 3 } else { 1 };
        Ok(Layout {
            n: 2 * axes * p.refs as usize,
            first1: 0,
            first2: 0,
        })
    }

    /// Where the layout of a level of `nodes` nodes lies in `caps` (after the scan: axis 1's
    /// block starts at `caps[nodes]`, axis 2's at `caps[2 nodes]`, the total at `caps[3 nodes]`).
    pub(super) fn device_layout(&self, nodes: usize) -> DeviceLayout<'_> {
        let n = nodes as u64 * 4;
        DeviceLayout {
            buffer: self.bufs.caps.get(),
            n: 3 * n,
            first1: n,
            first2: 2 * n,
        }
    }
}
