//! The kd-tree every builder produces: 8-byte nodes and one array of primitive references.
//!
//! Node layout (two `u32` words):
//! - `bits & 3` is the split axis (0, 1, 2) of an interior node, or 3 for a leaf;
//! - `bits >> 2` is, for an interior node, the index of its left child (the right child is
//!   the next node), and for a leaf, its number of primitives;
//! - `word` is, for an interior node, the split position as `f32` bits, and for a leaf, the
//!   index of its first entry in `refs`.
//!
//! Children are always stored side by side, so depth-first and breadth-first builders write
//! the same format. Within a leaf the references are sorted by triangle index, which makes
//! trees from different builders comparable entry by entry.

pub(crate) mod layout;
mod stats;
pub(crate) mod validate;
pub(crate) mod wide;

pub use stats::TreeStats;

use crate::geometry::{Aabb, Triangle};
use layout::TraceLayout;
use std::sync::OnceLock;

const LEAF: u32 = 3;

/// One kd-tree node, 8 bytes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[repr(C)]
pub struct Node {
    word: u32,
    bits: u32,
}

/// A node as a value, for code that is not on the traversal's hot path.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum NodeKind {
    Interior { axis: usize, split: f32, left: u32 },
    Leaf { first: u32, count: u32 },
}

impl Node {
    /// The largest child index or leaf size a node can hold.
    pub const MAX_INDEX: u32 = (1 << 30) - 1;

    #[inline]
    pub fn interior(axis: usize, split: f32, left: u32) -> Node {
        debug_assert!(axis < 3 && left <= Self::MAX_INDEX);
        Node {
            word: split.to_bits(),
            bits: (left << 2) | axis as u32,
        }
    }
    #[inline]
    pub fn leaf(first: u32, count: u32) -> Node {
        debug_assert!(count <= Self::MAX_INDEX);
        Node {
            word: first,
            bits: (count << 2) | LEAF,
        }
    }
    #[inline(always)]
    pub fn is_leaf(&self) -> bool {
        self.bits & 3 == LEAF
    }
    /// Split axis of an interior node.
    #[inline(always)]
    pub fn axis(&self) -> usize {
        (self.bits & 3) as usize
    }
    #[inline(always)]
    pub fn split(&self) -> f32 {
        f32::from_bits(self.word)
    }
    /// Left child of an interior node; the right child is `left + 1`.
    #[inline(always)]
    pub fn left(&self) -> u32 {
        self.bits >> 2
    }
    /// First reference of a leaf.
    #[inline(always)]
    pub fn first(&self) -> u32 {
        self.word
    }
    /// Number of primitives in a leaf.
    #[inline(always)]
    pub fn count(&self) -> u32 {
        self.bits >> 2
    }
    /// The node's two words as laid out above (`[word, bits]`), as files and Python see them.
    #[inline]
    pub fn words(&self) -> [u32; 2] {
        [self.word, self.bits]
    }
    /// A node from its two words; any pair is some node, so what it says must be checked
    /// against the tree it goes into (as `KdTree::from_bytes` does).
    #[inline]
    pub fn from_words([word, bits]: [u32; 2]) -> Node {
        Node { word, bits }
    }
    pub fn kind(&self) -> NodeKind {
        if self.is_leaf() {
            NodeKind::Leaf {
                first: self.first(),
                count: self.count(),
            }
        } else {
            NodeKind::Interior {
                axis: self.axis(),
                split: self.split(),
                left: self.left(),
            }
        }
    }
}

/// A built kd-tree over a triangle list, ready for ray queries.
#[derive(Clone, Debug)]
pub struct KdTree {
    pub(crate) nodes: Vec<Node>,
    pub(crate) refs: Vec<u32>,
    pub(crate) triangles: Vec<Triangle>,
    pub(crate) bounds: Aabb,
    /// The copy of the tree ray queries walk, made on the first query.
    pub(crate) layout: OnceLock<TraceLayout>,
}

impl KdTree {
    /// Assembles a tree from a builder's output. Node 0 is the root. Each leaf's references
    /// are sorted here, so builders need not care about their order.
    pub fn from_parts(
        triangles: Vec<Triangle>,
        bounds: Aabb,
        nodes: Vec<Node>,
        mut refs: Vec<u32>,
    ) -> KdTree {
        sort_leaves(&nodes, &mut refs);
        KdTree {
            nodes,
            refs,
            triangles,
            bounds,
            layout: OnceLock::new(),
        }
    }

    /// The tree of no triangles: one empty leaf that every ray misses.
    pub fn empty() -> KdTree {
        KdTree::from_parts(Vec::new(), Aabb::EMPTY, vec![Node::leaf(0, 0)], Vec::new())
    }

