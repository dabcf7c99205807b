//! The sweep builder against independent oracles:
//! - a naive reference builder written here from the shared semantics (every candidate of
//!   every node priced by direct O(n^2) counting), which must produce the very same tree;
//! - the brute-force ray oracle, which every tree must answer like;
//! - `KdTree::validate`.

use sahkd::clip::clipped_bounds;
use sahkd::geometry::triangle_bounds;
use sahkd::trace::brute;
use sahkd::{
    build_triangles, Aabb, Algorithm, Axes, BuildOptions, CostModel, KdTree, Node, Ray, Triangle,
    Vec3, BINNED_REFS_PER_BIN,
};
use std::path::PathBuf;

// ---------------------------------------------------------------------------------------
// Random numbers and scenes

/// SplitMix64: small, seedable, good enough for test scenes.
struct Rng(u64);

impl Rng {
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    /// Uniform in [0, 1).
    fn unit(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 / (1u64 << 24) as f32
    }
    fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.unit()
    }
    fn below(&mut self, n: u64) -> u64 {
        self.next_u64() % n
    }
    fn point(&mut self, lo: f32, hi: f32) -> Vec3 {
        Vec3::new(self.range(lo, hi), self.range(lo, hi), self.range(lo, hi))
    }
}

fn tri(a: [f32; 3], b: [f32; 3], c: [f32; 3]) -> Triangle {
    [Vec3(a), Vec3(b), Vec3(c)]
}

/// Triangles of mixed sizes in the unit cube; some axis-aligned (flat on an axis, so planar
/// events), some with corners snapped to a coarse grid (coincident events), some large.
fn mixed_scene(rng: &mut Rng, n: usize) -> Vec<Triangle> {
    let snap = |x: f32| (x * 8.0).round() / 8.0;
    (0..n)
        .map(|_| {
            let centre = rng.point(0.0, 1.0);
            let size = match rng.below(10) {
                0 => 0.5,
                1..=3 => 0.1,
                _ => 0.02,
            };
            let mut t = [
                centre + rng.point(-size, size),
                centre + rng.point(-size, size),
                centre + rng.point(-size, size),
            ];
            match rng.below(6) {
                0 => {
                    // Flat on a random axis.
                    let a = rng.below(3) as usize;
                    let c = t[0][a];
                    for v in &mut t {
                        v[a] = c;
                    }
                }
                1 => {
                    // Flat on a snapped plane, shared with other triangles.
                    let a = rng.below(3) as usize;
                    let c = snap(centre[a]);
                    for v in &mut t {
                        v[a] = c;
                    }
                }
                2 => {
                    for v in &mut t {
                        *v = Vec3(v.0.map(snap));
                    }
                }
                _ => {}
            }
            t
        })
        .collect()
}

fn options(axes: Axes, clip: bool) -> BuildOptions {
    BuildOptions {
        algorithm: Algorithm::Sweep,
        axes,
        clip,
        ..BuildOptions::default()
    }
}

fn all_option_sets() -> Vec<BuildOptions> {
    let mut v = Vec::new();
    for axes in [Axes::All, Axes::Longest] {
        for clip in [true, false] {
            v.push(options(axes, clip));
        }
    }
    v
}

fn sweep(tris: &[Triangle], opts: &BuildOptions) -> KdTree {
    build_triangles(tris.to_vec(), opts).unwrap().tree
}

// ---------------------------------------------------------------------------------------
// The ray oracle

