//! Binned SAH for big nodes (`BuildOptions::bins`): the hybrid's default, the other builders
//! exact by default; off (`Some(0)`), the exact trees of before; on, valid trees that answer rays like brute force, the same on any number of
//! threads, and options out of range refused.

mod common;

use common::*;
use sahkd::{build_triangles, Algorithm, Axes, BuildOptions, CostModel};

/// The exact trees' fingerprints, taken before binning existed (commit e4cfe04, with Wald &
/// Havran's constants, the default then): bins 0 must leave every tree as it was, bit for bit.
#[test]
fn bins_zero_gives_the_exact_trees_of_before() {
    let tris = random_triangles(&mut rng(13), 6000);
    for (algorithm, axes, clip, want) in [
        (
            Algorithm::Sweep,
            Axes::Longest,
            true,
            0x5906_c129_6e03_a6e8u64,
        ),
        (Algorithm::Sweep, Axes::All, false, 0x2f51_6f01_2962_dcc4),
        (Algorithm::Hybrid, Axes::All, true, 0x592a_a079_6a28_81ab),
    ] {
        let options = BuildOptions {
            algorithm,
            axes,
            clip,
            threads: Some(2),
            bins: Some(0),
            cost: CostModel::wald_havran(),
            ..BuildOptions::default()
        };
        let tree = build_triangles(tris.clone(), &options).unwrap().tree;
        let got = fingerprint(&tree);
        assert_eq!(got, want, "{algorithm:?} {axes:?} clip {clip}: {got:#x}");
    }
}

fn binned(algorithm: Algorithm, bins: u32, threads: usize) -> BuildOptions {
    BuildOptions {
        algorithm,
        axes: Axes::All,
        bins: Some(bins),
        threads: Some(threads),
        ..BuildOptions::default()
    }
}

/// Rays through binned trees hit what a loop over every triangle hits, on scenes big enough
/// for several binned levels (the threshold is `BINNED_REFS_PER_BIN * bins` references).
#[test]
fn binned_trees_answer_rays_like_brute_force() {
    for (seed, n, bins) in [(21u64, 3000usize, 2u32), (22, 5000, 8), (23, 9000, 16)] {
        let mut rng = rng(seed);
        let tris = random_triangles(&mut rng, n);
        let rays = random_rays(&mut rng, &bounds_of(&tris), 800);
        for algorithm in [Algorithm::Sweep, Algorithm::Hybrid] {
            for clip in [true, false] {
                let options = BuildOptions {
                    clip,
                    ..binned(algorithm, bins, 2)
                };
                let tree = build_triangles(tris.clone(), &options).unwrap().tree;
                let what = format!("{algorithm:?} clip {clip}, {bins} bins, {n} triangles");
                tree.validate().unwrap_or_else(|e| panic!("{what}: {e}"));
                check_oracle(&tree, &rays).unwrap_or_else(|e| panic!("{what}: {e}"));
            }
        }
    }
}

fn bounds_of(tris: &[sahkd::Triangle]) -> sahkd::Aabb {
    tris.iter().fold(sahkd::Aabb::EMPTY, |b, t| {
        b.union(sahkd::geometry::triangle_bounds(t))
    })
}

/// The same arrays on 1, 2 and 3 threads, and the hybrid's equal the sweep's.
#[test]
fn binned_trees_are_the_same_on_any_thread_count() {
    let tris = random_triangles(&mut rng(31), 12_000);
    for bins in [4, 32] {
        let want = build_triangles(tris.clone(), &binned(Algorithm::Sweep, bins, 1))
            .unwrap()
            .tree;
        for algorithm in [Algorithm::Sweep, Algorithm::Hybrid] {
            for threads in [1, 2, 3] {
                let got = build_triangles(tris.clone(), &binned(algorithm, bins, threads))
                    .unwrap()
                    .tree;
                let what = format!("{algorithm:?}, {bins} bins, {threads} threads");
                assert_eq!(got.nodes(), want.nodes(), "{what}: nodes");
                assert_eq!(got.refs(), want.refs(), "{what}: references");
            }
        }
    }
}

/// Below the threshold a parallel build splits the biggest nodes by the sweep's own search and
/// builds their children at once (`FORK_SHARE` in `builders/sweep/binned.rs`; every node here
/// over 1024 triangles at 2 or 3 threads): the tree is still the one-thread exact sweep's.
#[test]
fn nodes_split_at_once_below_the_threshold_give_the_sweeps_tree() {
    let tris = random_triangles(&mut rng(61), 6000);
    for axes in [Axes::Longest, Axes::All] {
        for clip in [true, false] {
            let options = |algorithm, bins, threads| BuildOptions {
                axes,
                clip,
                ..binned(algorithm, bins, threads)
            };
            let want = build_triangles(tris.clone(), &options(Algorithm::Sweep, 0, 1))
                .unwrap()
                .tree;
            for threads in [2, 3] {
                let got = build_triangles(tris.clone(), &options(Algorithm::Hybrid, 256, threads))
                    .unwrap()
                    .tree;
                let what = format!("{axes:?}, clip {clip}, {threads} threads");
                assert_eq!(got.nodes(), want.nodes(), "{what}: nodes");
                assert_eq!(got.refs(), want.refs(), "{what}: references");
            }
        }
    }
}

