//! Points, vectors, boxes and triangles in single precision.
//!
//! Everything in a kd-tree is indexed by axis, so `Vec3` is a thin wrapper around `[f32; 3]`
//! with `v[axis]` access rather than named fields.

use std::ops::{Add, Index, IndexMut, Mul, Sub};

/// A point or direction in 3-D, indexed by axis (0 = x, 1 = y, 2 = z).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Vec3(pub [f32; 3]);

impl Vec3 {
    pub const fn new(x: f32, y: f32, z: f32) -> Self {
        Vec3([x, y, z])
    }
    pub const fn splat(s: f32) -> Self {
        Vec3([s, s, s])
    }
    pub fn min(self, o: Vec3) -> Vec3 {
        Vec3([self[0].min(o[0]), self[1].min(o[1]), self[2].min(o[2])])
    }
    pub fn max(self, o: Vec3) -> Vec3 {
        Vec3([self[0].max(o[0]), self[1].max(o[1]), self[2].max(o[2])])
    }
    pub fn dot(self, o: Vec3) -> f32 {
        self[0] * o[0] + self[1] * o[1] + self[2] * o[2]
    }
    pub fn cross(self, o: Vec3) -> Vec3 {
        Vec3([
            self[1] * o[2] - self[2] * o[1],
            self[2] * o[0] - self[0] * o[2],
            self[0] * o[1] - self[1] * o[0],
        ])
    }
    pub fn length(self) -> f32 {
        self.dot(self).sqrt()
    }
    pub fn normalized(self) -> Vec3 {
        self * (1.0 / self.length())
    }
    pub fn is_finite(self) -> bool {
        self.0.iter().all(|c| c.is_finite())
    }
}

impl Index<usize> for Vec3 {
    type Output = f32;
    #[inline(always)]
    fn index(&self, axis: usize) -> &f32 {
        &self.0[axis]
    }
}
impl IndexMut<usize> for Vec3 {
    #[inline(always)]
    fn index_mut(&mut self, axis: usize) -> &mut f32 {
        &mut self.0[axis]
    }
}
impl Add for Vec3 {
    type Output = Vec3;
    fn add(self, o: Vec3) -> Vec3 {
        Vec3([self[0] + o[0], self[1] + o[1], self[2] + o[2]])
    }
}
impl Sub for Vec3 {
    type Output = Vec3;
    fn sub(self, o: Vec3) -> Vec3 {
        Vec3([self[0] - o[0], self[1] - o[1], self[2] - o[2]])
    }
}
impl Mul<f32> for Vec3 {
    type Output = Vec3;
    fn mul(self, s: f32) -> Vec3 {
        Vec3([self[0] * s, self[1] * s, self[2] * s])
    }
}
impl From<[f32; 3]> for Vec3 {
    fn from(a: [f32; 3]) -> Self {
        Vec3(a)
    }
}

/// An axis-aligned box. The empty box has `lo = +inf`, `hi = -inf` so that `union` needs no
/// special case.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    pub lo: Vec3,
    pub hi: Vec3,
}

impl Aabb {
    pub const EMPTY: Aabb = Aabb {
        lo: Vec3::splat(f32::INFINITY),
        hi: Vec3::splat(f32::NEG_INFINITY),
    };

    pub fn new(lo: Vec3, hi: Vec3) -> Self {
        Aabb { lo, hi }
    }
    pub fn of_points(points: &[Vec3]) -> Aabb {
        points.iter().fold(Aabb::EMPTY, |b, &p| b.grow(p))
    }
    pub fn grow(self, p: Vec3) -> Aabb {
        Aabb {
            lo: self.lo.min(p),
            hi: self.hi.max(p),
        }
    }
    pub fn union(self, o: Aabb) -> Aabb {
        Aabb {
            lo: self.lo.min(o.lo),
            hi: self.hi.max(o.hi),
        }
    }
    pub fn intersection(self, o: Aabb) -> Aabb {
        Aabb {
            lo: self.lo.max(o.lo),
            hi: self.hi.min(o.hi),
        }
    }
    /// True when the box contains no point (a flat box, `lo == hi` on an axis, is not empty;
    /// a NaN bound makes it empty).
    pub fn is_empty(&self) -> bool {
        (0..3).any(|a| {
            self.lo[a]
                .partial_cmp(&self.hi[a])
                .is_none_or(|o| o.is_gt())
        })
    }
    pub fn extent(&self) -> Vec3 {
        self.hi - self.lo
    }
    pub fn longest_axis(&self) -> usize {
        let d = self.extent();
        // Ties go to the lower axis, so the choice is reproducible.
        if d[0] >= d[1] && d[0] >= d[2] {
            0
        } else if d[1] >= d[2] {
            1
        } else {
            2
        }
    }
    /// In f64 from f64 differences, so that boxes spanning more than the float32 range
    /// (+-3e38) have a finite area.
    pub fn surface_area(&self) -> f64 {
        if self.is_empty() {
            return 0.0;
        }
        let d = |a: usize| self.hi[a] as f64 - self.lo[a] as f64;
        let (x, y, z) = (d(0), d(1), d(2));
        2.0 * (x * y + y * z + z * x)
    }
    /// The box with both corners multiplied by `s`.
    pub fn scaled(&self, s: f32) -> Aabb {
        Aabb {
            lo: self.lo * s,
            hi: self.hi * s,
        }
    }
    pub fn centre(&self) -> Vec3 {
        (self.lo + self.hi) * 0.5
    }
    pub fn diagonal(&self) -> f32 {
        self.extent().length()
    }
    /// The two halves of the box cut by the plane `axis = pos`.
    pub fn split(&self, axis: usize, pos: f32) -> (Aabb, Aabb) {
        let mut left = *self;
        let mut right = *self;
        left.hi[axis] = pos;
        right.lo[axis] = pos;
        (left, right)
    }
}

/// Scenes whose largest extent lies in `[2^-SCALE_WINDOW, 2^(SCALE_WINDOW + 1))` are built
/// and traced in their own coordinates.
pub const SCALE_WINDOW: i32 = 20;

/// The power of two the builder and the ray queries multiply a scene's coordinates (and ray
/// origins) by: 1 for scenes whose largest extent is within [`SCALE_WINDOW`], so that their
/// trees and answers are those of their own coordinates; for others, the power that brings
/// the largest extent into `[1, 2)`. Multiplying by a power of two is exact, so the scaled
/// scene is the scene; what it avoids is float32 products of coordinates (the watertight
/// test's edge functions and distance, squares and cubes of the scene's size) overflowing
/// beyond 1e38 or losing bits below 1e-38. Kept within `[2^-126, 2^126]`, so that both it
/// and its inverse are normal floats.
pub fn scene_scale(bounds: &Aabb) -> f32 {
    if bounds.is_empty() {
        return 1.0;
    }
    let extent = (0..3)
        .map(|a| bounds.hi[a] as f64 - bounds.lo[a] as f64)
        .fold(0.0f64, f64::max);
    if !(extent > 0.0 && extent.is_finite()) {
        return 1.0;
    }
    // The binary exponent of a normal f64 (every difference of two float32 is one).
    let exponent = ((extent.to_bits() >> 52) & 0x7ff) as i32 - 1023;
    if exponent.abs() <= SCALE_WINDOW {
        return 1.0;
    }
    f32::from_bits(((127 - exponent.clamp(-126, 126)) as u32) << 23)
}

/// A triangle as its three corners.
pub type Triangle = [Vec3; 3];

pub fn triangle_bounds(t: &Triangle) -> Aabb {
    Aabb::of_points(t)
}
