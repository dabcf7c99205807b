//! The GPU's clip against the CPU's `clipped_bounds`, bit for bit (all six floats by
//! `to_bits`, so -0 and +0 differ), and its software f64 against the CPU's f64 arithmetic.

mod common;

use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use sahkd::clip::{clipped_bounds, round_down, round_up};
use sahkd::{Aabb, Mesh, Triangle, Vec3};
use sahkd_gpu::clip::{clip_triangles, f64_ops};
use sahkd_gpu::Gpu;

fn bits(b: &Aabb) -> [u32; 6] {
    [b.lo[0], b.lo[1], b.lo[2], b.hi[0], b.hi[1], b.hi[2]].map(f32::to_bits)
}

/// Clips every pair on the GPU and on the CPU and fails on the first difference.
fn check(gpu: &Gpu, what: &str, tris: &[Triangle], boxes: &[Aabb]) {
    let out = clip_triangles(gpu, tris, boxes).unwrap();
    assert_eq!(out.len(), tris.len());
    let mut cut = 0;
    let mut empty = 0;
    for (i, ((t, b), (g, g_empty))) in tris.iter().zip(boxes).zip(&out).enumerate() {
        let c = clipped_bounds(t, b);
        assert_eq!(
            bits(g),
            bits(&c),
            "{what}: pair {i}: triangle {t:?} box {b:?}: GPU {g:?}, CPU {c:?}"
        );
        assert_eq!(*g_empty, c.is_empty(), "{what}: pair {i}: empty flag");
        empty += c.is_empty() as usize;
        cut +=
            (!c.is_empty() && c != sahkd::geometry::triangle_bounds(t).intersection(*b)) as usize;
    }
    eprintln!(
        "{what}: {} pairs equal ({empty} empty, {cut} cut tighter than the triangle's box)",
        tris.len()
    );
}

fn random_box(rng: &mut StdRng, centre: Vec3, size: f32) -> Aabb {
    let mut corner = || {
        let d = Vec3::new(
            rng.random_range(-size..=size),
            rng.random_range(-size..=size),
            rng.random_range(-size..=size),
        );
        centre + d
    };
    let (p, q) = (corner(), corner());
    Aabb::new(p.min(q), p.max(q))
}

fn random_triangle(rng: &mut StdRng, centre: Vec3, size: f32) -> Triangle {
    let mut corner = || {
        centre
            + Vec3::new(
                rng.random_range(-size..=size),
                rng.random_range(-size..=size),
                rng.random_range(-size..=size),
            )
    };
    [corner(), corner(), corner()]
}

