//! The level builder (both countings) and the naive builder: rays against the brute-force
//! oracle, structure, determinism over thread counts, degenerate input, agreement between the
//! countings and with naive, and the root split against a brute-force best split.

mod common;

use sahkd::trace::brute;
use sahkd::{
    build, build_triangles, Aabb, Algorithm, Axes, BuildOptions, Counting, KdTree, Ray, Triangle,
    Vec3,
};

/// The level builder with the default options (the library's default is the hybrid).
fn level_options() -> BuildOptions {
    BuildOptions {
        algorithm: Algorithm::Level,
        ..BuildOptions::default()
    }
}

/// A small deterministic generator (no dependency needed for test data).
struct Rng(u64);

impl Rng {
    fn next_u32(&mut self) -> u32 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (self.0 >> 32) as u32
    }
    /// Uniform in [0, 1).
    fn unit(&mut self) -> f32 {
        (self.next_u32() >> 8) as f32 / (1u32 << 24) as f32
    }
    fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.unit()
    }
    fn below(&mut self, n: u32) -> u32 {
        self.next_u32() % n
    }
}

fn snap(x: f32, grid: f32) -> f32 {
    (x * grid).round() / grid
}

/// A soup of `n` triangles in the unit cube mixing what builders get wrong: large and small
/// triangles, corners on a coarse grid (shared lo/hi values), axis-aligned triangles (planar
/// on an axis, often in the same plane), and zero-area ones.
fn random_triangles(seed: u64, n: usize) -> Vec<Triangle> {
    let mut rng = Rng(seed);
    (0..n)
        .map(|i| {
            let c = Vec3::new(rng.unit(), rng.unit(), rng.unit());
            let size = [0.5, 0.02, 0.02, 0.1, 0.1, 0.1, 0.1][i % 7];
            let mut t = [(); 3].map(|_| {
                c + Vec3::new(
                    rng.range(-size, size),
                    rng.range(-size, size),
                    rng.range(-size, size),
                )
            });
            match i % 5 {
                0 => t
                    .iter_mut()
                    .for_each(|v| (0..3).for_each(|a| v[a] = snap(v[a], 8.0))),
                1 => {
                    let axis = i % 3;
                    let plane = snap(c[axis], 16.0);
                    t.iter_mut().for_each(|v| v[axis] = plane);
                }
                _ => {}
            }
            if i % 37 == 0 {
                t[2] = t[0] * 0.5 + t[1] * 0.5; // zero area
            }
            t
        })
        .collect()
}

fn bounds(tris: &[Triangle]) -> Aabb {
    tris.iter().flatten().fold(Aabb::EMPTY, |b, &v| b.grow(v))
}

/// Rays from around and inside the scene, including axis-parallel ones, rays along grid planes
/// and rays with a bounded range.
fn random_rays(seed: u64, scene: Aabb, n: usize) -> Vec<Ray> {
    let mut rng = Rng(seed);
    let (lo, d) = (scene.lo, scene.extent());
    let point = |rng: &mut Rng, margin: f32| {
        Vec3::new(
            lo[0] + d[0] * rng.range(-margin, 1.0 + margin),
            lo[1] + d[1] * rng.range(-margin, 1.0 + margin),
            lo[2] + d[2] * rng.range(-margin, 1.0 + margin),
        )
    };
    (0..n)
        .map(|i| {
            let o = point(&mut rng, 0.3);
            let mut dir = point(&mut rng, 0.0) - o;
            match i % 6 {
                0 => {
                    let a = rng.below(3) as usize;
                    dir = Vec3::splat(0.0);
                    dir[a] = if rng.below(2) == 0 { 1.0 } else { -1.0 };
                }
                1 => dir[rng.below(3) as usize] = 0.0,
                _ => {}
            }
            if dir == Vec3::splat(0.0) {
                dir = Vec3::new(0.3, -0.2, 1.0);
            }
            let ray = Ray::new(o, dir);
            if i % 7 == 0 {
                ray.with_range(0.1, 0.8)
            } else {
                ray
            }
        })
        .collect()
}

