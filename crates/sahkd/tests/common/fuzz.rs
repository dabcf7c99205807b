//! The fuzzing harness of `tests/fuzz.rs`, on stable Rust: a counting global allocator, a
//! watchdog per case, a time budget, and byte mutations of small valid seeds.
//!
//! Cases are numbered; case `i` of a target draws everything from a generator seeded with
//! `i`, so a failure names the case and `SAHKD_FUZZ_CASE=i` runs that case alone. The time
//! budget only decides how many cases run: `SAHKD_FUZZ_SECONDS` per target (default 20: three targets, about 60 s in CI),
//! or `SAHKD_FUZZ_CASES` cases per target.

use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::io::Write;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc;
use std::time::{Duration, Instant};

/// The global allocator of the test binary: counts, on the thread that runs a case and only
/// while it does, the largest single request and the peak of live bytes.
pub struct Counting;

/// A single request above this aborts the process at once, after naming the case: larger
/// ones are what a lying header produces, and actually making them could take the machine.
const HARD_LIMIT: usize = 256 << 20;

thread_local! {
    static ARMED: Cell<bool> = const { Cell::new(false) };
    static LARGEST: Cell<usize> = const { Cell::new(0) };
    static LIVE: Cell<isize> = const { Cell::new(0) };
    static PEAK: Cell<isize> = const { Cell::new(0) };
}

/// The case running now, for the message of an aborting allocation.
static CURRENT: AtomicU64 = AtomicU64::new(u64::MAX);

