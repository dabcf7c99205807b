//! The paper's counting: the space tree, an interval tree laid out in a node's lo-sorted list.
//!
//! The list `s[0..n]` is read as an implicit balanced binary search tree: slot `i` (1-based)
//! holds `s[i - 1]`, has height `h = trailing_zeros(i)`, children `i -+ 2^(h-1)` and covers the
//! slots `i - 2^h + 1 ..= i + 2^h - 1`. This is the in-order layout of the perfect tree of
//! `2^k - 1` slots covering the list (each range's middle slot is its root); slots past `n` are
//! absent. Each present slot stores its span's `lo` and `hi` and `T` = the largest `hi` in its
//! subtree (12 bytes, so that a step of the walk reads one place), computed bottom-up, height
//! by height, without recursion. Because a slot's parent is found from its index alone, the
//! walk needs no stack.
//!
//! Counting a plane `p` over a node of `n` spans:
//! - `L = #(lo < p)` and `#(lo <= p)` by binary search in the lo-sorted list;
//! - the walk finds `R = #(hi > p)`: a subtree with `T <= p` holds nothing right of `p` and is
//!   skipped; a slot with `lo > p` lies right of `p` with its whole right subtree (added in one
//!   go, only its left subtree is walked); any other slot is classified itself (cut: `lo < p <
//!   hi`, the paper's NP; or touching: `lo == p < hi`) and both subtrees are walked. The walk
//!   visits O(NP + log n) slots when few spans touch `p`;
//! - `P = #(lo == hi == p) = #(lo == p) - touching`, since a span with `lo == p` has `hi == p`
//!   or `hi > p`.

use super::candidates::{self, fill_extents, Candidates, Counts, HOLE};
use super::entries::Span;
use super::segments::Scatter;
use super::Level;
use crate::cost::CostModel;
use rayon::prelude::*;

/// Phase 1: the lo and hi of every span of every node, on the node's axes.
pub(super) fn candidates(level: &Level<Span>, uses: &[u8], cands: &mut Candidates) {
    let starts = [0, 1, 2].map(|a| level.list_starts[a].as_slice());
    fill_extents(cands, starts, uses, &level.boxes, |axis, i| {
        let s = level.lists[axis][i];
        (s.lo, s.hi)
    });
}

/// One slot of a space tree: a span and the largest `hi` in its subtree.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(super) struct TreeNode {
    pub lo: f32,
    pub hi: f32,
    pub max: f32,
}

/// Where the space trees of node segments on `axis` live in the level's tree array: with all
/// axes one block per axis, otherwise one block (each node uses one axis). Span lists have one
/// entry per reference on every axis, so their segments coincide on all axes.
fn block(axis: usize, all: bool, len: usize) -> usize {
    if all {
        axis * len
    } else {
        0
    }
}

/// Segments above this size build their tree in parallel.
const PARALLEL_TREE: usize = 1 << 15;
/// Height of the aligned subtrees built independently in a parallel build (2^14 slots).
const BLOCK_HEIGHT: u32 = 13;

/// Phase 2: the space tree of every node on each axis it uses.
pub(super) fn build_trees(level: &Level<Span>, uses: &[u8], all: bool, trees: &mut Vec<TreeNode>) {
    let len = level.lists[0].len();
    let total = if all { 3 * len } else { len };
    trees.clear();
    // Entries of nodes that are not priced are never read; zero-filling once per level keeps
    // the array initialised at the cost of one cheap pass.
    trees.resize(total, TreeNode::default());
    let sink = Scatter::new(trees);
    (0..level.nodes())
        .into_par_iter()
        .with_min_len(64)
        .for_each(|k| {
            for axis in 0..3 {
                if uses[k] & (1 << axis) == 0 {
                    continue;
                }
                let (s, e) = (
                    level.list_starts[axis][k] as usize,
                    level.list_starts[axis][k + 1] as usize,
                );
                let at = block(axis, all, len);
                // Safety: node segments are disjoint, and each (node, axis) pair owns its
                // segment of its block.
                let t = unsafe { sink.slice(at + s..at + e) };
                build_tree(&level.lists[axis][s..e], t);
            }
        });
}

