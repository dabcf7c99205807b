//! The GPU space tree against plain Rust: counts against direct counting over each node's
//! references, trees against the subtree maxima by definition, the walk's counters against
//! the CPU level builder's on a real mesh's root.

mod common;

use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use sahkd::geometry::triangle_bounds;
use sahkd::{Aabb, BuildOptions, Counting, Vec3};
use sahkd_gpu::space_tree::{run_space_tree, HostRun, TreeNode};
use sahkd_gpu::Gpu;
use std::time::Instant;

/// A level as the kernels see it: boxes per reference id, nine lists, their starts.
struct Level {
    boxes: Vec<Aabb>,
    members: Vec<Vec<u32>>,
    entries: Vec<u32>,
    starts: Vec<u32>,
}

impl Level {
    fn new(boxes: Vec<Aabb>, members: Vec<Vec<u32>>) -> Level {
        let mut entries = Vec::new();
        let mut starts = Vec::new();
        for a in 0..3 {
            let end = |r: u32, side: usize| {
                let b = &boxes[r as usize];
                [b.lo, b.hi][side][a]
            };
            for list in 0..3 {
                for m in &members {
                    starts.push(entries.len() as u32);
                    let mut ids: Vec<u32> = m.clone();
                    if list == 2 {
                        ids.retain(|&r| end(r, 0) == end(r, 1));
                    }
                    // Lists 3a + 1 by hi, the others by lo; ties by id.
                    let side = (list == 1) as usize;
                    ids.sort_by(|&x, &y| end(x, side).total_cmp(&end(y, side)).then(x.cmp(&y)));
                    entries.extend(ids);
                }
                starts.push(entries.len() as u32);
            }
        }
        Level {
            boxes,
            members,
            entries,
            starts,
        }
    }

    fn nodes(&self) -> usize {
        self.members.len()
    }

    /// The node's lo-sorted list on `axis`, as the tree's slots.
    fn lo_list(&self, axis: usize, k: usize) -> &[u32] {
        let stride = self.nodes() + 1;
        let s = self.starts[3 * axis * stride + k] as usize;
        let e = self.starts[3 * axis * stride + k + 1] as usize;
        &self.entries[s..e]
    }
}

/// L, R, P and the cut count of plane `p` by looking at every reference of the node.
fn direct(level: &Level, axis: usize, k: usize, p: f32) -> ([u32; 3], u64) {
    let (mut c, mut cut) = ([0u32; 3], 0);
    for &r in &level.members[k] {
        let b = &level.boxes[r as usize];
        let (lo, hi) = (b.lo[axis], b.hi[axis]);
        c[0] += (lo < p) as u32;
        c[1] += (hi > p) as u32;
        c[2] += (lo == p && hi == p) as u32;
        cut += (lo < p && p < hi) as u64;
    }
    (c, cut)
}

/// Every slot's max by its definition: the largest hi over the slots of its subtree, which
/// are the contiguous slots i - 2^h + 1 ..= i + 2^h - 1 cut at the segment's end.
fn check_trees(level: &Level, trees: &[TreeNode]) {
    let refs = level.starts[level.nodes()] as usize - level.starts[0] as usize;
    assert_eq!(trees.len(), 3 * refs);
    for a in 0..3 {
        let list_start = level.starts[3 * a * (level.nodes() + 1)] as usize;
        for k in 0..level.nodes() {
            let ids = level.lo_list(a, k);
            let n = ids.len();
            let first = level.starts[3 * a * (level.nodes() + 1) + k] as usize;
            let slots = &trees[a * refs + first - list_start..][..n];
            for i in 1..=n {
                let h = i.trailing_zeros();
                let span = (i + 1 - (1 << h))..=(i + (1 << h) - 1).min(n);
                let max = span
                    .map(|j| level.boxes[ids[j - 1] as usize].hi[a])
                    .fold(f32::NEG_INFINITY, f32::max);
                let b = &level.boxes[ids[i - 1] as usize];
                let expected = TreeNode {
                    lo: b.lo[a],
                    hi: b.hi[a],
                    max,
                };
                assert_eq!(
                    slots[i - 1],
                    expected,
                    "axis {a}, node {k} of {n}, slot {i}"
                );
            }
        }
    }
}

/// A coordinate on a grid of `grid` values, sometimes -0 (equal to +0 for every comparison).
fn coordinate(rng: &mut StdRng, grid: u32) -> f32 {
    let v = rng.random_range(0..grid) as f32 * 0.5 - (grid / 4) as f32;
    if v == 0.0 && rng.random_bool(0.5) {
        -0.0
    } else {
        v
    }
}

/// A box for a node of n references: small nodes on coarse grids (many equal ends, many flat
/// spans, planes cutting most spans), large ones short spans on a finer grid, like triangles.
fn random_box(rng: &mut StdRng, n: usize, grid: u32) -> Aabb {
    let mut lo = [0.0; 3];
    let mut hi = [0.0; 3];
    for a in 0..3 {
        if n > 1000 {
            lo[a] = rng.random_range(0..n as u32 / 4) as f32 * 0.25;
            hi[a] = lo[a] + rng.random_range(0..4) as f32 * 0.25;
        } else {
            let (x, y) = (coordinate(rng, grid), coordinate(rng, grid));
            let y = if rng.random_bool(0.25) { x } else { y };
            (lo[a], hi[a]) = if x <= y { (x, y) } else { (y, x) };
        }
    }
    Aabb::new(Vec3(lo), Vec3(hi))
}

