//! The tree re-laid out for traversal, built once per tree on its first ray query.
//!
//! Builders write nodes in the order they make them (the level builder breadth first), and a
//! leaf names its triangles through `refs`. A ray walks down one path and then along
//! neighbouring leaves, so here
//! - nodes are copied depth first, a node's pair of children placed when the copy reaches the
//!   node, so a left child's children sit right after it and a walk down a subtree reads
//!   neighbouring cache lines instead of one line per level, as breadth-first order gives;
//! - every leaf's triangles are copied, corners and index, into one contiguous run of
//!   [`TriangleRecord`]s in leaf order, so a leaf costs one sequential read instead of an
//!   index lookup and a random read per triangle.
//!
//! The node format is the tree's own ([`Node`]); a leaf's `first` indexes `triangles` here.
//! Corners, planes and box are multiplied by the scene's [`scene_scale`] (1 for most scenes),
//! and rays' origins with them, so that the ray/triangle test works in float32's range.

use crate::geometry::{scene_scale, Aabb, Triangle};
use crate::tree::{KdTree, Node};

/// One triangle of a leaf: its corners and its index in the tree's triangle list.
#[derive(Clone, Copy, Debug)]
pub(crate) struct TriangleRecord {
    pub corners: Triangle,
    pub prim: u32,
}

#[derive(Clone, Debug)]
pub(crate) struct TraceLayout {
    pub nodes: Vec<Node>,
    pub triangles: Vec<TriangleRecord>,
    /// The tree's box, scaled.
    pub bounds: Aabb,
    /// What coordinates here are the tree's times: a power of two.
    pub scale: f32,
    /// `1 / scale`, exact.
    pub inv_scale: f32,
    /// The scaled box's largest extent (see [`ShearedRay::with_reach`](super::ShearedRay)).
    pub reach: f32,
}

impl TraceLayout {
    pub fn new(tree: &KdTree) -> TraceLayout {
        let old = tree.nodes();
        let scale = scene_scale(&tree.bounds);
        let mut nodes = vec![Node::leaf(0, 0); old.len().max(1)];
        let mut triangles = Vec::with_capacity(tree.refs().len());
        let mut next = 1u32;
        // (node in the tree, its place here); left children are popped first.
        let mut stack = vec![(0u32, 0u32)];
        while let Some((from, to)) = stack.pop() {
            let node = &old[from as usize];
            nodes[to as usize] = if node.is_leaf() {
                let first = triangles.len() as u32;
                triangles.extend(tree.leaf_refs(node).iter().map(|&prim| TriangleRecord {
                    corners: tree.triangles()[prim as usize].map(|v| v * scale),
                    prim,
                }));
                Node::leaf(first, node.count())
            } else {
                let pair = next;
                next += 2;
                stack.push((node.left() + 1, pair + 1));
                stack.push((node.left(), pair));
                Node::interior(node.axis(), node.split() * scale, pair)
            };
        }
        nodes.truncate(next as usize);
        TraceLayout {
            nodes,
            triangles,
            bounds: tree.bounds.scaled(scale),
            reach: reach_of(&tree.bounds.scaled(scale)),
            scale,
            inv_scale: 1.0 / scale,
        }
    }

    /// The triangles of a leaf of this layout.
    #[inline(always)]
    pub fn leaf(&self, node: &Node) -> &[TriangleRecord] {
        let first = node.first() as usize;
        &self.triangles[first..first + node.count() as usize]
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
    use crate::{build_triangles, BuildOptions, Vec3};

    /// The layout holds the tree's nodes and leaves, renumbered: walking both from the root
    /// side by side meets the same planes and the same triangles, and every node of the layout
    /// is reached exactly once.
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
        let tree = build_triangles(tris, &BuildOptions::default())
            .unwrap()
            .tree;
        let layout = TraceLayout::new(&tree);
        assert!(tree.nodes().len() > 50, "a tree worth renumbering");
        let mut reached = vec![0u32; layout.nodes.len()];
        let mut stack = vec![(0u32, 0u32)];
        while let Some((a, b)) = stack.pop() {
            reached[b as usize] += 1;
            let (old, new) = (&tree.nodes()[a as usize], &layout.nodes[b as usize]);
            assert_eq!(old.is_leaf(), new.is_leaf());
            if old.is_leaf() {
                let want: Vec<(u32, Triangle)> = tree
                    .leaf_refs(old)
                    .iter()
                    .map(|&p| (p, tree.triangles()[p as usize]))
                    .collect();
                let got: Vec<(u32, Triangle)> = layout
                    .leaf(new)
                    .iter()
                    .map(|r| (r.prim, r.corners))
                    .collect();
                assert_eq!(got, want);
            } else {
                assert_eq!((old.axis(), old.split()), (new.axis(), new.split()));
                stack.push((old.left(), new.left()));
                stack.push((old.left() + 1, new.left() + 1));
            }
        }
        assert!(reached.iter().all(|&n| n == 1), "every node reached once");
        assert_eq!(layout.triangles.len(), tree.refs().len());
    }
}
