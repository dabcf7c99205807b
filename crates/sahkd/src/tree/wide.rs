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
use crate::tree::layout::{in_runs, Placement, BLOCK};
use crate::tree::Node;
use rayon::prelude::*;
use std::mem::MaybeUninit;
use std::sync::atomic::{AtomicU32, Ordering::Relaxed};

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
/// only where they are not a union of others: a leaf's as its blocks' boxes in `block_boxes`
/// (one per 4-triangle block, in order, from `slot[leaf]` on), an interior node's in `inner`
/// at the index of its pair of children (`(left - 1) / 2`: the layout numbers pairs from 1).
/// They are what the collapse holds beside the tree and the wide nodes (the layout's words
/// are made after they are freed), so they take 4 bytes per kd node and 24 per interior node
/// and per block, rather than a box and an index for every kd node. An interior kd node's `slot` counts the wide nodes made from it (`count`).
struct Collapse<'a> {
    kd: &'a [Node],
    slot: Vec<AtomicU32>,
    inner: Vec<Aabb>,
    block_boxes: Vec<Aabb>,
    pad: f32,
}

/// A child of a wide node being made, with its box: a kd node, or one block of a kd leaf
/// (its first triangle in the layout and its count).
#[derive(Clone, Copy)]
enum Kid {
    Kd(u32, Aabb),
    Block(u32, u32, Aabb),
}