/// Rays from random points around the scene aimed at the centroids of some triangles, so that
/// scenes of tiny triangles are hit too.
fn aimed_rays(seed: u64, tris: &[Triangle], n: usize) -> Vec<Ray> {
    let mut rng = Rng(seed);
    let scene = bounds(tris);
    let around = random_rays(seed, scene, n);
    (0..n)
        .map(|i| {
            let t = &tris[rng.below(tris.len() as u32) as usize];
            let centroid = (t[0] + t[1] + t[2]) * (1.0 / 3.0);
            let o = around[i].origin;
            Ray::new(o, centroid - o)
        })
        .collect()
}

/// Every ray's closest hit and any-hit answer equal brute force over all triangles, and enough
/// rays hit something for that to mean something.
fn assert_oracle(tree: &KdTree, rays: &[Ray], case: &str) {
    let hits = assert_matches(tree, rays, case);
    assert!(
        hits * 20 >= rays.len(),
        "{case}: only {hits} of {} rays hit",
        rays.len()
    );
}

/// Every ray's answers equal brute force; returns how many rays hit.
fn assert_matches(tree: &KdTree, rays: &[Ray], case: &str) -> usize {
    let tris = tree.triangles();
    let mut hits = 0;
    for (i, r) in rays.iter().enumerate() {
        let (got, want) = (tree.intersect(r), brute::intersect(tris, r));
        assert_eq!(got, want, "{case}: ray {i} {r:?}");
        assert_eq!(
            tree.occluded(r),
            brute::occluded(tris, r),
            "{case}: ray {i} occlusion"
        );
        hits += want.is_some() as usize;
    }
    hits
}

/// Every builder variant of this file.
fn variants() -> Vec<BuildOptions> {
    let mut v = Vec::new();
    for clip in [false, true] {
        for axes in [Axes::Longest, Axes::All] {
            for (algorithm, counting) in [
                (Algorithm::Level, Counting::Scan),
                (Algorithm::Level, Counting::SpaceTree),
                (Algorithm::Naive, Counting::Scan),
            ] {
                v.push(BuildOptions {
                    algorithm,
                    counting,
                    axes,
                    clip,
                    ..level_options()
                });
            }
        }
    }
    v
}

fn describe(o: &BuildOptions) -> String {
    format!(
        "{:?}/{:?}/{:?}/clip {}",
        o.algorithm, o.counting, o.axes, o.clip
    )
}

fn build_tree(tris: &[Triangle], options: &BuildOptions) -> sahkd::Build {
    build_triangles(tris.to_vec(), options).unwrap()
}

#[test]
fn every_variant_matches_brute_force_on_random_scenes() {
    for (seed, n) in [(1u64, 60usize), (2, 700), (3, 2500)] {
        let tris = random_triangles(seed, n);
        let rays = random_rays(seed + 100, bounds(&tris), 1000);
        for options in variants() {
            let case = format!("{n} triangles, {}", describe(&options));
            let built = build_tree(&tris, &options);
            built
                .tree
                .validate()
                .unwrap_or_else(|e| panic!("{case}: {e}"));
            assert!(built.tree.nodes().len() > 1, "{case}: nothing was split");
            assert_oracle(&built.tree, &rays, &case);
        }
    }
}

/// Same nodes, same references, same order, whatever the pool size.
#[test]
fn trees_are_identical_on_1_2_3_and_8_threads() {
    let tris = random_triangles(5, 3000);
    for options in variants() {
        let mut first: Option<KdTree> = None;
        for threads in [1, 2, 3, 8] {
            let o = BuildOptions {
                threads: Some(threads),
                ..options
            };
            let tree = build_tree(&tris, &o).tree;
            if let Some(f) = &first {
                assert_eq!(
                    f.nodes(),
                    tree.nodes(),
                    "{}: {threads} threads",
                    describe(&o)
                );
                assert_eq!(f.refs(), tree.refs(), "{}: {threads} threads", describe(&o));
            } else {
                first = Some(tree);
            }
        }
    }
}