#[test]
fn soft_f64_matches_the_cpu() {
    let Some(gpu) = common::gpu() else { return };
    let mut rng = StdRng::seed_from_u64(7);
    // Any finite f64 with an exponent in `exp` (unbiased), sign and mantissa random.
    let any = |rng: &mut StdRng, exp: std::ops::RangeInclusive<i32>| {
        let e = rng.random_range(exp) + 1023;
        let m = rng.random::<u64>() & ((1 << 52) - 1);
        f64::from_bits((rng.random::<u64>() & 1 << 63) | (e.clamp(0, 2046) as u64) << 52 | m)
    };
    let f32_any = |rng: &mut StdRng| loop {
        let f = f32::from_bits(rng.random());
        if f.is_finite() {
            return f;
        }
    };
    let specials = [
        0.0,
        -0.0,
        1.0,
        -1.0,
        0.5,
        f64::MIN_POSITIVE,
        -f64::MIN_POSITIVE,
        f64::from_bits(1),
        f64::from_bits(0x000f_ffff_ffff_ffff),
        f64::MAX,
        -f64::MAX,
        f32::MAX as f64,
        f32::MIN_POSITIVE as f64,
        f32::from_bits(1) as f64,
        1.0 + f64::EPSILON,
        1.0 - f64::EPSILON / 2.0,
    ];
    let mut cases = Vec::new();
    for &a in &specials {
        for &b in &specials {
            cases.push((a, b, a as f32));
        }
    }
    for i in 0..200_000 {
        let (a, b) = match i % 6 {
            // What the clip sees: f32 values, their differences, products and quotients.
            0 => {
                let (x, y) = (f32_any(&mut rng) as f64, f32_any(&mut rng) as f64);
                (x, y)
            }
            1 => {
                let x = f32_any(&mut rng) as f64;
                let y = f32_any(&mut rng) as f64;
                let z = rng.random::<f32>() as f64;
                ((x - y) / (x + y), z * (x - y))
            }
            // Close values: cancellation, ties in rounding, equal magnitudes.
            2 => {
                let x = any(&mut rng, -20..=20);
                let k = rng.random_range(-3i64..=3);
                let y = f64::from_bits((x.to_bits() as i64 + k) as u64);
                let y = if rng.random() { -y } else { y };
                (x, y)
            }
            3 => {
                let x = any(&mut rng, -60..=60);
                let y = any(&mut rng, -60..=60);
                (x, y)
            }
            // Whole exponent range: overflow to infinity, gradual underflow, subnormal inputs.
            4 => (any(&mut rng, -1075..=1023), any(&mut rng, -1075..=1023)),
            // Around the f32 range, for the directed roundings to f32.
            _ => (any(&mut rng, -155..=130), any(&mut rng, -30..=30)),
        };
        if a.is_finite() && b.is_finite() {
            cases.push((a, b, f32_any(&mut rng)));
        }
    }
    let out = f64_ops(&gpu, &cases).unwrap();
    let same = |x: f64, y: f64| x.to_bits() == y.to_bits();
    for (&(a, b, c), g) in cases.iter().zip(&out) {
        let ctx = format!(
            "a = {a:e} ({:#x}), b = {b:e} ({:#x})",
            a.to_bits(),
            b.to_bits()
        );
        assert!(
            same(g.add, a + b),
            "{ctx}: a + b = {:e}, not {:e}",
            a + b,
            g.add
        );
        assert!(
            same(g.sub, a - b),
            "{ctx}: a - b = {:e}, not {:e}",
            a - b,
            g.sub
        );
        assert!(
            same(g.mul, a * b),
            "{ctx}: a * b = {:e}, not {:e}",
            a * b,
            g.mul
        );
        if b != 0.0 {
            assert!(
                same(g.div, a / b),
                "{ctx}: a / b = {:e}, not {:e}",
                a / b,
                g.div
            );
        }
        // The clip's rule between -0 and +0: the first argument stays.
        let min = if b < a { b } else { a };
        let max = if b > a { b } else { a };
        assert!(same(g.min, min) && same(g.max, max), "{ctx}: min/max");
        assert_eq!(
            [g.lt, g.le, g.ge, g.eq],
            [a < b, a <= b, a >= b, a == b],
            "{ctx}: comparisons"
        );
        assert_eq!(g.down.to_bits(), round_down(a).to_bits(), "{ctx}: down");
        assert_eq!(g.up.to_bits(), round_up(a).to_bits(), "{ctx}: up");
        assert!(same(g.widened, c as f64), "{c:e} as f64");
    }
    eprintln!("{} cases of every soft-f64 operation equal", cases.len());
}

#[test]
fn random_triangles_at_several_scales() {
    let Some(gpu) = common::gpu() else { return };
    let mut rng = StdRng::seed_from_u64(11);
    let (mut tris, mut boxes) = (Vec::new(), Vec::new());
    for scale in [1e-30f32, 1.0, 1e30] {
        for i in 0..33_000 {
            // Boxes anywhere in the scene, or about a triangle's size near it (most cut), or
            // small triangles far from the origin (large coordinates, small differences).
            let (tri, b) = match i % 3 {
                0 => {
                    let t = random_triangle(&mut rng, Vec3::splat(0.0), scale);
                    (t, random_box(&mut rng, Vec3::splat(0.0), scale))
                }
                1 => {
                    let c = Vec3::new(
                        rng.random_range(-scale..scale),
                        rng.random_range(-scale..scale),
                        rng.random_range(-scale..scale),
                    );
                    let size = scale * 0.1;
                    let t = random_triangle(&mut rng, c, size);
                    (t, random_box(&mut rng, c, size))
                }
                _ => {
                    let c = Vec3::splat(scale * rng.random_range(-1.0..1.0));
                    let size = scale * [1e-3, 1e-5][i % 2];
                    let t = random_triangle(&mut rng, c, size);
                    (t, random_box(&mut rng, c, size))
                }
            };
            tris.push(tri);
            boxes.push(b);
        }
    }
    check(&gpu, "random, scales 1e-30, 1, 1e30", &tris, &boxes);
}