/// Rays from a box around `bounds` toward random points inside it, plus axis-parallel rays
/// (zero direction components) through the grid coordinates the scenes snap to.
fn rays(rng: &mut Rng, bounds: &Aabb, count: usize) -> Vec<Ray> {
    let ext = bounds.extent();
    let margin = ext * 0.5 + Vec3::splat(1e-3);
    let (outer_lo, outer_hi) = (bounds.lo - margin, bounds.hi + margin);
    (0..count)
        .map(|i| {
            let at = |rng: &mut Rng, lo: Vec3, hi: Vec3| {
                Vec3::new(
                    rng.range(lo[0], hi[0]),
                    rng.range(lo[1], hi[1]),
                    rng.range(lo[2], hi[2]),
                )
            };
            let origin = at(rng, outer_lo, outer_hi);
            if i % 8 == 7 {
                // Axis-parallel, through a snapped coordinate.
                let a = rng.below(3) as usize;
                let mut o = origin;
                for b in 0..3 {
                    if b != a {
                        o[b] = (o[b] * 8.0).round() / 8.0;
                    }
                }
                let mut d = Vec3::splat(0.0);
                d[a] = if rng.below(2) == 0 { 1.0 } else { -1.0 };
                return Ray::new(o, d);
            }
            let target = at(rng, bounds.lo, bounds.hi);
            let ray = Ray::new(origin, target - origin);
            if i % 5 == 4 {
                // A short segment, to exercise t_max.
                ray.with_range(0.0, rng.range(0.2, 1.2))
            } else {
                ray
            }
        })
        .collect()
}

/// Every ray answers as the brute force does: same t bit for bit, same triangle.
fn check_rays(tree: &KdTree, rays: &[Ray], what: &str) {
    for (i, ray) in rays.iter().enumerate() {
        let want = brute::intersect(tree.triangles(), ray);
        let got = tree.intersect(ray);
        assert_eq!(
            got.map(|h| (h.t.to_bits(), h.prim)),
            want.map(|h| (h.t.to_bits(), h.prim)),
            "{what}: ray {i} {ray:?}: tree {got:?}, brute force {want:?}"
        );
        assert_eq!(
            tree.occluded(ray),
            brute::occluded(tree.triangles(), ray),
            "{what}: occlusion of ray {i} {ray:?}"
        );
    }
}

/// Builds with every option set, validates, and checks `ray_count` rays.
fn build_and_check(tris: &[Triangle], ray_count: usize, seed: u64, what: &str) {
    let bounds = tris
        .iter()
        .fold(Aabb::EMPTY, |b, t| b.union(triangle_bounds(t)));
    let rays = rays(&mut Rng(seed), &bounds, ray_count);
    for opts in all_option_sets() {
        let what = format!("{what}, {:?}, clip {}", opts.axes, opts.clip);
        let tree = sweep(tris, &opts);
        tree.validate()
            .unwrap_or_else(|e| panic!("{what}: invalid tree: {e}"));
        check_rays(&tree, &rays, &what);
    }
}

// ---------------------------------------------------------------------------------------
// The reference builder: the shared semantics, written as directly as possible.

#[derive(Clone, Copy, Debug, PartialEq)]
struct RefSplit {
    cost: f32,
    axis: usize,
    pos: f32,
    planar_left: bool,
    n_left: u32,
    n_right: u32,
}

/// The best split of a node holding `items` (triangle index, box), by direct counting. With
/// `bins` (not 0) and more than `BINNED_REFS_PER_BIN * bins` items, the candidates are the
/// documented bin boundaries `lo + (hi - lo) * (i / bins)` instead of the boxes' ends.
fn reference_best_split(
    items: &[(u32, Aabb)],
    node: &Aabb,
    axes: Axes,
    bins: u32,
    cost: &CostModel,
) -> Option<RefSplit> {
    let axis_list = match axes {
        Axes::All => vec![0, 1, 2],
        Axes::Longest => vec![node.longest_axis()],
    };
    let binned = bins != 0 && items.len() > BINNED_REFS_PER_BIN * bins as usize;
    let mut best: Option<RefSplit> = None;
    for a in axis_list {
        let candidates: Vec<f32> = if binned {
            let (lo, hi) = (node.lo[a], node.hi[a]);
            (1..bins)
                .map(|i| lo + (hi - lo) * (i as f32 / bins as f32))
                .collect()
        } else {
            items.iter().flat_map(|(_, b)| [b.lo[a], b.hi[a]]).collect()
        };
        {
            for p in candidates {
                if !(p > node.lo[a] && p < node.hi[a]) {
                    continue;
                }
                let p = p + 0.0; // -0.0 and 0.0 are one plane; store it as 0.0.
                let l = items.iter().filter(|(_, b)| b.lo[a] < p).count() as u32;
                let r = items.iter().filter(|(_, b)| b.hi[a] > p).count() as u32;
                let pl = items
                    .iter()
                    .filter(|(_, b)| b.lo[a] == p && b.hi[a] == p)
                    .count() as u32;
                let cost_left = cost.split_cost(node, a, p, l + pl, r);
                let cost_right = cost.split_cost(node, a, p, l, r + pl);
                let planar_left = cost_left <= cost_right;
                let c = RefSplit {
                    cost: cost_left.min(cost_right),
                    axis: a,
                    pos: p,
                    planar_left,
                    n_left: if planar_left { l + pl } else { l },
                    n_right: if planar_left { r } else { r + pl },
                };
                let better = match &best {
                    None => c.cost.is_finite(),
                    Some(o) => {
                        c.cost < o.cost || (c.cost == o.cost && (c.pos, c.axis) < (o.pos, o.axis))
                    }
                };
                if better {
                    best = Some(c);
                }
            }
        }
    }
    best
}