/// Fills `tree` (same length as `spans`) with the space tree of the spans.
pub(super) fn build_tree(spans: &[Span], tree: &mut [TreeNode]) {
    let n = spans.len();
    if n == 0 {
        return;
    }
    let copy = |t: &mut [TreeNode], s: &[Span]| {
        for (t, s) in t.iter_mut().zip(s) {
            *t = TreeNode {
                lo: s.lo,
                hi: s.hi,
                max: s.hi,
            };
        }
    };
    let top = usize::BITS - 1 - n.leading_zeros();
    if n < PARALLEL_TREE {
        copy(tree, spans);
        fill_heights(tree, 1..top + 1);
        return;
    }
    // Aligned blocks of 2^(B+1) slots hold whole subtrees of height <= B (and one slot of a
    // greater height at their end, left alone): build those in parallel, then the few slots
    // above serially.
    let size = 1usize << (BLOCK_HEIGHT + 1);
    tree.par_chunks_mut(size)
        .zip(spans.par_chunks(size))
        .for_each(|(t, s)| {
            copy(t, s);
            fill_heights(t, 1..BLOCK_HEIGHT + 1);
        });
    fill_heights(tree, BLOCK_HEIGHT + 1..top + 1);
}

/// Computes `T` for the present slots of the given heights (from 1; height 0 is `T = hi`),
/// lowest first; lower heights must be done already.
fn fill_heights(tree: &mut [TreeNode], heights: std::ops::Range<u32>) {
    let n = tree.len();
    for h in heights {
        let half = 1usize << (h - 1);
        let mut i = 1usize << h;
        while i <= n {
            let mut t = tree[i - 1].hi.max(tree[i - half - 1].max);
            if let Some(r) = subtree_max(tree, n, i + half) {
                t = t.max(r);
            }
            tree[i - 1].max = t;
            i += 2 << h;
        }
    }
}

/// `T` of the subtree at slot `c`, which may be absent: an absent slot's present descendants
/// all lie in its left subtree.
#[inline]
fn subtree_max(tree: &[TreeNode], n: usize, mut c: usize) -> Option<f32> {
    while c > n {
        let h = c.trailing_zeros();
        if h == 0 {
            return None;
        }
        c -= 1 << (h - 1);
    }
    Some(tree[c - 1].max)
}

/// Counts of one plane, with the walk's statistics.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(super) struct Walk {
    pub counts: Counts,
    /// Primitives with `lo < p < hi` (the paper's NP).
    pub cut: u32,
    /// Slots visited.
    pub steps: u32,
}

/// Counts the plane `p` over one node's space tree.
pub(super) fn count_plane(tree: &[TreeNode], p: f32) -> Walk {
    let n = tree.len();
    let below = tree.partition_point(|s| s.lo < p);
    let through = tree.partition_point(|s| s.lo <= p);
    let (mut right, mut cut, mut touching, mut steps) = (0usize, 0u32, 0u32, 0u32);
    if n > 0 {
        let root = 1usize << (usize::BITS - 1 - n.leading_zeros());
        let mut i = root;
        'walk: loop {
            // Down into slot i.
            steps += 1;
            let h = i.trailing_zeros();
            let mut down = true;
            if i <= n {
                let s = tree[i - 1];
                if s.max <= p {
                    down = false;
                } else if s.lo > p {
                    right += (i + (1 << h) - 1).min(n) - i + 1;
                } else if s.hi > p {
                    if s.lo < p {
                        cut += 1;
                    } else {
                        touching += 1;
                    }
                }
            }
            if down && h > 0 {
                i -= 1 << (h - 1);
                continue;
            }
            // Up to the nearest ancestor, entered from its left, whose right subtree is due:
            // one that was classified itself (present, T > p, lo <= p).
            loop {
                if i == root {
                    break 'walk;
                }
                let h = i.trailing_zeros();
                if (i >> (h + 1)) & 1 == 0 {
                    let parent = i + (1 << h);
                    if parent <= n && tree[parent - 1].max > p && tree[parent - 1].lo <= p {
                        i = parent + (1 << h);
                        continue 'walk;
                    }
                    i = parent;
                } else {
                    i -= 1 << h;
                }
            }
        }
    }
    Walk {
        counts: Counts {
            left: below as u32,
            right: right as u32 + cut + touching,
            planar: (through - below) as u32 - touching,
        },
        cut,
        steps,
    }
}

