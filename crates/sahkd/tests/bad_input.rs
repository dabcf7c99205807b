//! Input that breaks naive builders: each case has a defined outcome, for every builder.

mod common;

use common::*;
use sahkd::{build, build_triangles, BuildOptions, Mesh, Ray, Triangle, Vec3};

fn tri(a: [f32; 3], b: [f32; 3], c: [f32; 3]) -> Triangle {
    [Vec3(a), Vec3(b), Vec3(c)]
}

/// Builds `tris` with every variant; each tree must validate, answer like the brute force,
/// and respect the reference budget.
fn builds_and_answers(tris: Vec<Triangle>, rays: &[Ray], case: &str) {
    for options in all_variants() {
        let what = format!("{case}, {}", describe(&options));
        let tree = build_triangles(tris.clone(), &options)
            .unwrap_or_else(|e| panic!("{what}: {e}"))
            .tree;
        tree.validate().unwrap_or_else(|e| panic!("{what}: {e}"));
        check_oracle(&tree, rays).unwrap_or_else(|e| panic!("{what}: {e}"));
        let stats = tree.stats(&options.cost);
        assert!(
            stats.references <= options.cost.reference_budget(tris.len()),
            "{what}: {} references over the budget",
            stats.references
        );
        assert!(
            stats.max_depth <= options.cost.max_depth_for(tris.len()),
            "{what}: too deep"
        );
    }
}

#[test]
fn non_finite_coordinates_are_rejected_naming_the_vertex() {
    for bad in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
        let mesh = Mesh {
            vertices: vec![[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, bad, 0.0]],
            triangles: vec![[0, 1, 2], [1, 2, 3]],
        };
        let err = build(&mesh, &BuildOptions::default())
            .err()
            .expect("must be rejected");
        let msg = err.to_string();
        assert!(
            msg.contains("vertex 3") && msg.contains("non-finite"),
            "{msg}"
        );
    }
}

/// The corners are checked in chunks on the workers: the first bad triangle is named, on any
/// thread count, whichever chunk it lies in and whatever bad ones follow it.
#[test]
fn non_finite_triangles_are_rejected_naming_the_first() {
    let good: Triangle = [
        Vec3::new(0.0, 0.0, 0.0),
        Vec3::new(1.0, 0.0, 0.0),
        Vec3::new(0.0, 1.0, 0.0),
    ];
    for first in [0, 4095, 4096, 9000] {
        let mut tris = vec![good; 20_000];
        for (i, bad) in [
            (first, f32::NAN),
            (first + 1, f32::INFINITY),
            (19_999, f32::NAN),
        ] {
            tris[i][i % 3].0[i % 2] = bad;
        }
        for threads in [1, 2, 4] {
            let options = BuildOptions {
                threads: Some(threads),
                ..BuildOptions::default()
            };
            let msg = build_triangles(tris.clone(), &options)
                .err()
                .expect("must be rejected")
                .to_string();
            assert!(
                msg.contains(&format!("triangle {first} has a non-finite corner")),
                "{msg}"
            );
        }
    }
}

