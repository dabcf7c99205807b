//! Procedural scenes: valid meshes, deterministic on any thread count, counts within the
//! documented factor of the requested N, boxes where each kind's geometry puts them, and
//! clear errors for bad specs.

use sahkd::scenes::{generate, DEFAULT_SCENE, KINDS};
use sahkd::{Aabb, Mesh};

/// (kind, factor the count stays within, from this N on), as the module documentation says.
const COUNT_RULES: &[(&str, f64, u64)] = &[
    ("sphere", 1.2, 6),
    ("sphereflake", 1.2, 6),
    ("mount", 1.5, 8),
    ("tetra", 1.25, 64),
    ("toys", 1.25, 500),
];

fn scene(kind: &str, n: u64) -> Mesh {
    generate(&format!("spd:{kind}:{n}")).unwrap_or_else(|e| panic!("{kind} {n}: {e}"))
}

fn in_pool<T: Send>(threads: usize, f: impl FnOnce() -> T + Send) -> T {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap()
        .install(f)
}

fn inside(b: &Aabb, lo: [f32; 3], hi: [f32; 3]) -> bool {
    (0..3).all(|a| b.lo[a] >= lo[a] && b.hi[a] <= hi[a])
}

#[test]
fn every_kind_is_listed_and_has_a_count_rule() {
    let names: Vec<&str> = KINDS.iter().map(|k| k.name).collect();
    for (kind, _, _) in COUNT_RULES {
        assert!(names.contains(kind), "{kind} missing from KINDS");
    }
    assert_eq!(names.len(), COUNT_RULES.len());
    assert!(generate(DEFAULT_SCENE).is_ok());
}

#[test]
fn scenes_are_valid_without_degenerate_triangles() {
    for (kind, _, _) in COUNT_RULES {
        for n in [1, 7, 100, 5_000, 150_000] {
            let mesh = scene(kind, n);
            mesh.validate()
                .unwrap_or_else(|e| panic!("{kind} {n}: {e}"));
            assert!(!mesh.triangles.is_empty(), "{kind} {n}: empty");
            assert_eq!(mesh.zero_area_triangles(), 0, "{kind} {n}");
            // No unused vertices either: each generator writes exactly what it counted.
            let mut used = vec![false; mesh.vertices.len()];
            mesh.triangles
                .iter()
                .flatten()
                .for_each(|&i| used[i as usize] = true);
            assert!(used.iter().all(|&u| u), "{kind} {n}: unused vertices");
        }
    }
}

#[test]
fn counts_stay_within_the_documented_factor() {
    for &(kind, factor, from) in COUNT_RULES {
        // About 12 sizes per decade from 1 to 2 million, plus the edges of the rule.
        let mut sizes: Vec<u64> = (0..=76)
            .map(|i| 10f64.powf(i as f64 / 12.0).round() as u64)
            .collect();
        sizes.extend([from, from + 1, 2 * from + 3]);
        for n in sizes {
            let t = scene(kind, n).triangles.len() as f64;
            let ratio = if t > n as f64 {
                t / n as f64
            } else {
                n as f64 / t
            };
            if n >= from {
                assert!(
                    ratio <= factor,
                    "{kind}: {t} triangles for N = {n}, ratio {ratio:.3} > {factor}"
                );
            }
        }
    }
}

#[test]
fn same_spec_same_mesh_on_any_thread_count() {
    for (kind, _, _) in COUNT_RULES {
        let spec = format!("spd:{kind}:60000");
        let one = in_pool(1, || generate(&spec).unwrap());
        let four = in_pool(4, || generate(&spec).unwrap());
        let again = generate(&spec).unwrap();
        // Compare bit patterns, so that even -0.0 against 0.0 would count as a difference.
        let bits = |m: &Mesh| -> Vec<[u32; 3]> {
            m.vertices.iter().map(|v| v.map(f32::to_bits)).collect()
        };
        assert_eq!(
            bits(&one),
            bits(&four),
            "{kind}: vertices depend on threads"
        );
        assert_eq!(
            one.triangles, four.triangles,
            "{kind}: triangles depend on threads"
        );
        assert_eq!(bits(&one), bits(&again), "{kind}: not repeatable");
    }
}