struct ReferenceBuilder<'a> {
    tris: &'a [Triangle],
    opts: BuildOptions,
    max_depth: u32,
    budget: usize,
    references: usize,
    nodes: Vec<Node>,
    refs: Vec<u32>,
    /// Splits refused only because of the reference budget.
    budget_refusals: usize,
}

impl ReferenceBuilder<'_> {
    fn node(&mut self, slot: usize, items: Vec<(u32, Aabb)>, bounds: Aabb, depth: u32) {
        let cost = self.opts.cost;
        let n = items.len() as u32;
        let mut split = None;
        if n > cost.leaf_size && depth < self.max_depth {
            if let Some(s) = reference_best_split(
                &items,
                &bounds,
                self.opts.axes,
                self.opts.resolved_bins(),
                &cost,
            ) {
                if s.cost < cost.leaf_cost(n) {
                    if self.references + (s.n_left + s.n_right - n) as usize <= self.budget {
                        split = Some(s);
                    } else {
                        self.budget_refusals += 1;
                    }
                }
            }
        }
        let Some(s) = split else {
            self.nodes[slot] = Node::leaf(self.refs.len() as u32, n);
            self.refs.extend(items.iter().map(|(i, _)| *i));
            return;
        };
        let (lbox, rbox) = bounds.split(s.axis, s.pos);
        let (mut left, mut right) = (Vec::new(), Vec::new());
        for &(i, b) in &items {
            let (lo, hi) = (b.lo[s.axis], b.hi[s.axis]);
            if lo == s.pos && hi == s.pos {
                if s.planar_left {
                    left.push((i, b));
                } else {
                    right.push((i, b));
                }
            } else if hi <= s.pos {
                left.push((i, b));
            } else if lo >= s.pos {
                right.push((i, b));
            } else if self.opts.clip {
                for (child, list) in [(&lbox, &mut left), (&rbox, &mut right)] {
                    let c = clipped_bounds(&self.tris[i as usize], child);
                    if !c.is_empty() {
                        list.push((i, c));
                    }
                }
            } else {
                left.push((i, b.intersection(lbox)));
                right.push((i, b.intersection(rbox)));
            }
        }
        self.references = self.references + left.len() + right.len() - n as usize;
        let first = self.nodes.len();
        self.nodes[slot] = Node::interior(s.axis, s.pos, first as u32);
        self.nodes.extend([Node::leaf(0, 0); 2]);
        self.node(first, left, lbox, depth + 1);
        self.node(first + 1, right, rbox, depth + 1);
    }
}

