//! `sphereflake`: Haines' fractal of spheres. A sphere of radius r carries 9 children of
//! radius r/3 touching it: 6 around its equator and 3 at 60 degrees latitude, where the
//! "pole" of a child points away from its parent. The whole flake fits in a box of half size
//! 2 around the root (radius 1 at the origin, pole up +y).
//!
//! Count: depth L (0 = the root alone) is the largest with `S(L) * 40 <= N`, where
//! `S(L) = (9^(L+1) - 1) / 8` is the number of spheres; every sphere is a UV sphere of about
//! `N / S(L)` triangles (see `sphere_tessellation`), so the total is `S(L) * 2 m (s - 1)`,
//! within 1.2x of N for N >= 6.

use super::shapes::{add, assemble, scale, sphere_tessellation, Frame, Shape};
use crate::mesh::Mesh;
use rayon::prelude::*;

/// The fewest triangles a sphere gets before the flake grows another level.
const MIN_TRIANGLES_PER_SPHERE: u64 = 40;

#[derive(Clone, Copy)]
struct Ball {
    frame: Frame,
    radius: f64,
}

/// Unit directions of the 9 children in the parent's frame (local y is the parent's pole).
fn child_directions() -> [[f64; 3]; 9] {
    let mut d = [[0.0; 3]; 9];
    for (j, dir) in d.iter_mut().enumerate().take(6) {
        let a = (j as f64 * 60.0).to_radians();
        *dir = [a.cos(), 0.0, -a.sin()];
    }
    let (se, ce) = 60f64.to_radians().sin_cos();
    for k in 0..3 {
        let a = (30.0 + k as f64 * 120.0).to_radians();
        d[6 + k] = [ce * a.cos(), se, -ce * a.sin()];
    }
    d
}

fn children(parent: &Ball, dirs: &[[f64; 3]; 9]) -> [Ball; 9] {
    let f = &parent.frame;
    let r = parent.radius / 3.0;
    dirs.map(|l| {
        let d = add(scale(f.ex, l[0]), add(scale(f.ey, l[1]), scale(f.ez, l[2])));
        let centre = add(f.origin, scale(d, parent.radius + r));
        Ball {
            frame: Frame::with_up(centre, d, f.ez),
            radius: r,
        }
    })
}

pub(super) fn sphere_count(depth: u32) -> u64 {
    (9u64.pow(depth + 1) - 1) / 8
}

pub(super) fn generate(n: u64) -> Mesh {
    let mut depth = 0;
    while sphere_count(depth + 1) * MIN_TRIANGLES_PER_SPHERE <= n {
        depth += 1;
    }
    let (stacks, slices) = sphere_tessellation(n as f64 / sphere_count(depth) as f64);
    let dirs = child_directions();
    let mut level = vec![Ball {
        frame: Frame::at([0.0; 3]),
        radius: 1.0,
    }];
    let mut balls = level.clone();
    for _ in 0..depth {
        level = level
            .par_iter()
            .flat_map_iter(|b| children(b, &dirs))
            .collect();
        balls.extend_from_slice(&level);
    }
    let shapes: Vec<Shape> = balls
        .par_iter()
        .map(|b| Shape::Sphere {
            frame: b.frame,
            radius: b.radius,
            stacks,
            slices,
        })
        .collect();
    assemble(&shapes)
}