impl<'a> Collapse<'a> {
    fn new(kd: &'a [Node], placement: &Placement, bounds: Aabb, reach: f32) -> Collapse<'a> {
        let mut c = Collapse {
            kd,
            slot: std::iter::repeat_with(|| AtomicU32::new(0))
                .take(kd.len())
                .collect(),
            inner: Vec::new(),
            block_boxes: Vec::new(),
            pad: reach * WIDEN,
        };
        c.clip_leaves(placement, bounds);
        c.inner = vec![Aabb::EMPTY; kd.len() / 2];
        // Children before parents: the layout numbers a node's children after it.
        for i in (0..kd.len()).rev() {
            let node = kd[i];
            if !node.is_leaf() {
                debug_assert!(node.left() as usize > i && node.left() % 2 == 1);
                let b = c.content(node.left()).union(c.content(node.left() + 1));
                c.inner[node.left() as usize / 2] = b;
            }
        }
        c
    }

    /// The boxes of every leaf's blocks, clipped to the leaf's cell: the cells found in one
    /// walk down, the clipping (the collapse's costly part) in parallel over runs of leaves,
    /// each writing its own part of `block_boxes`, so they are the same on any thread count.
    fn clip_leaves(&mut self, placement: &Placement, bounds: Aabb) {
        // The layout's leaves in the order `placement` has the tree's, with their cells.
        let mut leaves = Vec::with_capacity(placement.leaves.len());
        let mut blocks = 0;
        let mut stack = vec![(0u32, bounds)];
        while let Some((i, cell)) = stack.pop() {
            let node = self.kd[i as usize];
            if node.is_leaf() {
                if node.count() > 0 {
                    *self.slot[i as usize].get_mut() = blocks as u32;
                    blocks += (node.count() as usize).div_ceil(BLOCK);
                    let leaf = placement.leaves[leaves.len()];
                    debug_assert_eq!(leaf.count(), node.count());
                    leaves.push((leaf, cell));
                }
            } else {
                let (l, r) = cell.split(node.axis(), node.split());
                stack.extend([(node.left() + 1, r), (node.left(), l)]);
            }
        }
        let mut boxes = vec![Aabb::EMPTY; blocks];
        let blocks_of = |(node, _): &(Node, Aabb)| (node.count() as usize).div_ceil(BLOCK);
        in_runs(&leaves, blocks_of, &mut boxes, |run, out| {
            let blocks = run.iter().flat_map(|(leaf, cell)| {
                placement.blocks(leaf).map(|block| {
                    block.iter().fold(Aabb::EMPTY, |b, &prim| {
                        b.union(clipped_bounds(&placement.corners(prim), cell))
                    })
                })
            });
            for (o, b) in out.iter_mut().zip(blocks) {
                *o = b;
            }
        });
        self.block_boxes = boxes;
    }

    /// The boxes of kd leaf `k`'s blocks.
    fn blocks(&self, k: u32) -> &[Aabb] {
        let first = self.slot[k as usize].load(Relaxed) as usize;
        let count = (self.kd[k as usize].count() as usize).div_ceil(BLOCK);
        &self.block_boxes[first..first + count]
    }

    fn content(&self, k: u32) -> Aabb {
        let node = self.kd[k as usize];
        if node.is_leaf() {
            self.blocks(k).iter().fold(Aabb::EMPTY, |a, b| a.union(*b))
        } else {
            self.inner[node.left() as usize / 2]
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
    fn kids(&self, i: u32) -> Kids {
        let mut kids = Kids {
            kid: [Kid::Kd(i, self.content(i)); WIDTH],
            len: 1,
        };
        loop {
            let n = kids.len;
            let open = (0..n)
                .filter(|&j| {
                    let p = self.pieces(&kids.kid[j]);
                    p > 0 && n - 1 + p <= WIDTH
                })
                .max_by(|&a, &b| {
                    Self::area(&Self::bounds(&kids.kid[a]))
                        .total_cmp(&Self::area(&Self::bounds(&kids.kid[b])))
                });
            let Some(j) = open else { break };
            let Kid::Kd(k, _) = kids.kid[j] else {
                unreachable!("only kd nodes open")
            };
            kids.kid[j..n].rotate_left(1);
            kids.len -= 1;
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
        kids
    }

    /// How many wide nodes `make(i)` makes, noted in `slot[i]` for it; at the top
    /// `PARALLEL_LEVELS` levels of wide nodes the children are counted in parallel.
    fn count(&self, i: u32, level: usize) -> u32 {
        let kids = self.kids(i);
        let below = |kid: &Kid| match *kid {
            Kid::Kd(k, _) if !self.kd[k as usize].is_leaf() => self.count(k, level + 1),
            _ => 0,
        };
        let n = 1 + if level < PARALLEL_LEVELS {
            kids.as_slice().par_iter().map(below).sum::<u32>()
        } else {
            kids.as_slice().iter().map(below).sum()
        };
        if !self.kd[i as usize].is_leaf() {
            // A leaf's slot says where its blocks' boxes are (a tree of one leaf).
            self.slot[i as usize].store(n, Relaxed);
        }
        n
    }

    /// Writes the wide node of kd node `i`, whose index is `at`, to `out[0]`, and the wide
    /// nodes below it after it: each child's in lane order, numbered as a depth-first walk
    /// would number them, so the nodes are the same on any thread count. At the top
    /// `PARALLEL_LEVELS` levels the children are made in parallel.
    fn make(&self, i: u32, at: u32, out: &mut [WideNode], level: usize) {
        let (node, mut rest) = out.split_first_mut().expect("counted");
        let mut below = Vec::new();
        let mut next = at + 1;
        for (lane, kid) in self.kids(i).as_slice().iter().enumerate() {
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
                        let n = self.slot[k as usize].load(Relaxed);
                        let (theirs, tail) = std::mem::take(&mut rest).split_at_mut(n as usize);
                        rest = tail;
                        below.push((k, next, theirs));
                        next += n;
                        (next - n, 0)
                    }
                }
            };
        }
        let make = |(k, at, out): (u32, u32, &mut [WideNode])| self.make(k, at, out, level + 1);
        if level < PARALLEL_LEVELS {
            below.into_par_iter().for_each(make);
        } else {
            below.into_iter().for_each(make);
        }
    }
}

/// The children of a wide node being made, in lane order.
struct Kids {
    kid: [Kid; WIDTH],
    len: usize,
}

impl Kids {
    fn push(&mut self, kid: Kid) {
        self.kid[self.len] = kid;
        self.len += 1;
    }

