//! The pinhole camera: where it stands, where it looks, and the ray through each pixel.

use crate::geometry::{Aabb, Vec3};
use crate::trace::Ray;
use crate::tree::KdTree;

/// A pinhole camera. `up` need not be perpendicular to the view direction, only not parallel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    pub eye: Vec3,
    pub look_at: Vec3,
    pub up: Vec3,
    pub fov_y_degrees: f32,
}

/// The narrowest aspect ratio (width / height) `Camera::auto` frames the scene for.
const LANDSCAPE: f32 = 4.0 / 3.0;

/// Bounds with a usable centre and size: an empty or non-finite box becomes the unit cube,
/// and a single point gets a size of 1.
fn usable(bounds: Aabb) -> (Vec3, f32) {
    if bounds.is_empty() || !bounds.lo.is_finite() || !bounds.hi.is_finite() {
        return (Vec3::splat(0.5), 3f32.sqrt());
    }
    let d = bounds.diagonal();
    (bounds.centre(), if d > 0.0 { d } else { 1.0 })
}

impl Camera {
    /// The fixed benchmark camera: eye at the box centre + (0, 0, 2 x diagonal), looking at
    /// the centre, up +y, 45 degree vertical field of view. (An empty box is taken as the unit
    /// cube, a point as having diagonal 1.)
    pub fn front(bounds: Aabb) -> Camera {
        let (centre, diagonal) = usable(bounds);
        Camera {
            eye: centre + Vec3::new(0.0, 0.0, 2.0 * diagonal),
            look_at: centre,
            up: Vec3::new(0.0, 1.0, 0.0),
            fov_y_degrees: 45.0,
        }
    }

    /// The benchmark camera at 0.75 diagonals instead of 2: the scene fills most of the
    /// picture, so most primary rays hit.
    pub fn near(bounds: Aabb) -> Camera {
        let (centre, diagonal) = usable(bounds);
        Camera {
            eye: centre + Vec3::new(0.0, 0.0, 0.75 * diagonal),
            ..Camera::front(bounds)
        }
    }

    /// A pleasant three-quarter view of the whole box: looking down 30 degrees from the +z
    /// side turned 35 degrees towards +x, 40 degree vertical field of view, placed as close
    /// as it can be with all 8 corners of the box inside a 4:3 landscape picture (or a wider
    /// one), the box centred in the picture. The scene fills the frame, so most primary rays
    /// hit.
    pub fn auto(bounds: Aabb) -> Camera {
        let (centre, diagonal) = usable(bounds);
        let (lo, hi) = if bounds.is_empty() || !bounds.lo.is_finite() || !bounds.hi.is_finite() {
            (Vec3::splat(0.0), Vec3::splat(1.0))
        } else {
            (bounds.lo, bounds.hi)
        };
        let corners = (0..8).map(|k| {
            Vec3::new(
                if k & 1 == 0 { lo[0] } else { hi[0] },
                if k & 2 == 0 { lo[1] } else { hi[1] },
                if k & 4 == 0 { lo[2] } else { hi[2] },
            )
        });
        three_quarter(centre, diagonal, corners, 1.0)
    }

    /// The camera `sahkd render` calls `auto`, fitted to the tree's own triangles rather than
    /// their box. For a scene around its box's centre (a building seen from inside, such as
    /// Sponza, where the outside view shows only a closed box), a view from inside; else
    /// the three-quarter view of [`Camera::auto`] moved as close as it can be with every
    /// vertex inside the picture and a small margin, centred on the vertices' projected
    /// extent rather than on the box (boxes of tilted or one-sided models are mostly empty).
    pub fn framing(tree: &KdTree) -> Camera {
        let bounds = tree.bounds();
        let (centre, diagonal) = usable(bounds);
        let triangles = tree.triangles();
        if triangles.is_empty() {
            return Camera::auto(bounds);
        }
        if let Some(inside) = inside_view(tree, centre) {
            return inside;
        }
        let vertices = triangles.iter().flat_map(|t| t.iter().copied());
        three_quarter(centre, diagonal, vertices, FRAMING_MARGIN)
    }
    /// The ray through the point (px, py) of a width x height picture, in pixel units from
    /// the top-left corner, y down (pixel (i, j) has its centre at (i + 0.5, j + 0.5)). The
    /// direction is unit length, so hit distances are distances from the eye.
    pub fn primary_ray(&self, width: u32, height: u32, px: f32, py: f32) -> Ray {
        Projection::new(self, width, height).ray(px, py)
    }
}

/// The share of the picture's half-width and half-height `Camera::framing` fills.
const FRAMING_MARGIN: f32 = 0.92;
/// Directions `inside_view` probes from the box's centre.
const PROBES: usize = 256;
/// A scene encloses its centre when at least this share of the probes hit a triangle that
/// faces the centre (as a room's walls do; the inside of a closed object faces away).
const ENCLOSED: f32 = 0.8;