/// Nodes large enough to be counted and partitioned in parallel chunks (the top levels of a
/// 40k-triangle scene) build the same tree on any pool, and the same tree with both countings.
#[test]
fn large_nodes_build_the_same_tree_on_any_pool() {
    let mut rng = Rng(99);
    let tris: Vec<Triangle> = (0..40_000)
        .map(|_| {
            let c = Vec3::new(rng.unit(), rng.unit(), rng.unit());
            let mut corner = || {
                c + Vec3::new(
                    rng.range(-0.01, 0.01),
                    rng.range(-0.01, 0.01),
                    rng.range(-0.01, 0.01),
                )
            };
            [corner(), corner(), corner()]
        })
        .collect();
    for clip in [false, true] {
        let mut first: Option<KdTree> = None;
        for (threads, counting) in [
            (1, Counting::Scan),
            (2, Counting::Scan),
            (3, Counting::SpaceTree),
            (8, Counting::Scan),
        ] {
            let o = BuildOptions {
                threads: Some(threads),
                counting,
                clip,
                ..level_options()
            };
            let b = build_tree(&tris, &o);
            let case = format!("clip {clip}, {threads} threads, {counting:?}");
            assert!(b.report.levels.len() > 10, "{case}");
            if let Some(f) = &first {
                assert_eq!(f.nodes(), b.tree.nodes(), "{case}");
                assert_eq!(f.refs(), b.tree.refs(), "{case}");
            } else {
                b.tree.validate().unwrap();
                let rays = aimed_rays(5, &tris, 500);
                assert_oracle(&b.tree, &rays, &case);
                first = Some(b.tree);
            }
        }
    }
}

/// The two countings and the naive builder count the same, so build the very same tree.
#[test]
fn space_tree_scan_and_naive_build_the_same_tree() {
    for (seed, n) in [(7u64, 40usize), (8, 900), (9, 4000)] {
        let tris = random_triangles(seed, n);
        for clip in [false, true] {
            for axes in [Axes::Longest, Axes::All] {
                let base = BuildOptions {
                    axes,
                    clip,
                    ..level_options()
                };
                let scan = build_tree(
                    &tris,
                    &BuildOptions {
                        counting: Counting::Scan,
                        ..base
                    },
                );
                let walk = build_tree(
                    &tris,
                    &BuildOptions {
                        counting: Counting::SpaceTree,
                        ..base
                    },
                );
                let naive = build_tree(
                    &tris,
                    &BuildOptions {
                        algorithm: Algorithm::Naive,
                        ..base
                    },
                );
                let case = format!("{n} triangles, {axes:?}, clip {clip}");
                assert!(scan.tree.nodes().len() > 1, "{case}");
                for (name, other) in [("space tree", &walk), ("naive", &naive)] {
                    assert_eq!(
                        scan.tree.first_difference(&other.tree),
                        None,
                        "{case}: scan vs {name}"
                    );
                    assert_eq!(scan.tree.nodes(), other.tree.nodes(), "{case}: {name}");
                    assert_eq!(scan.tree.refs(), other.tree.refs(), "{case}: {name}");
                }
                // The same levels were priced, so the reports agree on sizes.
                let sizes = |b: &sahkd::Build| -> Vec<(usize, usize, usize)> {
                    b.report
                        .levels
                        .iter()
                        .map(|l| (l.nodes, l.leaves, l.references))
                        .collect()
                };
                assert_eq!(sizes(&scan), sizes(&walk), "{case}");
                assert_eq!(sizes(&scan), sizes(&naive), "{case}");
            }
        }
    }
}

