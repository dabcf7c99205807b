//! The median builder (Zhou et al. 2008) against independent oracles:
//! - the brute-force ray oracle and `KdTree::validate`, on random and real scenes;
//! - the sweep builder: with every node small, the median builder is exact SAH and must give
//!   the sweep's very tree;
//! - the large-node rule re-derived here from the node boxes and triangles (empty-space cut
//!   or spatial median), checked at every large node of a tree;
//! - a hand-made scene whose cuts and medians are known in advance.

mod common;

use common::*;
use sahkd::geometry::triangle_bounds;
use sahkd::{build, build_triangles, Aabb, Algorithm, Axes, BuildOptions, CostModel};
use sahkd::{KdTree, Node, Triangle, Vec3};
use std::collections::BTreeSet;

fn median(axes: Axes, clip: bool, large: u32) -> BuildOptions {
    BuildOptions {
        algorithm: Algorithm::Median,
        axes,
        clip,
        median_large_node: large,
        ..BuildOptions::default()
    }
}

fn bounds_of(tris: &[Triangle]) -> Aabb {
    tris.iter()
        .fold(Aabb::EMPTY, |b, t| b.union(triangle_bounds(t)))
}

/// Every node with its box and depth, depth first.
fn nodes_with_boxes(tree: &KdTree) -> Vec<(u32, Node, Aabb, u32)> {
    let mut out = Vec::new();
    tree.visit(|i, n, b, d| out.push((i, *n, *b, d)));
    out
}

/// The distinct triangles referenced below node `i`: the primitives the node held (every
/// primitive of a node reaches a leaf below it).
fn triangles_below(tree: &KdTree, i: u32) -> BTreeSet<u32> {
    let mut out = BTreeSet::new();
    let mut stack = vec![i];
    while let Some(i) = stack.pop() {
        let n = tree.nodes()[i as usize];
        if n.is_leaf() {
            out.extend(tree.leaf_refs(&n).iter().copied());
        } else {
            stack.extend([n.left(), n.left() + 1]);
        }
    }
    out
}

#[test]
fn random_scenes_match_brute_force() {
    for (seed, n) in [(41u64, 300usize), (42, 3000)] {
        let mut rng = rng(seed);
        let tris = random_triangles(&mut rng, n);
        let rays = random_rays(&mut rng, &bounds_of(&tris), 1500);
        for clip in [true, false] {
            for axes in [Axes::All, Axes::Longest] {
                for large in [64, 8, 0] {
                    let options = median(axes, clip, large);
                    let what = format!("{} on {n} random triangles", describe(&options));
                    let tree = build_triangles(tris.clone(), &options).unwrap().tree;
                    tree.validate().unwrap_or_else(|e| panic!("{what}: {e}"));
                    check_oracle(&tree, &rays).unwrap_or_else(|e| panic!("{what}: {e}"));
                }
            }
        }
    }
}

