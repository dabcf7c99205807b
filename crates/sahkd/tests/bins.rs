//! Binned SAH for big nodes (`BuildOptions::bins`): off by default and then the exact trees
//! of before; on, valid trees that answer rays like brute force, the same on any number of
//! threads, and options out of range refused.

mod common;

use common::*;
use sahkd::{build_triangles, Algorithm, Axes, BuildOptions, KdTree};

/// FNV-1a over the tree's node words and references: a fingerprint of the arrays.
fn fingerprint(tree: &KdTree) -> u64 {
    let mut h = 0xcbf2_9ce4_8422_2325u64;
    let words = tree.nodes().iter().flat_map(|n| n.words());
    for w in words.chain(tree.refs().iter().copied()) {
        for b in w.to_le_bytes() {
            h = (h ^ b as u64).wrapping_mul(0x100_0000_01b3);
        }
    }
    h
}

/// The exact trees' fingerprints, taken before binning existed (commit e4cfe04): bins = 0
/// must leave every tree as it was, bit for bit.
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
            ..BuildOptions::default()
        };
        assert_eq!(options.bins, 0, "binning is off by default");
        let tree = build_triangles(tris.clone(), &options).unwrap().tree;
        let got = fingerprint(&tree);
        assert_eq!(got, want, "{algorithm:?} {axes:?} clip {clip}: {got:#x}");
    }
}