/// L, R, P of a plane by testing every box (the shared semantics, independently written).
fn brute_counts(boxes: &[Aabb], axis: usize, p: f32) -> (u32, u32, u32) {
    let l = boxes.iter().filter(|b| b.lo[axis] < p).count() as u32;
    let r = boxes.iter().filter(|b| b.hi[axis] > p).count() as u32;
    let pl = boxes
        .iter()
        .filter(|b| b.lo[axis] == p && b.hi[axis] == p)
        .count() as u32;
    (l, r, pl)
}

/// The best root split by brute force over every candidate: (cost, axis, position).
fn brute_best_root(tris: &[Triangle], options: &BuildOptions) -> Option<(f32, usize, f32)> {
    let boxes: Vec<Aabb> = tris.iter().map(|t| Aabb::of_points(t)).collect();
    let scene = bounds(tris);
    let axes: Vec<usize> = match options.axes {
        Axes::All => vec![0, 1, 2],
        Axes::Longest => vec![scene.longest_axis()],
    };
    let c = &options.cost;
    let mut best: Option<(f32, usize, f32)> = None;
    for &axis in &axes {
        for b in &boxes {
            for p in [b.lo[axis], b.hi[axis]] {
                if !(scene.lo[axis] < p && p < scene.hi[axis]) {
                    continue;
                }
                let (l, r, pl) = brute_counts(&boxes, axis, p);
                let cost = c.split_cost(&scene, axis, p, l + pl, r).min(c.split_cost(
                    &scene,
                    axis,
                    p,
                    l,
                    r + pl,
                ));
                let better = match best {
                    None => true,
                    Some((bc, ba, bp)) => {
                        cost < bc || (cost == bc && (p < bp || (p == bp && axis < ba)))
                    }
                };
                if better {
                    best = Some((cost, axis, p));
                }
            }
        }
    }
    best
}

#[test]
fn root_split_is_the_brute_force_best() {
    for seed in 0..12u64 {
        let tris = random_triangles(1000 + seed, 30 + 17 * seed as usize);
        for axes in [Axes::All, Axes::Longest] {
            for counting in [Counting::Scan, Counting::SpaceTree] {
                let options = BuildOptions {
                    axes,
                    counting,
                    clip: seed % 2 == 0,
                    ..level_options()
                };
                let tree = build_tree(&tris, &options).tree;
                let root = tree.nodes()[0];
                let case = format!("seed {seed}, {axes:?}, {counting:?}");
                let (cost, axis, pos) = brute_best_root(&tris, &options).expect("candidates");
                if cost < options.cost.leaf_cost(tris.len() as u32) {
                    assert!(
                        !root.is_leaf(),
                        "{case}: root is a leaf, best split costs {cost}"
                    );
                    assert_eq!((root.axis(), root.split()), (axis, pos), "{case}");
                    // And the chosen plane indeed has that cost.
                    let boxes: Vec<Aabb> = tris.iter().map(|t| Aabb::of_points(t)).collect();
                    let (l, r, pl) = brute_counts(&boxes, axis, pos);
                    let c = &options.cost;
                    let scene = bounds(&tris);
                    let at = c.split_cost(&scene, axis, pos, l + pl, r).min(c.split_cost(
                        &scene,
                        axis,
                        pos,
                        l,
                        r + pl,
                    ));
                    assert_eq!(at, cost, "{case}");
                } else {
                    assert!(
                        root.is_leaf(),
                        "{case}: split although the best costs {cost}"
                    );
                }
            }
        }
    }
}

fn quad(a: Vec3, b: Vec3, c: Vec3, d: Vec3) -> [Triangle; 2] {
    [[a, b, c], [a, c, d]]
}