/// The tree the shared semantics define, and how many splits the budget refused.
fn reference_tree(tris: &[Triangle], opts: &BuildOptions) -> (KdTree, usize) {
    let items: Vec<(u32, Aabb)> = tris
        .iter()
        .enumerate()
        .map(|(i, t)| (i as u32, triangle_bounds(t)))
        .collect();
    let bounds = items.iter().fold(Aabb::EMPTY, |b, (_, x)| b.union(*x));
    let mut rb = ReferenceBuilder {
        tris,
        opts: *opts,
        max_depth: opts.cost.max_depth_for(tris.len()),
        budget: opts.cost.reference_budget(tris.len()),
        references: tris.len(),
        nodes: vec![Node::leaf(0, 0)],
        refs: Vec::new(),
        budget_refusals: 0,
    };
    rb.node(0, items, bounds, 0);
    let refusals = rb.budget_refusals;
    (
        KdTree::from_parts(tris.to_vec(), bounds, rb.nodes, rb.refs),
        refusals,
    )
}

fn assert_same_as_reference(tris: &[Triangle], opts: &BuildOptions, what: &str) -> usize {
    let got = sweep(tris, opts);
    let (want, refusals) = reference_tree(tris, opts);
    if let Some(d) = got.first_difference(&want) {
        panic!(
            "{what}, {:?}, clip {}: sweep tree differs from the reference: {d}",
            opts.axes, opts.clip
        );
    }
    // Same tree, and the node order is the one promised: depth first, children adjacent.
    assert_eq!(got.nodes(), want.nodes(), "{what}: node order");
    refusals
}

// ---------------------------------------------------------------------------------------
// Exactness

#[test]
fn root_split_is_the_brute_force_optimum() {
    let mut rng = Rng(1);
    let mut splits = 0;
    for round in 0..60 {
        let n = 5 + rng.below(80) as usize;
        let tris = mixed_scene(&mut rng, n);
        for opts in all_option_sets() {
            let items: Vec<(u32, Aabb)> = tris
                .iter()
                .enumerate()
                .map(|(i, t)| (i as u32, triangle_bounds(t)))
                .collect();
            let bounds = items.iter().fold(Aabb::EMPTY, |b, (_, x)| b.union(*x));
            let want = reference_best_split(&items, &bounds, opts.axes, 0, &opts.cost)
                .filter(|s| s.cost < opts.cost.leaf_cost(tris.len() as u32));
            let tree = sweep(&tris, &opts);
            let root = tree.nodes()[0];
            match want {
                None => assert!(root.is_leaf(), "round {round}: root should be a leaf"),
                Some(w) => {
                    splits += 1;
                    assert!(!root.is_leaf(), "round {round}: root should split");
                    assert_eq!(
                        (root.axis(), root.split().to_bits()),
                        (w.axis, w.pos.to_bits()),
                        "round {round}, {opts:?}"
                    );
                    // The chosen plane, priced by direct counting, has the optimal cost.
                    let l = items
                        .iter()
                        .filter(|(_, b)| b.lo[root.axis()] < root.split())
                        .count() as u32;
                    let r = items
                        .iter()
                        .filter(|(_, b)| b.hi[root.axis()] > root.split())
                        .count() as u32;
                    let p = items
                        .iter()
                        .filter(|(_, b)| {
                            b.lo[root.axis()] == root.split() && b.hi[root.axis()] == root.split()
                        })
                        .count() as u32;
                    let c = &opts.cost;
                    let cost = c
                        .split_cost(&bounds, root.axis(), root.split(), l + p, r)
                        .min(c.split_cost(&bounds, root.axis(), root.split(), l, r + p));
                    assert_eq!(cost.to_bits(), w.cost.to_bits(), "round {round}");
                }
            }
        }
    }
    assert!(
        splits > 100,
        "too few roots split ({splits}) to test anything"
    );
}

#[test]
fn whole_trees_equal_the_reference_builder() {
    let mut rng = Rng(2);
    for round in 0..40 {
        let n = 20 + rng.below(250) as usize;
        let tris = mixed_scene(&mut rng, n);
        for opts in all_option_sets() {
            assert_same_as_reference(&tris, &opts, &format!("round {round}"));
        }
    }
}

