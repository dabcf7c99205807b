//! The closest point of the mesh: a depth-first walk of the trace layout's 8-wide nodes
//! (`tree::wide`), nearest child first, that skips every child whose box lies farther than
//! the best triangle found so far.
//!
//! A triangle's closest point lies in (the closed cell of) a kd leaf that references it, so
//! within the box of every wide child holding that leaf or the leaf's block of it (the
//! boxes are the triangles clipped to their cells, padded outwards): a child farther than
//! the best distance cannot hold a better answer. The bound is loosened by a slack far
//! above f64 rounding (1e-9 of the coordinates' magnitude, far below f32's resolution): the
//! walk then tests every triangle whose computed distance could tie or beat the best, and
//! its answer is the brute force's (`query::brute`) to the bit, ties going to the lower
//! triangle index.
//!
//! A node's eight box distances are measured at once in float32 (AVX2 where the CPU has
//! it), and so are the boxes of a leaf block's four triangles, each against the bound
//! loosened by float32's rounding, before any triangle is read one by one; a triangle is
//! skipped without its exact test when its plane already lies beyond the bound.

use super::triangle::{closest_on_triangle, cross, d3, dot, sub, D3};
use super::ClosestPoint;
use crate::cost::MAX_DEPTH_CAP;
use crate::geometry::{Aabb, Triangle, Vec3};
use crate::tree::layout::{block_prim, block_record, BLOCK, WORDS};
use crate::tree::wide::{push_children, WideNode, LEAF, WIDTH};
use crate::tree::KdTree;
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

/// The query point in float32, for the four-triangle box test ([`boxes_within`]).
struct Near32 {
    p: [f32; 3],
    /// An upper bound on how far rounding moved the point (zero for the usual float32 query
    /// point, whose scaled coordinates are exact in float32).
    moved: f64,
}

impl Near32 {
    fn new(p: D3) -> Near32 {
        let p32 = p.map(|x| x as f32);
        let moved = (0..3).map(|a| (p[a] - p32[a] as f64).abs()).sum();
        Near32 { p: p32, moved }
    }

    /// The float32 bound for [`boxes_within`] from the f64 `limit` (squared): loose enough
    /// that a box it rejects lies beyond `limit` from the exact point. The rounded point is
    /// at most `moved` away, so the bound's root grows by that; the float32 box distance's
    /// own rounding (a few units in the last place of a sum of three squares) and this
    /// bound's are far below the relative 1e-5 added; the absolute `f32::MIN_POSITIVE`
    /// covers squares that fall below float32's normal range. An infinite or huge `limit`
    /// gives infinity, which rejects nothing.
    fn limit(&self, limit: f64) -> f32 {
        let root = limit.sqrt() + self.moved;
        (root * root * (1.0 + 1e-5) + f32::MIN_POSITIVE as f64) as f32
    }
}

/// The lanes (bit `i` for triangle `i`) of a layout block of `k >= 2` triangles whose
/// bounding boxes lie within `limit32` (squared, from [`Near32::limit`]) of the point: the
/// four boxes' distances in one pass of float32 SSE, each coordinate row one vector load, as
/// the ray test reads the blocks (`trace::triangle`). The bound is conservative, so a
/// dropped lane's triangle lies beyond the f64 bound; the survivors take the one-triangle
/// tests.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn boxes_within(block: &[u32], near: &Near32, limit32: f32) -> u32 {
    use std::arch::x86_64::*;
    let k = block.len() / WORDS;
    assert!(k >= 2, "a block of at least 2 triangles");
    let ptr = block.as_ptr() as *const f32;
    // SAFETY: SSE is part of x86_64. Row `r <= 8` starts at word `r * k` and a load reads
    // 4 words, at most word `8 * k + 3 < 10 * k` for `k >= 2`: inside the block. Lanes
    // `k..4` read other rows' floats or indices as floats and are masked off.
    unsafe {
        let row = |r: usize| _mm_loadu_ps(ptr.add(r * k));
        let zero = _mm_setzero_ps();
        let mut d2 = zero;
        for a in 0..3 {
            let (x, y, z) = (row(a), row(3 + a), row(6 + a));
            let lo = _mm_min_ps(_mm_min_ps(x, y), z);
            let hi = _mm_max_ps(_mm_max_ps(x, y), z);
            let q = _mm_set1_ps(near.p[a]);
            let e = _mm_max_ps(_mm_max_ps(_mm_sub_ps(lo, q), _mm_sub_ps(q, hi)), zero);
            d2 = _mm_add_ps(d2, _mm_mul_ps(e, e));
        }
        let beyond = _mm_movemask_ps(_mm_cmpgt_ps(d2, _mm_set1_ps(limit32))) as u32;
        !beyond & ((1 << k) - 1)
    }
}

