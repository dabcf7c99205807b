//! Tessellated solids (sphere, torus, box, cylinder, ground grid) placed in the world, and
//! the parallel assembly of many of them into one mesh.
//!
//! Every shape knows its vertex and triangle counts before it is emitted, so the mesh is
//! allocated once and each shape writes its own slices, on any thread, with the same result.
//! Geometry is computed in f64 and rounded to f32 once. Triangles wind counter-clockwise seen
//! from outside.

use crate::mesh::Mesh;
use rayon::prelude::*;
use std::f64::consts::PI;

pub(crate) type P3 = [f64; 3];

pub(crate) fn add(a: P3, b: P3) -> P3 {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}
pub(crate) fn sub(a: P3, b: P3) -> P3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
pub(crate) fn scale(a: P3, s: f64) -> P3 {
    [a[0] * s, a[1] * s, a[2] * s]
}
pub(crate) fn dot(a: P3, b: P3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
pub(crate) fn cross(a: P3, b: P3) -> P3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
pub(crate) fn normalize(a: P3) -> P3 {
    scale(a, 1.0 / dot(a, a).sqrt())
}

/// A right-handed orthonormal frame: local (x, y, z) maps to `origin + x*ex + y*ey + z*ez`.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Frame {
    pub origin: P3,
    pub ex: P3,
    pub ey: P3,
    pub ez: P3,
}

impl Frame {
    pub(crate) fn at(origin: P3) -> Frame {
        Frame {
            origin,
            ex: [1.0, 0.0, 0.0],
            ey: [0.0, 1.0, 0.0],
            ez: [0.0, 0.0, 1.0],
        }
    }
    /// A frame whose local y is `up` (any unit vector); `hint` picks the rotation about it.
    pub(crate) fn with_up(origin: P3, up: P3, hint: P3) -> Frame {
        let ey = normalize(up);
        let mut ex = cross(ey, hint);
        if dot(ex, ex) < 1e-12 {
            // The hint is parallel to up: any other axis will do.
            let other = if ey[0].abs() < 0.9 {
                [1.0, 0.0, 0.0]
            } else {
                [0.0, 0.0, 1.0]
            };
            ex = cross(ey, other);
        }
        let ex = normalize(ex);
        let ez = cross(ex, ey);
        Frame { origin, ex, ey, ez }
    }
    /// Turned by `angle` radians about the world y axis.
    pub(crate) fn yawed(origin: P3, angle: f64) -> Frame {
        let (s, c) = angle.sin_cos();
        Frame {
            origin,
            ex: [c, 0.0, -s],
            ey: [0.0, 1.0, 0.0],
            ez: [s, 0.0, c],
        }
    }
    fn place(&self, l: P3) -> [f32; 3] {
        let p = add(
            self.origin,
            add(
                scale(self.ex, l[0]),
                add(scale(self.ey, l[1]), scale(self.ez, l[2])),
            ),
        );
        [p[0] as f32, p[1] as f32, p[2] as f32]
    }
}

/// One tessellated solid in the world.
#[derive(Clone, Debug)]
pub(crate) enum Shape {
    /// Poles on local ±y; `stacks` >= 2 bands of latitude, `slices` >= 3 of longitude.
    Sphere {
        frame: Frame,
        radius: f64,
        stacks: u32,
        slices: u32,
    },
    /// Ring around local y: `rings` >= 3 steps around the axis, `sides` >= 3 around the tube.
    Torus {
        frame: Frame,
        major: f64,
        minor: f64,
        rings: u32,
        sides: u32,
    },
    /// Centred box with half extents `half`; face cells per axis `cells[a]` >= 1.
    Cuboid {
        frame: Frame,
        half: P3,
        cells: [u32; 3],
    },
    /// Along local y from 0 to `length`, closed by fans; `sides` >= 3, `segments` >= 1.
    Cylinder {
        frame: Frame,
        radius: f64,
        length: f64,
        sides: u32,
        segments: u32,
    },
    /// A square in the local xz plane facing +y, `cells` x `cells` quads.
    Ground { frame: Frame, half: f64, cells: u32 },
}

/// Stacks and slices of a sphere of about `target` triangles (`2 * slices * (stacks - 1)`,
/// slices about twice the stacks, at least 6 triangles).
pub(crate) fn sphere_tessellation(target: f64) -> (u32, u32) {
    let stacks = ((1.0 + (1.0 + target.max(0.0)).sqrt()) / 2.0)
        .round()
        .max(2.0);
    let slices = (target / (2.0 * (stacks - 1.0))).round().max(3.0);
    (stacks as u32, slices as u32)
}