/// Accounts for `grow` more live bytes in a request of `size`; false to refuse it.
fn account(size: usize, grow: isize) -> bool {
    let armed = ARMED.try_with(Cell::get).unwrap_or(false);
    if !armed {
        return true;
    }
    let _ = LARGEST.try_with(|l| l.set(l.get().max(size)));
    let _ = LIVE.try_with(|live| {
        live.set(live.get() + grow);
        let _ = PEAK.try_with(|p| p.set(p.get().max(live.get())));
    });
    if size > HARD_LIMIT {
        // No allocation here: the number is formatted on the stack.
        let mut digits = [0u8; 20];
        let mut n = CURRENT.load(Ordering::Relaxed);
        let mut at = digits.len();
        loop {
            at -= 1;
            digits[at] = b'0' + (n % 10) as u8;
            n /= 10;
            if n == 0 {
                break;
            }
        }
        let mut err = std::io::stderr();
        let _ = err.write_all(b"\nfuzz: a single allocation above 256 MiB in case ");
        let _ = err.write_all(&digits[at..]);
        let _ = err.write_all(b" (rerun it with SAHKD_FUZZ_CASE=that number)\n");
        return false;
    }
    true
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if !account(layout.size(), layout.size() as isize) {
            return std::ptr::null_mut();
        }
        unsafe { System.alloc(layout) }
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        if !account(layout.size(), layout.size() as isize) {
            return std::ptr::null_mut();
        }
        unsafe { System.alloc_zeroed(layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        if !account(new_size, new_size as isize - layout.size() as isize) {
            return std::ptr::null_mut();
        }
        unsafe { System.realloc(ptr, layout, new_size) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        if ARMED.try_with(Cell::get).unwrap_or(false) {
            let _ = LIVE.try_with(|live| live.set(live.get() - layout.size() as isize));
        }
        unsafe { System.dealloc(ptr, layout) }
    }
}

/// The memory a case used: the largest single request and the peak of live bytes.
#[derive(Clone, Copy, Debug)]
pub struct Usage {
    pub largest: usize,
    pub peak: usize,
}

/// Runs `f` with the allocator counting on this thread.
pub fn measured<T>(f: impl FnOnce() -> T) -> (T, Usage) {
    LARGEST.with(|l| l.set(0));
    LIVE.with(|l| l.set(0));
    PEAK.with(|p| p.set(0));
    ARMED.with(|a| a.set(true));
    let out = f();
    ARMED.with(|a| a.set(false));
    let usage = Usage {
        largest: LARGEST.with(Cell::get),
        peak: PEAK.with(Cell::get).max(0) as usize,
    };
    (out, usage)
}

/// The memory a reader may use on `len` bytes of input: a small floor, then a fixed factor
/// (a polygon of one-byte indices becomes 12 bytes a triangle, and vectors grow by doubling).
pub fn memory_bound(len: usize) -> usize {
    (64 << 10) + 64 * len
}

/// What a case must never take longer than; cases take microseconds.
pub const CASE_LIMIT: Duration = Duration::from_secs(10);

fn env_number(name: &str) -> Option<u64> {
    let value = std::env::var(name).ok()?;
    Some(
        value
            .trim()
            .parse()
            .unwrap_or_else(|_| panic!("{name}={value} is not a number")),
    )
}

/// The generator of case `case` of target `target`.
pub fn case_rng(target: &str, case: u64) -> StdRng {
    let salt = target.bytes().fold(0xcbf29ce484222325u64, |h, b| {
        (h ^ b as u64).wrapping_mul(0x100000001b3)
    });
    StdRng::seed_from_u64(salt ^ case.wrapping_mul(0x9e3779b97f4a7c15))
}

/// Runs cases 0, 1, 2, ... of `target` on a worker thread within the time budget (or the
/// one case `SAHKD_FUZZ_CASE`), each under the watchdog; `case(i)` returns `Err(why)` when
/// the property fails. Panics naming the first failing case; returns the number of cases.
pub fn run(target: &'static str, case: fn(u64) -> Result<(), String>) -> u64 {
    let (first, last) = match env_number("SAHKD_FUZZ_CASE") {
        Some(i) => (i, i + 1),
        None => (0, env_number("SAHKD_FUZZ_CASES").unwrap_or(u64::MAX)),
    };
    let seconds = env_number("SAHKD_FUZZ_SECONDS").unwrap_or(20);
    let deadline = Instant::now() + Duration::from_secs(seconds);
    let (to_worker, cases) = mpsc::channel::<u64>();
    let (to_main, results) = mpsc::channel::<(u64, Result<(), String>)>();
    std::thread::Builder::new()
        .name(format!("fuzz {target}"))
        .spawn(move || {
            for i in cases {
                CURRENT.store(i, Ordering::Relaxed);
                let outcome = std::panic::catch_unwind(|| case(i)).unwrap_or_else(|panic| {
                    let text = panic
                        .downcast_ref::<String>()
                        .cloned()
                        .or_else(|| panic.downcast_ref::<&str>().map(|s| s.to_string()))
                        .unwrap_or_default();
                    Err(format!("panicked: {text}"))
                });
                if to_main.send((i, outcome)).is_err() {
                    return;
                }
            }
        })
        .unwrap();
    let mut done = 0;
    for i in first..last {
        if i > first && Instant::now() > deadline {
            break;
        }
        to_worker.send(i).unwrap();
        match results.recv_timeout(CASE_LIMIT) {
            Ok((_, Ok(()))) => done += 1,
            Ok((_, Err(why))) => {
                panic!("fuzz {target}: case {i} fails (rerun with SAHKD_FUZZ_CASE={i}): {why}")
            }
            Err(_) => panic!(
                "fuzz {target}: case {i} still runs after {CASE_LIMIT:?} \
                 (rerun with SAHKD_FUZZ_CASE={i})"
            ),
        }
    }
    eprintln!("fuzz {target}: {done} cases passed");
    done
}

/// Checks a reader's answer on bad input: an error is one line of text, and the memory it
/// used is within the bound for the input's size.
pub fn check_outcome<T>(
    input_len: usize,
    outcome: &Result<T, String>,
    usage: Usage,
) -> Result<(), String> {
    if let Err(message) = outcome {
        if message.trim().is_empty() || message.contains('\n') {
            return Err(format!(
                "an error that is not one line of text: {message:?}"
            ));
        }
    }
    let bound = memory_bound(input_len);
    if usage.largest > bound || usage.peak > bound {
        return Err(format!(
            "{} bytes of input took a {} byte allocation and {} live bytes (bound {bound})",
            input_len, usage.largest, usage.peak
        ));
    }
    Ok(())
}

// ---------------------------------------------------------------------------------------
// Mutations

/// Numbers a lying header or index tends to hold.
const INTERESTING: &[&str] = &[
    "0",
    "1",
    "2",
    "-1",
    "255",
    "256",
    "65535",
    "2147483647",
    "2147483648",
    "4294967295",
    "4294967296",
    "9223372036854775807",
    "18446744073709551615",
    "18446744073709551616",
    "100000000000000000000",
    "1e39",
    "-1e39",
    "nan",
    "inf",
    "0.5",
];

/// Byte fragments worth inserting into text formats.
const FRAGMENTS: &[&[u8]] = &[
    b" ",
    b"\n",
    b"\r\n",
    b"\t",
    b"\\\n",
    b"/",
    b"//",
    b"-",
    b"#",
    b"\0",
    b"\xff",
    b"\xc3",
    b" 0",
    b" -1",
    b"f ",
    b"v ",
    b"end_header\n",
    b"element ",
    b"property ",
    b"list ",
];

/// The spans of the decimal numbers (with sign) in `bytes`.
fn numbers(bytes: &[u8]) -> Vec<(usize, usize)> {
    let mut spans = Vec::new();
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i].is_ascii_digit() {
            let start = if i > 0 && bytes[i - 1] == b'-' {
                i - 1
            } else {
                i
            };
            while i < bytes.len() && bytes[i].is_ascii_digit() {
                i += 1;
            }
            spans.push((start, i));
        } else {
            i += 1;
        }
    }
    spans
}