/// Nodes of the given sizes in random order; most references new, some shared with earlier
/// nodes (a straddler is in both children).
fn random_level(rng: &mut StdRng, sizes: &[usize]) -> Level {
    let mut order = sizes.to_vec();
    for i in (1..order.len()).rev() {
        order.swap(i, rng.random_range(0..=i));
    }
    let mut boxes = Vec::new();
    let mut members = Vec::new();
    for &n in &order {
        let grid = [3, 10, 1000][rng.random_range(0..3)];
        let mut m: Vec<u32> = Vec::new();
        while m.len() < n {
            let shared = !boxes.is_empty() && rng.random_bool(0.1);
            let r = if shared {
                rng.random_range(0..boxes.len() as u32)
            } else {
                boxes.push(random_box(rng, n, grid));
                boxes.len() as u32 - 1
            };
            if !shared || !m.contains(&r) {
                m.push(r);
            }
        }
        members.push(m);
    }
    Level::new(boxes, members)
}

/// Candidates per axis block and node: ends of the node's spans (exactly on lo or hi), random
/// positions, holes; at most `per_node` of each node's ends.
fn random_candidates(
    rng: &mut StdRng,
    level: &Level,
    per_node: usize,
) -> (Vec<(f32, u32)>, usize, usize) {
    let mut cands = Vec::new();
    let mut firsts = [0; 3];
    for (a, first) in firsts.iter_mut().enumerate() {
        *first = cands.len();
        for (k, m) in level.members.iter().enumerate() {
            let picks = (2 * m.len()).min(per_node);
            for _ in 0..picks {
                let b = &level.boxes[m[rng.random_range(0..m.len())] as usize];
                let p = if rng.random_bool(0.5) {
                    b.lo[a]
                } else {
                    b.hi[a]
                };
                let hole = rng.random_bool(0.2);
                cands.push(if hole { (0.0, u32::MAX) } else { (p, k as u32) });
            }
            for _ in 0..3 {
                cands.push((rng.random_range(-300.0..300.0f32), k as u32));
            }
        }
    }
    (cands, firsts[1], firsts[2])
}

fn run(gpu: &Gpu, level: &Level, cands: &[(f32, u32)], first1: usize, first2: usize) -> HostRun {
    run_space_tree(
        gpu,
        &level.boxes,
        &level.entries,
        &level.starts,
        level.nodes(),
        cands,
        first1,
        first2,
    )
    .unwrap()
}

fn check_counts(level: &Level, cands: &[(f32, u32)], first1: usize, first2: usize, got: &HostRun) {
    let (mut cut, mut walks, mut nonempty) = (0, 0, 0);
    for (i, &(p, k)) in cands.iter().enumerate() {
        if k == u32::MAX {
            assert_eq!(got.counts[i], [0; 3], "hole {i}");
            continue;
        }
        let axis = (i >= first1) as usize + (i >= first2) as usize;
        let (c, np) = direct(level, axis, k as usize, p);
        assert_eq!(
            got.counts[i],
            c,
            "candidate {i}: axis {axis}, plane {p} in node {k} of {}",
            level.members[k as usize].len()
        );
        cut += np;
        walks += 1;
        nonempty += !level.members[k as usize].is_empty() as u64;
    }
    assert_eq!(got.stats.cut_primitives, cut, "cut primitives");
    assert_eq!(got.stats.walks, walks, "candidates walked");
    // A walk of a non-empty tree visits its root at least.
    assert!(got.stats.walk_steps >= nonempty, "{:?}", got.stats);
}

#[test]
fn counts_match_direct_counting_on_random_levels() {
    let Some(gpu) = common::gpu() else { return };
    let mut rng = StdRng::seed_from_u64(31);
    // The sizes asked for, with small random nodes between them.
    let mut sizes = vec![0, 1, 2, 3, 7, 8, 9, 1000, 70_000];
    sizes.extend((0..60).map(|_| rng.random_range(0..40)));
    // Then many tiny nodes: windows of the higher heights hold many segments.
    let tiny: Vec<usize> = (0..3000).map(|_| rng.random_range(0..12)).collect();
    for (sizes, per_node) in [(sizes, 3000), (tiny, 30)] {
        let level = random_level(&mut rng, &sizes);
        let (cands, first1, first2) = random_candidates(&mut rng, &level, per_node);
        let t = Instant::now();
        let got = run(&gpu, &level, &cands, first1, first2);
        eprintln!(
            "{} nodes, {} references, {} candidates: {:.0} ms, {:?}",
            level.nodes(),
            level.boxes.len(),
            cands.len(),
            t.elapsed().as_secs_f64() * 1e3,
            got.stats
        );
        check_trees(&level, &got.trees);
        check_counts(&level, &cands, first1, first2, &got);
    }
}

