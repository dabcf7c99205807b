//! `toys`: a "toys on the floor" scene in the spirit of the SPD test scenes: a few large
//! objects (a big sphere, two tori, a box, a tower) and many small ones (pebbles, rings,
//! blocks, pegs) from a few centimetres to metres, two long thin cylinders (a rod lying
//! diagonally across the floor and a flagpole), all on a 60 x 60 ground plane of 32 large
//! triangles. Big triangles spanning the scene next to dense clusters of tiny ones: the case
//! where SAH splits pay off and median splits do not.
//!
//! Count: the ground has 32 triangles; there are `M = clamp(round(sqrt(N) / 3), 12, 4000)`
//! small objects besides the 7 large ones, and the other N - 32 triangles are shared by all
//! objects in proportion to the square root of their surface areas, each object tessellated
//! to its share (at least a few triangles). Within 1.25x of N for N >= 500; smaller N give
//! about 300 triangles, the fewest the objects can be made of.
//!
//! The layout is drawn from a seeded hash stream, so it depends only on N.

use super::random::Stream;
use super::shapes::{assemble, sphere_tessellation, Frame, Shape, P3};
use crate::mesh::Mesh;
use std::f64::consts::PI;

const SEED: u64 = 0x746f_7973;
const GROUND_HALF: f64 = 30.0;
const GROUND_CELLS: u32 = 4;

/// An object before it is tessellated.
#[derive(Clone, Copy, Debug)]
enum Solid {
    Sphere {
        frame: Frame,
        radius: f64,
    },
    Torus {
        frame: Frame,
        major: f64,
        minor: f64,
    },
    Cuboid {
        frame: Frame,
        half: P3,
    },
    Cylinder {
        frame: Frame,
        radius: f64,
        length: f64,
    },
}

impl Solid {
    fn area(&self) -> f64 {
        match *self {
            Solid::Sphere { radius, .. } => 4.0 * PI * radius * radius,
            Solid::Torus { major, minor, .. } => 4.0 * PI * PI * major * minor,
            Solid::Cuboid { half: h, .. } => 8.0 * (h[0] * h[1] + h[1] * h[2] + h[2] * h[0]),
            Solid::Cylinder { radius, length, .. } => 2.0 * PI * radius * (length + radius),
        }
    }

    /// The tessellation of about `target` triangles.
    fn tessellate(&self, target: f64) -> Shape {
        match *self {
            Solid::Sphere { frame, radius } => {
                let (stacks, slices) = sphere_tessellation(target);
                Shape::Sphere {
                    frame,
                    radius,
                    stacks,
                    slices,
                }
            }
            Solid::Torus {
                frame,
                major,
                minor,
            } => {
                // Cells about square: rings / sides follows major / minor.
                let aspect = (major / minor).clamp(1.0, 10.0);
                let sides = (target / (2.0 * aspect)).sqrt().round().max(3.0);
                let rings = (target / (2.0 * sides)).round().max(3.0);
                Shape::Torus {
                    frame,
                    major,
                    minor,
                    rings: rings as u32,
                    sides: sides as u32,
                }
            }
            Solid::Cuboid { frame, half } => {
                // Square cells of side 1 / density: 2 density^2 area triangles.
                let density = (target / (2.0 * self.area())).sqrt();
                let cells = half.map(|h| (2.0 * h * density).round().max(1.0) as u32);
                Shape::Cuboid { frame, half, cells }
            }
            Solid::Cylinder {
                frame,
                radius,
                length,
            } => {
                // Square cells would need length / (2 pi r / sides) segments; the count is
                // 2 sides (segments + 1).
                let slender = (length / (2.0 * PI * radius)).max(0.25);
                let sides = (target / (2.0 * slender)).sqrt().round().max(3.0);
                let segments = (target / (2.0 * sides) - 1.0).round().max(1.0);
                Shape::Cylinder {
                    frame,
                    radius,
                    length,
                    sides: sides as u32,
                    segments: segments as u32,
                }
            }
        }
    }
}

