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
fn the_level_builder_is_deterministic_on_a_real_scene() {
    let Some(mesh) = load_scene("bunny.ply") else {
        return;
    };
    let with = |threads| {
        let o = BuildOptions {
            threads: Some(threads),
            ..BuildOptions::default()
        };
        build(&mesh, &o).unwrap().tree
    };
    let (one, two) = (with(1), with(8));
    assert!(one.nodes() == two.nodes() && one.refs() == two.refs());
}