/// Degenerate scenes: every variant builds a valid tree that answers like brute force.
#[test]
fn degenerate_inputs_build_valid_trees() {
    let v = Vec3::new;
    let mut cases: Vec<(&str, Vec<Triangle>)> = Vec::new();
    cases.push((
        "single triangle",
        vec![[v(0., 0., 0.), v(1., 0., 0.), v(0., 1., 0.)]],
    ));
    cases.push((
        "10000 identical triangles",
        vec![[v(0., 0., 0.), v(1., 0., 0.5), v(0., 1., 1.)]; 10_000],
    ));
    let mut rng = Rng(3);
    cases.push((
        "all in the plane z = 0.5",
        (0..3000)
            .map(|_| {
                let (x, y) = (rng.unit(), rng.unit());
                [v(x, y, 0.5), v(x + 0.05, y, 0.5), v(x, y + 0.05, 0.5)]
            })
            .collect(),
    ));
    let mut grid = Vec::new();
    for i in 0..12 {
        for j in 0..12 {
            let (x, y) = (i as f32, j as f32);
            // Quads facing z on the grid, plus walls facing x and y.
            grid.extend(quad(
                v(x, y, 0.),
                v(x + 1., y, 0.),
                v(x + 1., y + 1., 0.),
                v(x, y + 1., 0.),
            ));
            grid.extend(quad(
                v(x, y, 0.),
                v(x, y + 1., 0.),
                v(x, y + 1., 1.),
                v(x, y, 1.),
            ));
            grid.extend(quad(
                v(x, y, 0.),
                v(x + 1., y, 0.),
                v(x + 1., y, 1.),
                v(x, y, 1.),
            ));
        }
    }
    cases.push(("grid of axis-aligned quads", grid));
    cases.push((
        "tiny triangles at 1e30",
        (0..500)
            .map(|i| {
                let c = v(
                    rng.range(-1e30, 1e30),
                    rng.range(-1e30, 1e30),
                    if i % 2 == 0 { 1e30 } else { -1e30 },
                );
                let s = 1e26;
                [c, c + v(s, 0., 0.), c + v(0., s, s)]
            })
            .collect(),
    ));
    cases.push((
        "zero-area triangles",
        (0..2000)
            .map(|i| {
                let a = v(rng.unit(), rng.unit(), rng.unit());
                let b = v(rng.unit(), rng.unit(), rng.unit());
                match i % 3 {
                    0 => [a, b, a * 0.5 + b * 0.5],
                    1 => [a, a, b],
                    _ => [a, a, a],
                }
            })
            .collect(),
    ));
    for (name, tris) in &cases {
        let mut rays = random_rays(42, bounds(tris), 300);
        rays.extend(aimed_rays(43, tris, 300));
        let mut trees = Vec::new();
        for options in variants() {
            let case = format!("{name}, {}", describe(&options));
            let built = build_tree(tris, &options);
            built
                .tree
                .validate()
                .unwrap_or_else(|e| panic!("{case}: {e}"));
            assert_eq!(
                built.tree.leaf_refs_total(),
                built.tree.refs().len(),
                "{case}"
            );
            let hits = assert_matches(&built.tree, &rays, &case);
            // Zero-area triangles are (nearly) never hit, and at 1e30 the single-precision
            // ray/triangle test overflows (the build itself is what those cases check);
            // everything else must be hit, or the rays test nothing.
            if !name.starts_with("zero-area") && !name.contains("1e30") {
                assert!(hits > 0, "{case}: no ray hits");
            }
            trees.push((options, built.tree));
        }
        // Within a (axes, clip) setting, every counting gives the same tree here too.
        for (o, t) in &trees {
            for (p, u) in &trees {
                if (o.axes, o.clip) == (p.axes, p.clip) {
                    assert_eq!(
                        t.nodes(),
                        u.nodes(),
                        "{name}: {} vs {}",
                        describe(o),
                        describe(p)
                    );
                }
            }
        }
    }
}

trait LeafRefs {
    fn leaf_refs_total(&self) -> usize;
}

impl LeafRefs for KdTree {
    /// References reachable through leaves: every reference belongs to exactly one leaf.
    fn leaf_refs_total(&self) -> usize {
        let mut n = 0;
        self.visit(|_, node, _, _| {
            if node.is_leaf() {
                n += node.count() as usize;
            }
        });
        n
    }
}

