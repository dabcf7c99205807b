//! Point queries against oracles: the closest point of the tree walk must equal the brute
//! force over all triangles to the bit (both use one point-triangle routine), and that
//! routine must agree with an independent float64 computation (plane projection or the
//! nearest edge). Inside tests are checked against the face planes of convex meshes, and
//! parity against the winding number on closed meshes; the winding number is checked on a
//! sphere with a hole, where parity may fail.

mod common;

use common::*;
use rand::rngs::StdRng;
use rand::Rng;
use sahkd::query::brute;
use sahkd::scenes::generate;
use sahkd::{build, build_triangles, BuildOptions, InsideTest, KdTree, Mesh, Triangle, Vec3};

type D3 = [f64; 3];

fn d3(v: Vec3) -> D3 {
    v.0.map(|c| c as f64)
}
fn sub(a: D3, b: D3) -> D3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn dot(a: D3, b: D3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn cross(a: D3, b: D3) -> D3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
fn len(a: D3) -> f64 {
    dot(a, a).sqrt()
}

fn segment_distance(p: D3, a: D3, b: D3) -> f64 {
    let ab = sub(b, a);
    let l2 = dot(ab, ab);
    let s = if l2 > 0.0 {
        (dot(sub(p, a), ab) / l2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    len(sub(
        p,
        [a[0] + s * ab[0], a[1] + s * ab[1], a[2] + s * ab[2]],
    ))
}

/// The independent reference: the distance to the plane when the point projects inside the
/// triangle (all three edge normals agree), else the nearest of the three edges.
fn reference_distance(p: D3, t: &Triangle) -> f64 {
    let (a, b, c) = (d3(t[0]), d3(t[1]), d3(t[2]));
    let edges = segment_distance(p, a, b)
        .min(segment_distance(p, b, c))
        .min(segment_distance(p, c, a));
    let n = cross(sub(b, a), sub(c, a));
    let n2 = dot(n, n);
    if n2 == 0.0 {
        return edges;
    }
    let h = dot(sub(p, a), n) / n2;
    let q = [p[0] - h * n[0], p[1] - h * n[1], p[2] - h * n[2]];
    let side = |u: D3, v: D3| dot(cross(sub(v, u), sub(q, u)), n);
    if side(a, b) >= 0.0 && side(b, c) >= 0.0 && side(c, a) >= 0.0 {
        (h.abs() * n2.sqrt()).min(edges)
    } else {
        edges
    }
}

fn bounds_of(tris: &[Triangle]) -> sahkd::Aabb {
    tris.iter().fold(sahkd::Aabb::EMPTY, |b, t| {
        b.union(sahkd::geometry::triangle_bounds(t))
    })
}

/// Query points of every kind: on corners, on edge midpoints, on faces, just off the
/// surface, anywhere in the box, and far outside it.
fn query_points(rng: &mut StdRng, tris: &[Triangle], n: usize) -> Vec<Vec3> {
    let b = bounds_of(tris);
    let ext = b.extent();
    let scale = ext[0].max(ext[1]).max(ext[2]).max(1e-3);
    let in_box = |rng: &mut StdRng, grow: f32| {
        Vec3(std::array::from_fn(|a| {
            let (lo, hi) = (b.lo[a] - grow * scale, b.hi[a] + grow * scale);
            if hi > lo {
                rng.random_range(lo..=hi)
            } else {
                lo
            }
        }))
    };
    (0..n)
        .map(|i| {
            let t = tris[rng.random_range(0..tris.len())];
            match i % 7 {
                0 => t[i % 3],
                1 => (t[0] + t[1]) * 0.5,
                2 | 3 => {
                    let (u, v): (f32, f32) = (rng.random(), rng.random());
                    let (u, v) = if u + v > 1.0 {
                        (1.0 - u, 1.0 - v)
                    } else {
                        (u, v)
                    };
                    let q = t[0] + (t[1] - t[0]) * u + (t[2] - t[0]) * v;
                    let off = if i % 7 == 3 { 1e-3 * scale } else { 0.0 };
                    q + Vec3(std::array::from_fn(|_| rng.random_range(-1.0..=1.0f32))) * off
                }
                4 => in_box(rng, 0.0),
                5 => in_box(rng, 0.2),
                _ => in_box(rng, 3.0),
            }
        })
        .collect()
}

/// The tree's answers against the brute force (to the bit), the independent distance, and
/// the answer's own consistency; the batch calls against the single ones.
fn check_closest(tree: &KdTree, points: &[Vec3], what: &str) {
    let tris = tree.triangles();
    let batch = tree.closest_point_batch(points);
    let distances = tree.distance_batch(points);
    for (i, &p) in points.iter().enumerate() {
        let got = tree.closest_point(p);
        let want = brute::closest_point(tris, p);
        assert_eq!(got, want, "{what}: point {i} {p:?}");
        assert_eq!(batch[i], got, "{what}: batch, point {i}");
        let Some(c) = got else {
            assert!(tris.is_empty(), "{what}: no answer for {p:?}");
            continue;
        };
        assert_eq!(
            distances[i], c.distance,
            "{what}: distance_batch, point {i}"
        );
        let pd = d3(p);
        let reference = tris
            .iter()
            .map(|t| reference_distance(pd, t))
            .fold(f64::INFINITY, f64::min);
        let scale = 1.0 + len(pd);
        assert!(
            (c.distance - reference).abs() <= 1e-9 * scale,
            "{what}: point {i} {p:?}: distance {} vs reference {reference}",
            c.distance
        );
        // The point lies on its triangle, at the reported distance.
        let on = reference_distance(c.point, &tris[c.prim as usize]);
        assert!(
            on <= 1e-9 * scale,
            "{what}: point {i}: {on} off its triangle"
        );
        assert!((len(sub(pd, c.point)) - c.distance).abs() <= 1e-9 * scale);
        let w = c.barycentrics;
        assert!(w.iter().all(|&x| x >= 0.0) && (w.iter().sum::<f64>() - 1.0).abs() < 1e-12);
    }
}

#[test]
fn closest_point_matches_brute_force_on_random_soups_with_every_builder() {
    for (seed, n) in [(11u64, 1usize), (12, 5), (13, 60), (14, 700)] {
        let mut rng = rng(seed);
        let tris = random_triangles(&mut rng, n);
        let points = query_points(&mut rng, &tris, 300);
        for options in all_variants() {
            let tree = build_triangles(tris.clone(), &options).unwrap().tree;
            check_closest(&tree, &points, &format!("{} on {n}", describe(&options)));
        }
    }
}

/// Scenes far outside float32's comfortable range are walked scaled by a power of two (the
/// trace layout): the answers must still be the brute force's to the bit.
#[test]
fn closest_point_matches_brute_force_on_scaled_scenes() {
    let mut rng = rng(15);
    let unit = random_triangles(&mut rng, 400);
    for factor in [2f32.powi(70), 2f32.powi(-70)] {
        let tris: Vec<Triangle> = unit.iter().map(|t| t.map(|v| v * factor)).collect();
        let points = query_points(&mut rng, &tris, 300);
        let tree = build_triangles(tris, &BuildOptions::default())
            .unwrap()
            .tree;
        check_closest(&tree, &points, &format!("scaled by {factor:e}"));
    }
}

#[test]
fn closest_point_handles_the_hard_cases() {
    let mut rng = rng(21);
    let mut cases: Vec<(&str, Vec<Triangle>)> = Vec::new();
    // Coplanar, overlapping triangles in one plane (also a split-plane candidate).
    cases.push((
        "coplanar soup",
        (0..200)
            .map(|_| {
                let c = |rng: &mut StdRng| Vec3::new(rng.random(), rng.random(), 0.5);
                [c(&mut rng), c(&mut rng), c(&mut rng)]
            })
            .collect(),
    ));
    // Needles: one side a thousand times the others, at every orientation.
    cases.push((
        "needles",
        (0..200)
            .map(|_| {
                let a = Vec3::new(rng.random(), rng.random(), rng.random());
                let d = Vec3::new(rng.random(), rng.random(), rng.random()) - Vec3::splat(0.5);
                let e = Vec3::new(rng.random(), rng.random(), rng.random()) * 1e-4;
                [a, a + d, a + d * 0.5 + e]
            })
            .collect(),
    ));
    // Every triangle twice (ties must go to the lower index), and zero-area ones.
    let mut dup = random_triangles(&mut rng, 100);
    dup.extend(dup.clone());
    dup.push([Vec3::splat(0.3); 3]);
    dup.push([Vec3::splat(0.0), Vec3::splat(0.5), Vec3::splat(1.0)]);
    cases.push(("duplicates and flat triangles", dup));
    // A closed mesh, queried on its vertices and edges.
    cases.push((
        "sphere",
        generate("spd:sphere:500").unwrap().corner_triangles(),
    ));
    for (what, tris) in cases {
        let points = query_points(&mut rng, &tris, 700);
        for options in [
            BuildOptions::default(),
            BuildOptions {
                clip: false,
                ..BuildOptions::default()
            },
        ] {
            let tree = build_triangles(tris.clone(), &options).unwrap().tree;
            check_closest(&tree, &points, what);
        }
    }
}

#[test]
fn duplicates_answer_with_the_lower_index() {
    let t = [
        Vec3::new(0.0, 0.0, 0.0),
        Vec3::new(1.0, 0.0, 0.0),
        Vec3::new(0.0, 1.0, 0.0),
    ];
    let tree = build_triangles(vec![t, t, t], &BuildOptions::default())
        .unwrap()
        .tree;
    let c = tree.closest_point(Vec3::new(0.2, 0.2, 3.0)).unwrap();
    assert_eq!((c.prim, c.distance), (0, 3.0));
}

#[test]
fn empty_meshes_and_non_finite_points_have_no_answer() {
    let empty = KdTree::empty();
    let p = Vec3::new(1.0, 2.0, 3.0);
    assert_eq!(empty.closest_point(p), None);
    assert_eq!(empty.distance(p), f64::INFINITY);
    assert!(!empty.contains(p, InsideTest::Parity));
    assert!(!empty.contains(p, InsideTest::Winding));
    assert_eq!(empty.signed_distance(p, InsideTest::Parity), f64::INFINITY);
    assert_eq!(empty.closest_point_batch(&[p, p]), vec![None, None]);
    let tree = sphere(200);
    for bad in [
        Vec3::new(f32::NAN, 0.0, 0.0),
        Vec3::new(0.0, f32::INFINITY, 0.0),
    ] {
        assert_eq!(tree.closest_point(bad), None);
        assert!(tree.distance(bad).is_nan());
        assert!(tree.signed_distance(bad, InsideTest::Parity).is_nan());
        assert!(!tree.contains(bad, InsideTest::Parity));
        assert!(!tree.contains(bad, InsideTest::Winding));
    }
}

fn sphere(n: u64) -> KdTree {
    build(
        &generate(&format!("spd:sphere:{n}")).unwrap(),
        &BuildOptions::default(),
    )
    .unwrap()
    .tree
}

/// Inside a convex mesh exactly when behind every face plane (faces wound outwards).
fn inside_convex(tris: &[Triangle], p: Vec3) -> bool {
    let pd = d3(p);
    tris.iter().all(|t| {
        let (a, b, c) = (d3(t[0]), d3(t[1]), d3(t[2]));
        let n = cross(sub(b, a), sub(c, a));
        dot(n, n) == 0.0 || dot(n, sub(pd, a)) < 0.0
    })
}

fn random_in(rng: &mut StdRng, lo: f32, hi: f32) -> Vec3 {
    Vec3(std::array::from_fn(|_| rng.random_range(lo..hi)))
}

#[test]
fn inside_tests_agree_with_the_face_planes_of_a_sphere() {
    let mesh = generate("spd:sphere:3000").unwrap();
    let tree = build(&mesh, &BuildOptions::default()).unwrap().tree;
    let tris = tree.triangles().to_vec();
    let mut rng = rng(31);
    let mut points: Vec<Vec3> = (0..3000).map(|_| random_in(&mut rng, -1.6, 1.6)).collect();
    // Points on the split planes most builders pick, and on the axes.
    points.extend((0..200).map(|i| Vec3::new(0.0, (i as f32 - 100.0) / 60.0, 0.0)));
    let (inside_count, mut checked) = (
        points.iter().filter(|&&p| inside_convex(&tris, p)).count(),
        0,
    );
    assert!(
        inside_count > 300,
        "the test needs points inside: {inside_count}"
    );
    let parity = tree.contains_batch(&points, InsideTest::Parity);
    let winding = tree.contains_batch(&points, InsideTest::Winding);
    let signed = tree.signed_distance_batch(&points, InsideTest::Parity);
    for (i, &p) in points.iter().enumerate() {
        let d = tree.distance(p);
        if d < 1e-6 {
            continue; // on the surface the side is moot
        }
        checked += 1;
        let want = inside_convex(&tris, p);
        assert_eq!(parity[i], want, "parity at {p:?}");
        assert_eq!(winding[i], want, "winding at {p:?}");
        assert_eq!(tree.contains(p, InsideTest::Parity), want);
        assert_eq!(
            signed[i],
            if want { -d } else { d },
            "signed distance at {p:?}"
        );
        let w = tree.winding_number(p);
        assert!(
            (w - if want { 1.0 } else { 0.0 }).abs() < 1e-9,
            "winding number {w} at {p:?}"
        );
    }
    assert!(checked > 3000);
}

#[test]
fn winding_number_sees_inside_a_sphere_with_a_hole() {
    let mut mesh = generate("spd:sphere:3000").unwrap();
    let full = mesh.corner_triangles();
    // Remove a cap of faces around +z: the mesh is no longer closed.
    mesh.triangles.retain(|t| {
        let c: f32 = t.iter().map(|&i| mesh.vertices[i as usize][2]).sum::<f32>() / 3.0;
        c < 0.8
    });
    assert!(mesh.triangles.len() < full.len());
    let tree = build(&mesh, &BuildOptions::default()).unwrap().tree;
    let mut rng = rng(41);
    let mut wrong_parity = 0;
    for _ in 0..2000 {
        let p = random_in(&mut rng, -1.2, 1.2);
        // Well inside or well outside the full sphere, not near the hole.
        let r = d3(p).iter().map(|c| c * c).sum::<f64>().sqrt();
        if (0.85..1.1).contains(&r) || p[2] > 0.7 {
            continue;
        }
        let want = inside_convex(&full, p);
        assert_eq!(
            tree.contains(p, InsideTest::Winding),
            want,
            "winding at {p:?}"
        );
        let s = tree.signed_distance(p, InsideTest::Winding);
        assert_eq!(s < 0.0, want, "signed distance {s} at {p:?}");
        wrong_parity += (tree.contains(p, InsideTest::Parity) != want) as usize;
    }
    eprintln!("parity was wrong on {wrong_parity} points of the holed sphere");
}

#[test]
fn parity_and_winding_agree_on_a_closed_non_convex_mesh() {
    // Spheres of a sphereflake overlap their parents, which breaks both tests' meaning of
    // "inside"; a tetra is disjoint closed tetrahedra touching at corners.
    let mesh = generate("spd:tetra:4000").unwrap();
    let tree = build(&mesh, &BuildOptions::default()).unwrap().tree;
    let b = tree.bounds();
    let tris = tree.triangles().to_vec();
    let mut rng = rng(51);
    // Half anywhere in the box, half just off a face on either side.
    let points: Vec<Vec3> = (0..2000)
        .map(|i| {
            if i % 2 == 0 {
                return Vec3(std::array::from_fn(|a| rng.random_range(b.lo[a]..b.hi[a])));
            }
            let t = tris[rng.random_range(0..tris.len())];
            let n = (t[1] - t[0]).cross(t[2] - t[0]).normalized();
            let centre = (t[0] + t[1] + t[2]) * (1.0 / 3.0);
            centre + n * rng.random_range(-0.01f32..0.01)
        })
        .collect();
    let parity = tree.contains_batch(&points, InsideTest::Parity);
    let winding = tree.contains_batch(&points, InsideTest::Winding);
    let mut inside = 0;
    for (i, &p) in points.iter().enumerate() {
        if tree.distance(p) < 1e-6 {
            continue;
        }
        inside += winding[i] as usize;
        assert_eq!(
            parity[i],
            winding[i],
            "at {p:?}: winding {}",
            tree.winding_number(p)
        );
    }
    assert!(inside > 200, "the test needs points inside: {inside}");
}

#[test]
fn batches_do_not_depend_on_the_thread_count() {
    let mut rng = rng(61);
    let tris = random_triangles(&mut rng, 500);
    let points = query_points(&mut rng, &tris, 2000);
    let tree = build_triangles(tris, &BuildOptions::default())
        .unwrap()
        .tree;
    let run = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| {
                (
                    tree.closest_point_batch(&points),
                    tree.signed_distance_batch(&points, InsideTest::Parity),
                )
            })
    };
    let one = run(1);
    let three = run(3);
    for i in 0..points.len() {
        assert_eq!(one.0[i], three.0[i], "closest point {i}");
        assert_eq!(
            one.1[i].to_bits(),
            three.1[i].to_bits(),
            "signed distance {i}"
        );
    }
}

fn real_mesh_check(file: &str, points: usize) {
    let Some(mesh) = load_scene(file) else {
        return;
    };
    let tree = build(&mesh, &BuildOptions::default()).unwrap().tree;
    let mut rng = rng(71);
    let tris = tree.triangles().to_vec();
    let pts = query_points(&mut rng, &tris, points);
    for (i, &p) in pts.iter().enumerate() {
        assert_eq!(
            tree.closest_point(p),
            brute::closest_point(&tris, p),
            "{file}: point {i} {p:?}"
        );
    }
}

#[test]
fn closest_point_matches_brute_force_on_real_meshes() {
    real_mesh_check("dragon_res4.ply", 400);
    real_mesh_check("bunny.ply", 150);
    real_mesh_check("sponza_dabrovic.ply", 150);
}

/// Vertices of a mesh as query points exactly: distance 0 on a triangle using the vertex.
#[test]
fn mesh_vertices_are_at_distance_zero() {
    let mesh: Mesh = generate("spd:toys:3000").unwrap();
    let tree = build(&mesh, &BuildOptions::default()).unwrap().tree;
    for (i, t) in mesh.triangles.iter().enumerate().step_by(7) {
        let v = Vec3(mesh.vertices[t[0] as usize]);
        let c = tree.closest_point(v).unwrap();
        assert_eq!(c.distance, 0.0, "triangle {i}");
        assert_eq!(c.point, d3(v));
        assert!(c.prim as usize <= i);
    }
}

/// Scenes outside float32's comfortable range are traced scaled by a power of two (see
/// `geometry::scene_scale`); the closest point must be answered in the caller's coordinates all
/// the same: a soup 1e7 across (millimetres of a 10 km scan) and one 1e-7 across.
#[test]
fn closest_points_of_scaled_scenes_match_brute_force() {
    for (seed, factor) in [(21u64, 1e7f32), (22, 1e-7), (23, 3e12)] {
        let mut rng = rng(seed);
        let tris: Vec<Triangle> = random_triangles(&mut rng, 300)
            .into_iter()
            .map(|t| t.map(|v| v * factor))
            .collect();
        let points = query_points(&mut rng, &tris, 200);
        let tree = build_triangles(tris, &BuildOptions::default())
            .unwrap()
            .tree;
        check_closest(&tree, &points, &format!("soup scaled by {factor}"));
    }
}
