//! The one rule for worker-thread counts, shared by the library, the command line and Python.
//!
//! Far more threads than cores only costs: each rayon worker reserves a stack, and tens of
//! thousands of them take seconds to start (or never finish starting). So a count must be at
//! least 1 and at most [`MAX_PER_CORE`] times the cores this process may use, or [`FLOOR`],
//! whichever is larger: small machines can still run the paper's thread counts and the
//! determinism checks (a few dozen threads start in milliseconds).

/// How many workers per core a caller may ask for.
pub const MAX_PER_CORE: usize = 4;

/// The cap never falls below this, however few the cores.
pub const FLOOR: usize = 64;

/// The cores this process may use (1 when the system cannot say).
pub fn cores() -> usize {
    std::thread::available_parallelism().map_or(1, |n| n.get())
}

/// The largest thread count [`check`] accepts on this machine.
pub fn max_threads() -> usize {
    cap(cores())
}

fn cap(cores: usize) -> usize {
    (MAX_PER_CORE * cores).max(FLOOR)
}

/// `n` if it is a thread count this machine can run, else a one-line reason.
pub fn check(n: usize) -> Result<usize, String> {
    check_against(n, cores())
}

fn check_against(n: usize, cores: usize) -> Result<usize, String> {
    let max = cap(cores);
    match n {
        0 => Err("the number of threads must be at least 1".into()),
        n if n > max => Err(format!(
            "{n} threads is too many: at most {max} on this machine ({cores} core{}; the cap \
             is {MAX_PER_CORE} per core, and never below {FLOOR})",
            if cores == 1 { "" } else { "s" }
        )),
        n => Ok(n),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_up_to_four_per_core_or_the_floor_pass() {
        assert_eq!(check_against(1, 1), Ok(1));
        assert_eq!(check_against(64, 1), Ok(64));
        assert_eq!(check_against(128, 32), Ok(128));
        assert_eq!(check(max_threads()), Ok(max_threads()));
    }

    #[test]
    fn zero_and_too_many_are_refused_with_the_limit() {
        assert!(check_against(0, 2).unwrap_err().contains("at least 1"));
        let e = check_against(65, 2).unwrap_err();
        assert!(e.contains("65 threads") && e.contains("at most 64"), "{e}");
        let e = check_against(129, 32).unwrap_err();
        assert!(e.contains("at most 128") && e.contains("32 cores"), "{e}");
        assert!(check(max_threads() + 1).is_err());
        assert!(check(100_000).is_err());
    }
}