#[test]
fn identical_triangles_end_in_one_leaf_and_planar_scene_splits() {
    let v = Vec3::new;
    let same = vec![[v(0., 0., 0.), v(1., 0., 0.5), v(0., 1., 1.)]; 10_000];
    let tree = build_tree(&same, &level_options()).tree;
    // No plane strictly inside the box separates identical triangles profitably.
    assert_eq!(tree.nodes().len(), 1);
    assert_eq!(tree.refs().len(), 10_000);
}

/// The per-level report describes the build: levels in order, references consistent with the
/// tree, walk statistics for the space tree only, a pre-sort time for sorted builds only.
#[test]
fn report_describes_the_levels() {
    let tris = random_triangles(77, 5000);
    for options in variants() {
        let b = build_tree(&tris, &options);
        let r = &b.report;
        let case = describe(&options);
        assert!(r.levels.len() > 3, "{case}");
        for (d, l) in r.levels.iter().enumerate() {
            assert_eq!(l.depth as usize, d, "{case}");
            assert!(l.leaves <= l.nodes, "{case}");
        }
        assert_eq!(r.levels[0].nodes, 1);
        assert_eq!(r.levels[0].references, tris.len());
        let last = r.levels.last().unwrap();
        assert_eq!(
            last.leaves, last.nodes,
            "{case}: the last level is all leaves"
        );
        let nodes: usize = r.levels.iter().map(|l| l.nodes).sum();
        assert_eq!(nodes, b.tree.nodes().len(), "{case}");
        let leaves: usize = r.levels.iter().map(|l| l.leaves).sum();
        assert_eq!(leaves, b.tree.stats(&options.cost).leaves, "{case}");
        let walked = r.levels.iter().map(|l| l.walk_steps).sum::<u64>();
        let space_tree =
            options.algorithm == Algorithm::Level && options.counting == Counting::SpaceTree;
        assert_eq!(walked > 0, space_tree, "{case}");
        assert!(r.peak_working_bytes > 0, "{case}");
        assert_eq!(
            r.presort_ms > 0.0,
            options.algorithm == Algorithm::Level,
            "{case}"
        );
        assert!(r.levels[0].candidates > 0, "{case}");
    }
}

/// The reference budget stops the build breadth first: with no duplication allowed beyond the
/// triangles themselves (plus the fixed slack), the tree holds at most the budget.
#[test]
fn reference_budget_is_respected() {
    let tris = random_triangles(88, 3000);
    for options in variants() {
        let mut o = options;
        o.cost.max_duplication = 1.0;
        let b = build_tree(&tris, &o);
        let budget = o.cost.reference_budget(tris.len());
        assert!(
            b.tree.refs().len() <= budget,
            "{}: {} refs",
            describe(&o),
            b.tree.refs().len()
        );
        b.tree.validate().unwrap();
    }
}

fn scene_test(file: &str, rays: usize) {
    let Some(mesh) = common::load_scene(file) else {
        return;
    };
    for options in [
        level_options(),
        BuildOptions::paper(),
        BuildOptions {
            counting: Counting::SpaceTree,
            axes: Axes::All,
            ..level_options()
        },
    ] {
        let built = build(&mesh, &options).unwrap();
        let case = format!("{file}, {}", describe(&options));
        built
            .tree
            .validate()
            .unwrap_or_else(|e| panic!("{case}: {e}"));
        let stats = built.tree.stats(&options.cost);
        assert!(
            stats.leaves > mesh.triangles.len() / 16,
            "{case}: {stats:?}"
        );
        let rays = random_rays(9, built.tree.bounds(), rays);
        assert_oracle(&built.tree, &rays, &case);
    }
}

#[test]
fn bunny_builds_validates_and_matches_brute_force() {
    scene_test("bunny.ply", 2000);
}

#[test]
fn dragon_res3_builds_validates_and_matches_brute_force() {
    scene_test("dragon_res3.ply", 3000);
}