/// What an object covers on the floor, for keeping objects apart.
#[derive(Clone, Copy, Debug)]
enum Footprint {
    Disc {
        x: f64,
        z: f64,
        r: f64,
    },
    /// A capsule: the segment from a to b in the xz plane, widened by r.
    Strip {
        a: [f64; 2],
        b: [f64; 2],
        r: f64,
    },
}

fn distance_to_segment(p: [f64; 2], a: [f64; 2], b: [f64; 2]) -> f64 {
    let (dx, dz) = (b[0] - a[0], b[1] - a[1]);
    let s = (((p[0] - a[0]) * dx + (p[1] - a[1]) * dz) / (dx * dx + dz * dz)).clamp(0.0, 1.0);
    let (qx, qz) = (a[0] + s * dx - p[0], a[1] + s * dz - p[1]);
    (qx * qx + qz * qz).sqrt()
}

impl Footprint {
    /// Whether a disc at (x, z) of radius r comes within `gap` of this footprint.
    fn crowds(&self, x: f64, z: f64, r: f64, gap: f64) -> bool {
        match *self {
            Footprint::Disc {
                x: x0,
                z: z0,
                r: r0,
            } => ((x - x0).powi(2) + (z - z0).powi(2)).sqrt() < r + r0 + gap,
            Footprint::Strip { a, b, r: r0 } => distance_to_segment([x, z], a, b) < r + r0 + gap,
        }
    }
}

fn lying_cylinder(from: [f64; 2], to: [f64; 2], radius: f64) -> (Solid, Footprint) {
    let d = [to[0] - from[0], 0.0, to[1] - from[1]];
    let length = (d[0] * d[0] + d[2] * d[2]).sqrt();
    let frame = Frame::with_up([from[0], radius, from[1]], d, [0.0, 1.0, 0.0]);
    (
        Solid::Cylinder {
            frame,
            radius,
            length,
        },
        Footprint::Strip {
            a: from,
            b: to,
            r: radius,
        },
    )
}

/// The large objects, placed by hand.
fn large_objects() -> Vec<(Solid, Footprint)> {
    let disc = |x: f64, z: f64, r: f64| Footprint::Disc { x, z, r };
    vec![
        (
            Solid::Sphere {
                frame: Frame::at([-7.0, 5.0, -6.0]),
                radius: 5.0,
            },
            disc(-7.0, -6.0, 5.0),
        ),
        (
            // Standing on its rim, facing the x axis.
            Solid::Torus {
                frame: Frame::with_up([8.0, 4.5, -10.0], [1.0, 0.0, 0.3], [0.0, 1.0, 0.0]),
                major: 3.5,
                minor: 1.0,
            },
            disc(8.0, -10.0, 4.5),
        ),
        (
            Solid::Torus {
                frame: Frame::at([6.0, 0.7, 7.0]),
                major: 2.5,
                minor: 0.7,
            },
            disc(6.0, 7.0, 3.2),
        ),
        (
            Solid::Cuboid {
                frame: Frame::yawed([-15.0, 1.5, 10.0], 25f64.to_radians()),
                half: [3.0, 1.5, 2.0],
            },
            disc(-15.0, 10.0, 3.7),
        ),
        (
            Solid::Cuboid {
                frame: Frame::yawed([16.0, 6.0, 2.0], 10f64.to_radians()),
                half: [0.8, 6.0, 0.8],
            },
            disc(16.0, 2.0, 1.2),
        ),
        lying_cylinder([-27.0, 26.0], [26.0, -16.0], 0.06),
        (
            Solid::Cylinder {
                frame: Frame::at([-2.0, 0.0, 15.0]),
                radius: 0.1,
                length: 22.0,
            },
            disc(-2.0, 15.0, 0.1),
        ),
    ]
}

