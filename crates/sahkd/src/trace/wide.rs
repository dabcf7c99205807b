//! The kd-tree collapsed into 8-wide bounded nodes, walked one ray at a time with the slab
//! tests of all eight children at once (AVX2 where the CPU has it).
//!
//! Every kd node gets the box of what it holds: a leaf's triangles clipped to its cell, an
//! interior node the union of its children's. A wide node is made from a kd node by opening,
//! again and again, the child of largest box area among its current children while what it
//! opens into still fits eight: an interior kd node into its two children, a leaf of more than
//! one 4-triangle block of the trace layout into its blocks, each with the box of its own
//! triangles (children holding nothing are dropped). Leaves are runs of the trace layout's
//! words, tested as the kd walk tests them, so the answers are the kd walk's; a child's box
//! is padded so that the float32 slab test cannot miss a hit on its border, and the walk
//! keeps the pending children of a closest-hit walk sorted by entry distance, nearest on top.
//!
//! Not yet walked by the public queries: `examples/trace_throughput --walk wide` measures it
//! against the kd walk's packets and single rays (BENCHMARKS.md, "A wide layout").

use super::{visit_leaf, Closest, Hit, Ray, ShearedRay, TraceCounters};
use crate::clip::clipped_bounds;
use crate::cost::MAX_DEPTH_CAP;
use crate::geometry::Aabb;
use crate::tree::layout::{block_record, TraceLayout, BLOCK, WORDS};
use crate::tree::{KdTree, Node};
use std::mem::MaybeUninit;

const WIDTH: usize = 8;
/// A child that is a leaf: `LEAF | first triangle` in the layout's words.
const LEAF: u32 = 1 << 31;

/// Eight children: rows lo x, lo y, lo z, hi x, hi y, hi z of their boxes, lane = child.
#[repr(C, align(64))]
#[derive(Clone, Copy)]
struct WideNode {
    bounds: [[f32; WIDTH]; 6],
    child: [u32; WIDTH],
    count: [u32; WIDTH],
}

impl WideNode {
    /// No children: a lane without one has a NaN box, which every comparison fails.
    fn empty() -> WideNode {
        WideNode {
            bounds: [[f32::NAN; WIDTH]; 6],
            child: [0; WIDTH],
            count: [0; WIDTH],
        }
    }
}

/// The wide layout of one tree.
pub struct WideBvh<'a> {
    tree: &'a KdTree,
    nodes: Vec<WideNode>,
}

/// Per kd node of the trace layout: its content box (empty when it holds nothing) and, for a
/// leaf, where its blocks' boxes start in `block_boxes` (one per 4-triangle block, in order).
struct Collapse<'a> {
    kd: &'a [Node],
    layout: &'a TraceLayout,
    content: Vec<Aabb>,
    first_block: Vec<u32>,
    block_boxes: Vec<Aabb>,
    nodes: Vec<WideNode>,
    pad: f32,
}

/// A child of a wide node being made: a kd node, or one block of a kd leaf (its first
/// triangle in the layout, its count and its box).
#[derive(Clone, Copy)]
enum Kid {
    Kd(u32),
    Block(u32, u32, Aabb),
}

