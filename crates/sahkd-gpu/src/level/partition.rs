//! Partition: the next level's reference table (each reference of a split node into the
//! children it goes to, with its clipped box), the clipped straddlers' rebuilt list entries
//! (sorted), then the next level's segment starts, node boxes and lists (kept entries
//! scattered by the scanned flags, rebuilt ones merged by rank).

use super::buffers::ListHandles;
use super::{Builder, Params, Totals};
use crate::GpuError;

impl Builder<'_> {
    /// Writes the next level's arrays into `self.lists[next]`; sets `p.next_nodes`, `p.regen`.
    pub(super) fn partition(
        &mut self,
        level: &ListHandles,
        next: usize,
        p: &mut Params,
        totals: &Totals,
    ) -> Result<(), GpuError> {
        let gpu = self.gpu;
        let (nodes, e, refs) = (p.nodes as usize, p.entries as usize, p.refs as usize);
        let next_nodes = 2 * totals.splits;
        let regen = totals.regen;
        p.next_nodes = next_nodes as u32;
        p.regen = regen as u32;
        let params = gpu.uniform(&*p);
        let to = &mut self.lists[next];
        to.entries.ensure(gpu, totals.next_entries, false)?;
        to.starts.ensure(gpu, 9 * (next_nodes + 1), false)?;
        to.boxes.ensure(gpu, 6 * next_nodes, false)?;
        to.ref_prim.ensure(gpu, totals.next_table, false)?;
        to.ref_node.ensure(gpu, totals.next_table, false)?;
        to.ref_boxes.ensure(gpu, 6 * totals.next_table, false)?;
        self.bufs.new_id.ensure(gpu, 2 * refs, false)?;
        self.bufs.records.ensure(gpu, 4 * regen, false)?;
        self.bufs.parents.ensure(gpu, next_nodes, false)?;
        let to = self.lists[next].handles();
        let (b, k) = (&self.bufs, &self.kernels);
        self.run(|enc| {
            k.scatter_refs.dispatch(
                gpu,
                enc,
                &[
                    ("params", &params),
                    ("starts", &level.starts),
                    ("ref_prim", &level.ref_prim),
                    ("ref_node", &level.ref_node),
                    ("ref_boxes", &level.ref_boxes),
                    ("moved", b.moved.get()),
                    ("clip_boxes", b.clipped.get()),
                    ("go_l", b.go_l.get()),
                    ("go_r", b.go_r.get()),
                    ("split_scan", b.split_scan.get()),
                    ("next_prim", &to.ref_prim),
                    ("next_node", &to.ref_node),
                    ("next_boxes", &to.ref_boxes),
                    ("new_id", b.new_id.get()),
                ],
                refs as u64,
            );
            if regen > 0 {
                k.regen_emit.dispatch(
                    gpu,
                    enc,
                    &[
                        ("params", &params),
                        ("ref_node", &level.ref_node),
                        ("moved", b.moved.get()),
                        ("clip_boxes", b.clipped.get()),
                        ("go_l", b.go_l.get()),
                        ("go_r", b.go_r.get()),
                        ("regen_scan", b.regen_scan.get()),
                        ("split_scan", b.split_scan.get()),
                        ("new_id", b.new_id.get()),
                        ("records", b.records.get()),
                    ],
                    refs as u64,
                );
                k.sort.record(gpu, enc, b.records.get(), regen)?;
            }
            k.next_level.dispatch(
                gpu,
                enc,
                &[
                    ("params", &params),
                    ("boxes", &level.boxes),
                    ("starts", &level.starts),
                    ("split", b.split.get()),
                    ("split_scan", b.split_scan.get()),
                    ("lscan", b.lflags.get()),
                    ("rscan", b.rflags.get()),
                    ("records", b.records.get()),
                    ("next_starts", &to.starts),
                    ("next_boxes", &to.boxes),
                    ("parent", b.parents.get()),
                ],
                9 * (nodes as u64 + 1),
            );
            k.scatter.dispatch(
                gpu,
                enc,
                &[
                    ("params", &params),
                    ("starts", &level.starts),
                    ("entries", &level.entries),
                    ("ref_node", &level.ref_node),
                    ("ref_boxes", &level.ref_boxes),
                    ("split_scan", b.split_scan.get()),
                    ("lscan", b.lflags.get()),
                    ("rscan", b.rflags.get()),
                    ("records", b.records.get()),
                    ("new_id", b.new_id.get()),
                    ("out_entries", &to.entries),
                ],
                e as u64,
            );
            if regen > 0 {
                k.regen_place.dispatch(
                    gpu,
                    enc,
                    &[
                        ("params", &params),
                        ("starts", &level.starts),
                        ("entries", &level.entries),
                        ("ref_boxes", &level.ref_boxes),
                        ("lscan", b.lflags.get()),
                        ("rscan", b.rflags.get()),
                        ("records", b.records.get()),
                        ("parent", b.parents.get()),
                        ("out_entries", &to.entries),
                    ],
                    regen as u64,
                );
            }
            Ok(())
        })
    }
}
