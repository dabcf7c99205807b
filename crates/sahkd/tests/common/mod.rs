//! Shared helpers of the integration tests: scenes, rays and the brute-force oracle.
#![allow(dead_code)]

use proptest::prelude::*;
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use sahkd::trace::brute;
use sahkd::{Aabb, Algorithm, Axes, BuildOptions, Counting, KdTree, Mesh, Ray, Triangle, Vec3};
use std::path::PathBuf;

/// FNV-1a over the tree's node words and references: a fingerprint of the arrays.
pub fn fingerprint(tree: &KdTree) -> u64 {
    let mut h = 0xcbf2_9ce4_8422_2325u64;
    let words = tree.nodes().iter().flat_map(|n| n.words());
    for w in words.chain(tree.refs().iter().copied()) {
        for b in w.to_le_bytes() {
            h = (h ^ b as u64).wrapping_mul(0x100_0000_01b3);
        }
    }
    h
}

/// The shared scenes folder: `SAHKD_SCENES`, else `../shared/scenes` beside the checkout.
pub fn scenes_dir() -> Option<PathBuf> {
    let dir = std::env::var_os("SAHKD_SCENES")
        .map(PathBuf::from)
        .unwrap_or_else(|| {
            PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/scenes")
        });
    dir.is_dir().then_some(dir)
}

/// Loads a scene from the shared folder, or says why the test is skipped.
pub fn load_scene(file: &str) -> Option<Mesh> {
    let Some(dir) = scenes_dir() else {
        eprintln!("SKIPPED: no scenes folder (set SAHKD_SCENES or put ../shared/scenes beside the checkout); {file} not tested");
        return None;
    };
    let path = dir.join(file);
    if !path.is_file() {
        eprintln!("SKIPPED: {} is missing", path.display());
        return None;
    }
    Some(Mesh::load(&path).unwrap_or_else(|e| panic!("{file}: {e}")))
}

pub fn rng(seed: u64) -> StdRng {
    StdRng::seed_from_u64(seed)
}

fn snap(x: f32, grid: f32) -> f32 {
    (x * grid).round() / grid
}

/// A random soup of `n` triangles in the unit cube, mixing the cases builders get wrong:
/// small and large triangles, corners snapped to a coarse grid (coincident events),
/// axis-aligned triangles lying in a plane (planar events), and zero-area ones.
pub fn random_triangles(rng: &mut StdRng, n: usize) -> Vec<Triangle> {
    (0..n)
        .map(|i| {
            let centre = Vec3::new(rng.random(), rng.random(), rng.random());
            let size = match i % 7 {
                0 => 0.5,
                1 | 2 => 0.02,
                _ => 0.1,
            };
            let corner = |rng: &mut StdRng| {
                centre
                    + Vec3::new(
                        rng.random_range(-size..size),
                        rng.random_range(-size..size),
                        rng.random_range(-size..size),
                    )
            };
            let mut t = [corner(rng), corner(rng), corner(rng)];
            match i % 5 {
                0 => {
                    for v in &mut t {
                        for a in 0..3 {
                            v[a] = snap(v[a], 8.0);
                        }
                    }
                }
                1 => {
                    let axis = i % 3;
                    let plane = snap(centre[axis], 16.0);
                    for v in &mut t {
                        v[axis] = plane;
                    }
                }
                _ => {}
            }
            if i % 97 == 0 {
                t[2] = t[1]; // zero area
            }
            t
        })
        .collect()
}

pub fn mesh_of(triangles: &[Triangle]) -> Mesh {
    Mesh {
        vertices: triangles
            .iter()
            .flat_map(|t| t.iter().map(|v| v.0))
            .collect(),
        triangles: (0..triangles.len() as u32)
            .map(|i| [3 * i, 3 * i + 1, 3 * i + 2])
            .collect(),
    }
}

/// Rays aimed at the scene: from outside and inside, along and off the axes, from origins
/// on grid planes (where split planes are likely), with finite and infinite ranges.
pub fn random_rays(rng: &mut StdRng, bounds: &Aabb, n: usize) -> Vec<Ray> {
    let ext = bounds.extent();
    let point = |rng: &mut StdRng, margin: f32| {
        let mut p = Vec3::splat(0.0);
        for a in 0..3 {
            let (lo, hi) = (
                bounds.lo[a] - margin * ext[a],
                bounds.hi[a] + margin * ext[a],
            );
            p[a] = if hi > lo {
                rng.random_range(lo..=hi)
            } else {
                lo
            };
        }
        p
    };
    (0..n)
        .map(|i| {
            let mut origin = point(rng, if i % 3 == 0 { 0.0 } else { 0.5 });
            let target = point(rng, 0.0);
            let mut dir = target - origin;
            match i % 6 {
                0 => {
                    // Axis-parallel: two zero components.
                    let keep = i % 3;
                    for a in 0..3 {
                        if a != keep {
                            dir[a] = 0.0;
                        }
                    }
                    if dir[keep] == 0.0 {
                        dir[keep] = 1.0;
                    }
                }
                1 => dir[i % 3] = 0.0,
                2 => {
                    for a in 0..3 {
                        origin[a] = snap(origin[a], 16.0);
                    }
                }
                _ => {}
            }
            if dir == Vec3::splat(0.0) {
                dir = Vec3::new(0.0, 0.0, 1.0);
            }
            let ray = Ray::new(origin, dir);
            if i % 4 == 3 {
                ray.with_range(0.1, 2.0)
            } else {
                ray
            }
        })
        .collect()
}

