//! What a pixel shows: the colour of a hit under each shading mode, and the background.
//!
//! Colours are display values in [0, 1]. Normal shading maps the normal straight to colour;
//! the lit modes compute a light intensity and apply a display gamma of 2.2.

use crate::geometry::{Triangle, Vec3};
use crate::trace::{Hit, Ray};
use serde::{Deserialize, Serialize};

/// How hits are coloured.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Shading {
    /// The geometric normal, turned to face the camera, as colour (n + 1) / 2. Primary rays
    /// only.
    #[default]
    Normal,
    /// Ambient occlusion: the share of `ao_samples` cosine-weighted rays per hit that leave
    /// without hitting anything within the AO distance.
    Ao,
    /// A headlight plus a fixed sun with a shadow ray.
    Diffuse,
}

impl Shading {
    pub const ALL: [Shading; 3] = [Shading::Normal, Shading::Ao, Shading::Diffuse];

    pub fn name(self) -> &'static str {
        match self {
            Shading::Normal => "normal",
            Shading::Ao => "ao",
            Shading::Diffuse => "diffuse",
        }
    }
}

impl std::str::FromStr for Shading {
    type Err = String;
    fn from_str(s: &str) -> Result<Shading, String> {
        Shading::ALL
            .into_iter()
            .find(|m| m.name() == s)
            .ok_or_else(|| format!("unknown shading '{s}': expected normal, ao or diffuse"))
    }
}

/// Direction towards the sun of diffuse shading, (-1, 2, 0.5) normalised: high, from the
/// left of both cameras, so that shadows fall to the right where they can be seen.
pub const SUN_DIRECTION: Vec3 = Vec3::new(-0.436_435_8, 0.872_871_6, 0.218_217_9);
/// Surface colour of the lit modes.
const ALBEDO: [f32; 3] = [0.85, 0.82, 0.76];
// Darker than the lit albedo at the horizon, so that pale models stand out from the sky.
const SKY_TOP: [f32; 3] = [0.3, 0.45, 0.72];
const SKY_BOTTOM: [f32; 3] = [0.74, 0.79, 0.86];

/// The background seen along a ray: a plain gradient from pale at and below the horizon
/// to blue straight up.
pub fn background(ray: &Ray) -> [f32; 3] {
    let d = ray.direction.normalized();
    let t = d[1].clamp(0.0, 1.0);
    [0, 1, 2].map(|c| SKY_BOTTOM[c] + (SKY_TOP[c] - SKY_BOTTOM[c]) * t)
}

/// The triangle's unit geometric normal on the side the ray comes from. A triangle too thin
/// for its normal to be computed in f32 faces the ray head on.
pub fn facing_normal(triangle: &Triangle, ray: &Ray) -> Vec3 {
    let [a, b, c] = *triangle;
    let n = (b - a).cross(c - a);
    let length = n.length();
    if !(length > 0.0 && length.is_finite()) {
        return ray.direction.normalized() * -1.0;
    }
    let n = n * (1.0 / length);
    if n.dot(ray.direction) > 0.0 {
        n * -1.0
    } else {
        n
    }
}

/// Where rays leaving a hit start, and the unit normal of the side the ray came from: the hit
/// point moved off its surface by `offset` plus a few f32 steps of its position, so that the
/// new rays do not hit the triangle they leave.
pub fn surface_origin(triangle: &Triangle, ray: &Ray, hit: &Hit, offset: f32) -> (Vec3, Vec3) {
    let normal = facing_normal(triangle, ray);
    let [a, b, c] = *triangle;
    let p = a * (1.0 - hit.u - hit.v) + b * hit.u + c * hit.v;
    let magnitude = p[0].abs().max(p[1].abs()).max(p[2].abs());
    (
        p + normal * (offset + 8.0 * f32::EPSILON * magnitude),
        normal,
    )
}

/// Normal shading of a hit triangle: `(n + 1) / 2` for the normal facing the ray.
pub fn normal_colour(triangle: &Triangle, ray: &Ray) -> [f32; 3] {
    let n = facing_normal(triangle, ray);
    [0, 1, 2].map(|c| 0.5 * n[c] + 0.5)
}

/// The colour of a lit surface of light intensity `intensity` (1 = fully lit).
pub(crate) fn lit(intensity: f32) -> [f32; 3] {
    ALBEDO.map(|a| (a * intensity).max(0.0).powf(1.0 / 2.2))
}

/// Diffuse intensity: some ambient, a headlight along the view ray, and the sun when the
/// shadow ray is free (`sun_cosine` is 0 when the surface faces away from the sun).
pub(crate) fn diffuse_intensity(normal: Vec3, ray: &Ray, sun_cosine: f32, sunlit: bool) -> f32 {
    let headlight = -normal.dot(ray.direction.normalized());
    let sun = if sunlit { sun_cosine } else { 0.0 };
    // At most 1: a surface facing both the eye and the sun is lit, not clipped white.
    0.08 + 0.25 * headlight.max(0.0) + 0.67 * sun
}

/// A display colour in bytes: clamped to [0, 1], scaled to 255 and rounded.
pub fn to_rgb8(colour: [f32; 3]) -> [u8; 3] {
    colour.map(|c| (c.clamp(0.0, 1.0) * 255.0 + 0.5) as u8)
}
