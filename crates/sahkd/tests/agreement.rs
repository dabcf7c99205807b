//! Builders that search the same candidates must agree, and every build must be the same on
//! any number of threads.

mod common;

use common::*;
use sahkd::{build, build_triangles, Algorithm, Axes, BuildOptions, Counting, KdTree};

fn sah(tree: &KdTree, options: &BuildOptions) -> f64 {
    tree.stats(&options.cost).sah_cost
}

fn relative(a: f64, b: f64) -> f64 {
    (a - b).abs() / a.abs().max(b.abs()).max(1e-30)
}

/// `level` (both countings) and `naive` (small scenes) against `sweep`, with all three axes, clip on and
/// off: the same SAH cost (within 1e-4), and where the trees differ, say where.
fn level_agrees_with_sweep(tris: &[sahkd::Triangle], case: &str) {
    for clip in [true, false] {
        let sweep_options = BuildOptions {
            algorithm: Algorithm::Sweep,
            axes: Axes::All,
            clip,
            ..BuildOptions::default()
        };
        let reference = build_triangles(tris.to_vec(), &sweep_options).unwrap().tree;
        let mut variants = vec![
            (Algorithm::Level, Counting::Scan),
            (Algorithm::Level, Counting::SpaceTree),
        ];
        // Naive counting is O(n) per candidate, O(n^2) per node: only on small scenes.
        if tris.len() <= 20_000 {
            variants.push((Algorithm::Naive, Counting::Scan));
        }
        for (algorithm, counting) in variants {
            let options = BuildOptions {
                algorithm,
                counting,
                ..sweep_options
            };
            let tree = build_triangles(tris.to_vec(), &options).unwrap().tree;
            let (a, b) = (sah(&reference, &sweep_options), sah(&tree, &options));
            assert!(
                relative(a, b) < 1e-4,
                "{case}, {}: SAH {b} vs sweep {a}; first difference: {:?}",
                describe(&options),
                tree.first_difference(&reference)
            );
            if let Some(d) = tree.first_difference(&reference) {
                eprintln!(
                    "{case}, {}: same SAH, different tree at {d}",
                    describe(&options)
                );
            }
        }
    }
}

#[test]
fn level_and_sweep_agree_on_random_scenes() {
    for (seed, n) in [(21u64, 50usize), (22, 400), (23, 3000)] {
        let tris = random_triangles(&mut rng(seed), n);
        level_agrees_with_sweep(&tris, &format!("{n} random triangles"));
    }
}

#[test]
fn level_and_sweep_agree_on_real_scenes() {
    for file in [
        "dragon_res4.ply",
        "bunny.ply",
        "buddha_res3.ply",
        "sponza_dabrovic.ply",
    ] {
        let Some(mesh) = load_scene(file) else { return };
        level_agrees_with_sweep(&mesh.corner_triangles(), file);
    }
}

#[test]
fn every_builder_gives_the_same_tree_on_1_2_3_and_8_threads() {
    let tris = random_triangles(&mut rng(31), 4000);
    for options in all_variants() {
        let with = |threads| {
            let o = BuildOptions {
                threads: Some(threads),
                ..options
            };
            build_triangles(tris.clone(), &o).unwrap().tree
        };
        let one = with(1);
        for threads in [2, 3, 8] {
            let other = with(threads);
            assert!(
                one.nodes() == other.nodes() && one.refs() == other.refs(),
                "{} differs between 1 and {threads} threads",
                describe(&options)
            );
        }
    }
}

#[test]
fn the_default_and_level_builders_are_deterministic_on_a_real_scene() {
    let Some(mesh) = load_scene("bunny.ply") else {
        return;
    };
    for algorithm in [Algorithm::default(), Algorithm::Level] {
        let with = |threads| {
            let o = BuildOptions {
                algorithm,
                threads: Some(threads),
                ..BuildOptions::default()
            };
            build(&mesh, &o).unwrap().tree
        };
        let (one, two) = (with(1), with(8));
        assert!(
            one.nodes() == two.nodes() && one.refs() == two.refs(),
            "{algorithm:?}"
        );
    }
}

