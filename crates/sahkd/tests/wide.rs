//! The 8-wide bounded layout made from a kd-tree must answer as the brute force does: every
//! builder, random and generated grid scenes, real meshes, scenes far from the origin and at
//! extreme scales, closest hit (ties to the lower index) and any hit.

mod common;

use common::*;
use proptest::prelude::*;
use sahkd::trace::brute;
use sahkd::trace::wide::WideBvh;
use sahkd::{build, build_triangles, BuildOptions, KdTree, Ray, Triangle, Vec3};

fn check_wide(tree: &KdTree, rays: &[Ray]) -> Result<(), String> {
    let wide = WideBvh::new(tree);
    let tris = tree.triangles();
    for (i, ray) in rays.iter().enumerate() {
        let (got, want) = (wide.intersect(ray), brute::intersect(tris, ray));
        if got != want {
            return Err(format!(
                "ray {i} {ray:?}: wide gives {got:?}, brute force {want:?}"
            ));
        }
        let (got, want) = (wide.occluded(ray), brute::occluded(tris, ray));
        if got != want {
            return Err(format!(
                "ray {i} {ray:?}: wide says occluded={got}, brute force {want}"
            ));
        }
    }
    Ok(())
}

fn bounds_of(tris: &[Triangle]) -> sahkd::Aabb {
    tris.iter().fold(sahkd::Aabb::EMPTY, |b, t| {
        b.union(sahkd::geometry::triangle_bounds(t))
    })
}

#[test]
fn every_builder_walked_wide_matches_brute_force() {
    for (seed, n) in [(1u64, 1usize), (2, 2), (3, 17), (4, 300), (5, 1500)] {
        let mut rng = rng(seed);
        let tris = random_triangles(&mut rng, n);
        let rays = random_rays(&mut rng, &bounds_of(&tris), 600);
        for options in all_variants() {
            let tree = build_triangles(tris.clone(), &options).unwrap().tree;
            check_wide(&tree, &rays)
                .unwrap_or_else(|e| panic!("{} on {n} random triangles: {e}", describe(&options)));
        }
    }
}

/// The same scenes moved far from the origin and scaled to the ends of float32's range: the
/// slab test must not lose a hit to rounding when the origin's coordinates dwarf the box,
/// and the layout's power-of-two scale must not change an answer.
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
        check_wide(&tree, &rays).unwrap_or_else(|e| panic!("scale {scale}, shift {shift}: {e}"));
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
    let wide = WideBvh::new(&tree);
    let down = Ray::new(Vec3::new(0.25, 0.25, 1.0), Vec3::new(0.0, 0.0, -1.0));
    assert_eq!(wide.intersect(&down).map(|h| (h.prim, h.t)), Some((0, 1.0)));
    assert!(!wide.occluded(&down.with_range(0.0, 0.5)));
    let empty = build_triangles(Vec::new(), &BuildOptions::default())
        .unwrap()
        .tree;
    assert_eq!(WideBvh::new(&empty).intersect(&down), None);
}

/// Corners drawn from a small set of values, so coincident and planar triangles, ties and
/// rays lying in split planes are the rule.
fn grid_triangle() -> impl Strategy<Value = Triangle> {
    let coord = (0i32..6).prop_map(|k| k as f32 * 0.25);
    let corner = [coord.clone(), coord.clone(), coord].prop_map(Vec3);
    [corner.clone(), corner.clone(), corner]
}

fn grid_ray() -> impl Strategy<Value = Ray> {
    let coord = (-4i32..10).prop_map(|k| k as f32 * 0.125 + 0.0);
    let dir = (-2i32..3).prop_map(|k| k as f32);
    (
        [coord.clone(), coord.clone(), coord],
        [dir.clone(), dir.clone(), dir],
    )
        .prop_map(|(o, d)| Ray::new(Vec3(o), Vec3(d)))
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]
    #[test]
    fn generated_grid_scenes_walked_wide_match_brute_force(
        tris in prop::collection::vec(grid_triangle(), 1..80),
        rays in prop::collection::vec(grid_ray(), 64),
    ) {
        for options in [BuildOptions::default(), BuildOptions::fast(), BuildOptions::paper()] {
            let tree = build_triangles(tris.clone(), &options).unwrap().tree;
            let result = check_wide(&tree, &rays);
            prop_assert!(result.is_ok(), "{}: {}", describe(&options), result.unwrap_err());
        }
    }
}

#[test]
fn bunny_walked_wide_matches_brute_force_on_10000_rays() {
    let Some(mesh) = load_scene("bunny.ply") else {
        return;
    };
    let rays = random_rays(&mut rng(7), &mesh.bounds(), 10_000);
    for options in [BuildOptions::default(), BuildOptions::fast()] {
        let tree = build(&mesh, &options).unwrap().tree;
        check_wide(&tree, &rays).unwrap_or_else(|e| panic!("bunny, {}: {e}", describe(&options)));
    }
}
