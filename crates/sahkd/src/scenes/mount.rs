//! `mount`: a fractal mountain, a height field over the square [-1, 1]^2 in x and z made by
//! midpoint displacement on top of a smooth dome.
//!
//! Count: `2 g^2` for a grid of g x g cells, g the integer next to `sqrt(N / 2)` (below or
//! above, whichever is closer in ratio; at least 1): within 1.5x of N for N >= 8 and within
//! 1.05x for N >= 800.
//!
//! Midpoint displacement for any g, not only powers of two: the cell indices 0..=g are split
//! as a binary tree of intervals (an interval [lo, hi] gets the point mid = (lo + hi) / 2),
//! the same hierarchy on both axes. Level by level, each new point on an existing row is the
//! mean of its two row neighbours, each new row is the mean of its two neighbouring rows, plus
//! a random offset scaled by the interval length to the power `ROUGHNESS_EXPONENT`. Every
//! offset is a hash of the point's coordinates and every new value depends only on the
//! previous level, so rows are filled in parallel and the result never depends on threads.

use super::random::{hash3, unit_f64};
use crate::mesh::Mesh;
use rayon::prelude::*;

const SEED: u64 = 0x006d_6f75_6e74;
/// Offsets shrink as length^H; H near 1 gives smooth slopes with fine detail.
const ROUGHNESS_EXPONENT: f64 = 0.9;
/// Largest offset, at the scale of the whole field.
const ROUGHNESS: f64 = 0.35;

/// Heights of the (g + 1) x (g + 1) grid points, row by row (row = z index).
fn heights(g: usize) -> Vec<Vec<f32>> {
    let noise = |x: usize, y: usize| (2.0 * unit_f64(hash3(SEED, x as u64, y as u64)) - 1.0) as f32;
    let amplitude =
        |len: usize| (ROUGHNESS * (len as f64 / g as f64).powf(ROUGHNESS_EXPONENT)) as f32;
    let mut rows: Vec<Vec<f32>> = vec![Vec::new(); g + 1];
    for y in [0, g] {
        let mut row = vec![0f32; g + 1];
        for x in [0, g] {
            row[x] = 0.25 * amplitude(g) * noise(x, y);
        }
        rows[y] = row;
    }
    let mut active = vec![0, g];
    let mut intervals = vec![(0usize, g)];
    loop {
        let splits: Vec<(usize, usize, usize)> = intervals
            .iter()
            .filter(|(lo, hi)| hi - lo > 1)
            .map(|&(lo, hi)| (lo, (lo + hi) / 2, hi))
            .collect();
        if splits.is_empty() {
            break;
        }
        // New points on the existing rows.
        rows.par_iter_mut().enumerate().for_each(|(y, row)| {
            if row.is_empty() {
                return;
            }
            for &(lo, mid, hi) in &splits {
                row[mid] = 0.5 * (row[lo] + row[hi]) + amplitude(hi - lo) * noise(mid, y);
            }
        });
        active.extend(splits.iter().map(|s| s.1));
        active.sort_unstable();
        // New rows, from the two rows around each.
        let new_rows: Vec<Vec<f32>> = splits
            .par_iter()
            .map(|&(lo, mid, hi)| {
                let mut row = vec![0f32; g + 1];
                let a = amplitude(hi - lo);
                for &x in &active {
                    row[x] = 0.5 * (rows[lo][x] + rows[hi][x]) + a * noise(x, mid);
                }
                row
            })
            .collect();
        for (s, row) in splits.iter().zip(new_rows) {
            rows[s.1] = row;
        }
        intervals = splits
            .iter()
            .flat_map(|&(lo, mid, hi)| [(lo, mid), (mid, hi)])
            .chain(intervals.iter().copied().filter(|(lo, hi)| hi - lo <= 1))
            .collect();
    }
    rows
}

/// The smooth mound the fractal detail sits on.
fn dome(x: f64, z: f64) -> f64 {
    0.7 * (-2.5 * (x * x + z * z)).exp()
}

/// Cells per side for about `n` triangles.
fn grid_size(n: u64) -> usize {
    let root = (n as f64 / 2.0).sqrt();
    let (below, above) = (root.floor().max(1.0), root.ceil().max(1.0));
    let ratio = |g: f64| {
        let t = 2.0 * g * g;
        (t / n as f64).max(n as f64 / t)
    };
    (if ratio(below) <= ratio(above) {
        below
    } else {
        above
    }) as usize
}

pub(super) fn generate(n: u64) -> Mesh {
    let g = grid_size(n);
    let rows = heights(g);
    let w = g + 1;
    let coord = |i: usize| -1.0 + 2.0 * i as f64 / g as f64;
    let mut vertices = vec![[0f32; 3]; w * w];
    vertices
        .par_chunks_mut(w)
        .zip(rows.par_iter())
        .enumerate()
        .for_each(|(j, (out, row))| {
            let z = coord(j);
            for (i, v) in out.iter_mut().enumerate() {
                let x = coord(i);
                *v = [x as f32, row[i] + dome(x, z) as f32, z as f32];
            }
        });
    let mut triangles = vec![[0u32; 3]; 2 * g * g];
    triangles
        .par_chunks_mut(2 * g)
        .enumerate()
        .for_each(|(j, out)| {
            for i in 0..g {
                let a = (j * w + i) as u32;
                let (b, c, d) = (a + 1, a + w as u32, a + w as u32 + 1);
                // Counter-clockwise seen from above (+y): along +z before +x.
                out[2 * i] = [a, c, b];
                out[2 * i + 1] = [b, c, d];
            }
        });
    Mesh {
        vertices,
        triangles,
    }
}