#[test]
fn scenes_lie_where_their_geometry_says() {
    let eps = 1e-5;
    for n in [10, 10_000, 300_000] {
        let b = scene("sphere", n).bounds();
        assert!(inside(&b, [-1.0 - eps; 3], [1.0 + eps; 3]), "sphere {b:?}");
        assert_eq!((b.lo[1], b.hi[1]), (-1.0, 1.0), "sphere poles");

        // The flake's children shrink by 3, so it reaches at most 1 + 2/3 + 2/9 + ... = 2.
        let b = scene("sphereflake", n).bounds();
        assert!(inside(&b, [-2.0; 3], [2.0; 3]), "sphereflake {b:?}");
        assert!(b.hi[1] >= 1.0 && b.lo[1] <= -1.0, "sphereflake {b:?}");
        if n >= 400 {
            // Children at 60 degrees latitude reach up to 4/3 sin 60 + 1/3 = 1.49.
            assert!(b.hi[1] > 1.3, "sphereflake without children {b:?}");
        }

        let b = scene("mount", n).bounds();
        assert_eq!((b.lo[0], b.hi[0], b.lo[2], b.hi[2]), (-1.0, 1.0, -1.0, 1.0));
        assert!(
            b.lo[1] > -2.0 && b.hi[1] < 2.0 && b.hi[1] > b.lo[1],
            "mount {b:?}"
        );

        // Edge 2 standing on y = 0: height 2 sqrt(2/3), base circumradius 2 / sqrt(3).
        let b = scene("tetra", n).bounds();
        let (h, r) = (2.0 * (2.0f32 / 3.0).sqrt(), 2.0 / 3f32.sqrt());
        assert!(
            (b.lo[1] - 0.0).abs() < eps && (b.hi[1] - h).abs() < eps,
            "tetra {b:?}"
        );
        assert!(inside(
            &b,
            [-r - eps, -eps, -r - eps],
            [r + eps, h + eps, r + eps]
        ));

        // Everything rests on the 60 x 60 floor; the flagpole is the tallest thing.
        let b = scene("toys", n).bounds();
        assert_eq!(
            (b.lo[0], b.hi[0], b.lo[2], b.hi[2]),
            (-30.0, 30.0, -30.0, 30.0)
        );
        assert!(
            b.lo[1].abs() < eps && (b.hi[1] - 22.0).abs() < eps,
            "toys {b:?}"
        );
    }
}

#[test]
fn tetra_is_a_sierpinski_tetrahedron() {
    // Each level keeps 4 half-size copies, so the enclosed volume halves: edge 2 gives
    // 8 / (6 sqrt 2) / 2^d. The signed volume (sum of det / 6 over triangles) also checks
    // that every face is wound outwards. 576 = 4^3 * 3^2: depth 2 with faces cut 3 x 3.
    for (n, depth) in [(4u64, 0), (64, 2), (256, 3), (1024, 4), (576, 2)] {
        let m = scene("tetra", n);
        assert_eq!(m.triangles.len() as u64, n);
        let volume: f64 = (0..m.triangles.len())
            .map(|i| {
                let t = m.triangle(i);
                t[0].dot(t[1].cross(t[2])) as f64 / 6.0
            })
            .sum();
        let expected = 8.0 / (6.0 * 2f64.sqrt()) / 2f64.powi(depth);
        assert!(
            (volume - expected).abs() < 1e-5,
            "{n}: {volume} vs {expected}"
        );
    }
}

#[test]
fn toys_has_objects_of_very_different_sizes() {
    // Triangle sizes spread over orders of magnitude: ground cells of 15 m next to pebbles.
    let m = scene("toys", 100_000);
    let mut areas: Vec<f32> = (0..m.triangles.len())
        .map(|i| {
            let t = m.triangle(i);
            0.5 * (t[1] - t[0]).cross(t[2] - t[0]).length()
        })
        .collect();
    areas.sort_by(f32::total_cmp);
    let (smallest, largest) = (areas[areas.len() / 100], areas[areas.len() - 1]);
    assert!(largest / smallest > 1e5, "{smallest} .. {largest}");
}

#[test]
fn bad_specs_are_explained() {
    let cases = [
        ("spd:cube:1000", "unknown scene kind 'cube'"),
        ("spd:toys", "triangle count N is missing"),
        ("spd:toys:", "triangle count N is missing"),
        ("spd:toys:0", "at least 1"),
        ("spd:toys:ten", "'ten' is not a whole number"),
        ("spd:toys:-5", "'-5' is not a whole number"),
        ("spd:toys:1e6", "'1e6' is not a whole number"),
        ("spd::100", "scene kind is missing"),
        ("toys:100", "does not start with 'spd:'"),
        ("", "does not start with 'spd:'"),
        ("spd:toys:100:7", "too many"),
        ("spd:toys:99999999999999", "more than the"),
    ];
    for (spec, why) in cases {
        let e = generate(spec).expect_err(spec);
        assert!(e.contains(why), "{spec}: {e}");
        for kind in KINDS {
            assert!(
                e.contains(kind.name),
                "{spec}: error does not list {}: {e}",
                kind.name
            );
        }
    }
    assert_eq!(
        generate("spd:sphere:1_000").unwrap(),
        generate(" spd:sphere:1000 ").unwrap()
    );
}