/// Every lane: the f64 tests decide alone.
#[cfg(not(target_arch = "x86_64"))]
#[inline(always)]
fn boxes_within(block: &[u32], _near: &Near32, _limit32: f32) -> u32 {
    (1 << (block.len() / WORDS)) - 1
}

/// `a` if greater, else `b`: a NaN in either gives `b`, as a vector max does.
#[inline(always)]
fn max2(a: f32, b: f32) -> f32 {
    if a > b {
        a
    } else {
        b
    }
}

/// The squared float32 distances from `q` to a wide node's eight boxes, lane by lane; NaN
/// for a lane without a child (its NaN bounds reach the sum, since `max2` passes its second
/// operand on) so that no comparison keeps it. The portable form, and the oracle of
/// [`lane_distances_avx2`].
#[inline(always)]
fn lane_distances(node: &WideNode, q: &[f32; 3]) -> [f32; WIDTH] {
    let mut d2 = [0f32; WIDTH];
    for a in 0..3 {
        for (l, d) in d2.iter_mut().enumerate() {
            let e = max2(
                0.0,
                max2(node.bounds[a][l] - q[a], q[a] - node.bounds[3 + a][l]),
            );
            *d += e * e;
        }
    }
    d2
}

/// [`lane_distances`] in AVX2, with the same operations in the same order (a vector max
/// returns its second operand where either is NaN, as `max2` does), so the same bits.
///
/// # Safety
/// The CPU must have AVX2. Called only from the walk compiled for AVX2, into which it is
/// inlined.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
unsafe fn lane_distances_avx2(node: &WideNode, q: &[f32; 3]) -> [f32; WIDTH] {
    use std::arch::x86_64::*;
    let zero = _mm256_setzero_ps();
    let mut d2 = zero;
    for a in 0..3 {
        let p = _mm256_set1_ps(q[a]);
        let below = _mm256_sub_ps(_mm256_load_ps(node.bounds[a].as_ptr()), p);
        let above = _mm256_sub_ps(p, _mm256_load_ps(node.bounds[3 + a].as_ptr()));
        let e = _mm256_max_ps(zero, _mm256_max_ps(below, above));
        d2 = _mm256_add_ps(d2, _mm256_mul_ps(e, e));
    }
    let mut out = [0f32; WIDTH];
    _mm256_storeu_ps(out.as_mut_ptr(), d2);
    out
}

/// A child to visit: a wide node's index or `LEAF | first triangle`, its triangle count,
/// and its box's squared float32 distance from the point ([`lane_distances`]).
#[derive(Clone, Copy)]
struct Pending {
    child: u32,
    count: u32,
    distance2: f32,
}

/// The closest point of the tree's triangles to `p`; `None` for an empty tree or a point
/// with a non-finite coordinate.
///
/// `hints` name triangles likely near `p` (neighbouring points' answers; indices out of
/// range are ignored): the nearest bounds the walk from the start, which then skips most of
/// what it would otherwise visit before finding a good triangle. The answer does not depend
/// on the hints: every triangle that could tie or beat the best is still tested, and the
/// tie rule is unchanged.
pub(crate) fn closest_point(tree: &KdTree, p: Vec3, hints: &[u32]) -> Option<ClosestPoint> {
    if tree.triangles.is_empty() || !p.is_finite() || tree.trace_layout().wide.is_empty() {
        return None;
    }
    #[cfg(target_arch = "x86_64")]
    if std::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU has AVX2 (checked just above).
        return unsafe { closest_point_avx2(tree, p, hints) };
    }
    closest_point_any::<false>(tree, p, hints)
}

