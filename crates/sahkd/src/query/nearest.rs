//! The closest point of the mesh: a depth-first walk of the kd-tree, nearer child first,
//! that skips every node whose content lies farther than the best triangle found so far.
//!
//! A triangle's closest point lies in (the closed box of) a leaf that references it, so it
//! lies in the triangle's box cut by that leaf's cell: the union of these over a leaf's
//! triangles, and over a subtree's leaves, is the node's *content box* (made once per tree,
//! on the first query, 24 bytes per node). A node whose content box lies farther than the
//! best distance cannot hold a better answer. The kd-tree's cells tile the whole scene box,
//! empty space included, so pruning by the cells alone visited every cell between a far
//! point and the surface; the content boxes skip empty cells outright and shrink the others
//! to what they hold, as a bounding volume hierarchy's boxes would. The bound is loosened by
//! a slack far above f64 rounding (1e-9 of the coordinates' magnitude, far below f32's
//! resolution): the walk then tests every triangle whose computed distance could tie or
//! beat the best, and its answer is the brute force's (`query::brute`) to the bit, ties
//! going to the lower triangle index. A triangle is skipped without its exact test when its
//! bounding box or its plane already lies beyond the bound.

use super::triangle::{closest_on_triangle, cross, d3, dot, sub, D3};
use super::ClosestPoint;
use crate::cost::MAX_DEPTH_CAP;
use crate::geometry::{Aabb, Triangle, Vec3};
use crate::tree::layout::{block_record, TraceLayout, BLOCK, WORDS};
use crate::tree::{KdTree, Node};
use std::mem::MaybeUninit;

/// The slack of the pruning bound, relative to the largest coordinate magnitude involved.
const SLACK: f64 = 1e-9;

/// Squared distance from `p` to the closed box `b`, in f64 (exact differences of f32s).
#[inline(always)]
pub(crate) fn box_distance2(p: D3, b: &Aabb) -> f64 {
    let mut d = 0.0;
    for (a, &x) in p.iter().enumerate() {
        let (lo, hi) = (b.lo[a] as f64, b.hi[a] as f64);
        let e = if x < lo {
            lo - x
        } else if x > hi {
            x - hi
        } else {
            0.0
        };
        d += e * e;
    }
    d
}

/// The pruning slack for a query point: SLACK of the largest magnitude among the point's and
/// the mesh box's coordinates.
pub(crate) fn slack(bounds: &Aabb, p: D3) -> f64 {
    let m = (0..3)
        .flat_map(|a| {
            [
                bounds.lo[a].abs() as f64,
                bounds.hi[a].abs() as f64,
                p[a].abs(),
            ]
        })
        .fold(0.0f64, f64::max);
    SLACK * m
}

/// Slots of the per-query memory of triangles already tested (direct-mapped by index): a
/// triangle clipped into several leaves is tested once while the walk stays near it.
const TESTED: usize = 256;

/// Whether the triangle's plane lies farther from `p` than `limit` (squared): then so does
/// the triangle. The f64 rounding here is far below the bound's slack, so no triangle that
/// could tie the best is skipped. A zero-area triangle has no plane and is never skipped.
#[inline(always)]
fn beyond_plane(p: D3, c: &Triangle, limit: f64) -> bool {
    let a = d3(c[0]);
    let n = cross(sub(d3(c[1]), a), sub(d3(c[2]), a));
    let h = dot(n, sub(p, a));
    h * h > limit * dot(n, n)
}

/// A node to visit and the squared distance from the point to its content box.
#[derive(Clone, Copy)]
struct Pending {
    node: u32,
    distance2: f64,
}

impl KdTree {
    /// The content box of every node of the trace layout (see the module's notes).
    fn content_boxes(&self) -> &[Aabb] {
        self.content_boxes.get_or_init(|| {
            let layout = self.trace_layout();
            content_boxes(layout.nodes(self), layout)
        })
    }
}

/// Content boxes of `nodes` (the layout's, whose children come after their parent): the
/// cells top down, then, bottom up, each leaf's triangles' box cut by its cell and each
/// interior node's children's union. An empty node's box is `Aabb::EMPTY`, infinitely far.
fn content_boxes(nodes: &[Node], layout: &TraceLayout) -> Vec<Aabb> {
    let mut boxes = vec![Aabb::EMPTY; nodes.len()];
    boxes[0] = layout.bounds;
    for (i, node) in nodes.iter().enumerate() {
        if !node.is_leaf() {
            let (lo, hi) = boxes[i].split(node.axis(), node.split());
            let left = node.left() as usize;
            (boxes[left], boxes[left + 1]) = (lo, hi);
        }
    }
    for (i, node) in nodes.iter().enumerate().rev() {
        boxes[i] = if node.is_leaf() {
            let held = layout
                .leaf_words(node)
                .chunks(BLOCK * WORDS)
                .flat_map(|b| (0..b.len() / WORDS).map(move |i| block_record(b, i)))
                .fold(Aabb::EMPTY, |held, r| {
                    held.union(Aabb::of_points(&r.corners))
                })
                .intersection(boxes[i]);
            if held.is_empty() {
                Aabb::EMPTY
            } else {
                held
            }
        } else {
            let left = node.left() as usize;
            boxes[left].union(boxes[left + 1])
        };
    }
    boxes
}