/// The real use: a triangle straddling a split plane is clipped to each child's box, the node
/// boxes themselves cut by earlier planes at ends of clipped boxes. For `count` random
/// triangles, walks `depth` levels down from the scene box, each level a plane through the
/// triangle's current clipped bounds (an end of a neighbour's clipped box, one of the
/// triangle's own corners, or a random point), recording both children.
fn split_walks(mesh: &Mesh, seed: u64, count: usize, depth: usize) -> (Vec<Triangle>, Vec<Aabb>) {
    let mut rng = StdRng::seed_from_u64(seed);
    let all = mesh.corner_triangles();
    let scene = mesh.bounds();
    let (mut tris, mut boxes) = (Vec::new(), Vec::new());
    for _ in 0..count {
        let k = rng.random_range(0..all.len());
        let tri = all[k];
        let mut node = scene;
        for _ in 0..depth {
            let clipped = clipped_bounds(&tri, &node);
            let axis = rng.random_range(0..3);
            let (lo, hi) = (clipped.lo[axis], clipped.hi[axis]);
            if lo >= hi {
                break;
            }
            let neighbour = &all[(k + rng.random_range(1..50)) % all.len()];
            let other = clipped_bounds(neighbour, &node);
            let choices = [
                other.lo[axis],
                other.hi[axis],
                tri[rng.random_range(0..3)][axis],
                lo + (hi - lo) * rng.random::<f32>(),
            ];
            let mut p = choices[rng.random_range(0..choices.len())];
            if !(p > node.lo[axis] && p < node.hi[axis]) {
                p = choices[3];
            }
            let (mut left, mut right) = (node, node);
            left.hi[axis] = p;
            right.lo[axis] = p;
            tris.extend([tri, tri]);
            boxes.extend([left, right]);
            node = if rng.random() { left } else { right };
        }
    }
    (tris, boxes)
}

#[test]
fn scene_triangles_clipped_to_split_children() {
    let Some(gpu) = common::gpu() else { return };
    for (file, seed) in [("bunny.ply", 1), ("sponza_dabrovic.ply", 2)] {
        let Some(mesh) = common::scene(file) else {
            continue;
        };
        let (tris, boxes) = split_walks(&mesh, seed, 6000, 8);
        check(&gpu, file, &tris, &boxes);
    }
}

fn t(a: [f32; 3], b: [f32; 3], c: [f32; 3]) -> Triangle {
    [Vec3(a), Vec3(b), Vec3(c)]
}

fn bx(lo: [f32; 3], hi: [f32; 3]) -> Aabb {
    Aabb::new(Vec3(lo), Vec3(hi))
}