#[test]
fn whole_trees_equal_the_reference_under_other_cost_models() {
    let mut rng = Rng(3);
    let models = [
        CostModel {
            leaf_size: 3,
            ..CostModel::default()
        },
        CostModel {
            max_depth: Some(4),
            ..CostModel::default()
        },
        CostModel {
            empty_bonus: 1.0,
            traversal: 1.0,
            intersection: 1.5,
            ..CostModel::default()
        },
    ];
    for round in 0..10 {
        let n = 50 + rng.below(200) as usize;
        let tris = mixed_scene(&mut rng, n);
        for cost in models {
            for mut opts in all_option_sets() {
                opts.cost = cost;
                assert_same_as_reference(&tris, &opts, &format!("round {round}, {cost:?}"));
            }
        }
    }
}

#[test]
fn reference_budget_stops_splitting_as_the_reference_does() {
    // Long slivers crossing the whole box in every direction: nearly every split cuts most
    // of them, so references pile up and the budget (n + 1024 at duplication 1) binds.
    let mut rng = Rng(4);
    let mut tris = Vec::new();
    for _ in 0..600 {
        let a = rng.point(0.0, 1.0);
        let b = rng.point(0.0, 1.0);
        let along = (b - a) * 3.0;
        tris.push([a - along, b + along, a - along + rng.point(-0.01, 0.01)]);
    }
    let mut refused = 0;
    for mut opts in all_option_sets() {
        opts.cost.max_duplication = 1.0;
        refused += assert_same_as_reference(&tris, &opts, "slivers");
        let tree = sweep(&tris, &opts);
        assert!(tree.refs().len() <= opts.cost.reference_budget(tris.len()));
        tree.validate().unwrap();
    }
    assert!(
        refused > 0,
        "the budget never bound: the test tests nothing"
    );
}

// ---------------------------------------------------------------------------------------
// Binning (`bins`): the reference prices the documented boundaries above the threshold

#[test]
fn binned_trees_equal_the_reference_builder() {
    let mut rng = Rng(6);
    for round in 0..6 {
        let n = 300 + rng.below(500) as usize;
        let tris = mixed_scene(&mut rng, n);
        // Thresholds of 128, 192 and 256 references: several binned levels, then the sweep.
        for bins in [2, 3, 4] {
            for mut opts in all_option_sets() {
                opts.bins = Some(bins);
                let what = format!("round {round}, {n} triangles, {bins} bins");
                assert_same_as_reference(&tris, &opts, &what);
                // The hybrid builds the binned nodes' children at once: the same tree.
                opts.algorithm = Algorithm::Hybrid;
                opts.threads = Some(3);
                let (want, _) = reference_tree(&tris, &opts);
                let got = sweep(&tris, &opts);
                assert_eq!(got.first_difference(&want), None, "{what}, hybrid");
                assert_eq!(got.nodes(), want.nodes(), "{what}, hybrid");
            }
        }
    }
}

#[test]
fn binned_builds_keep_the_reference_budget_as_the_reference_does() {
    // Slivers as above, and two clusters of small triangles in opposite corners that make
    // the splits worth their cost even where only a few boundaries are priced.
    let mut rng = Rng(7);
    let mut tris = Vec::new();
    for _ in 0..500 {
        let a = rng.point(0.0, 1.0);
        let b = rng.point(0.0, 1.0);
        let along = (b - a) * 3.0;
        tris.push([a - along, b + along, a - along + rng.point(-0.01, 0.01)]);
    }
    for k in 0..800 {
        let c = rng.point(0.0, 0.2) + Vec3::splat(if k % 2 == 0 { 0.0 } else { 0.8 });
        tris.push([c, c + rng.point(0.0, 0.02), c + rng.point(0.0, 0.02)]);
    }
    let mut refused = 0;
    for mut opts in all_option_sets() {
        opts.cost.max_duplication = 1.0;
        opts.bins = Some(2);
        refused += assert_same_as_reference(&tris, &opts, "binned slivers");
        // In parallel the budget binds, so the hybrid builds depth first: the same tree.
        opts.algorithm = Algorithm::Hybrid;
        opts.threads = Some(2);
        let got = sweep(&tris, &opts);
        let (want, _) = reference_tree(&tris, &opts);
        assert_eq!(got.first_difference(&want), None, "binned slivers, hybrid");
        assert!(got.refs().len() <= opts.cost.reference_budget(tris.len()));
    }
    assert!(
        refused > 0,
        "the budget never bound: the test tests nothing"
    );
}