#[test]
fn indices_out_of_range_are_rejected_naming_the_face() {
    let mesh = Mesh {
        vertices: vec![[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
        triangles: vec![[0, 1, 2], [0, 1, 3]],
    };
    let msg = build(&mesh, &BuildOptions::default())
        .err()
        .unwrap()
        .to_string();
    assert!(msg.contains("face 1") && msg.contains("vertex 3"), "{msg}");
}

#[test]
fn zero_threads_is_an_error_not_a_panic() {
    let options = BuildOptions {
        threads: Some(0),
        ..BuildOptions::default()
    };
    let msg = build(&Mesh::default(), &options).err().unwrap().to_string();
    assert!(msg.contains("threads"), "{msg}");
}

#[test]
fn an_empty_mesh_gives_an_empty_tree_that_every_ray_misses() {
    for options in all_variants() {
        let tree = build(&Mesh::default(), &options).unwrap().tree;
        tree.validate().unwrap();
        let ray = Ray::new(Vec3::splat(0.0), Vec3::new(0.0, 0.0, 1.0));
        assert_eq!(tree.intersect(&ray), None);
        assert!(!tree.occluded(&ray));
        assert_eq!(tree.stats(&options.cost).references, 0);
    }
}

#[test]
fn zero_area_triangles_are_kept_and_never_hit() {
    let mut rng = rng(11);
    let mut tris = random_triangles(&mut rng, 200);
    // Points, segments, and collinear corners.
    tris.push(tri([0.5; 3], [0.5; 3], [0.5; 3]));
    tris.push(tri([0.1, 0.1, 0.1], [0.9, 0.9, 0.9], [0.5, 0.5, 0.5]));
    tris.push(tri([0.0, 0.5, 0.5], [1.0, 0.5, 0.5], [1.0, 0.5, 0.5]));
    let rays = random_rays(
        &mut rng,
        &sahkd::Aabb::new(Vec3::splat(0.0), Vec3::splat(1.0)),
        500,
    );
    builds_and_answers(tris, &rays, "zero-area triangles");
}

#[test]
fn every_triangle_in_one_plane() {
    let mut rng = rng(12);
    let mut tris = random_triangles(&mut rng, 500);
    for t in &mut tris {
        for v in t.iter_mut() {
            v[2] = 0.25;
        }
    }
    let mut rays = random_rays(
        &mut rng,
        &sahkd::Aabb::new(Vec3::splat(0.0), Vec3::splat(1.0)),
        500,
    );
    // Rays lying in the plane itself, and rays starting in it.
    rays.push(Ray::new(
        Vec3::new(-1.0, 0.5, 0.25),
        Vec3::new(1.0, 0.0, 0.0),
    ));
    rays.push(Ray::new(
        Vec3::new(0.5, 0.5, 0.25),
        Vec3::new(0.0, 0.0, 1.0),
    ));
    builds_and_answers(tris, &rays, "one plane");
}

#[test]
fn ten_thousand_identical_triangles() {
    let t = tri([0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.5]);
    let mut rng = rng(13);
    let rays = random_rays(
        &mut rng,
        &sahkd::Aabb::new(Vec3::splat(0.0), Vec3::splat(1.0)),
        50,
    );
    builds_and_answers(vec![t; 10_000], &rays, "10 000 identical triangles");
}

#[test]
fn huge_coordinates_next_to_tiny_triangles() {
    let mut rng = rng(14);
    let mut tris: Vec<Triangle> = random_triangles(&mut rng, 300)
        .into_iter()
        .map(|t| t.map(|v| v * 1e-6))
        .collect();
    tris.push(tri(
        [-1e30, -1e30, 0.0],
        [1e30, -1e30, 0.0],
        [0.0, 1e30, 1e30],
    ));
    tris.push(tri(
        [1e30, 1e30, 1e30],
        [1e30, 1e30, -1e30],
        [-1e30, 1e30, 1e30],
    ));
    let small = sahkd::Aabb::new(Vec3::splat(0.0), Vec3::splat(1e-6));
    let mut rays = random_rays(&mut rng, &small, 300);
    rays.extend(random_rays(
        &mut rng,
        &sahkd::Aabb::new(Vec3::splat(-1e30), Vec3::splat(1e30)),
        100,
    ));
    builds_and_answers(tris, &rays, "1e30 coordinates");
}

#[test]
fn heavy_overlap_stays_within_the_reference_budget() {
    // Long thin triangles crossing the whole scene in every direction: each split cuts most
    // of them, the case where duplication explodes without a budget.
    let mut rng = rng(15);
    use rand::Rng;
    let tris: Vec<Triangle> = (0..3000)
        .map(|_| {
            let p = Vec3::new(rng.random(), rng.random(), rng.random());
            let q = Vec3::new(rng.random(), rng.random(), rng.random());
            let e = Vec3::new(rng.random(), rng.random(), rng.random()) * 0.001;
            [p, q, q + e]
        })
        .collect();
    let rays = random_rays(
        &mut rng,
        &sahkd::Aabb::new(Vec3::splat(0.0), Vec3::splat(1.0)),
        200,
    );
    builds_and_answers(tris, &rays, "heavy overlap");
}

#[test]
fn invalid_rays_hit_nothing() {
    let tris = vec![tri([0.0, 0.0, 1.0], [1.0, 0.0, 1.0], [0.0, 1.0, 1.0])];
    let tree = build_triangles(tris, &BuildOptions::default())
        .unwrap()
        .tree;
    let o = Vec3::new(0.2, 0.2, 0.0);
    for ray in [
        Ray::new(o, Vec3::splat(0.0)),
        Ray::new(o, Vec3::new(0.0, 0.0, f32::NAN)),
        Ray::new(Vec3::new(f32::NAN, 0.0, 0.0), Vec3::new(0.0, 0.0, 1.0)),
        Ray::new(o, Vec3::new(0.0, 0.0, 1.0)).with_range(2.0, 1.0),
    ] {
        assert_eq!(tree.intersect(&ray), None, "{ray:?}");
        assert!(!tree.occluded(&ray), "{ray:?}");
    }
    assert!(tree
        .intersect(&Ray::new(o, Vec3::new(0.0, 0.0, 1.0)))
        .is_some());
}