#[test]
fn degenerate_triangles_and_boxes() {
    let Some(gpu) = common::gpu() else { return };
    let diag = t([0.0; 3], [2.0, 0.0, 0.0], [0.0, 2.0, 0.0]);
    let flat = t([0.0, 0.0, 1.0], [2.0, 0.0, 1.0], [0.0, 2.0, 1.0]);
    let mut cases: Vec<(Triangle, Aabb)> = vec![
        // Planes through vertices, edges along planes.
        (diag, bx([0.0, 0.0, 0.0], [2.0, 2.0, 0.0])),
        (diag, bx([0.0, 0.0, -1.0], [1.0, 1.0, 1.0])),
        (diag, bx([1.0, 0.0, -1.0], [2.0, 1.0, 1.0])),
        (diag, bx([-1.0, -1.0, -1.0], [0.0, 0.0, 0.0])),
        // Touching at a vertex, along an edge, missing by a little.
        (diag, bx([2.0, 0.0, 0.0], [3.0, 1.0, 1.0])),
        (diag, bx([-1.0, -1.0, -1.0], [0.0, 3.0, 1.0])),
        (diag, bx([1.0, 1.0, -1.0], [3.0, 3.0, 1.0])),
        (diag, bx([1.0001, 1.0, -1.0], [3.0, 3.0, 1.0])),
        (diag, bx([0.0, 0.0, 0.5], [2.0, 2.0, 1.0])),
        // A triangle in a face of the box, and in a flat box.
        (flat, bx([0.0, 0.0, 1.0], [1.0, 1.0, 2.0])),
        (flat, bx([0.0, 0.0, 0.0], [1.0, 1.0, 1.0])),
        (flat, bx([0.5, 0.5, 1.0], [0.75, 3.0, 1.0])),
        (flat, bx([0.5, 0.5, 1.0], [0.5, 3.0, 1.0])),
        (flat, bx([0.5, 0.5, 1.0], [0.5, 0.5, 1.0])),
        // Zero-area triangles: a segment, a point, a doubled corner.
        (
            t([0.0; 3], [1.0, 1.0, 1.0], [2.0, 2.0, 2.0]),
            bx([0.5; 3], [1.5; 3]),
        ),
        (t([0.3; 3], [0.3; 3], [0.3; 3]), bx([0.0; 3], [1.0; 3])),
        (t([0.3; 3], [0.3; 3], [0.3; 3]), bx([0.3; 3], [0.3; 3])),
        (
            t([0.0; 3], [0.0; 3], [1.0, 2.0, 3.0]),
            bx([0.2, 0.0, 0.0], [0.7, 2.0, 3.0]),
        ),
        // Extremes of f32: subnormal and near-overflow coordinates.
        (
            t([1e-45, 0.0, 0.0], [3e-45, 1e-44, 0.0], [0.0, 2e-45, 7e-45]),
            bx([1e-45, 1e-45, 0.0], [2e-45, 1e-44, 1e-44]),
        ),
        (
            t(
                [-f32::MAX, -f32::MAX, 0.0],
                [f32::MAX, -f32::MAX, 1.0],
                [0.0, f32::MAX, -f32::MAX],
            ),
            bx([-f32::MAX, -1e38, -1e38], [3e38, f32::MAX, f32::MAX]),
        ),
    ];
    // Every combination of signed zeros in the corners and the box on x (nothing is cut, so
    // the result is the min/max of the zeros and then the intersection with the box): which
    // zero wins must be the CPU's.
    for signs in 0..32u32 {
        let z = |k: u32| if signs >> k & 1 == 1 { -0.0f32 } else { 0.0 };
        let tri = t([z(0), 0.0, 0.0], [z(1), 1.0, 0.0], [z(2), 0.0, 1.0]);
        cases.push((tri, bx([z(3), -1.0, -1.0], [z(4), 2.0, 2.0])));
        // The same on y, and with a cut that computes zeros as 0 + t * 0.
        let tri = t([0.0, z(0), 0.0], [1.0, z(1), 0.0], [0.0, z(2), 1.0]);
        cases.push((tri, bx([-1.0, z(3), -1.0], [0.5, z(4), 2.0])));
        cases.push((tri, bx([z(3), z(4), -1.0], [0.5, 1.0, 0.25])));
    }
    // Corners and boxes on a coarse grid, so planes pass through corners and edges and
    // triangles lie in faces all the time; at scales where products and quotients of
    // differences are far from f32's range.
    let mut rng = StdRng::seed_from_u64(5);
    for scale in [1.0f32, 2f32.powi(-120), 2f32.powi(100)] {
        for _ in 0..20_000 {
            let mut g = || rng.random_range(-2i32..=2) as f32 * 0.5 * scale;
            let tri = t([g(), g(), g()], [g(), g(), g()], [g(), g(), g()]);
            let (p, q) = (Vec3::new(g(), g(), g()), Vec3::new(g(), g(), g()));
            cases.push((tri, Aabb::new(p.min(q), p.max(q))));
        }
    }
    let (tris, boxes): (Vec<Triangle>, Vec<Aabb>) = cases.into_iter().unzip();
    check(&gpu, "degenerate", &tris, &boxes);
}
