//! Per-pixel random numbers and hemisphere directions.
//!
//! Every random number of a picture is a hash of (pixel, sample, dimension), so a pixel
//! looks the same whichever thread renders it and in whatever order.

use crate::geometry::Vec3;
use crate::scenes::random::{hash3, unit_f32};

const SEED: u64 = 0x7265_6e64_6572;

/// The random numbers of one sample of one pixel.
#[derive(Clone, Copy)]
pub(crate) struct SampleRng {
    key: u64,
}

impl SampleRng {
    pub(crate) fn new(pixel: u64, sample: u32) -> SampleRng {
        SampleRng {
            key: hash3(SEED, pixel, sample as u64),
        }
    }
    /// Uniform in [0, 1) for dimension `dim`.
    pub(crate) fn get(&self, dim: u64) -> f32 {
        unit_f32(hash3(self.key, dim, 0))
    }
}

/// Two unit vectors that make a right-handed orthonormal basis with unit `n`.
pub(crate) fn tangents(n: Vec3) -> (Vec3, Vec3) {
    let t = if n[0].abs() > n[2].abs() {
        Vec3::new(-n[1], n[0], 0.0)
    } else {
        Vec3::new(0.0, -n[2], n[1])
    }
    .normalized();
    (t, n.cross(t))
}

/// A direction in the hemisphere around unit `n`, cosine-weighted, from two uniform numbers:
/// a uniform point on the unit disc lifted to the hemisphere.
pub(crate) fn cosine_direction(n: Vec3, u1: f32, u2: f32) -> Vec3 {
    let (t, b) = tangents(n);
    let r = u1.sqrt();
    let phi = 2.0 * std::f32::consts::PI * u2;
    let z = (1.0 - u1).max(0.0).sqrt();
    (t * (r * phi.cos()) + b * (r * phi.sin()) + n * z).normalized()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cosine_directions_stay_in_the_hemisphere_with_mean_cosine_two_thirds() {
        let n = Vec3::new(0.3, -0.8, 0.52).normalized();
        let count = 20_000;
        let mut sum = 0.0f64;
        for i in 0..count {
            let rng = SampleRng::new(i, 3);
            let d = cosine_direction(n, rng.get(0), rng.get(1));
            assert!((d.length() - 1.0).abs() < 1e-5);
            let c = d.dot(n);
            assert!(c >= -1e-6, "{d:?}");
            sum += c as f64;
        }
        // E[cos] under the density cos / pi is 2/3.
        assert!(
            (sum / count as f64 - 2.0 / 3.0).abs() < 0.01,
            "{}",
            sum / count as f64
        );
    }
}