impl Shape {
    /// (vertices, triangles) this shape emits.
    pub(crate) fn counts(&self) -> (usize, usize) {
        match *self {
            Shape::Sphere { stacks, slices, .. } => {
                let (s, m) = (stacks as usize, slices as usize);
                (2 + (s - 1) * m, 2 * m * (s - 1))
            }
            Shape::Torus { rings, sides, .. } => {
                let n = rings as usize * sides as usize;
                (n, 2 * n)
            }
            Shape::Cuboid { cells, .. } => {
                let k = cells.map(|c| c as usize);
                let (mut v, mut t) = (0, 0);
                for a in 0..3 {
                    let (b, c) = (k[(a + 1) % 3], k[(a + 2) % 3]);
                    v += 2 * (b + 1) * (c + 1);
                    t += 4 * b * c;
                }
                (v, t)
            }
            Shape::Cylinder {
                sides, segments, ..
            } => {
                let (m, l) = (sides as usize, segments as usize);
                (m * (l + 1) + 2, 2 * m * l + 2 * m)
            }
            Shape::Ground { cells, .. } => {
                let c = cells as usize;
                ((c + 1) * (c + 1), 2 * c * c)
            }
        }
    }

    /// Writes the shape into `v` and `t` (exactly `counts()` long); indices start at `base`.
    pub(crate) fn emit(&self, v: &mut [[f32; 3]], t: &mut [[u32; 3]], base: u32) {
        let mut out = Out {
            v,
            t,
            nv: 0,
            nt: 0,
            base,
        };
        match *self {
            Shape::Sphere {
                ref frame,
                radius,
                stacks,
                slices,
            } => emit_sphere(&mut out, frame, radius, stacks, slices),
            Shape::Torus {
                ref frame,
                major,
                minor,
                rings,
                sides,
            } => emit_torus(&mut out, frame, major, minor, rings, sides),
            Shape::Cuboid {
                ref frame,
                half,
                cells,
            } => emit_cuboid(&mut out, frame, half, cells),
            Shape::Cylinder {
                ref frame,
                radius,
                length,
                sides,
                segments,
            } => emit_cylinder(&mut out, frame, radius, length, sides, segments),
            Shape::Ground {
                ref frame,
                half,
                cells,
            } => emit_ground(&mut out, frame, half, cells),
        }
        debug_assert_eq!((out.nv, out.nt), (out.v.len(), out.t.len()));
    }
}

/// A shape's output slices and how much of them is written.
struct Out<'a> {
    v: &'a mut [[f32; 3]],
    t: &'a mut [[u32; 3]],
    nv: usize,
    nt: usize,
    base: u32,
}

impl Out<'_> {
    /// Adds a vertex and returns its local index.
    fn vertex(&mut self, p: [f32; 3]) -> u32 {
        self.v[self.nv] = p;
        self.nv += 1;
        (self.nv - 1) as u32
    }
    fn tri(&mut self, a: u32, b: u32, c: u32) {
        self.t[self.nt] = [self.base + a, self.base + b, self.base + c];
        self.nt += 1;
    }
    /// Two triangles of the quad a, b, c, d (counter-clockwise).
    fn quad(&mut self, a: u32, b: u32, c: u32, d: u32) {
        self.tri(a, b, c);
        self.tri(a, c, d);
    }
}

/// `(sin, cos)` of `n` equal steps of a full turn.
fn circle(n: u32) -> Vec<(f64, f64)> {
    (0..n)
        .map(|j| (2.0 * PI * j as f64 / n as f64).sin_cos())
        .collect()
}

