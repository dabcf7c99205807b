//! The walk of the 8-wide nodes answers as the brute force does where its slab test is most
//! at risk: scenes far from the origin (coordinates that dwarf the scene) and at the ends of
//! float32's range, and trees with no triangles or one leaf. Every builder on random,
//! generated and real scenes is checked through `check_oracle` (tests/oracle.rs).

mod common;

use common::*;
use sahkd::{build_triangles, BuildOptions, Ray, Triangle, Vec3};

#[test]
fn far_and_extreme_scenes_walked_wide_match_brute_force() {
    let mut rng = rng(11);
    let base = random_triangles(&mut rng, 400);
    for (scale, shift) in [
        (1.0f32, 1e5f32),
        (1.0, -3e6),
        (1e-30, 0.0),
        (1e30, 0.0),
        (1e-3, 50.0),
    ] {
        let tris: Vec<Triangle> = base
            .iter()
            .map(|t| t.map(|v| Vec3::new(v[0] * scale + shift, v[1] * scale, v[2] * scale - shift)))
            .collect();
        let rays = random_rays(&mut rng, &bounds_of(&tris), 800);
        let tree = build_triangles(tris, &BuildOptions::default())
            .unwrap()
            .tree;
        check_oracle(&tree, &rays).unwrap_or_else(|e| panic!("scale {scale}, shift {shift}: {e}"));
    }
}

#[test]
fn trees_with_no_triangles_or_one_leaf_walked_wide() {
    let one = vec![[
        Vec3::new(0.0, 0.0, 0.0),
        Vec3::new(1.0, 0.0, 0.0),
        Vec3::new(0.0, 1.0, 0.0),
    ]];
    let tree = build_triangles(one, &BuildOptions::default()).unwrap().tree;
    let down = Ray::new(Vec3::new(0.25, 0.25, 1.0), Vec3::new(0.0, 0.0, -1.0));
    assert_eq!(tree.intersect(&down).map(|h| (h.prim, h.t)), Some((0, 1.0)));
    assert!(!tree.occluded(&down.with_range(0.0, 0.5)));
    let empty = build_triangles(Vec::new(), &BuildOptions::default())
        .unwrap()
        .tree;
    assert_eq!(empty.intersect(&down), None);
    assert!(!empty.occluded(&down));
}
