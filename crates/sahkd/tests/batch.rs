//! The batch calls walk neighbouring rays in a narrow cone in packets and the others one at a
//! time; their answers must be those of the brute-force oracle and of the single-ray queries,
//! bit for bit, whatever mix of rays a packet holds: one narrow cone (walked together),
//! scattered directions of one octant or mixed signs (one at a time),
//! zero direction components, origins on split planes, invalid rays, short ranges and a
//! batch length that is not a multiple of the packet width.

mod common;

use common::*;
use proptest::prelude::*;
use rand::Rng;
use sahkd::render::{Camera, SUN_DIRECTION};
use sahkd::trace::brute;
use sahkd::{build, build_triangles, BuildOptions, KdTree, Ray, Vec3};

/// Sign bits of a direction, to group rays that can share a packet.
fn signs(r: &Ray) -> u32 {
    (0..3).fold(0, |s, a| {
        s | (r.direction[a].is_sign_negative() as u32) << a
    })
}

/// Each ray followed by `k` siblings: same direction signs (zero components kept, with
/// their sign), origins jittered by up to `jitter` and direction components scaled by up to
/// `1 +- spread`, some with their own range.
fn with_siblings(
    rng: &mut rand::rngs::StdRng,
    rays: &[Ray],
    k: usize,
    jitter: f32,
    spread: f32,
) -> Vec<Ray> {
    let mut out = Vec::new();
    for r in rays {
        out.push(*r);
        for j in 0..k {
            let mut o = r.origin;
            let mut d = r.direction;
            for a in 0..3 {
                if j % 3 != 0 {
                    o[a] += rng.random_range(-jitter..jitter);
                }
                if d[a] != 0.0 && j % 2 == 1 {
                    d[a] *= rng.random_range(1.0 - spread..1.0 + spread);
                }
            }
            let mut s = Ray::new(o, d);
            if j == 2 {
                s = s.with_range(r.t_min, r.t_max.min(0.7));
            }
            out.push(s);
        }
    }
    out
}

fn check_batches(tree: &KdTree, rays: &[Ray], brute_force: bool) -> Result<(), String> {
    let closest = tree.intersect_batch(rays);
    let any = tree.occluded_batch(rays);
    for (i, r) in rays.iter().enumerate() {
        let (want_hit, want_any) = if brute_force {
            (
                brute::intersect(tree.triangles(), r),
                brute::occluded(tree.triangles(), r),
            )
        } else {
            (tree.intersect(r), tree.occluded(r))
        };
        if closest[i] != want_hit {
            return Err(format!(
                "ray {i} {r:?}: batch gives {:?}, want {want_hit:?}",
                closest[i]
            ));
        }
        if any[i] != want_any {
            return Err(format!(
                "ray {i} {r:?}: batch says occluded={}, want {want_any}",
                any[i]
            ));
        }
    }
    Ok(())
}

#[test]
fn batches_match_brute_force_on_random_scenes() {
    for (seed, n) in [(11u64, 1usize), (12, 5), (13, 60), (14, 700), (15, 2500)] {
        let mut rng = rng(seed);
        let tris = random_triangles(&mut rng, n);
        let bounds = tris.iter().fold(sahkd::Aabb::EMPTY, |b, t| {
            b.union(sahkd::geometry::triangle_bounds(t))
        });
        let base = random_rays(&mut rng, &bounds, 300);
        let mut rays = with_siblings(&mut rng, &base, 3, 0.05, 0.5);
        // Invalid rays inside packets, and a tail shorter than a packet.
        rays[5].direction = Vec3::splat(0.0);
        rays[9].origin[1] = f32::NAN;
        rays[13] = rays[13].with_range(1.0, 0.5);
        rays.push(base[0]);
        rays.push(base[1]);
        let narrow = with_siblings(&mut rng, &base, 7, 0.02, 0.01);
        for options in [
            BuildOptions::default(),
            all_variants()[all_variants().len() / 2],
        ] {
            let tree = build_triangles(tris.clone(), &options).unwrap().tree;
            check_batches(&tree, &rays, true)
                .unwrap_or_else(|e| panic!("{} on {n} triangles: {e}", describe(&options)));
            // Sorted by signs, nearly every packet is walked together.
            let mut sorted = rays.clone();
            sorted.sort_by_key(signs);
            check_batches(&tree, &sorted, true)
                .unwrap_or_else(|e| panic!("{} on {n} triangles: {e}", describe(&options)));
            // Packets of eight in a narrow cone: walked together over the kd nodes.
            check_batches(&tree, &narrow, true)
                .unwrap_or_else(|e| panic!("{} on {n} triangles: {e}", describe(&options)));
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]
    #[test]
    fn grid_scene_batches_match_brute_force(
        tris in prop::collection::vec(grid_triangle(), 1..80),
        mut rays in prop::collection::vec(grid_ray(), 64),
    ) {
        rays.sort_by_key(signs);
        let tree = build_triangles(tris, &BuildOptions::default()).unwrap().tree;
        let result = check_batches(&tree, &rays, true);
        prop_assert!(result.is_ok(), "{}", result.unwrap_err());
    }
}

/// Camera rays and shadow rays of a real mesh (the workload of the throughput example):
/// batch answers equal the single-ray ones.
#[test]
fn camera_and_shadow_batches_match_single_rays_on_the_bunny() {
    let Some(mesh) = load_scene("bunny.ply") else {
        return;
    };
    let tree = build(&mesh, &BuildOptions::default()).unwrap().tree;
    for camera in [Camera::front(tree.bounds()), Camera::framing(&tree)] {
        let n = 160;
        let primary: Vec<Ray> = (0..n * n)
            .map(|i| camera.primary_ray(n, n, (i % n) as f32 + 0.5, (i / n) as f32 + 0.5))
            .collect();
        check_batches(&tree, &primary, false).unwrap();
        let shadow: Vec<Ray> = primary
            .iter()
            .filter_map(|r| tree.intersect(r).map(|h| (r, h)))
            .map(|(r, h)| Ray::new(r.at(h.t * 0.9999), SUN_DIRECTION))
            .collect();
        assert!(shadow.len() > 1000);
        check_batches(&tree, &shadow, false).unwrap();
    }
}

/// Ambient-occlusion-like batches: runs of rays leaving one point in scattered directions,
/// short and long. The batch calls sort each group of rays by direction octant before cutting
/// it into packets, so lanes of one packet come from different points and different places
/// in the batch; every answer must still be the brute-force one.
#[test]
fn scattered_rays_from_shared_origins_match_brute_force() {
    let mut rng = rng(21);
    let tris = random_triangles(&mut rng, 900);
    let bounds = tris.iter().fold(sahkd::Aabb::EMPTY, |b, t| {
        b.union(sahkd::geometry::triangle_bounds(t))
    });
    let mut rays = Vec::new();
    for (i, base) in random_rays(&mut rng, &bounds, 120).iter().enumerate() {
        // A point on the ray's path inside the box, then 1 to 11 rays from it.
        let origin = base.at(base.t_min.max(0.0) + 0.3 * rng.random::<f32>());
        for k in 0..(1 + i % 11) {
            let d = Vec3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                if k % 5 == 0 {
                    0.0
                } else {
                    rng.random_range(-1.0..1.0)
                },
            );
            let reach = if k % 2 == 0 { 0.05 } else { f32::INFINITY };
            rays.push(Ray::new(origin, d).with_range(0.0, reach));
        }
    }
    let tree = build_triangles(tris, &BuildOptions::default())
        .unwrap()
        .tree;
    check_batches(&tree, &rays, true).unwrap();
}
