//! The tree re-laid out for traversal, built once per tree on its first ray query.
//!
//! Builders write nodes in the order they make them (the level builder breadth first), and a
//! leaf names its triangles through `refs`. A ray walks down one path and then along
//! neighbouring leaves, so here
//! - nodes are copied depth first, a node's pair of children placed when the copy reaches the
//!   node, so a left child's children sit right after it and a walk down a subtree reads
//!   neighbouring cache lines instead of one line per level, as breadth-first order gives;
//! - every leaf's triangles are copied, corners and index, into one contiguous run of words in
//!   leaf order, so a leaf costs one sequential read instead of an index lookup and a random
//!   read per triangle;
//! - a leaf's run is cut into blocks of 4 triangles (the last block holds the 1-3 left over),
//!   each block stored as structure of arrays: for `k` triangles in the block, 9 rows of `k`
//!   floats (row `3 c + a` holds axis `a` of corner `c` of the `k` triangles), then the `k`
//!   triangle indices. The four-triangle test then loads each coordinate it needs for four
//!   triangles with one vector load (a row starting at the axis the ray's shear wants),
//!   instead of gathering 36 floats one by one. A short block's rows are `k` floats apart, not
//!   padded to 4: a vector load of a row reads the next row's first floats into the unused
//!   lanes, which the test masks off. So the layout keeps 40 bytes per triangle reference,
//!   as the array of `{corners, index}` records before it did.
//!
//! The node format is the tree's own ([`Node`]); a leaf's `first` counts triangles before it
//! here (its words start at `first * WORDS`). The depth-first builders (the sweep and the
//! hybrid) already write their nodes in this order and their leaves'
//! references in leaf order, so when the scale is 1 the renumbered nodes would equal the
//! tree's: then the layout keeps none of its own and walks the tree's (8 bytes per node, 22
//! per triangle at 16M, saved).
//! Corners, planes and box are multiplied by the scene's [`scene_scale`] (1 for most scenes),
//! and rays' origins with them, so that the ray/triangle test works in float32's range.

use crate::geometry::{scene_scale, Aabb, Triangle, Vec3};
use crate::tree::wide::{collapse, WideNode};
use crate::tree::{KdTree, Node};
use rayon::prelude::*;

/// Words per triangle in [`TraceLayout::words`]: 9 corner coordinates and the index.
pub(crate) const WORDS: usize = 10;

/// Triangles per block of a leaf.
pub(crate) const BLOCK: usize = 4;

/// One triangle of a leaf: its corners and its index in the tree's triangle list.
#[derive(Clone, Copy, Debug)]
pub(crate) struct TriangleRecord {
    pub corners: Triangle,
    pub prim: u32,
}

#[derive(Clone, Debug)]
pub(crate) struct TraceLayout {
    /// The renumbered nodes, or `None` where they equal the tree's ([`Self::nodes`]).
    own_nodes: Option<Vec<Node>>,
    /// Leaves' triangles in blocks (see the module's notes): `f32` bits, and the indices.
    pub words: Vec<u32>,
    /// The tree's box, scaled.
    pub bounds: Aabb,
    /// What coordinates here are the tree's times: a power of two.
    pub scale: f32,
    /// `1 / scale`, exact.
    pub inv_scale: f32,
    /// The scaled box's largest extent (see `ShearedRay::with_reach` in `trace`).
    pub reach: f32,
    /// The 8-wide nodes every ray query walks, root first (`tree::wide`); none for a tree
    /// with nothing to hit.
    pub wide: Vec<WideNode>,
}

impl TraceLayout {
    pub fn new(tree: &KdTree) -> TraceLayout {
        let old = tree.nodes();
        let scale = scene_scale(&tree.bounds);
        let mut own_nodes =
            (!in_trace_order(old, scale)).then(|| vec![Node::leaf(0, 0); old.len().max(1)]);
        // The tree's non-empty leaves in the order their triangles are placed here.
        let mut leaves = Vec::new();
        let mut placed = 0u32;
        let mut next = 1u32;
        // (node in the tree, its place here); left children are popped first.
        let mut stack = vec![(0u32, 0u32)];
        while let Some((from, to)) = stack.pop() {
            let node = &old[from as usize];
            let renumbered = if node.is_leaf() {
                if node.count() > 0 {
                    leaves.push(*node);
                }
                placed += node.count();
                Node::leaf(placed - node.count(), node.count())
            } else {
                let pair = next;
                next += 2;
                stack.push((node.left() + 1, pair + 1));
                stack.push((node.left(), pair));
                Node::interior(node.axis(), node.split() * scale, pair)
            };
            if let Some(nodes) = own_nodes.as_mut() {
                nodes[to as usize] = renumbered;
            }
        }
        if let Some(nodes) = own_nodes.as_mut() {
            nodes.truncate(next as usize);
        }
        let placement = Placement {
            tree,
            leaves,
            scale,
        };
        let bounds = tree.bounds.scaled(scale);
        let reach = reach_of(&bounds);
        // The wide nodes before the words: the boxes the collapse holds while it runs then
        // take memory that the words take after, instead of adding to the peak.
        let nodes = own_nodes.as_deref().unwrap_or(old);
        let wide = collapse(nodes, &placement, bounds, reach);
        crate::give_back_freed_memory(tree.triangles.len());
        let mut words = vec![0; placed as usize * WORDS];
        let size = |leaf: &Node| leaf.count() as usize * WORDS;
        in_runs(&placement.leaves, size, &mut words, |run, mut out| {
            for leaf in run {
                out = placement.write_leaf(leaf, out);
            }
        });
        TraceLayout {
            own_nodes,
            words,
            bounds,
            reach,
            scale,
            inv_scale: 1.0 / scale,
            wide,
        }
    }

