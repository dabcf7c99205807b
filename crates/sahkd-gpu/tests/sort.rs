//! The GPU sort against Rust's sort: exact equality for unique keys; for duplicate keys the
//! same key order and the same multiset of records (equal keys may come out in any order),
//! and the same output on every run.

mod common;

use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use sahkd_gpu::sort::{sort_records, Sort};
use std::time::Instant;

fn key(r: &[u32; 4]) -> [u32; 3] {
    [r[0], r[1], r[2]]
}

/// Sizes around the tile of 512 and the powers of two where the network grows a stage.
const SIZES: [usize; 21] = [
    0, 1, 2, 3, 5, 7, 31, 100, 255, 256, 257, 511, 512, 513, 1023, 1024, 1025, 4097, 12_345,
    65_537, 100_000,
];

/// Unique keys shaped like the level builder's: a small group, a float's order key, a
/// distinct tie-break.
fn unique(rng: &mut StdRng, n: usize) -> Vec<[u32; 4]> {
    let mut ids: Vec<u32> = (0..n as u32).collect();
    // Shuffled ids, so that the third word decides ties in a random order.
    for i in (1..n).rev() {
        ids.swap(i, rng.random_range(0..=i));
    }
    ids.iter()
        .map(|&id| [rng.random_range(0..8), rng.random(), id, rng.random()])
        .collect()
}

/// Few distinct values per word, among them the all-ones key the network's virtual records
/// carry past the end; the payload tells equal keys apart.
fn duplicates(rng: &mut StdRng, n: usize) -> Vec<[u32; 4]> {
    let values = [0, 1, 2, 0x8000_0000, u32::MAX];
    (0..n)
        .map(|i| {
            let mut w = || values[rng.random_range(0..values.len())];
            [w(), w(), w(), i as u32]
        })
        .collect()
}

#[test]
fn unique_keys_sort_like_rust() {
    let Some(gpu) = common::gpu() else { return };
    let sort = Sort::new(&gpu);
    let mut rng = StdRng::seed_from_u64(21);
    for n in SIZES {
        let records = unique(&mut rng, n);
        let mut expected = records.clone();
        expected.sort_unstable_by_key(key);
        assert_eq!(
            sort.sort_records(&gpu, &records).unwrap(),
            expected,
            "n = {n}"
        );
    }
}

#[test]
fn duplicate_keys_keep_order_and_records() {
    let Some(gpu) = common::gpu() else { return };
    let sort = Sort::new(&gpu);
    let mut rng = StdRng::seed_from_u64(22);
    for n in SIZES {
        let records = duplicates(&mut rng, n);
        let got = sort.sort_records(&gpu, &records).unwrap();
        let mut expected = records.clone();
        expected.sort_unstable_by_key(key);
        let keys = |v: &[[u32; 4]]| v.iter().map(key).collect::<Vec<_>>();
        assert_eq!(keys(&got), keys(&expected), "key order, n = {n}");
        let (mut a, mut b) = (got.clone(), records.clone());
        a.sort_unstable();
        b.sort_unstable();
        assert_eq!(a, b, "the same records, n = {n}");
        if n == 12_345 {
            assert_eq!(
                sort.sort_records(&gpu, &records).unwrap(),
                got,
                "deterministic"
            );
        }
    }
    // Only keys equal to the virtual maxima, an odd count.
    let ones: Vec<[u32; 4]> = (0..777)
        .map(|i| [u32::MAX, u32::MAX, u32::MAX, i])
        .collect();
    let mut got = sort.sort_records(&gpu, &ones).unwrap();
    got.sort_unstable();
    assert_eq!(got, ones);
}

#[test]
fn a_million_records() {
    let Some(gpu) = common::gpu() else { return };
    let mut rng = StdRng::seed_from_u64(23);
    let n = (1 << 20) + 4321;
    let records = unique(&mut rng, n);
    let mut expected = records.clone();
    expected.sort_unstable_by_key(key);
    let t = Instant::now();
    let got = sort_records(&gpu, &records).unwrap();
    eprintln!(
        "{n} records sorted in {:.0} ms",
        t.elapsed().as_secs_f64() * 1e3
    );
    assert!(got == expected, "1M records differ from Rust's sort");
}

#[test]
fn only_the_first_n_records_are_touched() {
    let Some(gpu) = common::gpu() else { return };
    let mut rng = StdRng::seed_from_u64(24);
    let records = unique(&mut rng, 3000);
    let n = 2000;
    let data = gpu.upload("records", records.as_flattened());
    let sort = Sort::new(&gpu);
    let mut encoder = gpu.encoder();
    sort.record(&gpu, &mut encoder, &data, n).unwrap();
    gpu.submit(encoder);
    let words = gpu.download::<u32>(&data, 4 * records.len()).unwrap();
    let got: Vec<[u32; 4]> = words
        .chunks_exact(4)
        .map(|w| [w[0], w[1], w[2], w[3]])
        .collect();
    let mut expected = records[..n].to_vec();
    expected.sort_unstable_by_key(key);
    expected.extend_from_slice(&records[n..]);
    assert_eq!(got, expected);
    // A buffer too small for n records is an error, not an out-of-bounds sort.
    let mut encoder = gpu.encoder();
    assert!(sort.record(&gpu, &mut encoder, &data, 3001).is_err());
}
