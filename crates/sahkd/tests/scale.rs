//! Scenes at every scale: the tree's answers against a float64 brute force, on random soups
//! from 1e-20 to 1e30 across and far from the origin, and the exact power-of-two invariance
//! the library promises (README, Reliability).

mod common;

use common::*;
use rand::Rng;
use sahkd::trace::{brute, precise};
use sahkd::{
    build_triangles, Aabb, BuildOptions, CostModel, Hit, KdTree, Ray, Ray64, Triangle, Vec3,
};

/// One triangle's hit in float64: distance and the smallest barycentric (how far inside).
#[derive(Clone, Copy, Debug)]
struct Hit64 {
    t: f64,
    prim: u32,
    margin: f64,
}

type V = [f64; 3];

fn v64(v: Vec3) -> V {
    [v[0] as f64, v[1] as f64, v[2] as f64]
}
fn sub(a: V, b: V) -> V {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn cross(a: V, b: V) -> V {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
fn dot(a: V, b: V) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Every triangle the ray meets or nearly meets (barycentrics above -1e-6) in its range,
/// Moeller-Trumbore in float64 on the float32 corners. Rays nearly parallel to a triangle
/// are left out: their answer is ill-conditioned in any precision.
fn hits64(tris: &[Triangle], ray: &Ray) -> Vec<Hit64> {
    let (o, d) = (v64(ray.origin), v64(ray.direction));
    let mut out = Vec::new();
    for (i, t) in tris.iter().enumerate() {
        let (p0, p1, p2) = (v64(t[0]), v64(t[1]), v64(t[2]));
        let (e1, e2) = (sub(p1, p0), sub(p2, p0));
        let n = cross(e1, e2);
        let nn = dot(n, n).sqrt();
        let det = -dot(n, d);
        if nn == 0.0 || det.abs() <= 1e-6 * nn * dot(d, d).sqrt() {
            continue;
        }
        let s = sub(o, p0);
        let q = cross(s, d);
        let u = dot(e2, q) / det;
        let v = -dot(e1, q) / det;
        let tt = dot(n, s) / det;
        let margin = u.min(v).min(1.0 - u - v);
        if margin > -1e-6 && tt >= ray.t_min as f64 && tt <= ray.t_max as f64 {
            out.push(Hit64 {
                t: tt,
                prim: i as u32,
                margin,
            });
        }
    }
    out
}

/// The tree's closest hit must be the float64 answer: a hit exactly when float64 finds a
/// clear one (inside by more than 1e-6 in barycentrics), on a triangle float64 hits or nearly
/// hits, at a distance within `tol` (relative) of float64's, and no clear float64 hit nearer.
fn check64(tris: &[Triangle], ray: &Ray, got: Option<(f64, u32)>, tol: f64) -> Result<(), String> {
    let all = hits64(tris, ray);
    let clear = all
        .iter()
        .filter(|h| h.margin > 1e-6)
        .min_by(|a, b| a.t.total_cmp(&b.t));
    match got {
        None => match clear {
            None => Ok(()),
            Some(h) => Err(format!("miss, float64 hits {h:?}")),
        },
        Some(g) => {
            let (t, prim) = g;
            let Some(same) = all.iter().find(|h| h.prim == prim) else {
                return Err(format!("{g:?} on a triangle float64 does not hit: {all:?}"));
            };
            let close = |a: f64, b: f64| (a - b).abs() <= tol * a.abs().max(b.abs());
            if !close(t, same.t) {
                return Err(format!("{g:?}, float64 t = {}", same.t));
            }
            if let Some(c) = clear {
                if c.t < t && !close(c.t, t) {
                    return Err(format!("{g:?}, float64 hits {c:?} nearer"));
                }
            }
            Ok(())
        }
    }
}

fn bounds_of(tris: &[Triangle]) -> Aabb {
    tris.iter().fold(Aabb::EMPTY, |b, t| {
        b.union(sahkd::geometry::triangle_bounds(t))
    })
}

fn transform(tris: &[Triangle], scale: f32, offset: Vec3) -> Vec<Triangle> {
    tris.iter().map(|t| t.map(|v| v * scale + offset)).collect()
}

/// Rays from inside the soup's box aimed at triangle centres (mostly hits) and in random
/// directions; unit-length directions, as a user would give.
fn soup_rays(rng: &mut rand::rngs::StdRng, tris: &[Triangle], n: usize) -> Vec<Ray> {
    let b = bounds_of(tris);
    (0..n)
        .map(|i| {
            // In f64: the box may be wider than float32's range.
            let origin = Vec3(std::array::from_fn(|a| {
                let (lo, hi) = (b.lo[a] as f64, b.hi[a] as f64);
                (lo + (hi - lo) * rng.random::<f64>()) as f32
            }));
            let dir = if i % 2 == 0 {
                let t = tris[rng.random_range(0..tris.len())];
                let c = v64(t[0]);
                let (p1, p2) = (v64(t[1]), v64(t[2]));
                let target: V = std::array::from_fn(|a| (c[a] + p1[a] + p2[a]) / 3.0);
                let o = v64(origin);
                let d = sub(target, o);
                let l = dot(d, d).sqrt();
                Vec3(d.map(|x| (x / l) as f32))
            } else {
                let d = [0; 3].map(|_| rng.random_range(-1.0f32..1.0));
                Vec3(d).normalized()
            };
            Ray::new(origin, dir)
        })
        .filter(|r| r.is_valid())
        .collect()
}

fn tree_of(tris: &[Triangle]) -> KdTree {
    build_triangles(tris.to_vec(), &BuildOptions::default())
        .unwrap()
        .tree
}

/// A walk that reports every hit it finds.
type Walk<'a> = &'a dyn Fn(&mut dyn FnMut(Hit));

/// Checks single and batch queries of `tris` against float64; returns the hits seen.
fn check_scene(what: &str, tris: &[Triangle], rays: &[Ray], tol: f64) -> usize {
    let tree = tree_of(tris);
    let batch = tree.intersect_batch(rays);
    let mut errors = Vec::new();
    for (i, ray) in rays.iter().enumerate() {
        let got = tree.intersect(ray);
        assert_eq!(got, batch[i], "{what}: ray {i}: batch and single disagree");
        assert_eq!(got, brute::intersect(tris, ray), "{what}: ray {i}: brute");
        assert_eq!(tree.occluded(ray), got.is_some(), "{what}: ray {i}");
        // Every hit (each triangle once, as the all-hits and parity queries use them).
        let every = |walk: Walk| {
            let mut hits = Vec::new();
            walk(&mut |h| hits.push((h.prim, h.t.to_bits())));
            hits.sort_unstable();
            hits.dedup();
            hits
        };
        assert_eq!(
            every(&|f| tree.for_each_hit(ray, f)),
            every(&|f| brute::for_each_hit(tris, ray, f)),
            "{what}: ray {i}: every hit"
        );
        if let Err(e) = check64(tris, ray, got.map(|h| (h.t as f64, h.prim)), tol) {
            errors.push(format!("ray {i} {ray:?}: {e}"));
        }
        // The f64 walk: the f64 brute force's answer, and float64's to 1e-9.
        let ray64 = Ray64::from(ray);
        let got64 = tree.intersect_f64(&ray64);
        assert_eq!(
            got64,
            precise::brute_intersect(tris, &ray64),
            "{what}: ray {i}: f64 brute"
        );
        assert_eq!(
            tree.occluded_f64(&ray64),
            got64.is_some(),
            "{what}: ray {i}"
        );
        if let Err(e) = check64(tris, ray, got64.map(|h| (h.t, h.prim)), 1e-9) {
            errors.push(format!("ray {i} {ray:?} in f64: {e}"));
        }
    }
    assert!(
        errors.is_empty(),
        "{what}: {} of {} rays wrong, first: {}",
        errors.len(),
        rays.len(),
        errors[..errors.len().min(3)].join("\n")
    );
    batch.iter().flatten().count()
}

#[test]
fn random_soups_at_every_scale_match_float64() {
    let mut rng = rng(140);
    let unit = random_triangles(&mut rng, 400);
    let rays = soup_rays(&mut rng, &unit, 600);
    for exp in (-20..=30).step_by(5) {
        let s = 10f32.powi(exp);
        let tris = transform(&unit, s, Vec3::splat(0.0));
        let rays: Vec<Ray> = rays
            .iter()
            .map(|r| Ray::new(r.origin * s, r.direction))
            .collect();
        let hits = check_scene(&format!("scale 1e{exp}"), &tris, &rays, 1e-5);
        assert!(hits > 250, "scale 1e{exp}: {hits} hits, a weak test");
    }
}

#[test]
fn random_soups_far_from_the_origin_match_float64() {
    let mut rng = rng(141);
    let unit = random_triangles(&mut rng, 400);
    // The soup's own extent against its distance from the origin, 1e-5 or 1e-3 (float32
    // corners at 1e15 are multiples of 2^26, 6.7e7).
    let cases = [
        (1e10f32, 1e15f32),
        (1e12, 1e15),
        (1e-6, 1e-3),
        (1e-18, 1e-15),
        (1e25, 1e30),
    ];
    for (scale, offset) in cases {
        let tris = transform(&unit, scale, Vec3::new(offset, -offset, 0.5 * offset));
        let rays = soup_rays(&mut rng, &tris, 600);
        let what = format!("extent {scale:e} at {offset:e}");
        let hits = check_scene(&what, &tris, &rays, 1e-5);
        assert!(hits > 200, "{what}: {hits} hits, a weak test");
    }
}

/// A scene and its rays scaled by a power of two answer exactly as the scene does, with `t`
/// scaled: the same triangle, the same barycentrics, to the bit.
#[test]
fn power_of_two_scaling_changes_no_answer() {
    let mut rng = rng(142);
    let unit = random_triangles(&mut rng, 300);
    let rays = soup_rays(&mut rng, &unit, 400);
    let tree = tree_of(&unit);
    let want = tree.intersect_batch(&rays);
    assert!(want.iter().flatten().count() > 200);
    for k in [
        -100, -66, -43, -30, -21, -20, -5, 5, 20, 21, 30, 50, 100, 126,
    ] {
        let s = 2f32.powi(k);
        let tris = transform(&unit, s, Vec3::splat(0.0));
        let scaled: Vec<Ray> = rays
            .iter()
            .map(|r| Ray::new(r.origin * s, r.direction))
            .collect();
        let got = tree_of(&tris).intersect_batch(&scaled);
        for (i, (g, w)) in got.iter().zip(&want).enumerate() {
            let w = w.map(|h| Hit { t: h.t * s, ..h });
            assert_eq!(*g, w, "2^{k}: ray {i}");
        }
    }
}

/// Two parallel triangles 1e15 across, at z = -5e14 and z = 0.
#[test]
fn parallel_triangles_1e15_across() {
    let big = 1e15f32;
    let tri = |z: f32| {
        [
            Vec3::new(-big, -big, z),
            Vec3::new(big, -big, z),
            Vec3::new(0.0, big, z),
        ]
    };
    let tris = vec![tri(-5e14), tri(0.0)];
    let tree = tree_of(&tris);
    let ray = Ray::new(Vec3::new(1e14, 1e14, 1e12), Vec3::new(0.0, 0.0, -1.0));
    let hit = tree.intersect(&ray).expect("a hit");
    assert_eq!((hit.prim, hit.t), (1, 1e12), "{hit:?}");
    assert_eq!(tree.intersect_batch(&[ray; 4])[3], Some(hit));
}

/// A mesh spanning +-3e38 (extents beyond float32) builds a tree with a finite SAH cost and
/// answers rays as float64 does.
#[test]
fn a_mesh_spanning_the_float32_range() {
    let m = 3e38f32;
    let mut tris = vec![
        [
            Vec3::new(-m, -m, -m),
            Vec3::new(m, -m, 0.0),
            Vec3::new(0.0, m, m),
        ],
        [
            Vec3::new(-m, m, -m),
            Vec3::new(m, m, m),
            Vec3::new(m, -m, -m),
        ],
    ];
    let mut rng = rng(143);
    let unit = random_triangles(&mut rng, 200);
    tris.extend(transform(&unit, 2e38, Vec3::splat(-1e38)));
    let tree = tree_of(&tris);
    let stats = tree.stats(&CostModel::default());
    assert!(stats.sah_cost.is_finite(), "{stats:?}");
    assert!(stats.leaves > 1, "a real tree: {stats:?}");
    let rays = soup_rays(&mut rng, &tris, 400);
    let hits = check_scene("+-3e38", &tris, &rays, 1e-5);
    assert!(hits > 100, "{hits} hits");
}

/// `t` is in `[t_min, inf)`: a ray starting exactly on a triangle hits it at `t = 0`.
#[test]
fn a_ray_starting_on_a_triangle_hits_it_at_zero() {
    let mut rng = rng(144);
    let mut checked = 0;
    for i in 0..2000 {
        let mut p = || Vec3(std::array::from_fn(|_| rng.random_range(-1.0f32..1.0)));
        let tri = [p(), p(), p()];
        // A corner, or a point on an axis-aligned triangle (exactly in its plane).
        let (tri, origin) = if i % 2 == 0 {
            (tri, tri[i % 3])
        } else {
            let mut flat = tri;
            for v in &mut flat {
                v[i % 3] = 0.25;
            }
            let w = [0.25f32, 0.5, 0.25];
            let o = (0..3).fold(Vec3::splat(0.0), |o, k| o + flat[k] * w[k]);
            let mut o = o;
            o[i % 3] = 0.25;
            (flat, o)
        };
        let dir = Vec3(std::array::from_fn(|_| rng.random_range(-1.0f32..1.0)));
        let ray = Ray::new(origin, dir);
        if !ray.is_valid() || hits64(&[tri], &ray).is_empty() {
            continue; // degenerate or parallel
        }
        let tree = tree_of(&[tri]);
        let hit = tree.intersect(&ray);
        assert_eq!(hit.map(|h| h.t), Some(0.0), "case {i}: {tri:?} {ray:?}");
        checked += 1;
    }
    assert!(checked > 1500, "{checked}");
}

/// On needle-thin triangles the reported `t` is float32-accurate against float64 (the
/// float32 watertight distance, which queries reported before, is measured beside it).
#[test]
fn needle_thin_triangles_get_accurate_distances() {
    let mut rng = rng(145);
    let mut tris = Vec::new();
    for i in 0..300 {
        let p = Vec3(std::array::from_fn(|_| rng.random_range(-1.0f32..1.0)));
        let long = Vec3(std::array::from_fn(|_| rng.random_range(-1.0f32..1.0)));
        let side = Vec3(std::array::from_fn(|_| rng.random_range(-1.0f32..1.0)));
        let width = 10f32.powi(-3 - (i % 4)); // 1e-3 .. 1e-6
        let along: f32 = rng.random_range(0.2..0.8);
        tris.push([p, p + long, p + long * along + side * width]);
    }
    let tree = tree_of(&tris);
    let (mut worst_tree, mut worst_f32, mut hits) = (0.0f64, 0.0f64, 0);
    for _ in 0..6000 {
        let k = rng.random_range(0..tris.len());
        let t = tris[k];
        let w: [f64; 3] = {
            let (a, b) = (rng.random::<f64>(), rng.random::<f64>());
            let (a, b) = if a + b > 1.0 {
                (1.0 - a, 1.0 - b)
            } else {
                (a, b)
            };
            [1.0 - a - b, a, b]
        };
        let target: V = std::array::from_fn(|c| (0..3).map(|j| w[j] * t[j][c] as f64).sum::<f64>());
        let origin = Vec3(std::array::from_fn(|_| rng.random_range(-2.0f32..2.0)));
        let d = sub(target, v64(origin));
        let ray = Ray::new(origin, Vec3(d.map(|x| x as f32)));
        let Some(hit) = tree.intersect(&ray) else {
            continue;
        };
        // Grazing rays and hits on a needle's edge (outside by float64's barycentrics) have
        // no well-defined distance to compare with.
        let Some(want) = hits64(&tris, &ray).into_iter().find(|h| h.prim == hit.prim) else {
            continue;
        };
        let rel = |t: f32| (t as f64 - want.t).abs() / want.t;
        worst_tree = worst_tree.max(rel(hit.t));
        let raw = sahkd::trace::ShearedRay::new(&ray)
            .intersect(&tris[hit.prim as usize], 0.0, f32::INFINITY)
            .expect("the float32 test hits it");
        worst_f32 = worst_f32.max(rel(raw.t));
        hits += 1;
    }
    eprintln!("{hits} needle hits: worst relative t error {worst_tree:e} (float32 test alone {worst_f32:e})");
    assert!(hits > 4000, "{hits}");
    assert!(worst_tree < 2e-7, "{worst_tree:e}");
    assert!(
        worst_f32 > 1e-6,
        "the float32 distance is no worse: {worst_f32:e}"
    );
}

/// Tiny triangles 1e5 from the origin above a ground plane 3e5 across, seen from 1e5 away:
/// float32 cannot hold these rays' shear (README, Reliability), so the f64 queries
/// (`intersect_f64`) must give float64's answer on every ray, and the brute force's.
#[test]
fn tiny_triangles_far_away_are_exact_in_f64() {
    let mut rng = rng(142);
    let g = 3e5f32;
    let mut tris: Vec<Triangle> = vec![
        [
            Vec3::new(-g, -g, 0.0),
            Vec3::new(g, -g, 0.0),
            Vec3::new(g, g, 0.0),
        ],
        [
            Vec3::new(-g, -g, 0.0),
            Vec3::new(g, g, 0.0),
            Vec3::new(-g, g, 0.0),
        ],
    ];
    for _ in 0..300 {
        let c = Vec3::new(
            1e5 + rng.random_range(-2.0..2.0),
            1e5 + rng.random_range(-2.0..2.0),
            rng.random_range(0.5..3.0),
        );
        tris.push([0; 3].map(|_| c + Vec3([0; 3].map(|_| rng.random_range(-0.03..0.03)))));
    }
    let tree = tree_of(&tris);
    let (mut tiny, mut wrong32) = (0, 0);
    let n = 3000;
    for i in 0..n {
        let origin = Vec3::new(
            rng.random_range(-10.0..10.0),
            rng.random_range(-10.0..10.0),
            rng.random_range(100.0..1000.0),
        );
        // Aimed in f64 at a random point of a random tiny triangle.
        let t = tris[rng.random_range(2..tris.len())];
        let (a, b) = (rng.random::<f64>(), rng.random::<f64>());
        let (a, b) = if a + b > 1.0 {
            (1.0 - a, 1.0 - b)
        } else {
            (a, b)
        };
        let target: V = std::array::from_fn(|k| {
            v64(t[0])[k] * (1.0 - a - b) + v64(t[1])[k] * a + v64(t[2])[k] * b
        });
        let d = sub(target, v64(origin));
        let l = dot(d, d).sqrt();
        let ray = Ray::new(origin, Vec3(d.map(|x| (x / l) as f32)));
        let ray64 = Ray64::from(&ray);
        let got = tree.intersect_f64(&ray64);
        assert_eq!(
            got,
            precise::brute_intersect(&tris, &ray64),
            "ray {i}: f64 brute"
        );
        if let Err(e) = check64(&tris, &ray, got.map(|h| (h.t, h.prim)), 1e-9) {
            panic!("ray {i} {ray:?} in f64: {e}");
        }
        tiny += got.is_some_and(|h| h.prim >= 2) as usize;
        let got32 = tree.intersect(&ray).map(|h| (h.t as f64, h.prim));
        wrong32 += check64(&tris, &ray, got32, 1e-5).is_err() as usize;
    }
    eprintln!("float32 queries: {wrong32} of {n} rays differ from float64 (f64 queries: none)");
    assert!(
        tiny > n / 4,
        "{tiny} of {n} rays hit a tiny triangle, a weak test"
    );
}
