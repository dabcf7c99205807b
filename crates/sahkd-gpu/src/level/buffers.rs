//! The level builder's device memory: the arrays of one level (double-buffered, so a level
//! writes the next one's while reading its own) and the per-level scratch, each a named field.

use crate::{Gpu, GpuError};

/// A storage buffer that grows geometrically (by at least half) when a level outgrows it.
pub(super) struct Grow {
    label: &'static str,
    buffer: Option<wgpu::Buffer>,
    /// Its length in words of 4 bytes.
    pub(super) len: usize,
}

impl Grow {
    pub(super) fn new(label: &'static str) -> Grow {
        Grow {
            label,
            buffer: None,
            len: 0,
        }
    }

    /// At least `len` words; `keep` copies the old contents over when growing.
    pub(super) fn ensure(
        &mut self,
        gpu: &Gpu,
        len: usize,
        keep: bool,
    ) -> Result<&wgpu::Buffer, GpuError> {
        if self.buffer.is_none() || len > self.len {
            let grown = len.max(self.len + self.len / 2).max(64);
            let binding_words = (gpu.max_binding / 4) as usize;
            let buffer_words = (gpu.max_buffer / 4) as usize;
            // Past one binding, every part costs a binding of the kernels that use the array
            // (a device has few): no slack there, unless the contents are kept (copied over).
            let size = if len > buffer_words || (len > binding_words && !keep) {
                len
            } else {
                grown.min(if keep { buffer_words } else { binding_words })
            };
            let buffer = gpu.storage(self.label, size)?;
            if keep {
                if let Some(old) = &self.buffer {
                    let mut encoder = gpu.encoder();
                    encoder.copy_buffer_to_buffer(old, 0, &buffer, 0, (self.len * 4) as u64);
                    gpu.submit(encoder);
                }
            }
            self.buffer = Some(buffer);
            self.len = size;
        }
        Ok(self.buffer.as_ref().unwrap())
    }

    /// The buffer; it must have been sized by [`Grow::ensure`] (a bug of this module if not).
    pub(super) fn get(&self) -> &wgpu::Buffer {
        self.buffer
            .as_ref()
            .unwrap_or_else(|| panic!("{} used before it was sized", self.label))
    }

    /// Sizes the buffer to hold `data` and writes it.
    pub(super) fn write(&mut self, gpu: &Gpu, data: &[u32]) -> Result<(), GpuError> {
        let buffer = self.ensure(gpu, data.len(), false)?;
        gpu.queue
            .write_buffer(buffer, 0, bytemuck::cast_slice(data));
        Ok(())
    }
}

/// One level's arrays: the nine sorted lists of reference ids and their segment starts, the
/// node boxes, and the reference table (primitive, node, box of each reference). Two of them
/// alternate: a level reads one and writes the next level's into the other.
pub(super) struct Lists {
    pub(super) entries: Grow,
    pub(super) starts: Grow,
    pub(super) boxes: Grow,
    pub(super) ref_prim: Grow,
    pub(super) ref_node: Grow,
    pub(super) ref_boxes: Grow,
}

/// Handles on the buffers of a [`Lists`] (shared references to the GPU buffers), so that a
/// level can read its lists while the other [`Lists`] grows.
#[derive(Clone)]
pub(super) struct ListHandles {
    pub(super) entries: wgpu::Buffer,
    pub(super) starts: wgpu::Buffer,
    pub(super) boxes: wgpu::Buffer,
    pub(super) ref_prim: wgpu::Buffer,
    pub(super) ref_node: wgpu::Buffer,
    pub(super) ref_boxes: wgpu::Buffer,
}

impl Lists {
    pub(super) fn new() -> Lists {
        Lists {
            entries: Grow::new("entries"),
            starts: Grow::new("starts"),
            boxes: Grow::new("boxes"),
            ref_prim: Grow::new("ref prim"),
            ref_node: Grow::new("ref node"),
            ref_boxes: Grow::new("ref boxes"),
        }
    }

    pub(super) fn handles(&self) -> ListHandles {
        ListHandles {
            entries: self.entries.get().clone(),
            starts: self.starts.get().clone(),
            boxes: self.boxes.get().clone(),
            ref_prim: self.ref_prim.get().clone(),
            ref_node: self.ref_node.get().clone(),
            ref_boxes: self.ref_boxes.get().clone(),
        }
    }

    fn all(&self) -> [&Grow; 6] {
        [
            &self.entries,
            &self.starts,
            &self.boxes,
            &self.ref_prim,
            &self.ref_node,
            &self.ref_boxes,
        ]
    }

    /// Words allocated.
    pub(super) fn words(&self) -> usize {
        self.all().iter().map(|g| g.len).sum()
    }
}