/// Compares the tree's answers with the brute force on every ray. The hit must be the same to
/// the bit: all use one triangle test, so any difference is a traversal or tree bug.
pub fn check_oracle(tree: &KdTree, rays: &[Ray]) -> Result<(), String> {
    let tris = tree.triangles();
    for (i, ray) in rays.iter().enumerate() {
        let got = tree.intersect(ray);
        let want = brute::intersect(tris, ray);
        if got != want {
            return Err(format!(
                "ray {i} {ray:?}: tree gives {got:?}, brute force {want:?}"
            ));
        }
        let got = tree.occluded(ray);
        let want = brute::occluded(tris, ray);
        if got != want {
            return Err(format!(
                "ray {i} {ray:?}: tree says occluded={got}, brute force {want}"
            ));
        }
        let got = every_hit(tree, ray);
        let want = brute_every_hit(tris, ray);
        if got != want {
            return Err(format!(
                "ray {i} {ray:?}: for_each_hit finds {} hits, brute force {}: {got:?} vs {want:?}",
                got.len(),
                want.len()
            ));
        }
    }
    Ok(())
}

/// Every hit `KdTree::for_each_hit` reports, one per triangle, sorted by triangle.
fn every_hit(tree: &KdTree, ray: &Ray) -> Vec<sahkd::Hit> {
    let mut hits = Vec::new();
    tree.for_each_hit(ray, |h| hits.push(h));
    hits.sort_by_key(|h| h.prim);
    hits.dedup();
    // A triangle in several leaves must be reported with the same hit each time.
    let mut prims: Vec<u32> = hits.iter().map(|h| h.prim).collect();
    prims.dedup();
    assert_eq!(
        prims.len(),
        hits.len(),
        "one triangle reported with different hits"
    );
    hits
}

/// Every triangle the ray hits in its range, by testing them all, sorted by triangle.
fn brute_every_hit(tris: &[sahkd::Triangle], ray: &Ray) -> Vec<sahkd::Hit> {
    let mut hits = Vec::new();
    brute::for_each_hit(tris, ray, |h| hits.push(h));
    hits
}

/// Every builder configuration the project offers.
pub fn all_variants() -> Vec<BuildOptions> {
    let mut out = Vec::new();
    for clip in [true, false] {
        for axes in [Axes::Longest, Axes::All] {
            // Three workers: the hand-over comes after a few level passes even on small scenes.
            // Exact (bins 0): the default's binning skips the level passes, which are tested
            // here; the binned hybrid comes below.
            out.push(BuildOptions {
                algorithm: Algorithm::Hybrid,
                axes,
                clip,
                threads: Some(3),
                bins: Some(0),
                ..BuildOptions::default()
            });
            out.push(BuildOptions {
                algorithm: Algorithm::Sweep,
                axes,
                clip,
                ..BuildOptions::default()
            });
            for counting in [Counting::SpaceTree, Counting::Scan] {
                out.push(BuildOptions {
                    algorithm: Algorithm::Level,
                    axes,
                    counting,
                    clip,
                    ..BuildOptions::default()
                });
            }
            out.push(BuildOptions {
                algorithm: Algorithm::Naive,
                axes,
                clip,
                ..BuildOptions::default()
            });
            out.push(BuildOptions {
                algorithm: Algorithm::Median,
                axes,
                clip,
                ..BuildOptions::default()
            });
        }
        // Binning with few bins, so that small scenes have binned nodes (above 128 and 256
        // references).
        out.push(BuildOptions {
            algorithm: Algorithm::Sweep,
            clip,
            bins: Some(2),
            ..BuildOptions::default()
        });
        out.push(BuildOptions {
            algorithm: Algorithm::Hybrid,
            axes: Axes::All,
            clip,
            bins: Some(4),
            threads: Some(3),
            ..BuildOptions::default()
        });
        // Large nodes down to 4 primitives: the median phase meets small scenes' corner cases.
        out.push(BuildOptions {
            algorithm: Algorithm::Median,
            axes: Axes::All,
            clip,
            median_large_node: 4,
            ..BuildOptions::default()
        });
    }
    out
}

pub fn describe(o: &BuildOptions) -> String {
    let large = match o.algorithm {
        Algorithm::Median => format!(" large_node={}", o.median_large_node),
        _ => String::new(),
    };
    let bins = match o.resolved_bins() {
        0 => String::new(),
        n => format!(" bins={n}"),
    };
    format!(
        "{:?} axes={:?} counting={:?} clip={}{large}{bins}",
        o.algorithm, o.axes, o.counting, o.clip
    )
}

/// Triangles with corners drawn from a small set of values, so coincident and planar events,
/// ties and rays lying in split planes are the rule.
pub fn grid_triangle() -> impl Strategy<Value = Triangle> {
    let coord = (0i32..6).prop_map(|k| k as f32 * 0.25);
    let corner = [coord.clone(), coord.clone(), coord].prop_map(Vec3);
    [corner.clone(), corner.clone(), corner]
}

/// Origins on the grid (on split planes) and directions with zero components of either sign.
pub fn grid_ray() -> impl Strategy<Value = Ray> {
    let coord = (-4i32..10).prop_map(|k| k as f32 * 0.125);
    let dir = prop_oneof![(-2i32..3).prop_map(|k| k as f32), Just(-0.0f32)];
    (
        [coord.clone(), coord.clone(), coord],
        [dir.clone(), dir.clone(), dir],
    )
        .prop_map(|(o, d)| Ray::new(Vec3(o), Vec3(d)))
}

/// The box of the triangles.
pub fn bounds_of(tris: &[Triangle]) -> Aabb {
    tris.iter().fold(Aabb::EMPTY, |b, t| {
        b.union(sahkd::geometry::triangle_bounds(t))
    })
}