    /// Bytes held by the layout: its words, its own kd nodes and its wide nodes.
    pub fn bytes(&self) -> usize {
        use std::mem::size_of_val;
        size_of_val(&self.words[..])
            + self.own_nodes.as_deref().map_or(0, size_of_val)
            + size_of_val(&self.wide[..])
    }

    /// The nodes to walk: the layout's own, or the tree's where they are the same.
    #[inline(always)]
    pub fn nodes<'a>(&'a self, tree: &'a KdTree) -> &'a [Node] {
        self.own_nodes.as_deref().unwrap_or(tree.nodes())
    }

    /// The words of a leaf of this layout: its blocks one after the other.
    #[inline(always)]
    pub fn leaf_words(&self, node: &Node) -> &[u32] {
        let first = node.first() as usize * WORDS;
        &self.words[first..first + node.count() as usize * WORDS]
    }

    /// The triangles of a leaf of this layout, in order (the layout's test reads them).
    #[cfg(test)]
    pub fn leaf(&self, node: &Node) -> impl Iterator<Item = TriangleRecord> + '_ {
        self.leaf_words(node)
            .chunks(BLOCK * WORDS)
            .flat_map(|block| (0..block.len() / WORDS).map(move |i| block_record(block, i)))
    }
}

/// Whether renumbering `nodes` as [`TraceLayout::new`] does, with planes times `scale`, would
/// give them back unchanged: every node keeps its index (a node's children are the next
/// pair when the depth-first walk reaches it) and every leaf's references start where the
/// leaves before it in that walk end.
fn in_trace_order(nodes: &[Node], scale: f32) -> bool {
    if scale != 1.0 || nodes.is_empty() {
        return false;
    }
    let (mut next, mut refs) = (1u32, 0u32);
    let mut stack = vec![0u32];
    while let Some(i) = stack.pop() {
        let node = &nodes[i as usize];
        if node.is_leaf() {
            if node.first() != refs {
                return false;
            }
            refs += node.count();
        } else {
            if node.left() != next {
                return false;
            }
            next += 2;
            stack.extend([node.left() + 1, node.left()]);
        }
    }
    next as usize == nodes.len()
}

/// The tree's triangles as the layout places them: its non-empty leaves in the order their
/// triangles are placed, corners times `scale`. The words and the wide nodes' boxes are both
/// made from it.
pub(crate) struct Placement<'a> {
    pub tree: &'a KdTree,
    pub leaves: Vec<Node>,
    pub scale: f32,
}

impl Placement<'_> {
    /// Triangle `prim` of the tree, scaled.
    pub fn corners(&self, prim: u32) -> Triangle {
        self.tree.triangles()[prim as usize].map(|v| v * self.scale)
    }

    /// The triangle indices of a leaf of the tree, in its blocks.
    pub fn blocks<'b>(&'b self, leaf: &Node) -> std::slice::Chunks<'b, u32> {
        self.tree.leaf_refs(leaf).chunks(BLOCK)
    }

    /// Writes the triangles of a leaf of the tree in blocks (the module's notes) at the start
    /// of `out`; returns the rest of it.
    fn write_leaf<'o>(&self, leaf: &Node, out: &'o mut [u32]) -> &'o mut [u32] {
        let (mut mine, rest) = out.split_at_mut(leaf.count() as usize * WORDS);
        for block in self.blocks(leaf) {
            let k = block.len();
            let (words, tail) = std::mem::take(&mut mine).split_at_mut(k * WORDS);
            mine = tail;
            for (t, &prim) in block.iter().enumerate() {
                let corners = self.corners(prim);
                for row in 0..9 {
                    words[row * k + t] = corners[row / 3][row % 3].to_bits();
                }
                words[9 * k + t] = prim;
            }
        }
        rest
    }
}

/// Leaves per task of [`in_runs`].
const LEAVES_PER_RUN: usize = 256;

