//! Best split, decision and sides: each node's cheapest candidate, whether it splits there
//! (the scans of the decision give child ranks, leaf offsets and the next level's size), and
//! which children each reference and list entry goes to (clipping straddlers). The host reads
//! the totals once, to check the reference budget and size the next level.

use super::buffers::ListHandles;
use super::{Builder, Params, Totals};
use crate::price::Layout;
use crate::GpuError;

impl Builder<'_> {
    /// The segmented min: each node's best candidate into `best`.
    pub(super) fn best_split(
        &mut self,
        p: &Params,
        params: &wgpu::Buffer,
        layout: Layout,
    ) -> Result<(), GpuError> {
        let (gpu, b, nodes) = (self.gpu, &self.bufs, p.nodes as usize);
        self.run(|enc| {
            self.kernels.fill.dispatch(
                gpu,
                enc,
                &[("params", params), ("out", b.best.get())],
                3 * nodes as u64,
            );
            if layout.n > 0 {
                self.kernels.segmin.record(
                    gpu,
                    enc,
                    b.cand_cost.get(),
                    b.cand_pos.get(),
                    b.cand_owner.get(),
                    layout.n,
                    Some(self.device_layout(nodes)),
                    b.best.get(),
                );
            }
            Ok(())
        })
    }

    /// Sizes the decision's and the sides' arrays, then decides every node.
    pub(super) fn decide(
        &mut self,
        level: &ListHandles,
        p: &Params,
        params: &wgpu::Buffer,
    ) -> Result<(), GpuError> {
        let (gpu, b) = (self.gpu, &mut self.bufs);
        let (nodes, e, refs) = (p.nodes as usize, p.entries as usize, p.refs as usize);
        for g in [&mut b.split_scan, &mut b.leaf_scan, &mut b.next_scan] {
            g.ensure(gpu, nodes + 1, false)?;
        }
        b.split.ensure(gpu, 4 * nodes, false)?;
        b.lflags.ensure(gpu, e + 1, false)?;
        b.rflags.ensure(gpu, e + 1, false)?;
        for g in [&mut b.go_l, &mut b.go_r, &mut b.regen_scan] {
            g.ensure(gpu, refs + 1, false)?;
        }
        b.moved.ensure(gpu, refs, false)?;
        let clipped = if self.options.clip { 12 * refs } else { 1 };
        b.clipped.ensure(gpu, clipped, false)?;
        // Candidate buffers must exist to bind, even on a level without candidates.
        for g in [&mut b.cand_pos, &mut b.cand_cost, &mut b.packed] {
            g.ensure(gpu, 1, false)?;
        }
        self.run(|enc| self.record_decide(enc, level, nodes, params))
    }

    /// The decision's launches: `decide`, then the scans of its per-node values.
    fn record_decide(
        &self,
        enc: &mut wgpu::CommandEncoder,
        level: &ListHandles,
        nodes: usize,
        params: &wgpu::Buffer,
    ) -> Result<(), GpuError> {
        let (gpu, b) = (self.gpu, &self.bufs);
        self.kernels.decide.dispatch(
            gpu,
            enc,
            &[
                ("params", params),
                ("uses", b.uses.get()),
                ("starts", &level.starts),
                ("best", b.best.get()),
                ("cost", b.cand_cost.get()),
                ("packed", b.packed.get()),
                ("cand_pos", b.cand_pos.get()),
                ("split", b.split.get()),
                ("split_scan", b.split_scan.get()),
                ("leaf_scan", b.leaf_scan.get()),
                ("next_scan", b.next_scan.get()),
            ],
            nodes as u64,
        );
        for g in [&b.split_scan, &b.leaf_scan, &b.next_scan] {
            self.kernels.scan.record(gpu, enc, g.get(), nodes + 1)?;
        }
        Ok(())
    }

    /// The sides of every reference (clipping straddlers) and every list entry, then one read
    /// of the level's totals. When the reference budget would be exceeded, the level is
    /// decided again with `p.force_leaves` set: all its nodes become leaves.
    pub(super) fn sides(
        &mut self,
        level: &ListHandles,
        p: &mut Params,
        params: &wgpu::Buffer,
        budget: usize,
    ) -> Result<Totals, GpuError> {
        let gpu = self.gpu;
        let (nodes, e, refs) = (p.nodes as usize, p.entries as usize, p.refs as usize);
        let b = &self.bufs;
        let k = &self.kernels;
        let mut enc = gpu.encoder();
        k.sides.dispatch(
            gpu,
            &mut enc,
            &[
                ("params", params),
                ("ref_boxes", &level.ref_boxes),
                ("ref_prim", &level.ref_prim),
                ("ref_node", &level.ref_node),
                ("triangles", &self.corners),
                ("boxes", &level.boxes),
                ("split", b.split.get()),
                ("go_l", b.go_l.get()),
                ("go_r", b.go_r.get()),
                ("moved", b.moved.get()),
                ("regen_count", b.regen_scan.get()),
                ("clip_boxes", b.clipped.get()),
            ],
            refs as u64 + 1,
        );
        for g in [&b.go_l, &b.go_r, &b.regen_scan] {
            k.scan.record(gpu, &mut enc, g.get(), refs + 1)?;
        }
        k.classify.dispatch(
            gpu,
            &mut enc,
            &[
                ("params", params),
                ("entries", &level.entries),
                ("moved", b.moved.get()),
                ("go_l", b.go_l.get()),
                ("go_r", b.go_r.get()),
                ("lflags", b.lflags.get()),
                ("rflags", b.rflags.get()),
            ],
            e as u64 + 1,
        );
        k.scan.record(gpu, &mut enc, b.lflags.get(), e + 1)?;
        k.scan.record(gpu, &mut enc, b.rflags.get(), e + 1)?;
        let words = [
            (b.split_scan.get().clone(), nodes),
            (b.leaf_scan.get().clone(), nodes),
            (b.next_scan.get().clone(), nodes),
            (b.lflags.get().clone(), e),
            (b.rflags.get().clone(), e),
            (b.go_l.get().clone(), refs),
            (b.go_r.get().clone(), refs),
            (b.regen_scan.get().clone(), refs),
        ];
        let words: Vec<(&wgpu::Buffer, usize)> = words.iter().map(|(b, at)| (b, *at)).collect();
        let sums = self.read_totals(enc, &words)?;
        let regen = sums[7] as usize;
        let mut totals = Totals {
            splits: sums[0] as usize,
            leaf_refs: sums[1] as usize,
            next_refs: sums[2] as usize,
            next_entries: (sums[3] + sums[4]) as usize + regen,
            next_table: (sums[5] + sums[6]) as usize,
            regen,
        };
        // The reference budget, as the CPU checks it: the references already in leaves, this
        // level's leaves and the next level's (before clipping, which only removes) must fit,
        // or the whole level becomes leaves.
        if p.ref_base as usize + totals.leaf_refs + totals.next_refs > budget && totals.splits > 0 {
            p.force_leaves = 1;
            let forced = gpu.uniform(&*p);
            let mut enc = gpu.encoder();
            self.device_layout(nodes)
                .patch(&mut enc, &forced, super::layout::PARAMS_LAYOUT);
            self.record_decide(&mut enc, level, nodes, &forced)?;
            gpu.submit(enc);
            totals.splits = 0;
            totals.leaf_refs = refs;
        }
        gpu.finish()?;
        Ok(totals)
    }
}
