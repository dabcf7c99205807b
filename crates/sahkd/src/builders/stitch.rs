//! Subtrees built apart (in parallel, each into its own arrays) placed into one tree, in a
//! fixed order, so that the tree does not depend on which worker finished first.

use super::BuiltTree;
use crate::tree::Node;

/// A subtree built on its own: its nodes (root first) and its leaves' references, already
/// mapped to the whole tree's primitives.
pub(crate) struct Piece {
    pub nodes: Vec<Node>,
    pub refs: Vec<u32>,
}

/// Places `piece` under the tree's slot `slot` (a placeholder): its root takes the slot, its
/// other nodes are appended, its references follow the tree's.
pub(crate) fn place(built: &mut BuiltTree, slot: usize, piece: &Piece) {
    place_at(&mut built.nodes, &mut built.refs, slot, piece);
}

/// [`place`] into a tree's two arrays.
pub(crate) fn place_at(nodes: &mut Vec<Node>, refs: &mut Vec<u32>, slot: usize, piece: &Piece) {
    let base = nodes.len();
    nodes.resize(base + piece.nodes.len() - 1, Node::leaf(0, 0));
    let (head, below) = nodes.split_at_mut(base);
    place_nodes(piece, &mut head[slot], below, base, refs.len());
    refs.extend_from_slice(&piece.refs);
}

/// The nodes of `piece` placed: its root into `root`, its other nodes into `below`, which the
/// tree holds from index `base` on (one node fewer than the piece); its references are to
/// start at `ref_base`. Writes into slices, so that pieces are placed in parallel.
pub(crate) fn place_nodes(
    piece: &Piece,
    root: &mut Node,
    below: &mut [Node],
    base: usize,
    ref_base: usize,
) {
    let (base, ref_base) = (base as u32, ref_base as u32);
    *root = relocate(&piece.nodes[0], base, ref_base);
    for (to, n) in below.iter_mut().zip(&piece.nodes[1..]) {
        *to = relocate(n, base, ref_base);
    }
}

/// The tree whose top is `top` (nodes below `first_slot` built there; each slot from
/// `first_slot` on is the root of `pieces[slot - first_slot]`), laid out as the sweep lays out
/// a tree: a node's two children side by side, appended when the node is split, in depth-first
/// order, left subtree first, and leaves' references in the same order. So the layout is the
/// same wherever the top ends and the pieces begin.
pub(crate) fn depth_first(top: &BuiltTree, first_slot: usize, pieces: &[Piece]) -> BuiltTree {
    let mut out = BuiltTree {
        nodes: Vec::with_capacity(first_slot + pieces.iter().map(|p| p.nodes.len()).sum::<usize>()),
        refs: Vec::with_capacity(
            top.refs.len() + pieces.iter().map(|p| p.refs.len()).sum::<usize>(),
        ),
        report: Default::default(),
    };
    out.nodes.push(Node::leaf(0, 0));
    // (slot in `top`, slot in `out`)
    let mut stack = vec![(0usize, 0usize)];
    while let Some((from, to)) = stack.pop() {
        if from >= first_slot {
            place(&mut out, to, &pieces[from - first_slot]);
            continue;
        }
        let node = top.nodes[from];
        if node.is_leaf() {
            let first = node.first() as usize;
            out.nodes[to] = Node::leaf(out.refs.len() as u32, node.count());
            out.refs
                .extend_from_slice(&top.refs[first..first + node.count() as usize]);
        } else {
            let left = out.nodes.len();
            out.nodes[to] = Node::interior(node.axis(), node.split(), left as u32);
            out.nodes.extend([Node::leaf(0, 0); 2]);
            let from_left = node.left() as usize;
            stack.push((from_left + 1, left + 1));
            stack.push((from_left, left));
        }
    }
    out
}

/// A subtree's node moved into the whole tree: the subtree's root takes its node's slot and
/// its other nodes `i` (always children, so `i > 0`) go to `base + i - 1`; its references
/// start at `ref_base`.
fn relocate(n: &Node, base: u32, ref_base: u32) -> Node {
    if n.is_leaf() {
        Node::leaf(n.first() + ref_base, n.count())
    } else {
        Node::interior(n.axis(), n.split(), base + n.left() - 1)
    }
}