/// Binning changes the tree only where a node is over the threshold: a scene at it gets the
/// exact tree, one over it a different one (else the test tests nothing).
#[test]
fn only_nodes_over_the_threshold_are_binned() {
    let bins = 8;
    let at = sahkd::BINNED_REFS_PER_BIN * bins as usize;
    for (n, same) in [(at, true), (4 * at, false)] {
        let tris = random_triangles(&mut rng(41), n);
        let exact = build_triangles(tris.clone(), &binned(Algorithm::Sweep, 0, 1))
            .unwrap()
            .tree;
        let tree = build_triangles(tris, &binned(Algorithm::Sweep, bins, 1))
            .unwrap()
            .tree;
        assert_eq!(tree.same_tree(&exact), same, "{n} triangles");
    }
}

#[test]
fn bins_out_of_range_or_with_other_builders_are_refused() {
    let tris = random_triangles(&mut rng(51), 10);
    for (options, words) in [
        (binned(Algorithm::Sweep, 1, 1), ["bins", "from 2 to 1024"]),
        (
            binned(Algorithm::Hybrid, sahkd::MAX_BINS + 1, 1),
            ["bins", "1025"],
        ),
        (binned(Algorithm::Level, 16, 1), ["bins", "level"]),
        (binned(Algorithm::Naive, 16, 1), ["bins", "naive"]),
        (binned(Algorithm::Median, 16, 1), ["bins", "median"]),
    ] {
        let err = options.validate().unwrap_err().to_string();
        for w in words {
            assert!(err.contains(w), "{err:?} should say {w:?}");
        }
        let Err(built) = build_triangles(tris.clone(), &options) else {
            panic!("{options:?} was built");
        };
        assert_eq!(built.to_string(), err);
    }
    for bins in [0, 2, sahkd::MAX_BINS] {
        assert!(binned(Algorithm::Sweep, bins, 1).validate().is_ok());
    }
}

/// Unset, `bins` is the hybrid's [`sahkd::HYBRID_BINS`] and exact SAH for every other
/// builder (the sweep stays the exact reference); set, it is what was asked. The default
/// hybrid's tree is the binned sweep's.
#[test]
fn bins_default_to_binning_for_the_hybrid_only() {
    for algorithm in Algorithm::ALL.iter().copied() {
        let options = BuildOptions {
            algorithm,
            ..BuildOptions::default()
        };
        assert_eq!(options.bins, None);
        assert!(options.validate().is_ok(), "{algorithm:?}");
        let want = if algorithm == Algorithm::Hybrid {
            sahkd::HYBRID_BINS
        } else {
            0
        };
        assert_eq!(options.resolved_bins(), want, "{algorithm:?}");
        for bins in [0, 64] {
            let set = BuildOptions {
                bins: Some(bins),
                ..options
            };
            assert_eq!(set.resolved_bins(), bins, "{algorithm:?}");
        }
    }
    assert_eq!(
        BuildOptions::quality().resolved_bins(),
        0,
        "quality is exact"
    );
    // Enough triangles for the root to be binned (over 64 x 256 references).
    let tris = sahkd::scenes::generate("spd:toys:20000")
        .unwrap()
        .corner_triangles();
    let default = build_triangles(tris.clone(), &BuildOptions::default())
        .unwrap()
        .tree;
    let sweep = build_triangles(
        tris.clone(),
        &BuildOptions {
            bins: Some(sahkd::HYBRID_BINS),
            ..BuildOptions::sweep()
        },
    )
    .unwrap()
    .tree;
    assert!(
        default.same_tree(&sweep),
        "default hybrid = sweep with HYBRID_BINS"
    );
    let exact = build_triangles(tris, &BuildOptions::sweep()).unwrap().tree;
    assert!(!default.same_tree(&exact), "the default is binned");
}

/// Options leave `bins` out when unset and read it back when set; options saved before it
/// existed read as unset.
#[test]
fn bins_round_trips_through_saved_options() {
    let unset = serde_json::to_string(&BuildOptions::default()).unwrap();
    assert!(!unset.contains("bins"), "{unset}");
    for bins in [0, 64] {
        let options = binned(Algorithm::Sweep, bins, 1);
        let text = serde_json::to_string(&options).unwrap();
        let back: BuildOptions = serde_json::from_str(&text).unwrap();
        assert_eq!(back.bins, Some(bins));
    }
    let old: BuildOptions = serde_json::from_str(&unset).unwrap();
    assert_eq!(old.bins, None);
}