    fn as_slice(&self) -> &[Kid] {
        &self.kid[..self.len]
    }
}

/// Levels of wide nodes, from the root, whose children are counted and made in parallel.
const PARALLEL_LEVELS: usize = 3;

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

/// The wide nodes of a trace layout whose kd nodes are `kd` and whose triangles are placed
/// as `placement` says, in a box `bounds` of largest extent `reach` (root first; none for a
/// tree with nothing to hit).
pub(crate) fn collapse(
    kd: &[Node],
    placement: &Placement,
    bounds: Aabb,
    reach: f32,
) -> Vec<WideNode> {
    if kd.is_empty() || placement.leaves.is_empty() {
        return Vec::new();
    }
    let c = Collapse::new(kd, placement, bounds, reach);
    if c.content(0).is_empty() {
        return Vec::new();
    }
    // Counted first, so that each subtree's nodes have their place before they are made, and
    // the array is sized once: a grown one leaves its old copy resident (a wide node's
    // alignment rules out growing in place).
    let mut nodes = vec![WideNode::empty(); c.count(0, 0) as usize];
    c.make(0, 0, &mut nodes, 0);
    nodes
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{Triangle, Vec3};
    use crate::tree::layout::{TraceLayout, WORDS};
    use crate::{build_triangles, Algorithm, BuildOptions};
    use rand::rngs::StdRng;
    use rand::{Rng, SeedableRng};

    fn layout_on(threads: usize, tree: &crate::KdTree) -> TraceLayout {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| TraceLayout::new(tree))
    }

    /// The wide nodes are made in parallel: one thread and four give the same nodes, bit for
    /// bit, and they form a tree: every node reached once from the root, every triangle of the
    /// layout in at most one leaf lane.
    #[test]
    fn wide_nodes_are_the_same_on_any_thread_count_and_form_a_tree() {
        let mut rng = StdRng::seed_from_u64(7);
        let mut next = move || rng.random::<f32>();
        let tris: Vec<Triangle> = (0..20_000)
            .map(|_| {
                let c = Vec3::new(next() * 100.0, next() * 100.0, next() * 10.0);
                [
                    c,
                    c + Vec3::new(next(), 0.0, next()),
                    c + Vec3::new(0.0, next(), next()),
                ]
            })
            .collect();
        for algorithm in [Algorithm::Hybrid, Algorithm::Level] {
            let options = BuildOptions {
                algorithm,
                ..BuildOptions::default()
            };
            let tree = build_triangles(tris.clone(), &options).unwrap().tree;
            let one = layout_on(1, &tree);
            let four = layout_on(4, &tree);
            let bits = |l: &TraceLayout| -> Vec<u32> {
                l.wide
                    .iter()
                    .flat_map(|n| {
                        let b = n.bounds.iter().flatten().map(|f| f.to_bits());
                        b.chain(n.child).chain(n.count).collect::<Vec<_>>()
                    })
                    .collect()
            };
            assert!(
                one.wide.len() > 100,
                "{algorithm:?}: a tree worth collapsing"
            );
            assert_eq!(bits(&one), bits(&four), "{algorithm:?}");

            let mut reached = vec![0u32; one.wide.len()];
            let mut covered = vec![0u32; one.words.len() / WORDS];
            let mut stack = vec![0usize];
            while let Some(i) = stack.pop() {
                reached[i] += 1;
                let n = &one.wide[i];
                for lane in (0..WIDTH).filter(|&l| !n.bounds[0][l].is_nan()) {
                    if n.child[lane] & LEAF != 0 {
                        let first = (n.child[lane] & !LEAF) as usize;
                        for t in &mut covered[first..first + n.count[lane] as usize] {
                            *t += 1;
                        }
                    } else {
                        stack.push(n.child[lane] as usize);
                    }
                }
            }
            assert!(reached.iter().all(|&r| r == 1), "{algorithm:?}");
            assert!(covered.iter().all(|&c| c <= 1), "{algorithm:?}");
            assert!(covered.iter().filter(|&&c| c == 1).count() * 10 > covered.len() * 9);
        }
    }
}