/// The walk compiled for AVX2: a node's eight box distances become vector operations.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn closest_point_avx2(tree: &KdTree, p: Vec3, hints: &[u32]) -> Option<ClosestPoint> {
    closest_point_any::<true>(tree, p, hints)
}

/// The walk over the trace layout's wide nodes; `AVX2` (only from [`closest_point_avx2`])
/// measures a node's boxes in AVX2 vector operations.
#[inline(always)]
fn closest_point_any<const AVX2: bool>(
    tree: &KdTree,
    p: Vec3,
    hints: &[u32],
) -> Option<ClosestPoint> {
    // The walk reads the trace layout, whose coordinates are the tree's times `scale`, a
    // power of two (1 unless the scene is too large or too small for float32): the point is
    // scaled the same way, exactly in f64, and so is every distance, so the answer is the
    // one of the unscaled triangles to the bit.
    let layout = tree.trace_layout();
    let nodes = &layout.wide[..];
    let scale = layout.scale as f64;
    let pd = d3(p).map(|x| x * scale);
    let slack = slack(&layout.bounds, pd);
    // Best so far: squared distance, triangle, weights; `limit` is the loosened bound.
    let mut best: Option<(f64, u32, [f64; 3])> = None;
    let mut limit = f64::INFINITY;
    for &prim in hints
        .iter()
        .filter(|&&h| (h as usize) < tree.triangles.len())
    {
        // The corners as the layout holds them (times a power of two: exact).
        let corners = tree.triangles[prim as usize].map(|v| v * layout.scale);
        let found = closest_on_triangle(pd, &corners);
        let better = match best {
            None => true,
            Some((d2, b, _)) => found.distance2 < d2 || (found.distance2 == d2 && prim < b),
        };
        if better {
            best = Some((found.distance2, prim, found.weights));
            let bound = found.distance2.sqrt() + slack;
            limit = bound * bound;
        }
    }
    // Boxes are measured in float32 against the bound loosened for it (as the blocks'
    // triangle boxes are): a child is skipped only when the f64 bound would skip it too,
    // since a triangle's closest point lies in the box of a child that holds it.
    let near32 = Near32::new(pd);
    let mut limit32 = near32.limit(limit);
    // A wide node is at least one kd level deep and pushes at most seven children.
    let mut stack = [MaybeUninit::<Pending>::uninit(); 7 * MAX_DEPTH_CAP as usize + 8];
    let mut tested = [u32::MAX; TESTED];
    let mut top = 0usize;
    let mut current = Pending {
        child: 0,
        count: 0,
        distance2: 0.0,
    };
    loop {
        if current.child & LEAF == 0 {
            let node = &nodes[current.child as usize];
            let d2 = match AVX2 {
                #[cfg(target_arch = "x86_64")]
                // SAFETY: `AVX2` is set only in the walk compiled for AVX2, which runs where
                // the CPU has it.
                true => unsafe { lane_distances_avx2(node, &near32.p) },
                _ => lane_distances(node, &near32.p),
            };
            let mut mask = 0u32;
            for (l, &d) in d2.iter().enumerate() {
                mask |= ((d <= limit32) as u32) << l;
            }
            if mask != 0 {
                let entry = |lane: usize| Pending {
                    child: node.child[lane],
                    count: node.count[lane],
                    distance2: d2[lane],
                };
                // The nearest child is visited next; the others are pushed sorted, so the
                // nearest of them pops first.
                current =
                    push_children::<_, true>(mask, entry, |e| e.distance2, &mut stack, &mut top);
                continue;
            }
        } else {
            let first = (current.child & !LEAF) as usize * WORDS;
            let words = &layout.words[first..first + current.count as usize * WORDS];
            for block in words.chunks(BLOCK * WORDS) {
                let k = block.len() / WORDS;
                // The block's triangles whose boxes may lie within the bound, four at a
                // time; a block of one takes the one-triangle tests.
                let (mut lanes, filtered) = if k >= 2 {
                    (boxes_within(block, &near32, limit32), limit)
                } else {
                    (1, f64::INFINITY)
                };
                while lanes != 0 {
                    let i = lanes.trailing_zeros() as usize;
                    lanes &= lanes - 1;
                    // A triangle in several leaves needs no second look: it was either
                    // tested or found beyond a bound, and the bound only shrinks. Its index
                    // is read first, its corners only when they are needed.
                    let prim = block_prim(block, i);
                    let slot = &mut tested[prim as usize % TESTED];
                    if *slot == prim {
                        continue;
                    }
                    *slot = prim;
                    let record = block_record(block, i);
                    // The triangle's box and its plane bound its distance from below: cheap
                    // rejections once a good answer is known (the box only where the
                    // block's test did not make it with the bound as it is now).
                    let c = &record.corners;
                    if limit < filtered {
                        let tri_box = Aabb::new(c[0].min(c[1]).min(c[2]), c[0].max(c[1]).max(c[2]));
                        if box_distance2(pd, &tri_box) > limit {
                            continue;
                        }
                    }
                    if beyond_plane(pd, c, limit) {
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
                        limit32 = near32.limit(limit);
                    }
                }
            }
        }
        // The nearest pending child still within the bound, which only shrank since it was
        // pushed.
        loop {
            if top == 0 {
                return best.map(|(d2, prim, weights)| {
                    let d2 = d2 / (scale * scale);
                    ClosestPoint::new(d2, prim, weights, &tree.triangles[prim as usize])
                });
            }
            top -= 1;
            // SAFETY: entries below `top` were all written by a push.
            let e = unsafe { stack[top].assume_init() };
            if e.distance2 <= limit32 {
                current = e;
                break;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::query::brute;
    use crate::{build_triangles, BuildOptions};
    use rand::rngs::StdRng;
    use rand::{Rng, SeedableRng};

    /// The four-triangle filter never drops a triangle that lies within the bound: blocks of
    /// 2-4 random triangles (some flat) at every scale, points near and far, the bound set to
    /// each triangle's own distance plus the walk's slack (the tightest that must keep it), and the f64
    /// point off float32's grid so that the rounded point moves.
    #[test]
    fn the_block_filter_keeps_every_triangle_within_the_bound() {
        let mut rng = StdRng::seed_from_u64(11);
        let mut kept = 0;
        for round in 0..20_000 {
            let size = 10f32.powi(rng.random_range(-6..7));
            let point =
                |rng: &mut StdRng| Vec3(std::array::from_fn(|_| rng.random_range(-size..size)));
            let k = 2 + round % 3;
            let mut tris: Vec<Triangle> = (0..k)
                .map(|_| [point(&mut rng), point(&mut rng), point(&mut rng)])
                .collect();
            if round % 7 == 0 {
                tris[0][2] = tris[0][0] + (tris[0][1] - tris[0][0]) * 0.5;
            }
            let mut block = Vec::new();
            for r in 0..9 {
                block.extend(tris.iter().map(|t| t[r / 3][r % 3].to_bits()));
            }
            block.extend(0..k as u32);
            let reach = size * 10f32.powi(rng.random_range(-3..3));
            let p: D3 = std::array::from_fn(|_| rng.random_range(-reach..reach) as f64 * 1.1);
            let near = Near32::new(p);
            let corners: Vec<Vec3> = tris.iter().flatten().copied().collect();
            let slack = slack(&Aabb::of_points(&corners), p);
            for (i, t) in tris.iter().enumerate() {
                let bound = closest_on_triangle(p, t).distance2.sqrt() + slack;
                let limit = bound * bound;
                let lanes = boxes_within(&block, &near, near.limit(limit));
                assert!(lanes >> i & 1 == 1, "{t:?} from {p:?} at {limit}");
                kept += 1;
            }
        }
        assert!(kept > 0);
    }

    /// A node's float32 box distances keep every box within the bound, measured by the f64
    /// box distance from the exact point, and no empty lane; the AVX2 form gives the
    /// portable one's bits. Random boxes at every scale, some lanes empty, points inside,
    /// near and far and off float32's grid.
    #[test]
    fn node_distances_keep_every_box_within_the_bound() {
        let mut rng = StdRng::seed_from_u64(13);
        let mut kept = 0;
        for _ in 0..20_000 {
            let size = 10f32.powi(rng.random_range(-6..7));
            let mut node = WideNode::empty();
            let mut boxes = Vec::new();
            for lane in 0..WIDTH {
                if rng.random_range(0..4) == 0 {
                    continue;
                }
                let (x, y) = (
                    Vec3(std::array::from_fn(|_| rng.random_range(-size..size))),
                    Vec3(std::array::from_fn(|_| rng.random_range(-size..size))),
                );
                let b = Aabb::new(x.min(y), x.max(y));
                for a in 0..3 {
                    node.bounds[a][lane] = b.lo[a];
                    node.bounds[3 + a][lane] = b.hi[a];
                }
                boxes.push((lane, b));
            }
            let reach = size * 10f32.powi(rng.random_range(-3..3));
            let p: D3 = std::array::from_fn(|_| rng.random_range(-reach..reach) as f64 * 1.1);
            let near = Near32::new(p);
            let d2 = lane_distances(&node, &near.p);
            #[cfg(target_arch = "x86_64")]
            if std::is_x86_feature_detected!("avx2") {
                // SAFETY: the CPU has AVX2 (checked just above).
                let v = unsafe { lane_distances_avx2(&node, &near.p) };
                assert_eq!(v.map(f32::to_bits), d2.map(f32::to_bits));
            }
            let limit32 = near.limit(f64::INFINITY);
            for lane in 0..WIDTH {
                let empty = !boxes.iter().any(|&(l, _)| l == lane);
                assert_eq!(d2[lane] <= limit32, !empty, "lane {lane} of {node:?}");
            }
            for &(lane, b) in &boxes {
                let limit = box_distance2(p, &b);
                assert!(d2[lane] <= near.limit(limit), "{b:?} from {p:?}");
                kept += 1;
            }
        }
        assert!(kept > 0);
    }

    /// The walk without AVX2 (the form every CPU runs) answers as the brute force does, on
    /// a scaled scene (coordinates far below float32's comfortable range) and points near
    /// and far.
    #[test]
    fn portable_walk_matches_brute_force() {
        let mut rng = StdRng::seed_from_u64(17);
        for unit in [1.0f32, 1e-30] {
            let point = |rng: &mut StdRng, r: f32| {
                Vec3(std::array::from_fn(|_| rng.random_range(-r..r) * unit))
            };
            let tris: Vec<Triangle> = (0..500)
                .map(|_| {
                    let c = point(&mut rng, 1.0);
                    [0, 1, 2].map(|_| c + point(&mut rng, 0.1))
                })
                .collect();
            let tree = build_triangles(tris.clone(), &BuildOptions::default())
                .unwrap()
                .tree;
            for i in 0..1000 {
                let p = point(&mut rng, [1.2, 3.0][i % 2]);
                assert_eq!(
                    closest_point_any::<false>(&tree, p, &[]),
                    brute::closest_point(&tris, p),
                    "{p:?}"
                );
            }
        }
    }

    /// Hints change where a walk starts, never its answer: random points against random
    /// triangles with every triangle twice (ties everywhere), each point walked without
    /// hints, with the answer's duplicate, with far triangles and with out-of-range indices.
    #[test]
    fn answers_do_not_depend_on_the_hints() {
        let mut rng = StdRng::seed_from_u64(7);
        let point =
            |rng: &mut StdRng, r: f32| Vec3(std::array::from_fn(|_| rng.random_range(-r..r)));
        let mut tris: Vec<Triangle> = (0..300)
            .map(|_| {
                let c = point(&mut rng, 1.0);
                [
                    c + point(&mut rng, 0.1),
                    c + point(&mut rng, 0.1),
                    c + point(&mut rng, 0.1),
                ]
            })
            .collect();
        tris.extend(tris.clone());
        let n = tris.len() as u32;
        let tree = build_triangles(tris.clone(), &BuildOptions::default())
            .unwrap()
            .tree;
        for _ in 0..300 {
            let p = point(&mut rng, 2.5);
            let want = brute::closest_point(&tris, p);
            let prim = want.unwrap().prim;
            let twin = (prim + n / 2) % n;
            let others = [rng.random_range(0..n), rng.random_range(0..n)];
            for hints in [
                &[][..],
                &[twin][..],
                &[prim, twin][..],
                &[others[0], others[1], twin][..],
                &[n, u32::MAX, others[0]][..],
            ] {
                assert_eq!(
                    closest_point(&tree, p, hints),
                    want,
                    "{p:?} with hints {hints:?}"
                );
            }
        }
    }
}