#[test]
fn identical_flat_and_empty_levels() {
    let Some(gpu) = common::gpu() else { return };
    let same = Aabb::new(Vec3([1.0; 3]), Vec3([2.0; 3]));
    let flat = Aabb::new(Vec3([1.0; 3]), Vec3([1.0; 3]));
    let mut boxes = vec![same; 300];
    boxes.extend(vec![flat; 300]);
    let members = vec![(0..300).collect(), (300..600).collect(), (0..600).collect()];
    let level = Level::new(boxes, members);
    let planes = [0.5, 1.0, 1.5, 2.0, 2.5];
    let mut cands = Vec::new();
    for _axis in 0..3 {
        for k in 0..3 {
            cands.extend(planes.iter().map(|&p| (p, k)));
        }
    }
    let (first1, first2) = (15, 30);
    let got = run(&gpu, &level, &cands, first1, first2);
    check_trees(&level, &got.trees);
    check_counts(&level, &cands, first1, first2, &got);
    // No references at all, and no candidates.
    let empty = Level::new(Vec::new(), vec![Vec::new(); 4]);
    let got = run(&gpu, &empty, &[], 0, 0);
    assert!(got.trees.is_empty() && got.counts.is_empty());
    assert_eq!(got.stats, Default::default());
}

/// The bunny's root as the paper's level builder lays it out: the longest axis, every span's
/// lo and hi as a candidate when strictly inside the scene box (the other axes' blocks empty;
/// their trees are built and checked all the same). The counts against binary searches of
/// the sorted ends, the walk's counters against the CPU's space-tree counting of that root.
/// (One axis, as the root's planes cut about 600 spans each: 820 walk steps per candidate.)
#[test]
fn bunny_root_counts_like_the_cpu() {
    let Some(gpu) = common::gpu() else { return };
    let Some(mesh) = common::scene("bunny.ply") else {
        return;
    };
    let triangles = mesh.corner_triangles();
    let boxes: Vec<Aabb> = triangles.iter().map(triangle_bounds).collect();
    let bounds = boxes.iter().fold(Aabb::EMPTY, |b, &t| b.union(t));
    let n = boxes.len();
    let level = Level::new(boxes, vec![(0..n as u32).collect()]);
    let a = bounds.longest_axis();
    let mut cands = Vec::new();
    for &r in level.lo_list(a, 0) {
        let b = &level.boxes[r as usize];
        for p in [b.lo[a], b.hi[a]] {
            let inside = bounds.lo[a] < p && p < bounds.hi[a];
            cands.push(if inside { (p, 0) } else { (0.0, u32::MAX) });
        }
    }
    // Axis a's block is the whole array; the blocks before and after it are empty.
    let first1 = if a == 0 { cands.len() } else { 0 };
    let first2 = if a == 2 { 0 } else { cands.len() };
    let t = Instant::now();
    let got = run(&gpu, &level, &cands, first1, first2);
    eprintln!(
        "bunny root, axis {a}: {} candidates in {:.0} ms, {:?}",
        cands.len(),
        t.elapsed().as_secs_f64() * 1e3,
        got.stats
    );
    check_trees(&level, &got.trees);
    let sorted = |f: &dyn Fn(&Aabb) -> f32, flat: bool| {
        let mut v: Vec<f32> = level
            .boxes
            .iter()
            .filter(|b| !flat || b.lo[a] == b.hi[a])
            .map(f)
            .collect();
        v.sort_by(f32::total_cmp);
        v
    };
    let (los, his, flats) = (
        sorted(&|b| b.lo[a], false),
        sorted(&|b| b.hi[a], false),
        sorted(&|b| b.lo[a], true),
    );
    let mut cut = 0u64;
    for (i, &(p, k)) in cands.iter().enumerate() {
        if k == u32::MAX {
            assert_eq!(got.counts[i], [0; 3]);
            continue;
        }
        let below = |v: &[f32]| v.partition_point(|&x| x < p) as u32;
        let through = |v: &[f32]| v.partition_point(|&x| x <= p) as u32;
        let c = [
            below(&los),
            n as u32 - through(&his),
            through(&flats) - below(&flats),
        ];
        assert_eq!(got.counts[i], c, "plane {p}");
        // lo < p < hi: lo < p, minus those with hi <= p, which have lo < p unless flat at p.
        cut += (c[0] - (n as u32 - c[1]) + c[2]) as u64;
    }
    assert_eq!(got.stats.cut_primitives, cut);
    let options = BuildOptions {
        counting: Counting::SpaceTree,
        ..BuildOptions::paper()
    };
    let cpu = sahkd::build_triangles(triangles, &options).unwrap();
    let root = &cpu.report.levels[0];
    assert_eq!(
        (
            got.stats.walk_steps,
            got.stats.cut_primitives,
            got.stats.walks as usize
        ),
        (root.walk_steps, root.cut_primitives, root.candidates),
        "walk steps, cut primitives, candidates: GPU vs CPU"
    );
}