// ---------------------------------------------------------------------------------------
// Rays

#[test]
fn random_scenes_answer_rays_like_brute_force() {
    let mut rng = Rng(5);
    for (round, n) in [200, 700, 1500, 3000].into_iter().enumerate() {
        let tris = mixed_scene(&mut rng, n);
        build_and_check(&tris, 1000, 100 + round as u64, &format!("{n} triangles"));
    }
}

#[test]
fn same_input_gives_the_same_tree_on_any_thread_count() {
    let tris = mixed_scene(&mut Rng(6), 2000);
    for opts in all_option_sets() {
        let one = build_triangles(
            tris.clone(),
            &BuildOptions {
                threads: Some(1),
                ..opts
            },
        )
        .unwrap();
        let two = build_triangles(
            tris.clone(),
            &BuildOptions {
                threads: Some(2),
                ..opts
            },
        )
        .unwrap();
        assert_eq!(one.tree.nodes(), two.tree.nodes());
        assert_eq!(one.tree.refs(), two.tree.refs());
        assert!(one.report.peak_working_bytes >= 2000 * 6 * 8);
    }
}

// ---------------------------------------------------------------------------------------
// Degenerate input

#[test]
fn a_single_triangle() {
    let tris = vec![tri([0., 0., 0.], [1., 0., 0.], [0., 1., 1.])];
    build_and_check(&tris, 300, 7, "one triangle");
    for opts in all_option_sets() {
        let tree = sweep(&tris, &opts);
        assert_eq!(tree.nodes(), &[Node::leaf(0, 1)]);
    }
}

#[test]
fn ten_thousand_identical_triangles_stay_bounded() {
    let t = tri([0.2, 0.1, 0.3], [0.7, 0.4, 0.3], [0.3, 0.8, 0.6]);
    let mut tris = vec![t; 10_000];
    // A few others, so that the scene box is larger and planes exist around the pile.
    let mut rng = Rng(8);
    tris.extend(mixed_scene(&mut rng, 20));
    for opts in all_option_sets() {
        let tree = sweep(&tris, &opts);
        tree.validate().unwrap();
        assert!(tree.refs().len() <= opts.cost.reference_budget(tris.len()));
        check_rays(&tree, &rays(&mut Rng(9), &tree.bounds(), 200), "identical");
    }
}

#[test]
fn all_triangles_in_one_plane() {
    let mut rng = Rng(10);
    let mut tris = Vec::new();
    for i in 0..800 {
        let c = rng.point(0.0, 1.0);
        // Half of them written with z = -0.0: the same plane.
        let z = if i % 2 == 0 { 0.0 } else { -0.0 };
        let mut corner = || {
            [
                c[0] + rng.range(-0.05, 0.05),
                c[1] + rng.range(-0.05, 0.05),
                z,
            ]
        };
        tris.push(tri(corner(), corner(), corner()));
    }
    build_and_check(&tris, 1000, 11, "one plane");
    for opts in all_option_sets() {
        assert_same_as_reference(&tris[..150], &opts, "one plane");
    }
}

/// The faces of a `k^3` lattice of unit cubes, two triangles per face: every event is
/// shared by many primitives, and every primitive is planar on one axis.
fn cube_lattice(k: usize) -> Vec<Triangle> {
    let mut tris = Vec::new();
    for a in 0..3 {
        let (b, c) = ((a + 1) % 3, (a + 2) % 3);
        for i in 0..=k {
            for j in 0..k {
                for l in 0..k {
                    let corner = |dj: usize, dl: usize| {
                        let mut v = [0f32; 3];
                        v[a] = i as f32;
                        v[b] = (j + dj) as f32;
                        v[c] = (l + dl) as f32;
                        v
                    };
                    tris.push(tri(corner(0, 0), corner(1, 0), corner(1, 1)));
                    tris.push(tri(corner(0, 0), corner(1, 1), corner(0, 1)));
                }
            }
        }
    }
    tris
}