/// The three-quarter view of `auto` as close as it can be with every point inside the middle
/// `margin` of a 4:3 (or wider) picture, the points' projected extent centred.
fn three_quarter(
    centre: Vec3,
    diagonal: f32,
    points: impl Iterator<Item = Vec3> + Clone,
    margin: f32,
) -> Camera {
    let (azimuth, elevation) = (35f32.to_radians(), 30f32.to_radians());
    let back = Vec3::new(
        azimuth.sin() * elevation.cos(),
        elevation.sin(),
        azimuth.cos() * elevation.cos(),
    );
    let fov_y_degrees = 40.0f32;
    let forward = back * -1.0;
    let right = forward.cross(Vec3::new(0.0, 1.0, 0.0)).normalized();
    let up = right.cross(forward);
    let tan = (0.5 * fov_y_degrees).to_radians().tan() * margin;
    // The eye is centre + back * d + right * sx + up * sy. A point at offset q from the
    // centre is in view when |q.right - sx| <= tan_x (q.forward + d), and likewise for
    // up. Per axis, the least d is reached with the shift halfway between the limits.
    let fit = |axis: Vec3, tan: f32| {
        let (mut upper, mut lower) = (f32::NEG_INFINITY, f32::INFINITY);
        for p in points.clone() {
            let q = p - centre;
            upper = upper.max(q.dot(axis) - tan * q.dot(forward));
            lower = lower.min(q.dot(axis) + tan * q.dot(forward));
        }
        ((upper - lower) / (2.0 * tan), 0.5 * (upper + lower))
    };
    let (d_across, shift_across) = fit(right, tan * LANDSCAPE);
    let (d_up, shift_up) = fit(up, tan);
    // Never inside the box, whatever its shape.
    let distance = d_across.max(d_up).max(0.75 * diagonal);
    // The shifts centre the points at each axis's own least distance; at a greater one,
    // perspective moves them off centre, so centre them again at the distance chosen.
    let (shift_across, shift_up) = if margin < 1.0 {
        (
            centred_shift(points.clone(), centre, right, forward, distance),
            centred_shift(points, centre, up, forward, distance),
        )
    } else {
        (shift_across, shift_up)
    };
    let target = centre + right * shift_across + up * shift_up;
    Camera {
        eye: target + back * distance,
        look_at: target,
        up: Vec3::new(0.0, 1.0, 0.0),
        fov_y_degrees,
    }
}

/// The shift s along `axis` that centres the points in the picture of an eye at distance
/// `distance`: their screen coordinates (q.axis - s) / (q.forward + distance) range
/// symmetrically about 0. Both extremes decrease as s grows, so bisection finds it.
fn centred_shift(
    points: impl Iterator<Item = Vec3>,
    centre: Vec3,
    axis: Vec3,
    forward: Vec3,
    distance: f32,
) -> f32 {
    let projected: Vec<(f32, f32)> = points
        .map(|p| {
            let q = p - centre;
            (q.dot(axis), q.dot(forward) + distance)
        })
        .collect();
    let (mut lo, mut hi) = projected
        .iter()
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &(a, _)| {
            (lo.min(a), hi.max(a))
        });
    for _ in 0..40 {
        let s = 0.5 * (lo + hi);
        let (least, most) =
            projected
                .iter()
                .fold((f32::INFINITY, f32::NEG_INFINITY), |(l, m), &(a, depth)| {
                    let x = (a - s) / depth;
                    (l.min(x), m.max(x))
                });
        if least + most > 0.0 {
            lo = s;
        } else {
            hi = s;
        }
    }
    0.5 * (lo + hi)
}

/// A view from inside when the scene surrounds the centre of its box, `None` otherwise.
/// The eye backs away from the centre along the longer horizontal axis, as far as a fifth
/// of the box's length or most of the way to the first wall, and looks across the centre
/// with a wide (60 degree) field of view.
fn inside_view(tree: &KdTree, centre: Vec3) -> Option<Camera> {
    let triangles = tree.triangles();
    let mut facing = 0;
    for k in 0..PROBES {
        // Fibonacci sphere: evenly spread, deterministic directions.
        let z = 1.0 - (2 * k + 1) as f32 / PROBES as f32;
        let phi = k as f32 * std::f32::consts::PI * (3.0 - 5f32.sqrt());
        let r = (1.0 - z * z).max(0.0).sqrt();
        let direction = Vec3::new(r * phi.cos(), r * phi.sin(), z);
        if let Some(hit) = tree.intersect(&Ray::new(centre, direction)) {
            let [a, b, c] = triangles[hit.prim as usize];
            if (b - a).cross(c - a).dot(direction) < 0.0 {
                facing += 1;
            }
        }
    }
    if (facing as f32) < ENCLOSED * PROBES as f32 {
        return None;
    }
    let extent = tree.bounds().extent();
    let axis = if extent[0] >= extent[2] {
        Vec3::new(1.0, 0.0, 0.0)
    } else {
        Vec3::new(0.0, 0.0, 1.0)
    };
    let length = extent[0].max(extent[2]);
    let wall = tree
        .intersect(&Ray::new(centre, axis * -1.0))
        .map_or(f32::INFINITY, |h| h.t);
    let back = (0.2 * length).min(0.8 * wall);
    Some(Camera {
        eye: centre - axis * back,
        look_at: centre,
        up: Vec3::new(0.0, 1.0, 0.0),
        fov_y_degrees: 60.0,
    })
}

/// A camera's per-picture constants, so that a renderer need not recompute the view basis
/// for every ray. `Camera::primary_ray` goes through it too: both give the same bits.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Projection {
    eye: Vec3,
    forward: Vec3,
    right: Vec3,
    up: Vec3,
    width: f32,
    height: f32,
}

impl Projection {
    pub(crate) fn new(camera: &Camera, width: u32, height: u32) -> Projection {
        let forward = (camera.look_at - camera.eye).normalized();
        let right = forward.cross(camera.up).normalized();
        let up = right.cross(forward);
        let tan = (0.5 * camera.fov_y_degrees).to_radians().tan();
        let aspect = width as f32 / height as f32;
        Projection {
            eye: camera.eye,
            forward,
            right: right * (tan * aspect),
            up: up * tan,
            width: width as f32,
            height: height as f32,
        }
    }

    pub(crate) fn ray(&self, px: f32, py: f32) -> Ray {
        let x = 2.0 * px / self.width - 1.0;
        let y = 1.0 - 2.0 * py / self.height;
        let direction = (self.forward + self.right * x + self.up * y).normalized();
        Ray::new(self.eye, direction)
    }
}
