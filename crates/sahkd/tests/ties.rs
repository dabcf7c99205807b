//! Ties in t go to the lower triangle index, in every walk: coplanar soups (every hit of a ray
//! at one distance, or nearly) against the brute force's full list of hits, the closest being
//! the least (t, index) of that list as reported.

mod common;

use common::*;
use rand::Rng;
use sahkd::scene::{Scene, Transform};
use sahkd::trace::{brute, precise};
use sahkd::{build_triangles, BuildOptions, Hit, Hit64, Ray, Ray64, Triangle, Vec3};

/// `n` triangles in one plane (`z = 0` when `tilt` is false, a tilted plane otherwise),
/// overlapping heavily so that most rays hit several at once.
fn coplanar_soup(seed: u64, n: usize, tilt: bool) -> Vec<Triangle> {
    let mut rng = rng(seed);
    let plane = |x: f32, y: f32| {
        let z = if tilt { 0.3 * x - 0.7 * y + 0.25 } else { 0.0 };
        Vec3([x, y, z])
    };
    (0..n)
        .map(|_| {
            let (cx, cy) = (rng.random_range(0.0..1.0f32), rng.random_range(0.0..1.0f32));
            let mut corner = || {
                plane(
                    cx + rng.random_range(-0.6..0.6f32),
                    cy + rng.random_range(-0.6..0.6f32),
                )
            };
            [corner(), corner(), corner()]
        })
        .collect()
}

fn rays_at(seed: u64, n: usize, straight: bool) -> Vec<Ray> {
    let mut rng = rng(seed ^ 0x7135);
    (0..n)
        .map(|_| {
            let o = Vec3([
                rng.random_range(-0.2..1.2f32),
                rng.random_range(-0.2..1.2f32),
                rng.random_range(1.0..3.0f32),
            ]);
            let d = if straight {
                Vec3([0.0, 0.0, -1.0])
            } else {
                Vec3([
                    rng.random_range(-0.5..0.5f32),
                    rng.random_range(-0.5..0.5f32),
                    -1.0,
                ])
            };
            Ray::new(o, d)
        })
        .collect()
}

/// The least (t, index) of every hit the brute force reports.
fn least_hit(tris: &[Triangle], ray: &Ray) -> Option<Hit> {
    let mut best: Option<Hit> = None;
    brute::for_each_hit(tris, ray, |h| {
        if best.map_or(true, |b| (h.t, h.prim) < (b.t, b.prim)) {
            best = Some(h);
        }
    });
    best
}

fn least_hit64(tris: &[Triangle], ray: &Ray64) -> Option<Hit64> {
    let mut best: Option<Hit64> = None;
    precise::brute_for_each_hit(tris, ray, |h| {
        if best.map_or(true, |b| (h.t, h.prim) < (b.t, b.prim)) {
            best = Some(h);
        }
    });
    best
}

fn soups() -> Vec<(String, Vec<Triangle>, Vec<Ray>)> {
    let mut out = Vec::new();
    for (seed, n) in [(1u64, 2usize), (2, 7), (3, 60), (4, 300)] {
        for tilt in [false, true] {
            for straight in [true, false] {
                out.push((
                    format!("{n} coplanar triangles, tilt {tilt}, straight {straight}"),
                    coplanar_soup(seed, n, tilt),
                    rays_at(seed, 400, straight),
                ));
            }
        }
    }
    out
}

#[test]
fn two_triangles_one_ray_lower_index_wins() {
    // Two coplanar triangles in z = 0, one ray straight down onto both.
    let tris = vec![
        [
            Vec3([0.0, 0.0, 0.0]),
            Vec3([1.0, 0.0, 0.0]),
            Vec3([0.0, 1.0, 0.0]),
        ],
        [
            Vec3([0.3, -0.1, 0.0]),
            Vec3([0.9, 0.7, 0.0]),
            Vec3([-0.2, 0.6, 0.0]),
        ],
    ];
    let ray = Ray::new(Vec3([0.25, 0.25, 2.0]), Vec3([0.0, 0.0, -1.0]));
    for options in all_variants() {
        let tree = build_triangles(tris.clone(), &options).unwrap().tree;
        let hit = tree.intersect(&ray).unwrap();
        assert_eq!((hit.t, hit.prim), (2.0, 0), "{}", describe(&options));
        let hit = tree.intersect_batch(&[ray; 9])[8].unwrap();
        assert_eq!((hit.t, hit.prim), (2.0, 0), "{}", describe(&options));
        let hit = tree.intersect_f64(&Ray64::from(&ray)).unwrap();
        assert_eq!((hit.t, hit.prim), (2.0, 0), "{}", describe(&options));
    }
}

#[test]
fn every_walk_keeps_the_lower_index_on_coplanar_soups() {
    let mut variants = all_variants();
    variants.truncate(6);
    for (what, tris, rays) in soups() {
        let want: Vec<Option<Hit>> = rays.iter().map(|r| least_hit(&tris, r)).collect();
        let want64: Vec<Option<Hit64>> = rays
            .iter()
            .map(|r| least_hit64(&tris, &Ray64::from(r)))
            .collect();
        // The brute force's own closest hit follows the rule too.
        for (i, r) in rays.iter().enumerate() {
            assert_eq!(brute::intersect(&tris, r), want[i], "{what}: brute ray {i}");
            let r64 = Ray64::from(r);
            assert_eq!(
                precise::brute_intersect(&tris, &r64),
                want64[i],
                "{what}: brute f64 ray {i}"
            );
        }
        for options in &variants {
            let tree = build_triangles(tris.clone(), options).unwrap().tree;
            let what = format!("{what}, {}", describe(options));
            let batch = tree.intersect_batch(&rays);
            let rays64: Vec<Ray64> = rays.iter().map(Ray64::from).collect();
            let batch64 = tree.intersect_batch_f64(&rays64);
            for (i, r) in rays.iter().enumerate() {
                assert_eq!(tree.intersect(r), want[i], "{what}: single ray {i}");
                assert_eq!(batch[i], want[i], "{what}: batch ray {i}");
                assert_eq!(tree.intersect_f64(&rays64[i]), want64[i], "{what}: f64 {i}");
                assert_eq!(batch64[i], want64[i], "{what}: f64 batch ray {i}");
            }
        }
    }
}

#[test]
fn scene_ties_go_to_the_lower_geometry_then_primitive() {
    let tris = coplanar_soup(9, 40, true);
    let rays = rays_at(9, 400, false);
    // Two geometries: the soup's halves, the second placed twice (once as itself).
    let (a, b) = tris.split_at(20);
    let mut scene = Scene::new();
    scene.add_mesh(&mesh_of(a)).unwrap();
    let g = scene.add_mesh(&mesh_of(b)).unwrap();
    scene.add_instance(g, Transform::IDENTITY).unwrap();
    let tree = scene.build(&BuildOptions::default()).unwrap();
    let placed: Vec<Triangle> = tris.iter().chain(b).copied().collect();
    let batch = tree.intersect_batch(&rays);
    for (i, r) in rays.iter().enumerate() {
        let want = least_hit(&placed, r).map(|h| tree.scene_hit(h));
        assert_eq!(tree.intersect(r), want, "scene ray {i}");
        assert_eq!(batch[i], want, "scene batch ray {i}");
        let all = tree.all_hits(r);
        assert_eq!(all.first().copied(), want, "scene all hits ray {i}");
    }
}
