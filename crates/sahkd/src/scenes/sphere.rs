//! `sphere`: one UV sphere of radius 1 at the origin.
//!
//! Count: `2 m (s - 1)` with `s = round((1 + sqrt(1 + N)) / 2)` stacks (at least 2) and
//! `m = round(N / (2 (s - 1)))` slices (at least 3), so about twice as many slices as stacks
//! and within 1.2x of N for N >= 6 (6 triangles at least).

use super::shapes::{assemble, sphere_tessellation, Frame, Shape};
use crate::mesh::Mesh;

pub(super) fn generate(n: u64) -> Mesh {
    let (stacks, slices) = sphere_tessellation(n as f64);
    assemble(&[Shape::Sphere {
        frame: Frame::at([0.0; 3]),
        radius: 1.0,
        stacks,
        slices,
    }])
}
