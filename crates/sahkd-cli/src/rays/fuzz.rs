//! Fuzzing of the `.npy` ray and point readers, with the mesh readers' harness
//! (`crates/sahkd/tests/common/fuzz.rs`: counting allocator, watchdog, time budget, cases
//! rerun by number): valid (R, 6), (R, 8) and (N, 3) float32 files in every header version,
//! either byte order and either memory order must read as written; mutated (lying shapes,
//! dtypes, fortran_order, header lengths and versions, truncations, byte edits) they must
//! give the rays or a one-line error within the memory bound. Also the regression corpus
//! of `tests/corpus/`.

use super::{read, read_points};
use crate::fuzz_harness::{self as harness, case_rng, check_outcome, measured, mutate, Counting};
use rand::rngs::StdRng;
use rand::Rng;
use sahkd::{Ray, Vec3};
use std::path::{Path, PathBuf};

#[global_allocator]
static ALLOCATOR: Counting = Counting;

/// Words of a .npy header a mutation may swap for one another.
const NPY_WORDS: &[&str] = &[
    "<f4",
    ">f4",
    "<f8",
    "<i4",
    "|u1",
    "<f2",
    "|b1",
    "<c8",
    "O",
    "'shape'",
    "'descr'",
    "False",
    "True",
    "fortran_order",
    "(",
    ")",
    ",",
    "L",
];

/// A .npy file of `values` (rows x width, listed row by row) in the given header version,
/// byte order and memory order.
fn npy(
    values: &[f32],
    rows: usize,
    width: usize,
    version: u8,
    big: bool,
    fortran: bool,
) -> Vec<u8> {
    let descr = if big { ">f4" } else { "<f4" };
    let order = if fortran { "True" } else { "False" };
    let mut header =
        format!("{{'descr': '{descr}', 'fortran_order': {order}, 'shape': ({rows}, {width}), }}")
            .into_bytes();
    let prefix = if version == 1 { 10 } else { 12 };
    while (prefix + header.len() + 1) % 64 != 0 {
        header.push(b' ');
    }
    header.push(b'\n');
    let mut out = b"\x93NUMPY".to_vec();
    out.extend_from_slice(&[version, 0]);
    if version == 1 {
        out.extend_from_slice(&(header.len() as u16).to_le_bytes());
    } else {
        out.extend_from_slice(&(header.len() as u32).to_le_bytes());
    }
    out.extend_from_slice(&header);
    let at = |r: usize, c: usize| values[r * width + c];
    let order: Vec<f32> = if fortran {
        (0..width)
            .flat_map(|c| (0..rows).map(move |r| at(r, c)))
            .collect()
    } else {
        values.to_vec()
    };
    for v in order {
        out.extend_from_slice(&if big {
            v.to_be_bytes()
        } else {
            v.to_le_bytes()
        });
    }
    out
}

/// A random valid file: `(bytes, rows, width, values)`.
fn seed(rng: &mut StdRng) -> (Vec<u8>, usize, usize, Vec<f32>) {
    let rows = rng.random_range(0..5);
    let width = [3, 6, 8][rng.random_range(0..3)];
    let values: Vec<f32> = (0..rows * width)
        .map(|_| rng.random_range(-64..64) as f32 / 4.0)
        .collect();
    let version = rng.random_range(1..=3);
    let bytes = npy(
        &values,
        rows,
        width,
        version,
        rng.random_bool(0.3),
        rng.random_bool(0.3),
    );
    (bytes, rows, width, values)
}

/// The file each case is written to, in memory where the system offers it: on a disk the
/// writes made cases 30 times slower.
fn scratch() -> PathBuf {
    let shm = Path::new("/dev/shm");
    let base = if shm.is_dir() {
        shm.to_path_buf()
    } else {
        std::env::temp_dir()
    };
    let dir = base.join(format!("sahkd-npy-fuzz-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join("case.npy")
}

fn both_readers(path: &Path, len: usize) -> Result<(), String> {
    let (rays, usage) = measured(|| read(path).map_err(|e| format!("{e:#}")));
    check_outcome(len, &rays, usage).map_err(|e| format!("rays: {e}"))?;
    let (points, usage) = measured(|| read_points(path).map_err(|e| format!("{e:#}")));
    check_outcome(len, &points, usage).map_err(|e| format!("points: {e}"))
}

fn npy_case(case: u64) -> Result<(), String> {
    let mut rng = case_rng("npy", case);
    let (mut bytes, rows, width, values) = seed(&mut rng);
    let path = scratch();
    std::fs::write(&path, &bytes).unwrap();
    // The seed reads as written, by the reader of its width.
    let row = |r: usize| &values[r * width..(r + 1) * width];
    if width == 3 {
        let want: Vec<Vec3> = (0..rows)
            .map(|r| Vec3::new(row(r)[0], row(r)[1], row(r)[2]))
            .collect();
        let got = read_points(&path).map_err(|e| format!("seed: {e:#}"))?;
        if got != want {
            return Err(format!("seed reads as {got:?}, not {want:?}"));
        }
    } else {
        let want: Vec<Ray> = (0..rows)
            .map(|r| {
                let v = row(r);
                let ray = Ray::new(Vec3::new(v[0], v[1], v[2]), Vec3::new(v[3], v[4], v[5]));
                if width == 8 {
                    ray.with_range(v[6], v[7])
                } else {
                    ray
                }
            })
            .collect();
        let got = read(&path).map_err(|e| format!("seed: {e:#}"))?;
        if got != want {
            return Err(format!("seed reads as {got:?}, not {want:?}"));
        }
    }
    mutate(&mut rng, &mut bytes, NPY_WORDS);
    // The header length field (bytes 8..) lies now and then.
    if rng.random_bool(0.1) && bytes.len() > 10 {
        bytes[8 + rng.random_range(0..2)] = rng.random();
    }
    std::fs::write(&path, &bytes).unwrap();
    both_readers(&path, bytes.len())
}

#[test]
fn fuzz_npy() {
    assert!(harness::run("npy", npy_case) > 0);
    let _ = std::fs::remove_dir_all(scratch().parent().unwrap());
}

/// Every file of `tests/corpus/` with the outcome `expected.txt` records for it:
/// `name: ok N rays`, `name: ok N points` or `name: error: <part of the message>`.
#[test]
fn corpus_inputs_read_as_recorded() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/corpus");
    harness::check_corpus(&dir, |path, len, outcome| {
        both_readers(path, len).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        let got = if outcome.ends_with(" points") {
            read_points(path).map(|p| format!("ok {} points", p.len()))
        } else {
            read(path).map(|r| format!("ok {} rays", r.len()))
        };
        got.map_err(|e| format!("{e:#}"))
    });
}