/// The hybrid builder's tree is the sweep's, node for node, on any number of threads (the
/// hand-over to the sweep happens at a different level for each), clip on and off, both axes
/// settings.
fn hybrid_builds_the_sweeps_tree(tris: &[sahkd::Triangle], case: &str) {
    for clip in [true, false] {
        for axes in [Axes::All, Axes::Longest] {
            // Exact: the hybrid's level passes and hand-over are what is compared.
            let sweep_options = BuildOptions {
                algorithm: Algorithm::Sweep,
                axes,
                clip,
                bins: Some(0),
                ..BuildOptions::default()
            };
            let reference = build_triangles(tris.to_vec(), &sweep_options).unwrap().tree;
            for threads in [1, 2, 3, 8] {
                let options = BuildOptions {
                    algorithm: Algorithm::Hybrid,
                    threads: Some(threads),
                    ..sweep_options
                };
                let built = build_triangles(tris.to_vec(), &options).unwrap();
                let levels = built.report.levels.len();
                if threads == 1 {
                    assert_eq!(levels, 0, "{case}: one thread hands the root over");
                } else if tris.len() >= 5000 {
                    assert!(
                        levels > 0,
                        "{case}: {threads} threads start with level passes"
                    );
                }
                assert_eq!(
                    built.tree.first_difference(&reference),
                    None,
                    "{case}, {}, {threads} threads (hand-over after {} levels)",
                    describe(&options),
                    levels
                );
                // The same layout too: the same arrays, not only the same shape.
                assert!(
                    built.tree.nodes() == reference.nodes()
                        && built.tree.refs() == reference.refs(),
                    "{case}, {}, {threads} threads: same tree, another layout",
                    describe(&options)
                );
            }
        }
    }
}

#[test]
fn hybrid_and_sweep_build_the_same_tree_on_random_scenes() {
    for (seed, n) in [(31u64, 60usize), (32, 700), (33, 5000)] {
        let tris = random_triangles(&mut rng(seed), n);
        hybrid_builds_the_sweeps_tree(&tris, &format!("{n} random triangles"));
    }
}

#[test]
fn hybrid_and_sweep_build_the_same_tree_on_real_scenes() {
    for file in ["dragon_res4.ply", "bunny.ply", "sponza_dabrovic.ply"] {
        let Some(mesh) = load_scene(file) else { return };
        hybrid_builds_the_sweeps_tree(&mesh.corner_triangles(), file);
    }
}

/// Long needles crossing a soup of small triangles: with clipping every split that cuts a
/// needle keeps it on both sides, and the reference budget binds.
fn needles_in_a_soup(seed: u64, small: usize, needles: usize) -> Vec<sahkd::Triangle> {
    use rand::Rng;
    let mut r = rng(seed);
    let mut tris = random_triangles(&mut r, small);
    for _ in 0..needles {
        let a = sahkd::Vec3::new(r.random(), r.random(), 0.0);
        let b = sahkd::Vec3::new(r.random(), r.random(), 1.0);
        let thin = sahkd::Vec3::new(1e-3, 0.0, 0.0);
        tris.push([a, b, b + thin]);
    }
    tris
}

/// When the budget binds, the hybrid builder still builds the sweep's tree, on any number of
/// threads, and every builder keeps within the budget.
#[test]
fn a_binding_budget_keeps_every_builder_within_it_and_hybrid_the_sweep() {
    let tris = needles_in_a_soup(41, 3000, 300);
    let cost = sahkd::CostModel {
        max_duplication: 2.0,
        ..sahkd::CostModel::default()
    };
    let budget = cost.reference_budget(tris.len());
    let with = |algorithm, threads, cost| {
        let options = BuildOptions {
            algorithm,
            axes: Axes::All,
            clip: true,
            cost,
            threads: Some(threads),
            bins: Some(0),
            ..BuildOptions::default()
        };
        build_triangles(tris.clone(), &options).unwrap().tree
    };
    // The budget does bind: unlimited, the sweep makes more references than it allows.
    let unlimited = with(Algorithm::Sweep, 1, sahkd::CostModel::default());
    assert!(unlimited.refs().len() > budget, "the budget does not bind");
    let sweep = with(Algorithm::Sweep, 1, cost);
    for algorithm in [Algorithm::Level, Algorithm::Median, Algorithm::Hybrid] {
        for threads in [1, 3] {
            let tree = with(algorithm, threads, cost);
            assert!(tree.refs().len() <= budget, "{algorithm:?} overspent");
            if algorithm == Algorithm::Hybrid {
                assert!(
                    tree.nodes() == sweep.nodes() && tree.refs() == sweep.refs(),
                    "hybrid on {threads} threads is not the sweep's tree"
                );
            }
        }
    }
}