#[test]
fn axis_aligned_grid_of_quads() {
    let tris = cube_lattice(6);
    build_and_check(&tris, 1000, 12, "cube lattice");
    let small = cube_lattice(2);
    for opts in all_option_sets() {
        assert_same_as_reference(&small, &opts, "cube lattice");
    }
}

#[test]
fn huge_coordinates_with_tiny_triangles() {
    let mut rng = Rng(13);
    let mut tris = mixed_scene(&mut rng, 300)
        .into_iter()
        .map(|t| t.map(|v| v * 1e-3))
        .collect::<Vec<_>>();
    tris.push(tri(
        [-1e30, -1e30, 0.0],
        [1e30, -1e30, 0.0],
        [0.0, 1e30, 1e30],
    ));
    tris.push(tri(
        [1e30, 1e30, 1e30],
        [0.9e30, 1e30, 1e30],
        [1e30, 0.9e30, 1e30],
    ));
    build_and_check(&tris, 500, 14, "huge and tiny");
    // Rays among the tiny triangles too.
    let near = Aabb::new(Vec3::splat(0.0), Vec3::splat(1e-3));
    for opts in all_option_sets() {
        let tree = sweep(&tris, &opts);
        check_rays(
            &tree,
            &rays(&mut Rng(15), &near, 500),
            "huge and tiny, near",
        );
    }
}

#[test]
fn zero_area_triangles() {
    let mut rng = Rng(16);
    let mut tris = mixed_scene(&mut rng, 300);
    tris.push(tri([0.5, 0.5, 0.5], [0.5, 0.5, 0.5], [0.5, 0.5, 0.5])); // a point
    tris.push(tri([0.1, 0.2, 0.3], [0.4, 0.5, 0.6], [0.7, 0.8, 0.9])); // collinear
    tris.push(tri([0.2, 0.2, 0.2], [0.2, 0.9, 0.2], [0.2, 0.5, 0.2])); // a segment on y
    build_and_check(&tris, 1000, 17, "zero-area");
    for opts in all_option_sets() {
        assert_same_as_reference(&tris, &opts, "zero-area");
    }
}

// ---------------------------------------------------------------------------------------
// Real scenes

fn scenes_dir() -> Option<PathBuf> {
    let dir = std::env::var_os("SAHKD_SCENES")
        .map(PathBuf::from)
        .unwrap_or_else(|| {
            PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/scenes")
        });
    dir.is_dir().then_some(dir)
}

fn load_ply(path: &std::path::Path) -> Vec<Triangle> {
    sahkd::Mesh::load(path).unwrap().corner_triangles()
}

#[test]
fn real_scenes_build_validate_and_answer_rays() {
    let Some(dir) = scenes_dir() else {
        println!("skipping: no scenes folder (set SAHKD_SCENES)");
        return;
    };
    for (name, count) in [("bunny", 69_451), ("dragon_res3", 47_794)] {
        let path = dir.join(format!("{name}.ply"));
        if !path.exists() {
            println!("skipping {name}: {} not found", path.display());
            continue;
        }
        let tris = load_ply(&path);
        assert_eq!(tris.len(), count);
        let bounds = tris
            .iter()
            .fold(Aabb::EMPTY, |b, t| b.union(triangle_bounds(t)));
        let rays = rays(&mut Rng(18), &bounds, 2000);
        for opts in [options(Axes::All, true), options(Axes::Longest, false)] {
            let what = format!("{name}, {:?}, clip {}", opts.axes, opts.clip);
            let tree = sweep(&tris, &opts);
            tree.validate()
                .unwrap_or_else(|e| panic!("{what}: invalid tree: {e}"));
            let stats = tree.stats(&opts.cost);
            assert!(
                stats.leaves > count / 4,
                "{what}: only {} leaves",
                stats.leaves
            );
            check_rays(&tree, &rays, &what);
        }
    }
}
