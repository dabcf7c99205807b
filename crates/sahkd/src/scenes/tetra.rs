//! `tetra`: a Sierpinski tetrahedron. A regular tetrahedron of edge 2 standing on the plane
//! y = 0 (apex up) is replaced by its 4 half-size corner copies, d times; each of the 4^d
//! small tetrahedra has 4 faces, each cut into k x k triangles (a finer mesh of the same
//! shape, which lets the count follow N closely).
//!
//! Count: `4^(d+1) k^2`. For each depth d with `4^(d+1) <= N` the best k is the integer
//! nearest to `sqrt(N / 4^(d+1))` in ratio; d is the deepest whose count is within 1.25x of
//! N, or else the one closest to N. That is within 1.25x of N for N >= 64 (4 at least).

use super::shapes::{add, cross, dot, scale, sub, P3};
use crate::mesh::Mesh;
use rayon::prelude::*;

/// Depth and face cuts for about `n` triangles.
pub(super) fn shape_for(n: u64) -> (u32, u64) {
    let n = n as f64;
    let ratio = |t: f64| if t > n { t / n } else { n / t };
    let mut best: Option<(u32, u64, f64)> = None;
    let mut d = 0u32;
    loop {
        let base = 4f64.powi(d as i32 + 1);
        if d > 0 && base > n {
            break;
        }
        let root = (n / base).sqrt();
        let k = [root.floor().max(1.0), root.ceil().max(1.0)]
            .into_iter()
            .min_by(|a, b| ratio(base * a * a).total_cmp(&ratio(base * b * b)))
            .unwrap();
        let r = ratio(base * k * k);
        let better = match best {
            None => true,
            Some((_, _, rb)) => r <= 1.25 || r < rb,
        };
        if better {
            best = Some((d, k as u64, r));
        }
        d += 1;
    }
    let (d, k, _) = best.unwrap();
    (d, k)
}

/// Corners of the base tetrahedron: edge 2, base on y = 0, apex up.
fn base_corners() -> [P3; 4] {
    let r = 2.0 / 3f64.sqrt(); // circumradius of the base triangle
    let h = 2.0 * (2.0f64 / 3.0).sqrt();
    let mut c = [[0.0, h, 0.0]; 4];
    for (k, corner) in c.iter_mut().skip(1).enumerate() {
        let a = (90.0 + 120.0 * k as f64).to_radians();
        *corner = [r * a.cos(), 0.0, r * a.sin()];
    }
    c
}

/// The 4 faces as corner indices, each wound to face away from the opposite corner.
fn faces(c: &[P3; 4]) -> [[usize; 3]; 4] {
    [[1, 2, 3], [0, 2, 3], [0, 1, 3], [0, 1, 2]].map(|[a, b, e]| {
        let opposite = (0..4).find(|i| ![a, b, e].contains(i)).unwrap();
        let n = cross(sub(c[b], c[a]), sub(c[e], c[a]));
        if dot(n, sub(c[opposite], c[a])) > 0.0 {
            [a, e, b]
        } else {
            [a, b, e]
        }
    })
}

pub(super) fn generate(n: u64) -> Mesh {
    let (depth, k) = shape_for(n);
    let c = base_corners();
    let faces = faces(&c);
    let k = k as usize;
    let face_vertices = (k + 1) * (k + 2) / 2;
    let leaves = 4usize.pow(depth);
    let (tet_v, tet_t) = (4 * face_vertices, 4 * k * k);
    assert!(leaves * tet_v <= u32::MAX as usize);
    let mut vertices = vec![[0f32; 3]; leaves * tet_v];
    let mut triangles = vec![[0u32; 3]; leaves * tet_t];
    let size = 0.5f64.powi(depth as i32);
    vertices
        .par_chunks_mut(tet_v)
        .zip(triangles.par_chunks_mut(tet_t))
        .enumerate()
        .for_each(|(leaf, (v, t))| {
            // Leaf corner i = c_i / 2^d + sum over levels l of c[digit_l] / 2^l, digit 1 the
            // most significant base-4 digit of the leaf index.
            let mut offset = [0.0; 3];
            for l in 1..=depth {
                let digit = (leaf >> (2 * (depth - l))) & 3;
                offset = add(offset, scale(c[digit], 0.5f64.powi(l as i32)));
            }
            let corner = |i: usize| add(offset, scale(c[i], size));
            let base = (leaf * tet_v) as u32;
            let (mut nv, mut nt) = (0usize, 0usize);
            for f in &faces {
                let (a, b, e) = (corner(f[0]), corner(f[1]), corner(f[2]));
                let (ab, ae) = (sub(b, a), sub(e, a));
                let first = nv;
                // Lattice point (i, j), i + j <= k: a + ab i/k + ae j/k, row by row in i.
                for i in 0..=k {
                    for j in 0..=k - i {
                        let p = add(
                            a,
                            add(
                                scale(ab, i as f64 / k as f64),
                                scale(ae, j as f64 / k as f64),
                            ),
                        );
                        v[nv] = [p[0] as f32, p[1] as f32, p[2] as f32];
                        nv += 1;
                    }
                }
                // Row i starts after rows 0..i, of lengths k + 1, k, ..., so at i (2k + 3 - i) / 2.
                let at = |i: usize, j: usize| base + (first + i * (2 * k + 3 - i) / 2 + j) as u32;
                for i in 0..k {
                    for j in 0..k - i {
                        t[nt] = [at(i, j), at(i + 1, j), at(i, j + 1)];
                        nt += 1;
                        if i + j + 1 < k {
                            t[nt] = [at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)];
                            nt += 1;
                        }
                    }
                }
            }
            debug_assert_eq!((nv, nt), (tet_v, tet_t));
        });
    Mesh {
        vertices,
        triangles,
    }
}