fn emit_sphere(out: &mut Out, f: &Frame, r: f64, stacks: u32, slices: u32) {
    let ring = circle(slices);
    let m = slices;
    let top = out.vertex(f.place([0.0, r, 0.0]));
    for i in 1..stacks {
        let (st, ct) = (PI * i as f64 / stacks as f64).sin_cos();
        for &(sp, cp) in &ring {
            out.vertex(f.place([r * st * cp, r * ct, -r * st * sp]));
        }
    }
    let bottom = out.vertex(f.place([0.0, -r, 0.0]));
    // Ring i (1-based) starts at 1 + (i - 1) * m; longitude runs counter-clockwise seen from +y.
    let at = |i: u32, j: u32| 1 + (i - 1) * m + j % m;
    for j in 0..m {
        out.tri(top, at(1, j), at(1, j + 1));
    }
    for i in 1..stacks - 1 {
        for j in 0..m {
            out.quad(at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
        }
    }
    for j in 0..m {
        out.tri(bottom, at(stacks - 1, j + 1), at(stacks - 1, j));
    }
}

fn emit_torus(out: &mut Out, f: &Frame, major: f64, minor: f64, rings: u32, sides: u32) {
    let around = circle(rings);
    let tube = circle(sides);
    for &(sp, cp) in &around {
        for &(sq, cq) in &tube {
            let d = major + minor * cq;
            out.vertex(f.place([d * cp, minor * sq, -d * sp]));
        }
    }
    let at = |i: u32, j: u32| (i % rings) * sides + j % sides;
    for i in 0..rings {
        for j in 0..sides {
            out.quad(at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
        }
    }
}

fn emit_cuboid(out: &mut Out, f: &Frame, half: P3, cells: [u32; 3]) {
    for a in 0..3 {
        let (b, c) = ((a + 1) % 3, (a + 2) % 3);
        let (kb, kc) = (cells[b], cells[c]);
        for sign in [1.0, -1.0] {
            let first = out.nv as u32;
            for i in 0..=kb {
                for j in 0..=kc {
                    let mut l = [0.0; 3];
                    l[a] = sign * half[a];
                    l[b] = half[b] * (2.0 * i as f64 / kb as f64 - 1.0);
                    l[c] = half[c] * (2.0 * j as f64 / kc as f64 - 1.0);
                    out.vertex(f.place(l));
                }
            }
            let at = |i: u32, j: u32| first + i * (kc + 1) + j;
            for i in 0..kb {
                for j in 0..kc {
                    // b x c = a, so this order faces +a; the -a face is wound the other way.
                    if sign > 0.0 {
                        out.quad(at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
                    } else {
                        out.quad(at(i, j), at(i, j + 1), at(i + 1, j + 1), at(i + 1, j));
                    }
                }
            }
        }
    }
}

fn emit_cylinder(out: &mut Out, f: &Frame, r: f64, length: f64, sides: u32, segments: u32) {
    let ring = circle(sides);
    for k in 0..=segments {
        let y = length * k as f64 / segments as f64;
        for &(s, c) in &ring {
            out.vertex(f.place([r * c, y, -r * s]));
        }
    }
    let bottom = out.vertex(f.place([0.0, 0.0, 0.0]));
    let top = out.vertex(f.place([0.0, length, 0.0]));
    let at = |k: u32, j: u32| k * sides + j % sides;
    for k in 0..segments {
        for j in 0..sides {
            out.quad(at(k, j), at(k, j + 1), at(k + 1, j + 1), at(k + 1, j));
        }
    }
    for j in 0..sides {
        out.tri(bottom, at(0, j + 1), at(0, j));
        out.tri(top, at(segments, j), at(segments, j + 1));
    }
}

fn emit_ground(out: &mut Out, f: &Frame, half: f64, cells: u32) {
    for i in 0..=cells {
        for j in 0..=cells {
            let x = half * (2.0 * i as f64 / cells as f64 - 1.0);
            let z = half * (2.0 * j as f64 / cells as f64 - 1.0);
            out.vertex(f.place([x, 0.0, z]));
        }
    }
    let at = |i: u32, j: u32| i * (cells + 1) + j;
    for i in 0..cells {
        for j in 0..cells {
            // Along +z then +x turns counter-clockwise seen from +y.
            out.quad(at(i, j), at(i, j + 1), at(i + 1, j + 1), at(i + 1, j));
        }
    }
}

/// Total (vertices, triangles) of a list of shapes.
pub(crate) fn total_counts(shapes: &[Shape]) -> (usize, usize) {
    shapes.iter().fold((0, 0), |(v, t), s| {
        let (a, b) = s.counts();
        (v + a, t + b)
    })
}

/// One mesh of all shapes, in list order, emitted in parallel.
pub(crate) fn assemble(shapes: &[Shape]) -> Mesh {
    let (nv, nt) = total_counts(shapes);
    assert!(
        nv <= u32::MAX as usize,
        "scene has more vertices than u32 indices can address"
    );
    let mut vertices = vec![[0f32; 3]; nv];
    let mut triangles = vec![[0u32; 3]; nt];
    let mut jobs = Vec::with_capacity(shapes.len());
    let (mut v_rest, mut t_rest) = (vertices.as_mut_slice(), triangles.as_mut_slice());
    let mut base = 0u32;
    for shape in shapes {
        let (cv, ct) = shape.counts();
        let (v, vr) = std::mem::take(&mut v_rest).split_at_mut(cv);
        let (t, tr) = std::mem::take(&mut t_rest).split_at_mut(ct);
        v_rest = vr;
        t_rest = tr;
        jobs.push((shape, v, t, base));
        base += cv as u32;
    }
    jobs.into_par_iter()
        .with_min_len(16)
        .for_each(|(shape, v, t, base)| shape.emit(v, t, base));
    Mesh {
        vertices,
        triangles,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Vec3;

    /// Every triangle's normal points away from `inside` (a point inside the convex solid).
    fn assert_outward(mesh: &Mesh, inside: P3) {
        mesh.validate().unwrap();
        for i in 0..mesh.triangles.len() {
            let t = mesh.triangle(i);
            let n = (t[1] - t[0]).cross(t[2] - t[0]);
            let centroid = (t[0] + t[1] + t[2]) * (1.0 / 3.0);
            let out = centroid - Vec3::new(inside[0] as f32, inside[1] as f32, inside[2] as f32);
            assert!(n.dot(out) > 0.0, "triangle {i} faces inwards: {t:?}");
        }
    }

    #[test]
    fn convex_shapes_are_closed_counted_and_wound_outwards() {
        let frame = Frame::with_up([1.0, 2.0, 3.0], [0.3, 1.0, -0.2], [0.0, 0.0, 1.0]);
        let shapes = [
            Shape::Sphere {
                frame,
                radius: 2.0,
                stacks: 5,
                slices: 7,
            },
            Shape::Cuboid {
                frame,
                half: [1.0, 2.0, 0.5],
                cells: [2, 3, 1],
            },
            Shape::Cylinder {
                frame,
                radius: 0.5,
                length: 4.0,
                sides: 6,
                segments: 3,
            },
        ];
        for s in &shapes {
            let mesh = assemble(std::slice::from_ref(s));
            assert_eq!(
                (mesh.vertices.len(), mesh.triangles.len()),
                s.counts(),
                "{s:?}"
            );
            let inside = match s {
                Shape::Cylinder { frame, .. } => add(frame.origin, scale(frame.ey, 2.0)),
                _ => frame.origin,
            };
            assert_outward(&mesh, inside);
            // Closed: every edge (by corner positions, as faces of a box share no indices)
            // is used by exactly two triangles, in opposite directions.
            let key = |i: u32| mesh.vertices[i as usize].map(f32::to_bits);
            let mut edges = std::collections::HashMap::new();
            for t in &mesh.triangles {
                for k in 0..3 {
                    *edges.entry((key(t[k]), key(t[(k + 1) % 3]))).or_insert(0) += 1;
                }
            }
            for (&(a, b), &n) in &edges {
                assert_eq!(n, 1, "{s:?}: edge {a:?}-{b:?} used {n} times");
                assert_eq!(
                    edges.get(&(b, a)),
                    Some(&1),
                    "{s:?}: edge {a:?}-{b:?} is open"
                );
            }
        }
    }

    #[test]
    fn sphere_vertices_lie_on_the_sphere() {
        let s = Shape::Sphere {
            frame: Frame::at([0.5, 0.0, -1.0]),
            radius: 3.0,
            stacks: 9,
            slices: 17,
        };
        let mesh = assemble(&[s]);
        for v in &mesh.vertices {
            let d = Vec3::new(v[0] - 0.5, v[1], v[2] + 1.0).length();
            assert!((d - 3.0).abs() < 1e-5, "{v:?}");
        }
    }

    #[test]
    fn sphere_tessellation_is_close_to_its_target() {
        for target in [6.0, 10.0, 40.0, 100.0, 1234.0, 1e5] {
            let (s, m) = sphere_tessellation(target);
            let t = 2.0 * m as f64 * (s as f64 - 1.0);
            assert!(t / target < 1.2 && target / t < 1.2, "{target}: {s}x{m}");
        }
    }
}
