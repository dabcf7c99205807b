//! The trace layout's wide nodes: the kd-tree collapsed into 8-wide bounded nodes, which
//! every ray query walks (`trace::wide`).
//!
//! Every kd node gets the box of what it holds: a leaf's triangles clipped to its cell, an
//! interior node the union of its children's. A wide node is made from a kd node by opening,
//! again and again, the child of largest box area among its current children while what it
//! opens into still fits eight: an interior kd node into its two children, a leaf of more than
//! one 4-triangle block of the trace layout into its blocks, each with the box of its own
//! triangles (children holding nothing are dropped). Leaves are runs of the trace layout's
//! words; a child's box is padded so that the float32 slab test cannot miss a hit on its
//! border.

use crate::clip::clipped_bounds;
use crate::geometry::Aabb;
use crate::tree::layout::{block_record, TraceLayout, BLOCK, WORDS};
use crate::tree::Node;
use std::mem::MaybeUninit;

pub(crate) const WIDTH: usize = 8;
/// A child that is a leaf: `LEAF | first triangle` in the layout's words.
pub(crate) const LEAF: u32 = 1 << 31;

/// Eight children: rows lo x, lo y, lo z, hi x, hi y, hi z of their boxes, lane = child.
#[repr(C, align(64))]
#[derive(Clone, Copy, Debug)]
pub(crate) struct WideNode {
    pub bounds: [[f32; WIDTH]; 6],
    pub child: [u32; WIDTH],
    pub count: [u32; WIDTH],
}

impl WideNode {
    /// No children: a lane without one has a NaN box, which every comparison fails.
    pub(crate) fn empty() -> WideNode {
        WideNode {
            bounds: [[f32::NAN; WIDTH]; 6],
            child: [0; WIDTH],
            count: [0; WIDTH],
        }
    }
}

/// The content boxes of the trace layout's kd nodes (empty where one holds nothing), kept
/// only where they are not a union of others: an interior node's in `inner`, a leaf's as its
/// blocks' boxes in `block_boxes` (one per 4-triangle block, in order), `slot` saying where
/// for each kd node. They are what the collapse holds beside the layout at its peak, so they
/// take 4 bytes per kd node and 24 per interior node and per block, rather than a box and an
/// index for every kd node.
struct Collapse<'a> {
    kd: &'a [Node],
    layout: &'a TraceLayout,
    slot: Vec<u32>,
    inner: Vec<Aabb>,
    block_boxes: Vec<Aabb>,
    nodes: Vec<WideNode>,
    pad: f32,
}

/// A child of a wide node being made, with its box: a kd node, or one block of a kd leaf
/// (its first triangle in the layout and its count).
#[derive(Clone, Copy)]
enum Kid {
    Kd(u32, Aabb),
    Block(u32, u32, Aabb),
}

impl Collapse<'_> {
    fn content_of(&mut self, i: u32, cell: Aabb) -> Aabb {
        let node = self.kd[i as usize];
        if node.is_leaf() {
            self.slot[i as usize] = self.block_boxes.len() as u32;
            let words = self.layout.leaf_words(&node);
            let mut leaf = Aabb::EMPTY;
            for block in words.chunks(BLOCK * WORDS) {
                let b = (0..block.len() / WORDS).fold(Aabb::EMPTY, |b, t| {
                    b.union(clipped_bounds(&block_record(block, t).corners, &cell))
                });
                self.block_boxes.push(b);
                leaf = leaf.union(b);
            }
            leaf
        } else {
            let (l, r) = cell.split(node.axis(), node.split());
            let a = self.content_of(node.left(), l);
            let c = self.content_of(node.left() + 1, r);
            self.slot[i as usize] = self.inner.len() as u32;
            self.inner.push(a.union(c));
            a.union(c)
        }
    }

    /// The boxes of kd leaf `k`'s blocks.
    fn blocks(&self, k: u32) -> &[Aabb] {
        let first = self.slot[k as usize] as usize;
        let count = (self.kd[k as usize].count() as usize).div_ceil(BLOCK);
        &self.block_boxes[first..first + count]
    }

    fn content(&self, k: u32) -> Aabb {
        if self.kd[k as usize].is_leaf() {
            self.blocks(k).iter().fold(Aabb::EMPTY, |a, b| a.union(*b))
        } else {
            self.inner[self.slot[k as usize] as usize]
        }
    }

    fn bounds(kid: &Kid) -> Aabb {
        match *kid {
            Kid::Kd(_, b) | Kid::Block(_, _, b) => b,
        }
    }

    /// What opening `kid` gives at most: an interior kd node its two children, a leaf of
    /// more than a block its blocks; 0 where it cannot be opened.
    fn pieces(&self, kid: &Kid) -> usize {
        match *kid {
            Kid::Kd(k, _) => {
                let node = &self.kd[k as usize];
                if !node.is_leaf() {
                    2
                } else if node.count() as usize > BLOCK {
                    (node.count() as usize).div_ceil(BLOCK)
                } else {
                    0
                }
            }
            Kid::Block(..) => 0,
        }
    }

    fn area(b: &Aabb) -> f32 {
        let e = b.extent();
        e[0] * e[1] + e[1] * e[2] + e[2] * e[0]
    }

    /// The children of the wide node of kd node `i`: its children opened, the largest box
    /// first, while what they open into fits eight.
    fn kids(&self, i: u32) -> Vec<Kid> {
        let mut kids = vec![Kid::Kd(i, self.content(i))];
        loop {
            let open = (0..kids.len())
                .filter(|&j| {
                    let p = self.pieces(&kids[j]);
                    p > 0 && kids.len() - 1 + p <= WIDTH
                })
                .max_by(|&a, &b| {
                    Self::area(&Self::bounds(&kids[a]))
                        .total_cmp(&Self::area(&Self::bounds(&kids[b])))
                });
            let Some(j) = open else { break };
            let Kid::Kd(k, _) = kids.remove(j) else {
                unreachable!("only kd nodes open")
            };
            let node = self.kd[k as usize];
            if node.is_leaf() {
                // Its blocks' boxes, made with its content box.
                for (j, &b) in self.blocks(k).iter().enumerate() {
                    let first = (j * BLOCK) as u32;
                    if !b.is_empty() {
                        let count = (node.count() - first).min(BLOCK as u32);
                        kids.push(Kid::Block(node.first() + first, count, b));
                    }
                }
            } else {
                for c in [node.left(), node.left() + 1] {
                    let b = self.content(c);
                    if !b.is_empty() {
                        kids.push(Kid::Kd(c, b));
                    }
                }
            }
        }
        debug_assert!(kids.len() <= WIDTH);
        kids
    }

    /// How many wide nodes `make(i)` makes.
    fn count(&self, i: u32) -> usize {
        1 + self
            .kids(i)
            .iter()
            .map(|kid| match *kid {
                Kid::Kd(k, _) if !self.kd[k as usize].is_leaf() => self.count(k),
                _ => 0,
            })
            .sum::<usize>()
    }

    /// Makes the wide node of kd node `i` and those below it; returns its index.
    fn make(&mut self, i: u32) -> u32 {
        let kids = self.kids(i);
        let at = self.nodes.len() as u32;
        self.nodes.push(WideNode::empty());
        let mut node = WideNode::empty();
        for (lane, kid) in kids.iter().enumerate() {
            let b = Self::bounds(kid);
            for a in 0..3 {
                // Padded by the scene's own margin and by a few roundings of the coordinate:
                // far from the origin a float32 step dwarfs the scene's margin.
                node.bounds[a][lane] = b.lo[a] - (self.pad + b.lo[a].abs() * WIDEN);
                node.bounds[3 + a][lane] = b.hi[a] + (self.pad + b.hi[a].abs() * WIDEN);
            }
            (node.child[lane], node.count[lane]) = match *kid {
                Kid::Block(first, count, _) => (LEAF | first, count),
                Kid::Kd(k, _) => {
                    let kd = self.kd[k as usize];
                    if kd.is_leaf() {
                        (LEAF | kd.first(), kd.count())
                    } else {
                        (self.make(k), 0)
                    }
                }
            };
        }
        self.nodes[at as usize] = node;
        at
    }
}

