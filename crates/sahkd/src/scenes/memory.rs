//! How much memory the machine can still give, so that a size the user asks for is refused
//! up front with a clear error instead of aborting the process on a failed allocation.

/// Bytes the system says it can give without swapping (`MemAvailable` on Linux); `None`
/// where it cannot say, and no check is made there.
pub fn available_bytes() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    parse_meminfo(&text)
}

fn parse_meminfo(text: &str) -> Option<u64> {
    let line = text.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let mut words = line.split_whitespace().skip(1);
    let value: u64 = words.next()?.parse().ok()?;
    match words.next() {
        Some("kB") => value.checked_mul(1024),
        _ => None,
    }
}

/// Fails with a one-line reason when `needed` bytes (for `what`) exceed what is available.
pub fn check_available(needed: u64, what: &str) -> Result<(), String> {
    match available_bytes() {
        Some(available) if needed > available => Err(format!(
            "{what} needs about {}, more than the {} of memory available",
            gib(needed),
            gib(available)
        )),
        _ => Ok(()),
    }
}

fn gib(bytes: u64) -> String {
    format!("{:.1} GiB", bytes as f64 / (1u64 << 30) as f64)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn meminfo_is_read_in_bytes() {
        let text = "MemTotal:       24000000 kB\nMemFree:  100 kB\nMemAvailable:   2048 kB\n";
        assert_eq!(parse_meminfo(text), Some(2048 * 1024));
        assert_eq!(parse_meminfo("MemTotal: 5 kB\n"), None);
    }

    #[test]
    fn more_than_there_is_is_refused() {
        if let Some(available) = available_bytes() {
            let e = check_available(available.saturating_mul(4), "the test").unwrap_err();
            assert!(e.starts_with("the test needs about"), "{e}");
            check_available(1 << 10, "a kilobyte").unwrap();
        }
    }
}
