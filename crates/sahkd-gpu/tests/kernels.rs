//! Every kernel against a plain Rust reference on random inputs: exact for integers, and bit
//! for bit for the f32 costs (the reference is the CPU builders' own `CostModel::split_cost`).

mod common;

use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use sahkd::{Aabb, CostModel, Vec3};
use sahkd_gpu::partition::{split_segments, Segment, LEFT, RIGHT};
use sahkd_gpu::price::{divide_bits, price_candidates, Layout};
use sahkd_gpu::scan::exclusive_scan;
use sahkd_gpu::segmin::{best_candidates, NONE};
use sahkd_gpu::GpuError;

#[test]
fn adapter_is_named_and_validation_errors_fail() {
    let Some(gpu) = common::gpu() else { return };
    assert!(!gpu.adapter.name.is_empty());
    assert!(
        gpu.max_binding >= 128 << 20,
        "bindings of {} bytes",
        gpu.max_binding
    );
    gpu.finish().expect("a fresh device has no errors");
    // Binding a mappable buffer as storage is a validation error: it must surface as an Err.
    let mappable = gpu.device.create_buffer(&wgpu::BufferDescriptor {
        label: None,
        size: 16,
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let scan = sahkd_gpu::scan::Scan::new(&gpu);
    let mut encoder = gpu.encoder();
    scan.record(&gpu, &mut encoder, &mappable, 4).unwrap();
    gpu.submit(encoder);
    match gpu.finish() {
        Err(GpuError::Runtime(e)) => assert!(e.contains("STORAGE") || e.contains("usage"), "{e}"),
        other => panic!("validation error not reported: {other:?}"),
    }
}

fn reference_scan(values: &[u32]) -> Vec<u32> {
    let mut sum = 0u32;
    values
        .iter()
        .map(|&v| {
            let before = sum;
            sum = sum.wrapping_add(v);
            before
        })
        .collect()
}

#[test]
fn exclusive_scan_matches_reference() {
    let Some(gpu) = common::gpu() else { return };
    let mut rng = StdRng::seed_from_u64(1);
    // Sizes around the block of 256 and its powers (one, two and three levels of sums).
    for n in [
        0, 1, 2, 255, 256, 257, 1000, 65_535, 65_536, 65_537, 200_003,
    ] {
        let values: Vec<u32> = (0..n).map(|_| rng.random_range(0..1000)).collect();
        assert_eq!(
            exclusive_scan(&gpu, &values).unwrap(),
            reference_scan(&values),
            "n = {n}"
        );
    }
    // Sums wrap like u32::wrapping_add.
    let big: Vec<u32> = (0..5000).map(|_| rng.random()).collect();
    assert_eq!(exclusive_scan(&gpu, &big).unwrap(), reference_scan(&big));
}

/// Candidates laid out like the level builder's: axis 0's block, then 1's, then 2's; inside
/// each, every node's run (possibly empty), some slots holes.
struct Level {
    nodes: usize,
    layout: Layout,
    owner: Vec<u32>,
}

fn random_level(rng: &mut StdRng, nodes: usize, max_run: usize) -> Level {
    let mut owner = Vec::new();
    let mut firsts = [0; 3];
    for first in &mut firsts {
        *first = owner.len();
        for k in 0..nodes {
            for _ in 0..rng.random_range(0..=max_run) {
                let hole = rng.random_bool(0.2);
                owner.push(if hole { u32::MAX } else { k as u32 });
            }
        }
    }
    Level {
        nodes,
        layout: Layout {
            n: owner.len(),
            first1: firsts[1],
            first2: firsts[2],
        },
        owner,
    }
}

fn axis_of(layout: &Layout, i: usize) -> usize {
    (i >= layout.first1) as usize + (i >= layout.first2) as usize
}

#[test]
fn segmented_min_matches_reference() {
    let Some(gpu) = common::gpu() else { return };
    let mut rng = StdRng::seed_from_u64(2);
    for (nodes, max_run) in [(1, 3000), (7, 200), (500, 40), (3000, 6)] {
        let level = random_level(&mut rng, nodes, max_run);
        let n = level.layout.n;
        // Few distinct costs and positions, so that ties on both are common.
        let cost: Vec<f32> = (0..n)
            .map(|_| [1.0, 2.5, 3.0, f32::INFINITY][rng.random_range(0..4)])
            .collect();
        let pos: Vec<f32> = (0..n)
            .map(|_| [-2.0, -0.5, 0.0, 0.25, 7.0][rng.random_range(0..5)])
            .collect();
        // The CPU's order: cheaper, then smaller position, then lower axis; first of equals.
        let mut best: Vec<Option<usize>> = vec![None; nodes];
        for i in 0..n {
            let k = level.owner[i];
            if k == u32::MAX {
                continue;
            }
            let slot = &mut best[k as usize];
            let better = match *slot {
                None => true,
                Some(j) => {
                    cost[i] < cost[j]
                        || (cost[i] == cost[j]
                            && (pos[i] < pos[j]
                                || (pos[i] == pos[j]
                                    && axis_of(&level.layout, i) < axis_of(&level.layout, j))))
                }
            };
            if better {
                *slot = Some(i);
            }
        }
        let expected: Vec<u32> = best.iter().map(|b| b.map_or(NONE, |i| i as u32)).collect();
        let got = best_candidates(&gpu, &cost, &pos, &level.owner, nodes).unwrap();
        assert_eq!(got, expected, "{nodes} nodes");
    }
}

/// A float of random sign-less magnitude: random significand, exponent over the whole normal
/// range and some subnormals.
fn random_positive(rng: &mut StdRng) -> u32 {
    let exponent = rng.random_range(0..255u32);
    (exponent << 23) | rng.random_range(0..1u32 << 23)
}

#[test]
fn division_is_correctly_rounded() {
    let Some(gpu) = common::gpu() else { return };
    let mut rng = StdRng::seed_from_u64(3);
    let mut pairs: Vec<[u32; 2]> = (0..200_000)
        .map(|_| {
            let (a, b) = (random_positive(&mut rng), random_positive(&mut rng));
            let signs: u32 = rng.random_range(0..4);
            [a | (signs & 1) << 31, b | (signs >> 1) << 31]
        })
        .filter(|[_, b]| b & 0x7fff_ffff != 0)
        .collect();
    // The cost model's own divisions: 1 / extent, and ratios of nearby magnitudes (halfway
    // cases and results near 1, where a 1-ulp error would show).
    for _ in 0..50_000 {
        let b = rng.random_range(0x3000_0000..0x5000_0000u32);
        pairs.push([1.0f32.to_bits(), b]);
        let a = b.wrapping_add(rng.random_range(0..64)) ^ rng.random_range(0..2) << 23;
        pairs.push([a, b]);
    }
    let got = divide_bits(&gpu, &pairs).unwrap();
    for (&[a, b], q) in pairs.iter().zip(got) {
        let expected = (f32::from_bits(a) / f32::from_bits(b)).to_bits();
        assert_eq!(
            q,
            expected,
            "{:e} / {:e}: {:e} instead of {:e}",
            f32::from_bits(a),
            f32::from_bits(b),
            f32::from_bits(q),
            f32::from_bits(expected)
        );
    }
}

/// The level builder's pricing rule on the CPU, through the CPU's `split_cost`.
fn reference_price(
    model: &CostModel,
    node: &Aabb,
    axis: usize,
    pos: f32,
    c: [u32; 3],
) -> (f32, u32) {
    let pos = pos + 0.0;
    let finite = |x: f32| if x.is_nan() { f32::INFINITY } else { x };
    let [l, r, p] = c;
    let left = finite(model.split_cost(node, axis, pos, l + p, r));
    let (cost, planar_left) = if p == 0 {
        (left, true)
    } else {
        let right = finite(model.split_cost(node, axis, pos, l, r + p));
        if left <= right {
            (left, true)
        } else {
            (right, false)
        }
    };
    (cost, (l + r + p) << 1 | planar_left as u32)
}

fn random_box(rng: &mut StdRng) -> Aabb {
    let scale = 10f32.powi(rng.random_range(-30..=30));
    let mut lo = [0.0; 3];
    let mut hi = [0.0; 3];
    for a in 0..3 {
        let x: f32 = rng.random_range(-1.0..1.0) * scale;
        // Some flat or tiny extents, most ordinary.
        let extent = match rng.random_range(0..10) {
            0 => 0.0,
            1 => scale * 1e-6,
            _ => rng.random_range(0.0..2.0) * scale,
        };
        lo[a] = x;
        hi[a] = x + extent;
    }
    Aabb::new(Vec3(lo), Vec3(hi))
}

#[test]
fn candidate_costs_are_bit_identical_to_the_cpu() {
    let Some(gpu) = common::gpu() else { return };
    let mut rng = StdRng::seed_from_u64(4);
    let models = [
        CostModel::default(),
        CostModel {
            traversal: 1.0,
            intersection: 1.5,
            empty_bonus: 1.0,
            ..CostModel::default()
        },
    ];
    for model in &models {
        let level = random_level(&mut rng, 4000, 12);
        let boxes: Vec<Aabb> = (0..level.nodes).map(|_| random_box(&mut rng)).collect();
        let n = level.layout.n;
        let pos: Vec<f32> = (0..n)
            .map(|i| {
                let k = level.owner[i];
                if k == u32::MAX {
                    return 0.0;
                }
                let b = &boxes[k as usize];
                let axis = axis_of(&level.layout, i);
                let (lo, hi) = (b.lo[axis], b.hi[axis]);
                match rng.random_range(0..12) {
                    0 => lo,
                    1 => hi,
                    2 => -0.0,
                    3 => lo - (hi - lo),
                    _ => lo + (hi - lo) * rng.random_range(0.0..1.0f32),
                }
            })
            .collect();
        let counts: Vec<[u32; 3]> = (0..n)
            .map(|_| {
                let planar = if rng.random_bool(0.3) {
                    rng.random_range(1..50)
                } else {
                    0
                };
                let l = if rng.random_bool(0.1) {
                    0
                } else {
                    rng.random_range(0..100_000)
                };
                let r = if rng.random_bool(0.1) {
                    0
                } else {
                    rng.random_range(0..100_000)
                };
                [l, r, planar]
            })
            .collect();
        let (cost, packed) = price_candidates(
            &gpu,
            model,
            &boxes,
            level.layout,
            &pos,
            &level.owner,
            &counts,
        )
        .unwrap();
        let (mut finite, mut priced) = (0, 0);
        for i in 0..n {
            let k = level.owner[i];
            if k == u32::MAX {
                assert_eq!((cost[i], packed[i]), (f32::INFINITY, 0), "hole {i}");
                continue;
            }
            let axis = axis_of(&level.layout, i);
            let (c, p) = reference_price(model, &boxes[k as usize], axis, pos[i], counts[i]);
            assert_eq!(
                (cost[i].to_bits(), packed[i]),
                (c.to_bits(), p),
                "candidate {i}: axis {axis} at {:e} in {:?}, counts {:?}: {:e} instead of {c:e}",
                pos[i],
                boxes[k as usize],
                counts[i],
                cost[i]
            );
            finite += c.is_finite() as usize;
            priced += 1;
        }
        // The comparison must have been about real costs, not mostly infinities.
        assert!(finite > priced / 2, "{finite} finite costs of {priced}");
    }
}

#[test]
fn stable_partition_matches_reference() {
    let Some(gpu) = common::gpu() else { return };
    let mut rng = StdRng::seed_from_u64(5);
    for (segments, max_len) in [(1, 100_000), (50, 2000), (20_000, 8)] {
        let mut values = Vec::new();
        let mut owner = Vec::new();
        let mut side = Vec::new();
        let mut layout = Vec::new();
        let mut expected: Vec<u32> = Vec::new();
        for s in 0..segments {
            let first = values.len() as u32;
            let len = rng.random_range(0..=max_len);
            let mut left = Vec::new();
            let mut right = Vec::new();
            for _ in 0..len {
                let v: u32 = rng.random();
                let bits = [LEFT, RIGHT, LEFT | RIGHT, 0][rng.random_range(0..4)];
                values.push(v);
                owner.push(s as u32);
                side.push(bits);
                if bits & LEFT != 0 {
                    left.push(v);
                }
                if bits & RIGHT != 0 {
                    right.push(v);
                }
            }
            let left_out = expected.len() as u32;
            expected.extend(&left);
            let right_out = expected.len() as u32;
            expected.extend(&right);
            layout.push(Segment {
                first,
                left_out,
                right_out,
                pad: 0,
            });
        }
        let got = split_segments(&gpu, &values, &owner, &side, &layout, expected.len()).unwrap();
        assert_eq!(got, expected, "{segments} segments");
    }
}

#[test]
fn launches_beyond_65535_workgroups_reach_every_index() {
    let Some(gpu) = common::gpu() else { return };
    // 17M threads: 65 535 x 2 workgroups of 256; only candidates past the first row of
    // workgroups (index >= 65 535 * 256) are real, so a wrong 2-D index loses them.
    let n = 17_000_000;
    let first_row = 65_535 * 256;
    let mut owner = vec![u32::MAX; n];
    let mut cost = vec![0.0f32; n];
    let pos = vec![1.0f32; n];
    let picks = [first_row, first_row + 1, n - 2, n - 1];
    for (k, &i) in picks.iter().enumerate() {
        owner[i] = k as u32;
        cost[i] = k as f32;
    }
    let got = best_candidates(&gpu, &cost, &pos, &owner, picks.len()).unwrap();
    assert_eq!(got, picks.map(|i| i as u32));
}