/// Phase 3: counts and prices every candidate of the level, one parallel pass over the
/// candidate array. Returns the candidates priced, the total walk steps and cut primitives.
pub(super) fn count(
    level: &Level<Span>,
    cands: &mut Candidates,
    trees: &[TreeNode],
    all: bool,
    cost: &CostModel,
) -> (usize, u64, u64) {
    let len = level.lists[0].len();
    let firsts = [0, 1, 2].map(|a| cands.ranges[a].first().map_or(0, |r| r[0]));
    // Safety: fill_extents writes every slot.
    let items = unsafe { cands.all_mut() };
    items
        .par_iter_mut()
        .enumerate()
        .with_min_len(256)
        .map(|(i, c)| {
            if c.owner == HOLE {
                return (0, 0, 0);
            }
            let axis = candidates::axis_in(&firsts, i);
            let k = c.owner as usize;
            let (s, e) = (
                level.list_starts[axis][k] as usize,
                level.list_starts[axis][k + 1] as usize,
            );
            let at = block(axis, all, len);
            let w = count_plane(&trees[at + s..at + e], c.pos);
            *c = candidates::price(cost, &level.boxes[k], axis, c.pos, c.owner, w.counts);
            (1, w.steps as u64, w.cut as u64)
        })
        .reduce(|| (0, 0, 0), |a, b| (a.0 + b.0, a.1 + b.1, a.2 + b.2))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::builders::level::Lcg;

    fn direct(spans: &[Span], p: f32) -> (Counts, u32) {
        let mut c = Counts::default();
        let mut cut = 0;
        for s in spans {
            c.left += (s.lo < p) as u32;
            c.right += (s.hi > p) as u32;
            c.planar += (s.lo == p && s.hi == p) as u32;
            cut += (s.lo < p && p < s.hi) as u32;
        }
        (c, cut)
    }

    fn sorted(mut spans: Vec<Span>) -> Vec<Span> {
        spans.sort_by(|a, b| a.lo.total_cmp(&b.lo).then(a.slot.cmp(&b.slot)));
        spans
    }

    fn tree_of(spans: &[Span]) -> Vec<TreeNode> {
        let mut t = vec![TreeNode::default(); spans.len()];
        build_tree(spans, &mut t);
        t
    }

    fn check(spans: &[Span]) {
        let t = tree_of(spans);
        let mut planes: Vec<f32> = spans.iter().flat_map(|s| [s.lo, s.hi]).collect();
        planes.extend([-1.0, 0.5, 1e9]);
        for p in planes {
            let w = count_plane(&t, p);
            let (c, cut) = direct(spans, p);
            assert_eq!(
                (w.counts, w.cut),
                (c, cut),
                "plane {p} over {} spans",
                spans.len()
            );
        }
    }

    /// Random intervals on a coarse grid: many duplicates, planar spans (lo == hi) and spans
    /// starting or ending exactly on a candidate.
    #[test]
    fn walk_matches_direct_counting_on_random_intervals() {
        let mut rng = Lcg(7);
        for n in (0..70).chain([127, 128, 129, 255, 256, 257, 1000]) {
            for grid in [3u32, 10, 1000] {
                let spans: Vec<Span> = (0..n)
                    .map(|i| {
                        let a = rng.next(grid) as f32;
                        let b = if rng.next(4) == 0 {
                            a
                        } else {
                            rng.next(grid) as f32
                        };
                        Span {
                            lo: a.min(b),
                            hi: a.max(b),
                            slot: i,
                        }
                    })
                    .collect();
                check(&sorted(spans));
            }
        }
    }

    #[test]
    fn walk_handles_identical_and_all_planar_spans() {
        let same: Vec<Span> = (0..300)
            .map(|i| Span {
                lo: 1.0,
                hi: 2.0,
                slot: i,
            })
            .collect();
        check(&same);
        let flat: Vec<Span> = (0..300)
            .map(|i| Span {
                lo: 1.0,
                hi: 1.0,
                slot: i,
            })
            .collect();
        check(&flat);
    }

    /// The parallel build of a large segment equals the serial one.
    #[test]
    fn parallel_tree_equals_serial_tree() {
        let mut rng = Lcg(11);
        let n = PARALLEL_TREE * 3 + 12345;
        let spans = sorted(
            (0..n as u32)
                .map(|i| {
                    let a = rng.next(100_000) as f32;
                    Span {
                        lo: a,
                        hi: a + rng.next(500) as f32,
                        slot: i,
                    }
                })
                .collect(),
        );
        let parallel = tree_of(&spans);
        let mut serial: Vec<TreeNode> = spans
            .iter()
            .map(|s| TreeNode {
                lo: s.lo,
                hi: s.hi,
                max: s.hi,
            })
            .collect();
        let top = usize::BITS - 1 - n.leading_zeros();
        fill_heights(&mut serial, 1..top + 1);
        assert_eq!(parallel, serial);
        for p in [0.0, 5000.5, 50_000.0, 99_999.0] {
            assert_eq!(count_plane(&parallel, p).counts, direct(&spans, p).0);
        }
    }

    /// The walk's cost tracks the cut primitives, not the node size.
    #[test]
    fn walk_steps_grow_with_cut_primitives_not_with_n() {
        let n = 1 << 16;
        let spans: Vec<Span> = (0..n as u32)
            .map(|i| Span {
                lo: i as f32,
                hi: i as f32 + 0.5,
                slot: i,
            })
            .collect();
        let t = tree_of(&spans);
        let w = count_plane(&t, 1000.25);
        assert_eq!(w.cut, 1);
        assert!(w.steps < 4 * 17, "{} steps", w.steps);
    }
}