    pub fn nodes(&self) -> &[Node] {
        &self.nodes
    }
    pub fn refs(&self) -> &[u32] {
        &self.refs
    }
    pub fn triangles(&self) -> &[Triangle] {
        &self.triangles
    }
    pub fn bounds(&self) -> Aabb {
        self.bounds
    }
    /// The triangle indices of a leaf.
    pub fn leaf_refs(&self, leaf: &Node) -> &[u32] {
        let first = leaf.first() as usize;
        &self.refs[first..first + leaf.count() as usize]
    }

    /// The traversal layout of this tree, made on first use (walked by `trace` and `query`).
    pub(crate) fn trace_layout(&self) -> &TraceLayout {
        self.layout.get_or_init(|| TraceLayout::new(self))
    }

    /// Calls `f(node_index, node, box, depth)` for every node, depth first, left before right.
    pub fn visit(&self, mut f: impl FnMut(u32, &Node, &Aabb, u32)) {
        if self.nodes.is_empty() {
            return;
        }
        let mut stack = vec![(0u32, self.bounds, 0u32)];
        while let Some((i, bounds, depth)) = stack.pop() {
            let node = &self.nodes[i as usize];
            f(i, node, &bounds, depth);
            if !node.is_leaf() {
                let (l, r) = bounds.split(node.axis(), node.split());
                stack.push((node.left() + 1, r, depth + 1));
                stack.push((node.left(), l, depth + 1));
            }
        }
    }

    /// True when both trees have the same shape, split planes and leaf contents, whatever
    /// order their builders wrote the nodes in.
    pub fn same_tree(&self, other: &KdTree) -> bool {
        self.first_difference(other).is_none()
    }

    /// Describes the first place (depth-first) where two trees differ, if any.
    pub fn first_difference(&self, other: &KdTree) -> Option<String> {
        let mut stack = vec![(0u32, 0u32, String::from("root"))];
        while let Some((a, b, path)) = stack.pop() {
            let (na, nb) = (&self.nodes[a as usize], &other.nodes[b as usize]);
            match (na.kind(), nb.kind()) {
                (
                    NodeKind::Interior {
                        axis: xa,
                        split: sa,
                        left: la,
                    },
                    NodeKind::Interior {
                        axis: xb,
                        split: sb,
                        left: lb,
                    },
                ) => {
                    if xa != xb || sa.to_bits() != sb.to_bits() {
                        return Some(format!(
                            "{path}: split axis {xa} at {sa} vs axis {xb} at {sb}"
                        ));
                    }
                    stack.push((la + 1, lb + 1, format!("{path}.R")));
                    stack.push((la, lb, format!("{path}.L")));
                }
                (NodeKind::Leaf { .. }, NodeKind::Leaf { .. }) => {
                    let (ra, rb) = (self.leaf_refs(na), other.leaf_refs(nb));
                    if ra != rb {
                        return Some(format!(
                            "{path}: leaf of {} references vs leaf of {}",
                            ra.len(),
                            rb.len()
                        ));
                    }
                }
                (ka, kb) => return Some(format!("{path}: {ka:?} vs {kb:?}")),
            }
        }
        None
    }

    /// Structure and completeness check; see the `tree::validate` module.
    pub fn validate(&self) -> Result<(), String> {
        validate::validate(self)
    }

    /// Statistics of the tree under `cost`.
    pub fn stats(&self, cost: &crate::CostModel) -> TreeStats {
        stats::compute(self, cost)
    }
}

/// Sorts each leaf's run of `refs`, the runs of many leaves at once (`layout::in_runs`) when
/// they tile `refs`, as every builder writes them; otherwise each leaf's in turn, in node
/// order, runs reaching past `refs` left alone.
fn sort_leaves(nodes: &[Node], refs: &mut [u32]) {
    let mut leaves: Vec<Node> = nodes
        .iter()
        .filter(|n| n.is_leaf() && n.count() > 0)
        .copied()
        .collect();
    leaves.sort_unstable_by_key(|n| n.first());
    let mut end = 0;
    let tiled = leaves.iter().all(|n| {
        let next = n.first() as usize == end;
        end = n.first() as usize + n.count() as usize;
        next
    }) && end == refs.len();
    if !tiled {
        for n in nodes.iter().filter(|n| n.is_leaf()) {
            let (a, b) = (n.first() as usize, n.first() as usize + n.count() as usize);
            if b <= refs.len() {
                refs[a..b].sort_unstable();
            }
        }
        return;
    }
    layout::in_runs(
        &leaves,
        |n| n.count() as usize,
        refs,
        |run, mut part| {
            for n in run {
                let (leaf, rest) = part.split_at_mut(n.count() as usize);
                leaf.sort_unstable();
                part = rest;
            }
        },
    );
}