#[test]
fn same_tree_on_1_2_3_and_8_threads() {
    let tris = random_triangles(&mut rng(43), 6000);
    for clip in [true, false] {
        for large in [64, 16] {
            let options = median(Axes::All, clip, large);
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
}

/// With every node small, only the exact SAH phase runs: the tree must be the sweep's, node
/// for node, also under cost models that make the depth cap and the budget bite.
#[test]
fn with_every_node_small_the_tree_is_the_sweeps() {
    let costs = [
        CostModel::default(),
        CostModel {
            leaf_size: 4,
            max_depth: Some(6),
            ..CostModel::default()
        },
        CostModel {
            max_duplication: 1.0,
            empty_bonus: 1.0,
            ..CostModel::default()
        },
    ];
    for (seed, n) in [(44u64, 50usize), (45, 2500)] {
        let tris = random_triangles(&mut rng(seed), n);
        for clip in [true, false] {
            for axes in [Axes::All, Axes::Longest] {
                for cost in costs {
                    let options = BuildOptions {
                        cost,
                        ..median(axes, clip, n as u32)
                    };
                    let sweep_options = BuildOptions {
                        algorithm: Algorithm::Sweep,
                        ..options
                    };
                    let got = build_triangles(tris.clone(), &options).unwrap().tree;
                    let want = build_triangles(tris.clone(), &sweep_options).unwrap().tree;
                    assert!(
                        got.nodes() == want.nodes() && got.refs() == want.refs(),
                        "{} with {cost:?} on {n} triangles: {:?}",
                        describe(&options),
                        got.first_difference(&want)
                    );
                }
            }
        }
    }
}

/// The large-node rule, written directly: the largest empty space over 25% of the node's
/// extent is cut at the primitives' extent (ties to the lower axis, then the low side),
/// else the node is halved on its longest axis. With clip off, a primitive's box in a node
/// is its triangle's box cut to the node box, so the extent is known from the tree alone.
fn expected_large_split(node_box: &Aabb, tris: &[Triangle], ids: &BTreeSet<u32>) -> (usize, f32) {
    let extent = ids.iter().fold(Aabb::EMPTY, |b, &i| {
        b.union(triangle_bounds(&tris[i as usize]).intersection(*node_box))
    });
    let mut best: Option<(f32, usize, f32)> = None;
    for a in 0..3 {
        let (lo, hi) = (node_box.lo[a], node_box.hi[a]);
        for (gap, pos) in [
            (extent.lo[a] - lo, extent.lo[a]),
            (hi - extent.hi[a], extent.hi[a]),
        ] {
            let ratio = gap / (hi - lo);
            if ratio > 0.25 && pos > lo && pos < hi && best.is_none_or(|b| ratio > b.0) {
                best = Some((ratio, a, pos));
            }
        }
    }
    match best {
        Some((_, a, pos)) => (a, pos + 0.0),
        None => {
            let a = node_box.longest_axis();
            (a, node_box.lo[a] * 0.5 + node_box.hi[a] * 0.5 + 0.0)
        }
    }
}

#[test]
fn every_large_node_is_cut_or_halved_as_the_rule_says() {
    let mut tris = random_triangles(&mut rng(46), 4000);
    // A far cluster, so that empty space appears below the root.
    tris.extend(
        random_triangles(&mut rng(47), 1000)
            .into_iter()
            .map(|t| t.map(|v| v * 0.2 + Vec3::new(4.0, 0.0, 0.0))),
    );
    for clip in [false, true] {
        for large in [64, 16] {
            let options = median(Axes::All, clip, large);
            let tree = build_triangles(tris.clone(), &options).unwrap().tree;
            let (mut cuts, mut halves) = (0, 0);
            for (i, node, node_box, _) in nodes_with_boxes(&tree) {
                let ids = triangles_below(&tree, i);
                if node.is_leaf() || ids.len() <= large as usize {
                    continue;
                }
                let left = tree.nodes()[node.left() as usize];
                let right = tree.nodes()[node.left() as usize + 1];
                let empty_child = (left.is_leaf() && left.count() == 0)
                    || (right.is_leaf() && right.count() == 0);
                let a = node_box.longest_axis();
                let halved =
                    node.axis() == a && node.split() == node_box.lo[a] * 0.5 + node_box.hi[a] * 0.5;
                if clip {
                    // Clipped boxes are not known from outside: a cut leaves an empty leaf.
                    assert!(
                        halved || empty_child,
                        "node {i} of {} is neither",
                        ids.len()
                    );
                } else {
                    let want = expected_large_split(&node_box, tree.triangles(), &ids);
                    assert_eq!(
                        (node.axis(), node.split()),
                        want,
                        "node {i} ({} triangles, box {node_box:?})",
                        ids.len()
                    );
                }
                if halved {
                    halves += 1;
                } else {
                    cuts += 1;
                }
            }
            assert!(
                cuts > 0 && halves > 0,
                "clip {clip}: {cuts} cuts, {halves} halvings"
            );
        }
    }
}

/// A slab of triangles spanning y and z, `count` of them with x from `x0` stepping by `dx`.
fn slab(count: usize, x0: f32, dx: f32) -> Vec<Triangle> {
    (0..count)
        .map(|i| {
            let x = x0 + i as f32 * dx;
            [
                Vec3::new(x, 0.0, 0.0),
                Vec3::new(x + 0.1, 1.0, 0.0),
                Vec3::new(x, 1.0, 1.0),
            ]
        })
        .collect()
}

/// Two clusters along a long box: the root is halved (its box is the triangles' own, so it
/// has no empty space); the left half is 80% empty, so it is cut at its triangles' extent
/// with an empty leaf beside; the right half is only 21% empty, so it is halved.
#[test]
fn empty_space_is_cut_off_at_the_triangles_extent() {
    let left_cluster = slab(100, 0.0, 0.009);
    let right_cluster = slab(100, 6.039, 0.039);
    let tris = [left_cluster.clone(), right_cluster.clone()].concat();
    let scene = bounds_of(&tris);
    let rays = random_rays(&mut rng(48), &scene, 500);
    for clip in [true, false] {
        let tree = build_triangles(tris.clone(), &median(Axes::All, clip, 64))
            .unwrap()
            .tree;
        tree.validate().unwrap();
        check_oracle(&tree, &rays).unwrap();
        let nodes = tree.nodes();
        let root = nodes[0];
        let half = scene.lo[0] * 0.5 + scene.hi[0] * 0.5;
        assert_eq!((root.axis(), root.split()), (0, half), "clip {clip}: root");

        let cut = nodes[root.left() as usize];
        let extent = bounds_of(&left_cluster).hi[0];
        assert!(!cut.is_leaf(), "clip {clip}: the left half is a leaf");
        assert_eq!(
            (cut.axis(), cut.split()),
            (0, extent),
            "clip {clip}: left half"
        );
        let empty = nodes[cut.left() as usize + 1];
        assert!(
            empty.is_leaf() && empty.count() == 0,
            "clip {clip}: {empty:?}"
        );
        assert_eq!(triangles_below(&tree, cut.left()).len(), 100);

        let halved = nodes[root.left() as usize + 1];
        let right_lo = bounds_of(&right_cluster).lo[0];
        assert!((right_lo - half) / (scene.hi[0] - half) < 0.25);
        assert_eq!(
            (halved.axis(), halved.split()),
            (0, half * 0.5 + scene.hi[0] * 0.5),
            "clip {clip}: right half"
        );
    }
}

/// The depth cap applies to large nodes too: they become leaves there.
#[test]
fn large_nodes_at_the_depth_cap_become_leaves() {
    let tris = random_triangles(&mut rng(49), 5000);
    let rays = random_rays(&mut rng(50), &bounds_of(&tris), 500);
    let options = BuildOptions {
        cost: CostModel {
            max_depth: Some(3),
            ..CostModel::default()
        },
        ..median(Axes::Longest, true, 64)
    };
    let tree = build_triangles(tris, &options).unwrap().tree;
    tree.validate().unwrap();
    check_oracle(&tree, &rays).unwrap();
    let nodes = nodes_with_boxes(&tree);
    assert!(nodes.iter().all(|&(_, _, _, d)| d <= 3));
    assert!(nodes
        .iter()
        .any(|&(_, n, _, d)| d == 3 && n.is_leaf() && n.count() > 64));
}

#[test]
fn the_reference_budget_holds() {
    let tris = random_triangles(&mut rng(51), 5000);
    let rays = random_rays(&mut rng(52), &bounds_of(&tris), 500);
    for clip in [true, false] {
        let options = BuildOptions {
            cost: CostModel {
                max_duplication: 1.0,
                ..CostModel::default()
            },
            ..median(Axes::All, clip, 16)
        };
        let tree = build_triangles(tris.clone(), &options).unwrap().tree;
        tree.validate().unwrap();
        check_oracle(&tree, &rays).unwrap();
        let stats = tree.stats(&options.cost);
        let budget = options.cost.reference_budget(tris.len());
        assert!(
            stats.references <= budget,
            "{} > {budget}",
            stats.references
        );
    }
}

fn real_scene(file: &str) {
    let Some(mesh) = load_scene(file) else { return };
    let rays = random_rays(&mut rng(53), &mesh.bounds(), 2000);
    for (axes, clip) in [(Axes::Longest, true), (Axes::All, false)] {
        let options = median(axes, clip, 64);
        let tree = build(&mesh, &options).unwrap().tree;
        let what = format!("{file} with {}", describe(&options));
        tree.validate().unwrap_or_else(|e| panic!("{what}: {e}"));
        check_oracle(&tree, &rays).unwrap_or_else(|e| panic!("{what}: {e}"));
    }
}

#[test]
fn bunny_matches_brute_force_on_2000_rays() {
    real_scene("bunny.ply");
}

#[test]
fn dragon_res3_matches_brute_force_on_2000_rays() {
    real_scene("dragon_res3.ply");
}

/// Options saved before `median_large_node` existed (as the Python package's tree files
/// hold them) still load, with the default threshold.
#[test]
fn options_without_the_threshold_still_deserialize() {
    let mut saved = serde_json::to_value(BuildOptions::sweep()).unwrap();
    saved.as_object_mut().unwrap().remove("median_large_node");
    let loaded: BuildOptions = serde_json::from_value(saved).unwrap();
    assert_eq!(loaded, BuildOptions::sweep());
    assert_eq!(loaded.median_large_node, 64);
}