/// Applies 1 to 4 random edits: truncation, byte flips and sets, insertions, deletions,
/// duplicated chunks, numbers replaced by lying ones, and whole words swapped for others of
/// the same format (`swaps`, such as PLY type names).
pub fn mutate(rng: &mut StdRng, bytes: &mut Vec<u8>, swaps: &[&str]) {
    // Mostly one edit: the formats are strict, and each further edit makes it likelier that
    // the reader stops at the first one.
    for _ in 0..[1, 1, 1, 2, 3, 4][rng.random_range(0..6)] {
        let len = bytes.len();
        let at = rng.random_range(0..=len);
        match rng.random_range(0..10) {
            0 => bytes.truncate(at),
            1 if len > 0 => {
                let i = rng.random_range(0..len);
                bytes[i] ^= 1 << rng.random_range(0..8);
            }
            2 if len > 0 => {
                let i = rng.random_range(0..len);
                bytes[i] =
                    [0, 0xff, 0x7f, 0x80, b'\n', b' ', b'-', b'9', b'/'][rng.random_range(0..9)];
            }
            3 => {
                let fragment = FRAGMENTS[rng.random_range(0..FRAGMENTS.len())];
                bytes.splice(at..at, fragment.iter().copied());
            }
            4 => {
                let n = rng.random_range(1..8);
                let random: Vec<u8> = (0..n).map(|_| rng.random()).collect();
                bytes.splice(at..at, random);
            }
            5 => {
                let end = rng.random_range(at..=len.min(at + 16));
                bytes.drain(at..end);
            }
            6 => {
                let end = rng.random_range(at..=len.min(at + 64));
                let chunk = bytes[at..end].to_vec();
                let to = rng.random_range(0..=len);
                bytes.splice(to..to, chunk);
            }
            7 | 8 => {
                let spans = numbers(bytes);
                if !spans.is_empty() {
                    let (s, e) = spans[rng.random_range(0..spans.len())];
                    let new = INTERESTING[rng.random_range(0..INTERESTING.len())];
                    bytes.splice(s..e, new.bytes());
                }
            }
            _ if !swaps.is_empty() => {
                let from = swaps[rng.random_range(0..swaps.len())].as_bytes();
                let to = swaps[rng.random_range(0..swaps.len())].as_bytes();
                if let Some(i) = bytes.windows(from.len()).position(|w| w == from) {
                    bytes.splice(i..i + from.len(), to.iter().copied());
                }
            }
            _ => {}
        }
    }
}

/// Checks every file of a regression corpus: `dir/expected.txt` lists `name: outcome` lines
/// (`#` comments and blank lines aside); `read(path, size, outcome)` reads the file as its
/// target does (the recorded outcome may say how, e.g. as points or as rays), giving `Ok(summary)` (compared with the outcome as written) or `Err(message)` (which
/// must contain the part after an outcome's `error: `). A file of the folder that is not
/// listed fails too, so none is kept without a check.
pub fn check_corpus(
    dir: &std::path::Path,
    read: impl Fn(&std::path::Path, usize, &str) -> Result<String, String>,
) {
    let expected = std::fs::read_to_string(dir.join("expected.txt")).unwrap();
    let mut listed = Vec::new();
    for line in expected
        .lines()
        .filter(|l| !l.trim().is_empty() && !l.starts_with('#'))
    {
        let (name, outcome) = line
            .split_once(": ")
            .unwrap_or_else(|| panic!("bad line {line:?}"));
        listed.push(name.to_string());
        let path = dir.join(name);
        let size = std::fs::metadata(&path)
            .unwrap_or_else(|e| panic!("{name}: {e}"))
            .len();
        match (
            read(&path, size as usize, outcome),
            outcome.strip_prefix("error: "),
        ) {
            (Err(e), Some(part)) => assert!(e.contains(part), "{name}: {e:?} lacks {part:?}"),
            (Ok(got), None) => assert_eq!(got, outcome, "{name}"),
            (got, _) => panic!("{name}: expected {outcome:?}, got {got:?}"),
        }
    }
    for entry in std::fs::read_dir(dir).unwrap() {
        let name = entry.unwrap().file_name().to_string_lossy().into_owned();
        assert!(
            name == "expected.txt" || listed.contains(&name),
            "{name} is in the corpus folder but not in expected.txt"
        );
    }
}
