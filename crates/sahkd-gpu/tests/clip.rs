//! The GPU's software f64 against the CPU's f64 arithmetic, bit for bit.

mod common;

use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use sahkd_gpu::clip::f64_ops;

#[test]
fn soft_f64_matches_the_cpu() {
    let Some(gpu) = common::gpu() else { return };
    let mut rng = StdRng::seed_from_u64(7);
    // Any finite f64 with an exponent in `exp` (unbiased), sign and mantissa random.
    let any = |rng: &mut StdRng, exp: std::ops::RangeInclusive<i32>| {
        let e = rng.random_range(exp) + 1023;
        let m = rng.random::<u64>() & ((1 << 52) - 1);
        f64::from_bits((rng.random::<u64>() & 1 << 63) | (e.clamp(0, 2046) as u64) << 52 | m)
    };
    let f32_any = |rng: &mut StdRng| loop {
        let f = f32::from_bits(rng.random());
        if f.is_finite() {
            return f;
        }
    };
    let specials = [
        0.0,
        -0.0,
        1.0,
        -1.0,
        0.5,
        f64::MIN_POSITIVE,
        -f64::MIN_POSITIVE,
        f64::from_bits(1),
        f64::from_bits(0x000f_ffff_ffff_ffff),
        f64::MAX,
        -f64::MAX,
        f32::MAX as f64,
        f32::MIN_POSITIVE as f64,
        f32::from_bits(1) as f64,
        1.0 + f64::EPSILON,
        1.0 - f64::EPSILON / 2.0,
    ];
    let mut cases = Vec::new();
    for &a in &specials {
        for &b in &specials {
            cases.push((a, b, a as f32));
        }
    }
    for i in 0..200_000 {
        let (a, b) = match i % 6 {
            // What the clip sees: f32 values, their differences, products and quotients.
            0 => {
                let (x, y) = (f32_any(&mut rng) as f64, f32_any(&mut rng) as f64);
                (x, y)
            }
            1 => {
                let x = f32_any(&mut rng) as f64;
                let y = f32_any(&mut rng) as f64;
                let z = rng.random::<f32>() as f64;
                ((x - y) / (x + y), z * (x - y))
            }
            // Close values: cancellation, ties in rounding, equal magnitudes.
            2 => {
                let x = any(&mut rng, -20..=20);
                let k = rng.random_range(-3i64..=3);
                let y = f64::from_bits((x.to_bits() as i64 + k) as u64);
                let y = if rng.random() { -y } else { y };
                (x, y)
            }
            3 => {
                let x = any(&mut rng, -60..=60);
                let y = any(&mut rng, -60..=60);
                (x, y)
            }
            // Whole exponent range: overflow to infinity, gradual underflow, subnormal inputs.
            4 => (any(&mut rng, -1075..=1023), any(&mut rng, -1075..=1023)),
            // Around the f32 range, for the directed roundings to f32.
            _ => (any(&mut rng, -155..=130), any(&mut rng, -30..=30)),
        };
        if a.is_finite() && b.is_finite() {
            cases.push((a, b, f32_any(&mut rng)));
        }
    }
    let out = f64_ops(&gpu, &cases).unwrap();
    let same = |x: f64, y: f64| x.to_bits() == y.to_bits();
    for (&(a, b, c), g) in cases.iter().zip(&out) {
        let ctx = format!(
            "a = {a:e} ({:#x}), b = {b:e} ({:#x})",
            a.to_bits(),
            b.to_bits()
        );
        assert!(
            same(g.add, a + b),
            "{ctx}: a + b = {:e}, not {:e}",
            a + b,
            g.add
        );
        assert!(
            same(g.sub, a - b),
            "{ctx}: a - b = {:e}, not {:e}",
            a - b,
            g.sub
        );
        assert!(
            same(g.mul, a * b),
            "{ctx}: a * b = {:e}, not {:e}",
            a * b,
            g.mul
        );
        if b != 0.0 {
            assert!(
                same(g.div, a / b),
                "{ctx}: a / b = {:e}, not {:e}",
                a / b,
                g.div
            );
        }
        // The clip's rule between -0 and +0: the first argument stays.
        let min = if b < a { b } else { a };
        let max = if b > a { b } else { a };
        assert!(same(g.min, min) && same(g.max, max), "{ctx}: min/max");
        assert_eq!(
            [g.lt, g.le, g.ge, g.eq],
            [a < b, a <= b, a >= b, a == b],
            "{ctx}: comparisons"
        );
        assert_eq!(g.down.to_bits(), round_down(a).to_bits(), "{ctx}: down");
        assert_eq!(g.up.to_bits(), round_up(a).to_bits(), "{ctx}: up");
        assert!(same(g.widened, c as f64), "{c:e} as f64");
    }
    eprintln!("{} cases of every soft-f64 operation equal", cases.len());
}

// The CPU clip's outward roundings (private in sahkd::clip), restated.
fn round_down(x: f64) -> f32 {
    let f = x as f32;
    if (f as f64) > x {
        f.next_down()
    } else {
        f
    }
}

fn round_up(x: f64) -> f32 {
    let f = x as f32;
    if (f as f64) < x {
        f.next_up()
    } else {
        f
    }
}
