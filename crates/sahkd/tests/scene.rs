//! `Scene` against an independent oracle: every triangle of every placement transformed in
//! f64 by this test, tested by brute force (Moeller-Trumbore for rays, Ericson's region test
//! for closest points, the inverse transform for inside). Nothing here calls the library's
//! own brute force.

use sahkd::scene::{Scene, SceneTree, Transform};
use sahkd::{BuildOptions, InsideTest, Mesh, Ray, Ray64, Vec3};

type V = [f64; 3];

fn sub(a: V, b: V) -> V {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn add(a: V, b: V) -> V {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}
fn scale(a: V, s: f64) -> V {
    [a[0] * s, a[1] * s, a[2] * s]
}
fn dot(a: V, b: V) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn cross(a: V, b: V) -> V {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
fn norm(a: V) -> f64 {
    dot(a, a).sqrt()
}

/// A small deterministic generator (xorshift), so the test needs no crate.
struct Rng(u64);
impl Rng {
    fn f(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
    fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.f()
    }
    fn v(&mut self, lo: f64, hi: f64) -> V {
        [self.range(lo, hi), self.range(lo, hi), self.range(lo, hi)]
    }
    fn below(&mut self, n: usize) -> usize {
        ((self.f() * n as f64) as usize).min(n - 1)
    }
}

/// The closed unit cube [0, 1]^3 wound outwards, and each triangle's outward normal.
fn cube() -> (Mesh, Vec<V>) {
    let vertices: Vec<[f32; 3]> = (0..8)
        .map(|i| [(i & 1) as f32, ((i >> 1) & 1) as f32, ((i >> 2) & 1) as f32])
        .collect();
    let mut triangles = Vec::new();
    let mut normals = Vec::new();
    for axis in 0..3 {
        for side in 0..2u32 {
            let (a, b) = ((axis + 1) % 3, (axis + 2) % 3);
            let corner = |i: u32, j: u32| (side << axis) | (i << a) | (j << b);
            let quad = [corner(0, 0), corner(1, 0), corner(1, 1), corner(0, 1)];
            let mut n = [0.0; 3];
            n[axis] = if side == 1 { 1.0 } else { -1.0 };
            for mut t in [[quad[0], quad[1], quad[2]], [quad[0], quad[2], quad[3]]] {
                let p = t.map(|k| vertices[k as usize].map(f64::from));
                if dot(cross(sub(p[1], p[0]), sub(p[2], p[0])), n) < 0.0 {
                    t.swap(1, 2);
                }
                triangles.push(t);
                normals.push(n);
            }
        }
    }
    (
        Mesh {
            vertices,
            triangles,
        },
        normals,
    )
}

/// n random triangles in [-1, 1]^3, sides up to 0.6.
fn soup(rng: &mut Rng, n: usize) -> Mesh {
    let mut vertices = Vec::new();
    for _ in 0..n {
        let c = rng.v(-1.0, 1.0);
        for _ in 0..3 {
            let p = add(c, rng.v(-0.3, 0.3));
            vertices.push(p.map(|x| x as f32));
        }
    }
    let triangles = (0..n as u32)
        .map(|i| [3 * i, 3 * i + 1, 3 * i + 2])
        .collect();
    Mesh {
        vertices,
        triangles,
    }
}

fn rotation(axis: usize, angle: f64) -> [[f64; 3]; 3] {
    let (s, c) = angle.sin_cos();
    let (a, b) = ((axis + 1) % 3, (axis + 2) % 3);
    let mut m = [[0.0; 3]; 3];
    m[axis][axis] = 1.0;
    m[a][a] = c;
    m[a][b] = -s;
    m[b][a] = s;
    m[b][b] = c;
    m
}

fn affine(a: [[f64; 3]; 3], t: V) -> Transform {
    Transform([0, 1, 2].map(|i| [a[i][0], a[i][1], a[i][2], t[i]]))
}

fn mat_mul(a: [[f64; 3]; 3], b: [[f64; 3]; 3]) -> [[f64; 3]; 3] {
    [0, 1, 2].map(|i| [0, 1, 2].map(|j| (0..3).map(|k| a[i][k] * b[k][j]).sum()))
}

fn linear(t: &Transform) -> [[f64; 3]; 3] {
    t.0.map(|r| [r[0], r[1], r[2]])
}

fn inverse(m: [[f64; 3]; 3]) -> [[f64; 3]; 3] {
    let c = |r: usize, s: usize| cross(m[r], m[s]);
    let (c0, c1, c2) = (c(1, 2), c(2, 0), c(0, 1));
    let det = dot(m[0], c0);
    // Columns of the inverse are the cross products of rows over the determinant.
    [0, 1, 2].map(|i| [c0[i] / det, c1[i] / det, c2[i] / det])
}

fn mat_vec(m: [[f64; 3]; 3], v: V) -> V {
    m.map(|r| dot(r, v))
}

/// The oracle's copy of the scene: per geometry, its mesh's corners transformed in f64.
struct Oracle {
    geometries: Vec<Vec<[V; 3]>>,
}

impl Oracle {
    fn new(placed: &[(&Mesh, Option<Transform>)]) -> Oracle {
        let geometries = placed
            .iter()
            .map(|(mesh, t)| {
                mesh.triangles
                    .iter()
                    .map(|tri| {
                        tri.map(|k| {
                            let p = mesh.vertices[k as usize].map(f64::from);
                            match t {
                                Some(t) => t.apply(p),
                                None => p,
                            }
                        })
                    })
                    .collect()
            })
            .collect();
        Oracle { geometries }
    }

    fn tris(&self) -> impl Iterator<Item = (u32, u32, &[V; 3])> {
        self.geometries.iter().enumerate().flat_map(|(g, ts)| {
            ts.iter()
                .enumerate()
                .map(move |(p, t)| (g as u32, p as u32, t))
        })
    }

    /// Every hit with barycentrics allowed `margin` outside the triangle: (t, g, prim, u, v).
    fn hits(&self, o: V, d: V, margin: f64) -> Vec<(f64, u32, u32, f64, f64)> {
        let mut out = Vec::new();
        for (g, p, t) in self.tris() {
            let (e1, e2) = (sub(t[1], t[0]), sub(t[2], t[0]));
            let pv = cross(d, e2);
            let det = dot(e1, pv);
            if det.abs() < 1e-300 {
                continue;
            }
            let s = sub(o, t[0]);
            let u = dot(s, pv) / det;
            let q = cross(s, e1);
            let v = dot(d, q) / det;
            let tt = dot(e2, q) / det;
            if u >= -margin && v >= -margin && u + v <= 1.0 + margin && tt >= 0.0 {
                out.push((tt, g, p, u, v));
            }
        }
        out.sort_by(|a, b| a.0.total_cmp(&b.0).then((a.1, a.2).cmp(&(b.1, b.2))));
        out
    }

    /// Closest point of every triangle: (distance, g, prim, point).
    fn closest(&self, p: V) -> Vec<(f64, u32, u32, V)> {
        let mut out: Vec<_> = self
            .tris()
            .map(|(g, i, t)| {
                let c = closest_on_triangle(p, t);
                (norm(sub(p, c)), g, i, c)
            })
            .collect();
        out.sort_by(|a, b| a.0.total_cmp(&b.0).then((a.1, a.2).cmp(&(b.1, b.2))));
        out
    }
}

/// Ericson, Real-Time Collision Detection 5.1.5: the Voronoi region of p, in f64.
fn closest_on_triangle(p: V, t: &[V; 3]) -> V {
    let [a, b, c] = *t;
    let (ab, ac, ap) = (sub(b, a), sub(c, a), sub(p, a));
    let (d1, d2) = (dot(ab, ap), dot(ac, ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return a;
    }
    let bp = sub(p, b);
    let (d3, d4) = (dot(ab, bp), dot(ac, bp));
    if d3 >= 0.0 && d4 <= d3 {
        return b;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return add(a, scale(ab, d1 / (d1 - d3)));
    }
    let cp = sub(p, c);
    let (d5, d6) = (dot(ab, cp), dot(ac, cp));
    if d6 >= 0.0 && d5 <= d6 {
        return c;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return add(a, scale(ac, d2 / (d2 - d6)));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        return add(b, scale(sub(c, b), (d4 - d3) / ((d4 - d3) + (d5 - d6))));
    }
    let denom = 1.0 / (va + vb + vc);
    add(a, add(scale(ab, vb * denom), scale(ac, vc * denom)))
}

fn vec3(v: V) -> Vec3 {
    Vec3::new(v[0] as f32, v[1] as f32, v[2] as f32)
}

fn f64s(v: Vec3) -> V {
    v.0.map(f64::from)
}

/// The mixed scene: soups and cubes, moved, sheared, mirrored, overlapping, a mesh added
/// twice, an empty mesh, an exact copy by an identity instance.
struct Mixed {
    scene: Scene,
    placed: Vec<(Mesh, Option<Transform>)>,
}

fn mixed() -> Mixed {
    let mut rng = Rng(0x9E37_79B9_7F4A_7C15);
    let soup_a = soup(&mut rng, 60);
    let (cube, _) = cube();
    let empty = Mesh {
        vertices: vec![],
        triangles: vec![],
    };
    let mut scene = Scene::new();
    let mut placed = Vec::new();
    let mut mesh = |scene: &mut Scene, m: &Mesh| {
        let id = scene.add_mesh(m).unwrap();
        placed.push((m.clone(), None));
        id
    };
    let a = mesh(&mut scene, &soup_a);
    let e = mesh(&mut scene, &empty);
    let c = mesh(&mut scene, &cube);
    let a2 = mesh(&mut scene, &soup_a); // the same mesh added twice
    assert_eq!((a, e, c, a2), (0, 1, 2, 3));
    let transforms = [
        (
            a,
            affine(mat_mul(rotation(2, 0.7), rotation(0, 0.3)), [2.5, 0.0, 0.5]),
        ),
        (
            c,
            affine(
                [[1.5, 0.4, 0.0], [0.0, 0.7, 0.2], [0.1, 0.0, 1.2]],
                [-2.0, 1.0, 0.0],
            ),
        ),
        // Mirrors: one plane, and a rotation composed with a reflection.
        (
            c,
            affine(
                [[-1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
                [0.5, -2.5, 0.0],
            ),
        ),
        (
            c,
            affine(
                mat_mul(
                    rotation(1, 0.4),
                    [[1.3, 0.0, 0.0], [0.0, -0.8, 0.0], [0.0, 0.0, 1.1]],
                ),
                [2.0, 2.0, -1.5],
            ),
        ),
        // Overlapping the mesh it places, a little moved.
        (a, affine(rotation(1, 0.05), [0.1, 0.05, 0.0])),
        (c, Transform::translation([0.4, 0.3, 0.2])),
        // An exact copy.
        (c, Transform::IDENTITY),
        // The empty mesh placed: nothing.
        (e, Transform::translation([1.0, 1.0, 1.0])),
    ];
    for (m, t) in transforms {
        let id = scene.add_instance(m, t).unwrap();
        assert_eq!(id as usize, placed.len());
        let mesh = placed[m as usize].0.clone();
        placed.push((mesh, Some(t)));
    }
    Mixed { scene, placed }
}

fn oracle_of(placed: &[(Mesh, Option<Transform>)]) -> Oracle {
    let refs: Vec<(&Mesh, Option<Transform>)> = placed.iter().map(|(m, t)| (m, *t)).collect();
    Oracle::new(&refs)
}

fn built(scene: &Scene) -> SceneTree {
    let tree = scene.build(&BuildOptions::default()).unwrap();
    tree.tree().validate().unwrap();
    tree
}

#[test]
fn ray_hits_match_the_brute_force_over_every_placed_triangle() {
    let m = mixed();
    let tree = built(&m.scene);
    let oracle = oracle_of(&m.placed);
    let all: Vec<(u32, u32, [V; 3])> = oracle.tris().map(|(g, p, t)| (g, p, *t)).collect();
    let mut rng = Rng(42);
    let mut rays = Vec::new();
    for i in 0..3000 {
        let o = rng.v(-5.0, 5.0);
        let d = if i % 4 == 3 {
            rng.v(-1.0, 1.0)
        } else {
            // Aimed at a random point inside a random placed triangle.
            let (_, _, t) = all[rng.below(all.len())];
            let (mut u, mut v) = (rng.f(), rng.f());
            if u + v > 1.0 {
                (u, v) = (1.0 - u, 1.0 - v);
            }
            let q = add(
                t[0],
                add(scale(sub(t[1], t[0]), u), scale(sub(t[2], t[0]), v)),
            );
            sub(q, o)
        };
        rays.push(Ray::new(vec3(o), vec3(d)));
    }
    let batch = tree.intersect_batch(&rays);
    let occluded = tree.occluded_batch(&rays);
    let (mut hits, mut ties) = (0, 0);
    for (i, ray) in rays.iter().enumerate() {
        let (o, d) = (f64s(ray.origin), f64s(ray.direction));
        let got = tree.intersect(ray);
        assert_eq!(got, batch[i], "ray {i}: batch differs from single");
        assert_eq!(got.is_some(), occluded[i], "ray {i}: occluded");
        assert_eq!(got.is_some(), tree.occluded(ray), "ray {i}: occluded");
        let sure = oracle.hits(o, d, -1e-5);
        let maybe = oracle.hits(o, d, 1e-5);
        match got {
            None => assert!(sure.is_empty(), "ray {i}: missed {:?}", sure[0]),
            Some(h) => {
                hits += 1;
                let best = maybe[0].0;
                let mine = maybe
                    .iter()
                    .find(|x| (x.1, x.2) == (h.geometry, h.prim))
                    .unwrap_or_else(|| panic!("ray {i}: hit {h:?} is no hit of the oracle"));
                let tol = 1e-4 * best.max(1.0);
                assert!(
                    (h.t as f64 - mine.0).abs() < tol,
                    "ray {i}: t {} vs {}",
                    h.t,
                    mine.0
                );
                assert!(
                    mine.0 - best < tol,
                    "ray {i}: {h:?} is not the nearest, {:?}",
                    maybe[0]
                );
                if sure.first().map(|s| (s.1, s.2)) == Some((h.geometry, h.prim)) {
                    // Barycentrics in the mesh's own corner order, mirrored or not.
                    assert!(
                        (h.u as f64 - mine.3).abs() < 1e-3,
                        "ray {i}: u {} vs {}",
                        h.u,
                        mine.3
                    );
                    assert!(
                        (h.v as f64 - mine.4).abs() < 1e-3,
                        "ray {i}: v {} vs {}",
                        h.v,
                        mine.4
                    );
                }
                if maybe.len() > 1 && maybe[1].0 - best < tol {
                    ties += 1;
                }
            }
        }
        // Every hit: each sure one present, none outside the margin.
        let every = tree.all_hits(ray);
        assert!(
            every.windows(2).all(|w| w[0].t <= w[1].t),
            "ray {i}: all_hits unsorted"
        );
        for s in &sure {
            assert!(
                every.iter().any(|h| (h.geometry, h.prim) == (s.1, s.2)),
                "ray {i}: all_hits lacks {s:?}"
            );
        }
        for h in &every {
            assert!(
                maybe.iter().any(|x| (x.1, x.2) == (h.geometry, h.prim)),
                "ray {i}: all_hits has {h:?}"
            );
        }
        assert_eq!(
            every.first().copied(),
            got,
            "ray {i}: all_hits' first is not the closest"
        );
        // The f64 walk: a nearest (geometry, primitive) of the oracle too, mirrors remapped.
        let r64 = Ray64::new(o, d);
        let h64 = tree.intersect_f64(&r64);
        assert_eq!(
            h64.is_some(),
            tree.occluded_f64(&r64),
            "ray {i}: occluded_f64"
        );
        match h64 {
            None => assert!(sure.is_empty(), "ray {i}: f64 missed {:?}", sure[0]),
            Some(h) => {
                let mine = maybe
                    .iter()
                    .find(|x| (x.1, x.2) == (h.geometry, h.prim))
                    .unwrap_or_else(|| panic!("ray {i}: f64 hit {h:?} is no hit of the oracle"));
                let tol = 1e-4 * maybe[0].0.max(1.0);
                assert!(
                    mine.0 - maybe[0].0 < tol,
                    "ray {i}: f64 {h:?} is not the nearest"
                );
                if sure.first().map(|s| (s.1, s.2)) == Some((h.geometry, h.prim)) {
                    assert!(
                        (h.u - mine.3).abs() < 1e-3 && (h.v - mine.4).abs() < 1e-3,
                        "ray {i}"
                    );
                }
            }
        }
    }
    let rays64: Vec<Ray64> = rays
        .iter()
        .map(|r| Ray64::new(f64s(r.origin), f64s(r.direction)))
        .collect();
    let batch64 = tree.intersect_batch_f64(&rays64);
    for (r, h) in rays64.iter().zip(&batch64) {
        assert_eq!(*h, tree.intersect_f64(r));
    }
    let occluded64 = tree.occluded_batch_f64(&rays64);
    assert!(batch64
        .iter()
        .zip(&occluded64)
        .all(|(h, &o)| h.is_some() == o));
    assert_eq!(tree.all_hits_batch(&rays)[17], tree.all_hits(&rays[17]));
    // The copies make ties (the duplicate mesh, the identity instance): they must occur.
    assert!(hits > 2000 && ties > 100, "{hits} hits, {ties} ties");
}

#[test]
fn an_exact_copy_loses_ties_to_the_geometry_added_first() {
    let m = mixed();
    let tree = built(&m.scene);
    // Geometry 0 (the soup) and 3 (the same soup added again) are the same triangles.
    let oracle = oracle_of(&m.placed);
    for (p, t) in oracle.geometries[0].iter().enumerate() {
        let centre = scale(add(t[0], add(t[1], t[2])), 1.0 / 3.0);
        let n = cross(sub(t[1], t[0]), sub(t[2], t[0]));
        let o = add(centre, scale(n, 3.0 / norm(n)));
        let h = tree
            .intersect(&Ray::new(vec3(o), vec3(scale(n, -1.0))))
            .unwrap();
        // Another soup triangle may lie in front; if the ray meets triangle p first, it is
        // geometry 0's, never its copy's.
        if h.prim == p as u32 && (h.geometry == 0 || h.geometry == 3) {
            assert_eq!(h.geometry, 0, "triangle {p}");
        }
    }
    // The identity instance of the cube (geometry 10) never wins over the cube (2).
    let mut rng = Rng(5);
    for _ in 0..500 {
        let o = add(rng.v(0.1, 0.9), [0.0, 0.0, 5.0]);
        let h = tree
            .intersect(&Ray::new(vec3(o), Vec3::new(0.0, 0.0, -1.0)))
            .unwrap();
        assert_ne!(h.geometry, 10);
    }
}

#[test]
fn closest_points_match_the_brute_force() {
    let m = mixed();
    let tree = built(&m.scene);
    let oracle = oracle_of(&m.placed);
    let mut rng = Rng(7);
    let points: Vec<Vec3> = (0..1500)
        .map(|i| {
            vec3(if i % 3 == 0 {
                rng.v(-8.0, 8.0)
            } else {
                rng.v(-3.0, 3.5)
            })
        })
        .collect();
    let batch = tree.closest_point_batch(&points);
    let distances = tree.distance_batch(&points);
    for (i, &p) in points.iter().enumerate() {
        let c = tree.closest_point(p).unwrap();
        assert_eq!(Some(c), batch[i]);
        assert_eq!(c.distance, distances[i]);
        assert_eq!(c.distance, tree.distance(p));
        let all = oracle.closest(f64s(p));
        let best = all[0].0;
        let tol = 1e-5 * best.max(1.0);
        assert!(
            (c.distance - best).abs() < tol,
            "point {i}: {} vs {best}",
            c.distance
        );
        let mine = all
            .iter()
            .find(|x| (x.1, x.2) == (c.geometry, c.prim))
            .unwrap();
        assert!(
            mine.0 - best < tol,
            "point {i}: {c:?} is not the nearest, {:?}",
            all[0]
        );
        assert!(
            norm(sub(c.point, mine.3)) < 1e-4,
            "point {i}: {:?} vs {:?}",
            c.point,
            mine.3
        );
        // The barycentrics, in the mesh's corner order, give the point on the placed triangle.
        let t = &oracle.geometries[c.geometry as usize][c.prim as usize];
        let w = c.barycentrics;
        let q = add(scale(t[0], w[0]), add(scale(t[1], w[1]), scale(t[2], w[2])));
        assert!(norm(sub(q, c.point)) < 1e-4, "point {i}: barycentrics");
    }
}

/// Closed cubes only: a sheared one, two mirrored ones, one overlapping another.
fn cubes() -> (Scene, Vec<Transform>, Vec<V>) {
    let (cube, normals) = cube();
    let transforms = vec![
        Transform::IDENTITY,
        Transform::translation([0.5, 0.4, 0.3]), // overlaps the first
        affine(
            [[1.5, 0.4, 0.0], [0.0, 0.7, 0.2], [0.1, 0.0, 1.2]],
            [-3.0, 1.0, 0.0],
        ),
        affine(
            [[-1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            [0.5, -2.5, 0.0],
        ),
        affine(
            mat_mul(
                rotation(1, 0.4),
                [[1.3, 0.0, 0.0], [0.0, -0.8, 0.0], [0.0, 0.0, 1.1]],
            ),
            [2.0, 2.0, -1.5],
        ),
    ];
    let mut scene = Scene::new();
    let c = scene.add_mesh(&cube).unwrap();
    for t in &transforms[1..] {
        scene.add_instance(c, *t).unwrap();
    }
    (scene, transforms, normals)
}

#[test]
fn inside_is_the_union_of_the_geometries_mirrors_included() {
    let (scene, transforms, _) = cubes();
    assert!(transforms[3].determinant() < 0.0 && transforms[4].determinant() < 0.0);
    let tree = built(&scene);
    let inverses: Vec<_> = transforms.iter().map(|t| inverse(linear(t))).collect();
    let local = |k: usize, p: V| {
        let t = &transforms[k].0;
        mat_vec(inverses[k], sub(p, [t[0][3], t[1][3], t[2][3]]))
    };
    let mut rng = Rng(11);
    let (mut inside, mut in_two, mut checked) = (0, 0, 0);
    let mut points = Vec::new();
    let mut expected = Vec::new();
    while points.len() < 3000 {
        // Half near a random cube (in its frame, grown by a fifth), half anywhere.
        let p = if points.len() % 2 == 0 {
            transforms[rng.below(transforms.len())].apply(rng.v(-0.2, 1.2))
        } else {
            rng.v(-3.5, 3.5)
        };
        let p = f64s(vec3(p));
        let locals: Vec<V> = (0..transforms.len()).map(|k| local(k, p)).collect();
        // Away from every face, where the f32 placement could round either way.
        if locals
            .iter()
            .any(|l| l.iter().any(|&x| x.abs() < 1e-3 || (x - 1.0).abs() < 1e-3))
        {
            continue;
        }
        let count = locals
            .iter()
            .filter(|l| l.iter().all(|&x| x > 0.0 && x < 1.0))
            .count();
        inside += (count > 0) as usize;
        in_two += (count > 1) as usize;
        points.push(vec3(p));
        expected.push(count > 0);
    }
    for test in [InsideTest::Parity, InsideTest::Winding] {
        let got = tree.contains_batch(&points, test);
        let signed = tree.signed_distance_batch(&points, test);
        for (i, &p) in points.iter().enumerate() {
            assert_eq!(got[i], expected[i], "{test:?}: point {i} {p:?}");
            assert_eq!(got[i], tree.contains(p, test));
            let d = tree.distance(p);
            assert_eq!(
                signed[i],
                if expected[i] { -d } else { d },
                "{test:?}: point {i}"
            );
            assert_eq!(signed[i], tree.signed_distance(p, test));
            checked += 1;
        }
    }
    assert!(
        inside > 100 && in_two > 10,
        "{inside} inside, {in_two} in two cubes, {checked}"
    );
}

#[test]
fn normals_point_out_of_every_placed_cube_mirrors_included() {
    let (scene, transforms, normals) = cubes();
    let tree = built(&scene);
    let mut rng = Rng(13);
    let mut seen = vec![0; transforms.len()];
    for _ in 0..4000 {
        let o = rng.v(-6.0, 6.0);
        let target = rng.v(-3.0, 3.0);
        let ray = Ray::new(vec3(o), vec3(sub(target, o)));
        let Some(h) = tree.intersect(&ray) else {
            continue;
        };
        let g = h.geometry as usize;
        // The oracle's outward normal: the face's normal through the inverse transpose.
        let inv = inverse(linear(&transforms[g]));
        let n = normals[h.prim as usize];
        let world = [0, 1, 2].map(|j| (0..3).map(|i| inv[i][j] * n[i]).sum::<f64>());
        let world = scale(world, 1.0 / norm(world));
        let got = tree.normal(h.geometry, h.prim).unwrap();
        assert!(
            dot(got, world) > 1.0 - 1e-6,
            "geometry {g}, prim {}: {got:?} vs {world:?}",
            h.prim
        );
        // A ray from outside every cube meets an outer face: against the normal. (Origins
        // inside a cube meet it from within.)
        if !tree.contains(ray.origin, InsideTest::Winding) {
            assert!(dot(got, f64s(ray.direction)) < 0.0);
        }
        seen[g] += 1;
    }
    assert!(seen.iter().all(|&s| s > 20), "{seen:?}");
}

#[test]
fn an_empty_scene_answers_nothing() {
    for scene in [Scene::new(), {
        let mut s = Scene::new();
        let m = s
            .add_mesh(&Mesh {
                vertices: vec![],
                triangles: vec![],
            })
            .unwrap();
        s.add_instance(m, Transform::translation([1.0, 0.0, 0.0]))
            .unwrap();
        s
    }] {
        let tree = built(&scene);
        let ray = Ray::new(Vec3::new(0., 0., 0.), Vec3::new(0., 0., 1.));
        let p = Vec3::new(0.5, 0.5, 0.5);
        assert_eq!(tree.intersect(&ray), None);
        assert!(!tree.occluded(&ray));
        assert!(tree.all_hits(&ray).is_empty());
        assert_eq!(tree.intersect_batch(&[ray, ray]), vec![None, None]);
        assert_eq!(tree.closest_point(p), None);
        assert_eq!(tree.distance(p), f64::INFINITY);
        assert!(!tree.contains(p, InsideTest::Parity));
        assert!(!tree.contains(p, InsideTest::Winding));
        assert_eq!(tree.signed_distance(p, InsideTest::Parity), f64::INFINITY);
    }
}

#[test]
fn bad_transforms_and_ids_are_refused_clearly() {
    let (cube, _) = cube();
    let mut scene = Scene::new();
    let c = scene.add_mesh(&cube).unwrap();
    let i = scene
        .add_instance(c, Transform::translation([2.0, 0.0, 0.0]))
        .unwrap();
    let err = |r: Result<u32, sahkd::SceneError>| r.unwrap_err().to_string();

    let mut nan = Transform::IDENTITY;
    nan.0[1][2] = f64::NAN;
    assert!(err(scene.add_instance(c, nan)).contains("entry [1][2] is NaN"));
    let mut inf = Transform::IDENTITY;
    inf.0[0][3] = f64::INFINITY;
    assert!(err(scene.add_instance(c, inf)).contains("entry [0][3] is inf"));
    let flat = affine(
        [[1.0, 2.0, 3.0], [2.0, 4.0, 6.0], [0.0, 0.0, 1.0]],
        [0.0; 3],
    );
    assert!(err(scene.add_instance(c, flat)).contains("singular"));
    let zero = affine([[0.0; 3]; 3], [0.0; 3]);
    assert!(err(scene.add_instance(c, zero)).contains("singular"));
    // Tiny but uniform is no flattening.
    let tiny = affine(
        [[1e-20, 0., 0.], [0., 1e-20, 0.], [0., 0., 1e-20]],
        [0.0; 3],
    );
    scene.add_instance(c, tiny).unwrap();
    let projective = [
        [1., 0., 0., 0.],
        [0., 1., 0., 0.],
        [0., 0., 1., 0.],
        [0., 0., 1., 0.],
    ];
    assert!(Transform::from_4x4(projective)
        .unwrap_err()
        .to_string()
        .contains("last row"));

    assert!(err(scene.add_instance(99, Transform::IDENTITY)).contains("no mesh with id 99"));
    // An instance is not a mesh to place.
    assert!(
        err(scene.add_instance(i, Transform::IDENTITY)).contains(&format!("no mesh with id {i}"))
    );

    let bad = Mesh {
        vertices: vec![[0., 0., 0.], [1., f32::NAN, 0.], [0., 1., 0.]],
        triangles: vec![[0, 1, 2]],
    };
    assert!(err(scene.add_mesh(&bad)).contains("vertex 1"));
    let bad = Mesh {
        vertices: vec![[0., 0., 0.]],
        triangles: vec![[0, 0, 5]],
    };
    assert!(err(scene.add_mesh(&bad)).contains("face 0 refers to vertex 5"));
    // Placed beyond float32.
    let huge = affine([[1e39, 0., 0.], [0., 1e39, 0.], [0., 0., 1e39]], [0.0; 3]);
    scene.add_instance(c, huge).unwrap();
    let e = scene
        .build(&BuildOptions::default())
        .err()
        .unwrap()
        .to_string();
    assert!(e.contains("beyond the float32 range"), "{e}");
    // Refused calls added nothing.
    assert_eq!(scene.len(), 4);
}

/// Singular in float32 terms is judged by the condition of the rows scaled to length 1 and
/// by float32's range, not by the determinant: the determinant of a shear is 1 whatever its
/// size, and that of a row scaled to 1e-300 is no smaller than the row.
#[test]
fn transforms_are_judged_by_their_condition_in_float32() {
    let (cube, _) = cube();
    let mut scene = Scene::new();
    let c = scene.add_mesh(&cube).unwrap();
    let err = |r: Result<u32, sahkd::SceneError>| r.unwrap_err().to_string();
    let shear = |s: f64| affine([[1.0, s, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]], [0.0; 3]);
    let diag = |d: [f64; 3]| {
        affine(
            [[d[0], 0.0, 0.0], [0.0, d[1], 0.0], [0.0, 0.0, d[2]]],
            [0.0; 3],
        )
    };
    // A shear of 1e12 leaves x = x + 1e12 y without x once rounded to float32.
    let message = err(scene.add_instance(c, shear(1e12)));
    assert!(message.contains("condition number"), "{message}");
    assert!(message.contains("singular"), "{message}");
    // A row of 1e-300 is 0 in float32: flat, although the rows are orthogonal.
    let message = err(scene.add_instance(c, diag([1e-300, 1.0, 1.0])));
    assert!(
        message.contains("row 0") && message.contains("1e-300"),
        "{message}"
    );
    // Modest shears, axes scaled apart and huge uniform scales place the mesh.
    scene.add_instance(c, shear(1e3)).unwrap();
    scene.add_instance(c, diag([1e4, 1e-4, 1.0])).unwrap();
    scene.add_instance(c, diag([1e-30, 1e-30, 1e-30])).unwrap();
    scene
        .add_instance(c, diag([1e200, 1e200, 1e200]))
        .unwrap_or_else(|e| {
            panic!("a huge uniform scale is no flattening, whatever baking says later: {e}")
        });
    // A shear near float32's precision is refused, one well inside it accepted.
    assert!(scene.add_instance(c, shear(1e8)).is_err());
    scene.add_instance(c, shear(1e5)).unwrap();
}