impl Collapse<'_> {
    fn content_of(&mut self, i: u32, cell: Aabb) -> Aabb {
        let node = self.kd[i as usize];
        let b = if node.is_leaf() {
            self.first_block[i as usize] = self.block_boxes.len() as u32;
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
            a.union(c)
        };
        self.content[i as usize] = b;
        b
    }

    fn bounds(&self, kid: &Kid) -> Aabb {
        match *kid {
            Kid::Kd(k) => self.content[k as usize],
            Kid::Block(_, _, b) => b,
        }
    }

    /// What opening `kid` gives at most: an interior kd node its two children, a leaf of
    /// more than a block its blocks; 0 where it cannot be opened.
    fn pieces(&self, kid: &Kid) -> usize {
        match *kid {
            Kid::Kd(k) => {
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

    /// Makes the wide node of kd node `i`: its children opened, the largest box first, while
    /// what they open into fits eight; returns the wide node's index.
    fn make(&mut self, i: u32) -> u32 {
        let mut kids = vec![Kid::Kd(i)];
        loop {
            let open = (0..kids.len())
                .filter(|&j| {
                    let p = self.pieces(&kids[j]);
                    p > 0 && kids.len() - 1 + p <= WIDTH
                })
                .max_by(|&a, &b| {
                    Self::area(&self.bounds(&kids[a]))
                        .total_cmp(&Self::area(&self.bounds(&kids[b])))
                });
            let Some(j) = open else { break };
            let Kid::Kd(k) = kids.remove(j) else {
                unreachable!("only kd nodes open")
            };
            let node = self.kd[k as usize];
            if node.is_leaf() {
                // Its blocks' boxes, made with its content box.
                let boxes = &self.block_boxes[self.first_block[k as usize] as usize..];
                for (j, &b) in boxes.iter().take(self.pieces(&Kid::Kd(k))).enumerate() {
                    let first = (j * BLOCK) as u32;
                    if !b.is_empty() {
                        let count = (node.count() - first).min(BLOCK as u32);
                        kids.push(Kid::Block(node.first() + first, count, b));
                    }
                }
            } else {
                for c in [node.left(), node.left() + 1] {
                    if !self.content[c as usize].is_empty() {
                        kids.push(Kid::Kd(c));
                    }
                }
            }
        }
        debug_assert!(kids.len() <= WIDTH);
        let at = self.nodes.len() as u32;
        self.nodes.push(WideNode::empty());
        let mut node = WideNode::empty();
        for (lane, kid) in kids.iter().enumerate() {
            let b = self.bounds(kid);
            for a in 0..3 {
                // Padded by the scene's own margin and by a few roundings of the coordinate:
                // far from the origin a float32 step dwarfs the scene's margin.
                node.bounds[a][lane] = b.lo[a] - (self.pad + b.lo[a].abs() * WIDEN);
                node.bounds[3 + a][lane] = b.hi[a] + (self.pad + b.hi[a].abs() * WIDEN);
            }
            (node.child[lane], node.count[lane]) = match *kid {
                Kid::Block(first, count, _) => (LEAF | first, count),
                Kid::Kd(k) => {
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

/// What a ray needs to test a node's boxes: per axis, the row of the face it meets first
/// (`near`) and last (`far`), its origin and the reciprocal of its direction.
struct Slabs {
    near: [usize; 3],
    far: [usize; 3],
    origin: [f32; 3],
    rd: [f32; 3],
}

/// How far slab distances are rounded outwards, relative to their size: more than the
/// roundings of a difference and a product, so that no hit is lost to them, whatever the
/// origin's distance from the box.
const WIDEN: f32 = 1.0 / (1 << 20) as f32;

/// `a` if greater, else `b`: a NaN in either gives `b`, as a vector max does.
#[inline(always)]
fn max2(a: f32, b: f32) -> f32 {
    if a > b {
        a
    } else {
        b
    }
}

/// `a` if less, else `b`: a NaN in either gives `b`.
#[inline(always)]
fn min2(a: f32, b: f32) -> f32 {
    if a < b {
        a
    } else {
        b
    }
}

impl Slabs {
    /// The ray's reciprocal direction and the rows of the faces it meets first and last.
    #[inline(always)]
    fn of(ray: &Ray) -> Slabs {
        let d = ray.direction;
        // A zero (or subnormal) component gets the smallest normal float as a stand-in: its
        // reciprocal stays finite, so slab distances are never NaN (an infinite one times
        // a zero difference would be), and a ray parallel to a slab is kept or not by its
        // origin, as with an infinite reciprocal.
        let rd = [0, 1, 2].map(|a| {
            let x = d[a];
            let x = if x.abs() < f32::MIN_POSITIVE {
                f32::MIN_POSITIVE.copysign(x)
            } else {
                x
            };
            1.0 / x
        });
        Slabs {
            near: [0, 1, 2].map(|a| if rd[a] < 0.0 { 3 + a } else { a }),
            far: [0, 1, 2].map(|a| if rd[a] < 0.0 { a } else { 3 + a }),
            origin: ray.origin.0,
            rd,
        }
    }

    /// The children whose boxes the ray enters within `[t_min, limit]` (bit `i` for lane `i`)
    /// and where it enters each. A lane whose box is NaN fails (the NaN reaches the last
    /// comparison), and so does a box wholly beyond or behind a ray parallel to a slab (an
    /// infinite near distance widened is NaN).
    #[inline(always)]
    fn enter(&self, node: &WideNode, t_min: f32, limit: f32) -> (u32, [f32; WIDTH]) {
        let mut tn = [0f32; WIDTH];
        let mut hit = [0u32; WIDTH];
        for l in 0..WIDTH {
            let s = |r: usize, a: usize| (node.bounds[r][l] - self.origin[a]) * self.rd[a];
            let n = max2(
                max2(s(self.near[0], 0), s(self.near[1], 1)),
                s(self.near[2], 2),
            );
            let f = min2(
                min2(s(self.far[0], 0), s(self.far[1], 1)),
                s(self.far[2], 2),
            );
            let n = max2(t_min, n - n.abs() * WIDEN);
            let f = min2(limit, f + f.abs() * WIDEN);
            tn[l] = n;
            hit[l] = (n <= f) as u32;
        }
        let mut mask = 0;
        for (l, &h) in hit.iter().enumerate() {
            mask |= h << l;
        }
        (mask, tn)
    }

    /// [`Self::enter`] in AVX2 vector operations, with the same roundings and NaN rules (a
    /// vector max or min returns its second operand where either is NaN, as `max2` does).
    ///
    /// # Safety
    /// The CPU must have AVX2. Called only from the walk compiled for AVX2, into which it is
    /// inlined with the intrinsics it calls (a function of its own would not be).
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    unsafe fn enter_avx2(&self, node: &WideNode, t_min: f32, limit: f32) -> (u32, [f32; WIDTH]) {
        use std::arch::x86_64::*;
        let row = |r: usize| _mm256_load_ps(node.bounds[r].as_ptr());
        let slab = |r: usize, a: usize| {
            _mm256_mul_ps(
                _mm256_sub_ps(row(r), _mm256_set1_ps(self.origin[a])),
                _mm256_set1_ps(self.rd[a]),
            )
        };
        let n = _mm256_max_ps(
            _mm256_max_ps(slab(self.near[0], 0), slab(self.near[1], 1)),
            slab(self.near[2], 2),
        );
        let f = _mm256_min_ps(
            _mm256_min_ps(slab(self.far[0], 0), slab(self.far[1], 1)),
            slab(self.far[2], 2),
        );
        let abs = _mm256_castsi256_ps(_mm256_set1_epi32(0x7fff_ffff));
        let widen = _mm256_set1_ps(WIDEN);
        let n = _mm256_sub_ps(n, _mm256_mul_ps(_mm256_and_ps(n, abs), widen));
        let f = _mm256_add_ps(f, _mm256_mul_ps(_mm256_and_ps(f, abs), widen));
        let n = _mm256_max_ps(_mm256_set1_ps(t_min), n);
        let f = _mm256_min_ps(_mm256_set1_ps(limit), f);
        let mask = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(n, f)) as u32;
        let mut tn = [0f32; WIDTH];
        _mm256_storeu_ps(tn.as_mut_ptr(), n);
        (mask, tn)
    }
}

/// A pending child: what it is and where the ray enters its box.
#[derive(Clone, Copy)]
struct Entry {
    child: u32,
    count: u32,
    t: f32,
}

impl<'a> WideBvh<'a> {
    /// The wide layout of `tree` (made from its trace layout, which this makes if no query
    /// has yet).
    pub fn new(tree: &'a KdTree) -> WideBvh<'a> {
        let layout = tree.trace_layout();
        let kd = layout.nodes(tree);
        let mut c = Collapse {
            kd,
            layout,
            content: vec![Aabb::EMPTY; kd.len()],
            first_block: vec![0; kd.len()],
            block_boxes: Vec::new(),
            nodes: Vec::new(),
            pad: layout.reach * WIDEN,
        };
        if !kd.is_empty() && !tree.triangles().is_empty() {
            c.content_of(0, layout.bounds);
            if !c.content[0].is_empty() {
                c.make(0);
            }
        }
        WideBvh {
            tree,
            nodes: c.nodes,
        }
    }

    /// Bytes of the wide nodes.
    pub fn bytes(&self) -> usize {
        self.nodes.len() * std::mem::size_of::<WideNode>()
    }

    /// The number of wide nodes.
    pub fn len(&self) -> usize {
        self.nodes.len()
    }

    /// True for a tree with nothing to hit.
    pub fn is_empty(&self) -> bool {
        self.nodes.is_empty()
    }

    /// [`Self::intersect`], counting wide nodes visited, leaves entered and triangles tested.
    pub fn intersect_counted(&self, ray: &Ray, counters: &mut impl TraceCounters) -> Option<Hit> {
        let layout = self.tree.trace_layout();
        let mut closest = Closest::new(self.tree.triangles(), ray, layout.scale, layout.reach);
        self.walk::<true>(ray, counters, |hit, limit| {
            closest.offer(hit, limit);
            false
        });
        closest.best()
    }

    /// [`Self::occluded`], counting as [`Self::intersect_counted`] does.
    pub fn occluded_counted(&self, ray: &Ray, counters: &mut impl TraceCounters) -> bool {
        let mut found = false;
        self.walk::<false>(ray, counters, |_, _| {
            found = true;
            true
        });
        found
    }

    /// The closest hit in `[ray.t_min, ray.t_max]`: [`KdTree::intersect`]'s answer.
    pub fn intersect(&self, ray: &Ray) -> Option<Hit> {
        self.intersect_counted(ray, &mut ())
    }

    /// True when anything is hit in `[ray.t_min, ray.t_max]`: [`KdTree::occluded`]'s answer.
    pub fn occluded(&self, ray: &Ray) -> bool {
        self.occluded_counted(ray, &mut ())
    }

    /// The walk; `ORDERED` keeps the pending children sorted by entry distance, which a
    /// closest hit needs to stop early and an any hit does not (it stops at any hit).
    #[inline(always)]
    fn walk<const ORDERED: bool>(
        &self,
        ray: &Ray,
        counters: &mut impl TraceCounters,
        visit: impl FnMut(Hit, &mut f32) -> bool,
    ) {
        if !ray.is_valid() || self.nodes.is_empty() {
            return;
        }
        #[cfg(target_arch = "x86_64")]
        if std::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU has AVX2 (checked just above).
            return unsafe { self.walk_avx2::<ORDERED>(ray, counters, visit) };
        }
        self.walk_any::<false, ORDERED>(ray, counters, visit)
    }

    /// The walk compiled for AVX2: a node's eight slab tests become vector operations.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn walk_avx2<const ORDERED: bool>(
        &self,
        ray: &Ray,
        counters: &mut impl TraceCounters,
        visit: impl FnMut(Hit, &mut f32) -> bool,
    ) {
        self.walk_any::<true, ORDERED>(ray, counters, visit)
    }

    /// The walk; `AVX2` (only from [`Self::walk_avx2`]) tests a node's boxes in AVX2
    /// vector operations, `ORDERED` as in [`Self::walk`].
    #[inline(always)]
    fn walk_any<const AVX2: bool, const ORDERED: bool>(
        &self,
        ray: &Ray,
        counters: &mut impl TraceCounters,
        mut visit: impl FnMut(Hit, &mut f32) -> bool,
    ) {
        let layout = self.tree.trace_layout();
        let ray = &ray.scaled(layout.scale);
        if !ray.origin.is_finite() {
            return;
        }
        let slabs = Slabs::of(ray);
        let mut sheared: Option<ShearedRay> = None;
        let mut stack = [MaybeUninit::<Entry>::uninit(); 7 * MAX_DEPTH_CAP as usize + 8];
        let mut top = 0usize;
        let mut limit = ray.t_max;
        let mut cur = Entry {
            child: 0,
            count: 0,
            t: ray.t_min,
        };
        loop {
            if cur.child & LEAF == 0 {
                counters.node();
                let node = &self.nodes[cur.child as usize];
                let (mut mask, ts) = match AVX2 {
                    #[cfg(target_arch = "x86_64")]
                    // SAFETY: `AVX2` is set only in the walk compiled for AVX2, which runs
                    // where the CPU has it.
                    true => unsafe { slabs.enter_avx2(node, ray.t_min, limit) },
                    _ => slabs.enter(node, ray.t_min, limit),
                };
                if mask != 0 {
                    let lane = mask.trailing_zeros() as usize;
                    mask &= mask - 1;
                    let first = Entry {
                        child: node.child[lane],
                        count: node.count[lane],
                        t: ts[lane],
                    };
                    if mask == 0 {
                        cur = first;
                        continue;
                    }
                    // Two or more: all pushed; ordered, sorted so that the nearest is popped
                    // first.
                    let base = top;
                    let mut push = |e: Entry, top: &mut usize| {
                        let mut j = *top;
                        // SAFETY: entries from `base` to `top` were written by this push.
                        while ORDERED && j > base && unsafe { stack[j - 1].assume_init() }.t < e.t {
                            stack[j] = stack[j - 1];
                            j -= 1;
                        }
                        stack[j] = MaybeUninit::new(e);
                        *top += 1;
                    };
                    push(first, &mut top);
                    while mask != 0 {
                        let lane = mask.trailing_zeros() as usize;
                        mask &= mask - 1;
                        push(
                            Entry {
                                child: node.child[lane],
                                count: node.count[lane],
                                t: ts[lane],
                            },
                            &mut top,
                        );
                    }
                }
            } else {
                counters.leaf();
                let first = (cur.child & !LEAF) as usize * WORDS;
                let words = &layout.words[first..first + cur.count as usize * WORDS];
                let sheared =
                    sheared.get_or_insert_with(|| ShearedRay::with_reach(ray, layout.reach));
                if visit_leaf(sheared, words, ray.t_min, &mut limit, counters, &mut visit) {
                    return;
                }
            }
            loop {
                if top == 0 {
                    return;
                }
                top -= 1;
                // SAFETY: entries below `top` were all written by a push.
                let e = unsafe { stack[top].assume_init() };
                if e.t <= limit {
                    cur = e;
                    break;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Vec3;
    use crate::{build_triangles, BuildOptions};
    use rand::rngs::StdRng;
    use rand::{Rng, SeedableRng};

    /// The vector box test gives the scalar one's lanes and entry distances, with NaN lanes,
    /// boxes on every side of the origin and directions with zero components.
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn vector_box_test_equals_scalar() {
        if !std::is_x86_feature_detected!("avx2") {
            eprintln!("skipped: this CPU has no AVX2");
            return;
        }
        let mut rng = StdRng::seed_from_u64(5);
        for round in 0..20_000 {
            let mut node = WideNode::empty();
            for lane in 0..rng.random_range(0..=WIDTH) {
                for a in 0..3 {
                    let (x, y) = (
                        rng.random_range(-4.0..4.0f32),
                        rng.random_range(-4.0..4.0f32),
                    );
                    node.bounds[a][lane] = x.min(y);
                    node.bounds[3 + a][lane] = x.max(y);
                }
            }
            let mut d = [0f32; 3].map(|_| rng.random_range(-1.0..1.0f32));
            if round % 3 == 0 {
                d[round % 9 / 3] = 0.0;
            }
            let origin = [0f32; 3].map(|_| rng.random_range(-5.0..5.0f32));
            let ray = Ray::new(Vec3(origin), Vec3(d));
            let slabs = Slabs::of(&ray);
            let (t_min, limit) = (
                rng.random_range(-1.0..1.0f32),
                rng.random_range(0.0..20.0f32),
            );
            let (mask, tn) = slabs.enter(&node, t_min, limit);
            // SAFETY: the CPU has AVX2 (checked above).
            let (vmask, vtn) = unsafe { slabs.enter_avx2(&node, t_min, limit) };
            assert_eq!(mask, vmask, "round {round}");
            for lane in (0..WIDTH).filter(|l| mask >> l & 1 == 1) {
                assert_eq!(tn[lane].to_bits(), vtn[lane].to_bits(), "round {round}");
            }
        }
    }

    /// The walk without AVX2 answers as the brute force does.
    #[test]
    fn portable_walk_matches_brute_force() {
        let mut rng = StdRng::seed_from_u64(9);
        let tris: Vec<[Vec3; 3]> = (0..500)
            .map(|_| {
                let c = Vec3([0f32; 3].map(|_| rng.random_range(0.0..10.0f32)));
                [0, 1, 2].map(|_| c + Vec3([0f32; 3].map(|_| rng.random_range(-1.0..1.0f32))))
            })
            .collect();
        let tree = build_triangles(tris, &BuildOptions::default())
            .unwrap()
            .tree;
        let wide = WideBvh::new(&tree);
        for i in 0..2000 {
            let o = Vec3([0f32; 3].map(|_| rng.random_range(-2.0..12.0f32)));
            let mut d = Vec3([0f32; 3].map(|_| rng.random_range(-1.0..1.0f32)));
            if i % 4 == 0 {
                d[i % 3] = 0.0;
            }
            let ray = Ray::new(o, d);
            let layout = tree.trace_layout();
            let mut closest = Closest::new(tree.triangles(), &ray, layout.scale, layout.reach);
            wide.walk_any::<false, true>(&ray, &mut (), |hit, limit| {
                closest.offer(hit, limit);
                false
            });
            assert_eq!(
                closest.best(),
                crate::trace::brute::intersect(tree.triangles(), &ray),
                "ray {i}"
            );
        }
    }
}
