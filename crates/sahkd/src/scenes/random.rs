//! Counter-based random numbers: every value is a hash of its coordinates (seed, index, ...),
//! so any part of a scene or image can be made on any thread, in any order, and come out the
//! same bit for bit. The mixing function is the splitmix64 finaliser.

/// A well-mixed 64-bit value of `z` (bijective, so distinct keys give distinct values).
#[inline]
pub(crate) fn mix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// The hash of a key of three numbers.
#[inline]
pub(crate) fn hash3(seed: u64, a: u64, b: u64) -> u64 {
    mix(mix(mix(seed) ^ a) ^ b)
}

/// A uniform number in `[0, 1)` from the top 53 bits of `h`.
#[inline]
pub(crate) fn unit_f64(h: u64) -> f64 {
    (h >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
}

/// A uniform number in `[0, 1)` from the top 24 bits of `h`.
#[inline]
pub(crate) fn unit_f32(h: u64) -> f32 {
    (h >> 40) as f32 * (1.0 / (1u32 << 24) as f32)
}

/// A sequence of numbers for code that draws them one after another (scene layout).
pub(crate) struct Stream {
    seed: u64,
    counter: u64,
}

impl Stream {
    pub(crate) fn new(seed: u64) -> Stream {
        Stream { seed, counter: 0 }
    }
    /// Uniform in `[0, 1)`.
    pub(crate) fn next(&mut self) -> f64 {
        self.counter += 1;
        unit_f64(hash3(self.seed, self.counter, 0))
    }
    /// Uniform in `[lo, hi)`.
    pub(crate) fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.next()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unit_values_are_in_range_and_roughly_uniform() {
        let n = 100_000;
        let mut buckets = [0u32; 10];
        for i in 0..n {
            let x = unit_f64(hash3(7, i, 3));
            assert!((0.0..1.0).contains(&x));
            let y = unit_f32(hash3(7, i, 4));
            assert!((0.0..1.0).contains(&y));
            buckets[(x * 10.0) as usize] += 1;
        }
        for b in buckets {
            assert!((b as i64 - 10_000).abs() < 500, "{buckets:?}");
        }
    }
}