/// A small object of size `s` resting on the floor at (x, z), and its footprint radius.
fn small_object(rng: &mut Stream, x: f64, z: f64, s: f64) -> (Solid, f64) {
    let yaw = rng.range(0.0, 2.0 * PI);
    match (rng.next() * 4.0) as u32 {
        0 => (
            Solid::Sphere {
                frame: Frame::yawed([x, s, z], yaw),
                radius: s,
            },
            s,
        ),
        1 => {
            let minor = s * rng.range(0.15, 0.4);
            (
                Solid::Torus {
                    frame: Frame::yawed([x, minor, z], yaw),
                    major: s,
                    minor,
                },
                s + minor,
            )
        }
        2 => {
            let half = [
                s * rng.range(0.4, 1.0),
                s * rng.range(0.3, 1.0),
                s * rng.range(0.4, 1.0),
            ];
            (
                Solid::Cuboid {
                    frame: Frame::yawed([x, half[1], z], yaw),
                    half,
                },
                (half[0] * half[0] + half[2] * half[2]).sqrt(),
            )
        }
        _ => {
            let radius = s * rng.range(0.15, 0.4);
            (
                Solid::Cylinder {
                    frame: Frame::yawed([x, 0.0, z], yaw),
                    radius,
                    length: s * rng.range(1.0, 4.0),
                },
                radius,
            )
        }
    }
}

/// The small objects: most in a few clusters, the rest anywhere, none touching another.
fn small_objects(count: usize, placed: &mut Vec<Footprint>) -> Vec<Solid> {
    let mut rng = Stream::new(SEED);
    let clusters: Vec<[f64; 3]> = (0..5)
        .map(|_| {
            [
                rng.range(-22.0, 22.0),
                rng.range(-22.0, 22.0),
                rng.range(2.0, 6.0),
            ]
        })
        .collect();
    let margin = GROUND_HALF - 1.5;
    let mut solids = Vec::with_capacity(count);
    for _ in 0..count {
        // Sizes spread evenly on a log scale from 4 cm to 1.2 m.
        let s = 0.04 * 30f64.powf(rng.next());
        for _attempt in 0..40 {
            let (x, z) = if rng.next() < 0.7 {
                let c = clusters[(rng.next() * clusters.len() as f64) as usize];
                let (angle, dist) = (rng.range(0.0, 2.0 * PI), c[2] * rng.next().sqrt());
                (c[0] + dist * angle.cos(), c[1] + dist * angle.sin())
            } else {
                (rng.range(-margin, margin), rng.range(-margin, margin))
            };
            if x.abs() > margin || z.abs() > margin {
                continue;
            }
            let (solid, r) = small_object(&mut rng, x, z, s);
            if placed.iter().any(|f| f.crowds(x, z, r, 0.02)) {
                continue;
            }
            placed.push(Footprint::Disc { x, z, r });
            solids.push(solid);
            break;
        }
    }
    solids
}

/// Small objects for about `n` triangles.
pub(super) fn small_object_count(n: u64) -> usize {
    ((n as f64).sqrt() / 3.0).round().clamp(12.0, 4000.0) as usize
}

pub(super) fn generate(n: u64) -> Mesh {
    let (mut solids, mut placed): (Vec<Solid>, Vec<Footprint>) =
        large_objects().into_iter().unzip();
    solids.extend(small_objects(small_object_count(n), &mut placed));
    let ground = Shape::Ground {
        frame: Frame::at([0.0; 3]),
        half: GROUND_HALF,
        cells: GROUND_CELLS,
    };
    let budget = n.saturating_sub(ground.counts().1 as u64) as f64;
    let weights: Vec<f64> = solids.iter().map(|s| s.area().sqrt()).collect();
    let total: f64 = weights.iter().sum();
    let shapes: Vec<Shape> = std::iter::once(ground)
        .chain(
            solids
                .iter()
                .zip(&weights)
                .map(|(s, w)| s.tessellate(budget * w / total)),
        )
        .collect();
    assemble(&shapes)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn large_objects_keep_apart() {
        let objects = large_objects();
        for (i, (_, a)) in objects.iter().enumerate() {
            for (_, b) in &objects[i + 1..] {
                let apart = match (*a, *b) {
                    (Footprint::Disc { x, z, r }, other) | (other, Footprint::Disc { x, z, r }) => {
                        !other.crowds(x, z, r, 0.0)
                    }
                    _ => true,
                };
                assert!(apart, "{a:?} overlaps {b:?}");
            }
        }
    }
}