/// Fills `out` in parallel from `leaves`, each taking `size(leaf)` items of it in order: runs
/// of leaves are handed to `fill` with their own part of `out`, so what it writes does not
/// depend on the thread count.
pub(crate) fn in_runs<L: Sync, T: Send>(
    leaves: &[L],
    size: impl Fn(&L) -> usize,
    out: &mut [T],
    fill: impl Fn(&[L], &mut [T]) + Sync,
) {
    let mut rest = out;
    let mut tasks = Vec::with_capacity(leaves.len().div_ceil(LEAVES_PER_RUN));
    for run in leaves.chunks(LEAVES_PER_RUN) {
        let (part, tail) = std::mem::take(&mut rest).split_at_mut(run.iter().map(&size).sum());
        rest = tail;
        tasks.push((run, part));
    }
    tasks
        .into_par_iter()
        .for_each(|(run, part)| fill(run, part));
}

/// The triangle index of triangle `i` of a block: the row after the 9 coordinate rows.
#[inline(always)]
pub(crate) fn block_prim(block: &[u32], i: usize) -> u32 {
    block[9 * (block.len() / WORDS) + i]
}

/// Triangle `i` of a block (`block` holds the block's words, so its length gives its size).
#[inline(always)]
pub(crate) fn block_record(block: &[u32], i: usize) -> TriangleRecord {
    let k = block.len() / WORDS;
    let at = |row: usize| f32::from_bits(block[row * k + i]);
    let corner = |c: usize| Vec3([at(3 * c), at(3 * c + 1), at(3 * c + 2)]);
    // Written out: `[0, 1, 2].map(corner)` was compiled to an out-of-line call whose
    // result, stored as floats and reloaded in pairs, stalled the closest-point walk.
    TriangleRecord {
        corners: [corner(0), corner(1), corner(2)],
        prim: block_prim(block, i),
    }
}

/// The largest extent of a box (0 for an empty one).
pub(crate) fn reach_of(b: &Aabb) -> f32 {
    if b.is_empty() {
        return 0.0;
    }
    let e = b.extent();
    e[0].max(e[1]).max(e[2])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{build_triangles, Algorithm, BuildOptions};

    /// The layout holds the tree's nodes and leaves, renumbered: walking both from the root
    /// side by side meets the same planes and the same triangles, and every node of the layout
    /// is reached exactly once. The sweep's and the hybrid's nodes are already in this order and
    /// are shared; the level and median builders' (breadth first at the top) are copied.
    #[test]
    fn layout_is_the_tree_renumbered() {
        let tris: Vec<Triangle> = (0..400)
            .map(|i| {
                let (x, y, z) = ((i * 37 % 101) as f32, (i * 53 % 89) as f32, (i % 7) as f32);
                [
                    Vec3::new(x, y, z),
                    Vec3::new(x + 3.0, y, z + 1.0),
                    Vec3::new(x, y + 2.0, z + 2.0),
                ]
            })
            .collect();
        for (algorithm, shared) in [
            (Algorithm::Hybrid, true),
            (Algorithm::Sweep, true),
            (Algorithm::Median, false),
            (Algorithm::Level, false),
        ] {
            let options = BuildOptions {
                algorithm,
                ..BuildOptions::default()
            };
            let tree = build_triangles(tris.clone(), &options).unwrap().tree;
            let layout = TraceLayout::new(&tree);
            assert_eq!(layout.own_nodes.is_none(), shared, "{algorithm:?}");
            assert_layout_renumbers(&tree, &layout);
        }
    }

    fn assert_layout_renumbers(tree: &KdTree, layout: &TraceLayout) {
        let nodes = layout.nodes(tree);
        assert!(tree.nodes().len() > 50, "a tree worth renumbering");
        let mut reached = vec![0u32; nodes.len()];
        let mut stack = vec![(0u32, 0u32)];
        while let Some((a, b)) = stack.pop() {
            reached[b as usize] += 1;
            let (old, new) = (&tree.nodes()[a as usize], &nodes[b as usize]);
            assert_eq!(old.is_leaf(), new.is_leaf());
            if old.is_leaf() {
                let want: Vec<(u32, Triangle)> = tree
                    .leaf_refs(old)
                    .iter()
                    .map(|&p| (p, tree.triangles()[p as usize]))
                    .collect();
                let got: Vec<(u32, Triangle)> =
                    layout.leaf(new).map(|r| (r.prim, r.corners)).collect();
                assert_eq!(got, want);
            } else {
                assert_eq!((old.axis(), old.split()), (new.axis(), new.split()));
                stack.push((old.left(), new.left()));
                stack.push((old.left() + 1, new.left() + 1));
            }
        }
        assert!(reached.iter().all(|&n| n == 1), "every node reached once");
        assert_eq!(layout.words.len(), tree.refs().len() * WORDS);
    }
}