/// The walk's step at a wide node: of the children in `mask` (bit `i` for lane `i`, at
/// least one), made by `entry`, returns the one to walk next and pushes the others onto
/// `stack` at `top`. With `SORTED` the one returned has the smallest `key` and the pushed
/// ones are sorted so that the smallest pops first (a walk by distance: closest hits,
/// closest points); without, the order is the lanes' (an any-hit walk, which stops at any
/// hit).
#[inline(always)]
pub(crate) fn push_children<E: Copy, const SORTED: bool>(
    mut mask: u32,
    entry: impl Fn(usize) -> E,
    key: impl Fn(&E) -> f32,
    stack: &mut [MaybeUninit<E>],
    top: &mut usize,
) -> E {
    let mut next = entry(mask.trailing_zeros() as usize);
    mask &= mask - 1;
    let base = *top;
    while mask != 0 {
        let mut e = entry(mask.trailing_zeros() as usize);
        mask &= mask - 1;
        if SORTED && key(&e) < key(&next) {
            std::mem::swap(&mut e, &mut next);
        }
        let mut j = *top;
        // SAFETY: entries from `base` to `top` were written by this loop.
        while SORTED && j > base && key(unsafe { &stack[j - 1].assume_init() }) < key(&e) {
            stack[j] = stack[j - 1];
            j -= 1;
        }
        stack[j] = MaybeUninit::new(e);
        *top += 1;
    }
    next
}

/// How far slab distances are rounded outwards, relative to their size: more than the
/// roundings of a difference and a product, so that no hit is lost to them, whatever the
/// origin's distance from the box.
pub(crate) const WIDEN: f32 = 1.0 / (1 << 20) as f32;

/// The wide nodes of a trace layout whose kd nodes are `kd` (root first; none for a tree
/// with nothing to hit).
pub(crate) fn collapse(kd: &[Node], layout: &TraceLayout) -> Vec<WideNode> {
    // Every array is sized once: a grown one leaves its old copy resident (a wide node's
    // alignment rules out growing in place), and the wide nodes are counted before they are
    // made for that.
    let (blocks, interior) = kd.iter().fold((0, 0), |(b, i), n| match n.is_leaf() {
        true => (b + (n.count() as usize).div_ceil(BLOCK), i),
        false => (b, i + 1),
    });
    let mut c = Collapse {
        kd,
        layout,
        slot: vec![0; kd.len()],
        inner: Vec::with_capacity(interior),
        block_boxes: Vec::with_capacity(blocks),
        nodes: Vec::new(),
        pad: layout.reach * WIDEN,
    };
    if !kd.is_empty() && !layout.words.is_empty() && !c.content_of(0, layout.bounds).is_empty() {
        let count = c.count(0);
        c.nodes = Vec::with_capacity(count);
        c.make(0);
        debug_assert_eq!(c.nodes.len(), count);
    }
    c.nodes
}