/// The closest point of the tree's triangles to `p`; `None` for an empty tree or a point
/// with a non-finite coordinate.
pub(crate) fn closest_point(tree: &KdTree, p: Vec3) -> Option<ClosestPoint> {
    if tree.triangles.is_empty() || !p.is_finite() {
        return None;
    }
    // The walk reads the trace layout, whose coordinates are the tree's times `scale`, a
    // power of two (1 unless the scene is too large or too small for float32): the point is
    // scaled the same way, exactly in f64, and so is every distance, so the answer is the
    // one of the unscaled triangles to the bit.
    let layout = tree.trace_layout();
    let nodes = layout.nodes(tree);
    let scale = layout.scale as f64;
    let pd = d3(p).map(|x| x * scale);
    let slack = slack(&layout.bounds, pd);
    // Best so far: squared distance, triangle, weights; `limit` is the loosened bound.
    let mut best: Option<(f64, u32, [f64; 3])> = None;
    let mut limit = f64::INFINITY;
    let mut stack = [MaybeUninit::<Pending>::uninit(); MAX_DEPTH_CAP as usize + 4];
    let mut tested = [u32::MAX; TESTED];
    let mut top = 0usize;
    let boxes = tree.content_boxes();
    let mut current = Pending {
        node: 0,
        distance2: box_distance2(pd, &boxes[0]),
    };
    loop {
        if current.distance2 <= limit {
            let node = &nodes[current.node as usize];
            if node.is_leaf() {
                let blocks = layout.leaf_words(node).chunks(BLOCK * WORDS);
                for (block, i) in blocks.flat_map(|b| (0..b.len() / WORDS).map(move |i| (b, i))) {
                    // A triangle in several leaves needs no second look: it was either
                    // tested or found beyond a bound, and the bound only shrinks. Its index
                    // is read first, its corners only when they are needed.
                    let prim = block[9 * (block.len() / WORDS) + i];
                    let slot = &mut tested[prim as usize % TESTED];
                    if *slot == prim {
                        continue;
                    }
                    *slot = prim;
                    let record = block_record(block, i);
                    // The triangle's box and its plane bound its distance from below: cheap
                    // rejections of most of a leaf's triangles once a good answer is known.
                    let c = &record.corners;
                    let tri_box = Aabb::new(c[0].min(c[1]).min(c[2]), c[0].max(c[1]).max(c[2]));
                    if box_distance2(pd, &tri_box) > limit || beyond_plane(pd, c, limit) {
                        continue;
                    }
                    let found = closest_on_triangle(pd, &record.corners);
                    let better = match best {
                        None => true,
                        Some((d2, prim, _)) => {
                            found.distance2 < d2 || (found.distance2 == d2 && record.prim < prim)
                        }
                    };
                    if better {
                        best = Some((found.distance2, record.prim, found.weights));
                        let bound = found.distance2.sqrt() + slack;
                        limit = bound * bound;
                    }
                }
            } else {
                // The child whose content is nearer first; the other waits on the stack
                // if it could still hold a better answer.
                let left = node.left();
                let (dl, dr) = (
                    box_distance2(pd, &boxes[left as usize]),
                    box_distance2(pd, &boxes[left as usize + 1]),
                );
                let (near, far) = if dl <= dr {
                    ((left, dl), (left + 1, dr))
                } else {
                    ((left + 1, dr), (left, dl))
                };
                if far.1 <= limit {
                    stack[top] = MaybeUninit::new(Pending {
                        node: far.0,
                        distance2: far.1,
                    });
                    top += 1;
                }
                current = Pending {
                    node: near.0,
                    distance2: near.1,
                };
                continue;
            }
        }
        if top == 0 {
            break;
        }
        top -= 1;
        // SAFETY: entries below `top` were all written by a push.
        current = unsafe { stack[top].assume_init() };
    }
    best.map(|(d2, prim, weights)| {
        let d2 = d2 / (scale * scale);
        ClosestPoint::new(d2, prim, weights, &tree.triangles[prim as usize])
    })
}