/// The per-level scratch of the phases, sized for the largest level so far (in words: `n`
/// nodes, `e` list entries, `r` references, `c` candidates of the level).
pub(super) struct LevelBuffers {
    // Layout.
    /// Per node: the axes it prices (bit a for axis a; 0 for a leaf by size or depth).
    pub(super) uses: Grow,
    /// Per (axis, node): candidate capacity, scanned into the candidate layout (3n + 1).
    pub(super) caps: Grow,
    /// Small totals the host reads (the layout's, then the decision's).
    pub(super) totals: Grow,
    // Candidates, counting, pricing.
    /// Per candidate: position bits and node (`u32::MAX` for a hole).
    pub(super) cand_pos: Grow,
    pub(super) cand_owner: Grow,
    /// Per candidate: L, R, P.
    pub(super) counts: Grow,
    /// Per candidate: its cost, and `(L + R + P) << 1 | planar_left`.
    pub(super) cand_cost: Grow,
    pub(super) packed: Grow,
    /// Space-tree counting: the trees (9 words per reference) and the walk's counters.
    pub(super) space_trees: Grow,
    pub(super) walk_stats: Grow,
    // Best split and decision.
    /// Per node: the segmented minimum's three words (cost, position key, index).
    pub(super) best: Grow,
    /// Per node: split (0/1), axis, position bits, planar_left.
    pub(super) split: Grow,
    /// Per node (+1, scanned): splits before it, leaf references before it, next level's
    /// references before it.
    pub(super) split_scan: Grow,
    pub(super) leaf_scan: Grow,
    pub(super) next_scan: Grow,
    // Sides.
    /// Per reference (+1, scanned): whether it goes left, right; its rebuilt list entries.
    pub(super) go_l: Grow,
    pub(super) go_r: Grow,
    pub(super) regen_scan: Grow,
    /// Per reference: whether it was clipped (its entries are rebuilt), and its clipped boxes
    /// in both children (12 words; 1 word without clipping).
    pub(super) moved: Grow,
    pub(super) clipped: Grow,
    /// Per list entry (+1, scanned): whether it goes left, right.
    pub(super) lflags: Grow,
    pub(super) rflags: Grow,
    // Partition.
    /// Per reference: its ids in the left and right child's part of the next table.
    pub(super) new_id: Grow,
    /// The clipped references' rebuilt list entries (4 words each), sorted.
    pub(super) records: Grow,
    /// Per next-level node: its parent.
    pub(super) parents: Grow,
    // Output (kept across levels: the whole tree).
    /// Per node of the tree: 3 words (see `emit_nodes` in `shaders/level.wgsl`).
    pub(super) nodes_out: Grow,
    /// The leaves' primitive references.
    pub(super) refs_out: Grow,
}

impl LevelBuffers {
    pub(super) fn new() -> LevelBuffers {
        LevelBuffers {
            uses: Grow::new("uses"),
            caps: Grow::new("caps"),
            totals: Grow::new("totals"),
            cand_pos: Grow::new("cand pos"),
            cand_owner: Grow::new("cand owner"),
            counts: Grow::new("counts"),
            cand_cost: Grow::new("cost"),
            packed: Grow::new("packed"),
            space_trees: Grow::new("space trees"),
            walk_stats: Grow::new("walk stats"),
            best: Grow::new("best"),
            split: Grow::new("split"),
            split_scan: Grow::new("split scan"),
            leaf_scan: Grow::new("leaf scan"),
            next_scan: Grow::new("next scan"),
            go_l: Grow::new("go left"),
            go_r: Grow::new("go right"),
            regen_scan: Grow::new("regen scan"),
            moved: Grow::new("moved"),
            clipped: Grow::new("clipped boxes"),
            lflags: Grow::new("lflags"),
            rflags: Grow::new("rflags"),
            new_id: Grow::new("new ids"),
            records: Grow::new("records"),
            parents: Grow::new("parents"),
            nodes_out: Grow::new("nodes out"),
            refs_out: Grow::new("refs out"),
        }
    }

    fn all(&self) -> [&Grow; 27] {
        [
            &self.uses,
            &self.caps,
            &self.totals,
            &self.cand_pos,
            &self.cand_owner,
            &self.counts,
            &self.cand_cost,
            &self.packed,
            &self.space_trees,
            &self.walk_stats,
            &self.best,
            &self.split,
            &self.split_scan,
            &self.leaf_scan,
            &self.next_scan,
            &self.go_l,
            &self.go_r,
            &self.regen_scan,
            &self.moved,
            &self.clipped,
            &self.lflags,
            &self.rflags,
            &self.new_id,
            &self.records,
            &self.parents,
            &self.nodes_out,
            &self.refs_out,
        ]
    }

    /// Words allocated.
    pub(super) fn words(&self) -> usize {
        self.all().iter().map(|g| g.len).sum()
    }
}
