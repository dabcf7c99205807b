//! How much memory the machine can still give, so that a size the user asks for is refused
//! up front with a clear error instead of aborting the process on a failed allocation.

/// Bytes this process can still get: the least of what the system can give without swapping
/// (`MemAvailable`), what the address-space limit (`RLIMIT_AS`, `ulimit -v`) leaves beside
/// the address space in use, and what the memory limit of the process's cgroup and of each
/// cgroup above it (v2 `memory.max`, v1 `memory.limit_in_bytes`) leaves beside its use.
/// `None` where none of them can be read (not Linux), and no check is made there.
pub fn available_bytes() -> Option<u64> {
    available().map(|(bytes, _)| bytes)
}

/// [`available_bytes`] with what sets it, for messages.
fn available() -> Option<(u64, &'static str)> {
    let read = |path: &str| std::fs::read_to_string(path).ok();
    let meminfo = read("/proc/meminfo")
        .and_then(|t| parse_meminfo(&t))
        .map(|b| (b, "memory available"));
    let address_space = address_space_limit().map(|limit| {
        let used = read("/proc/self/status")
            .and_then(|t| status_kib(&t, "VmSize:"))
            .unwrap_or(0);
        (
            limit.saturating_sub(used),
            "memory the address-space limit (RLIMIT_AS) leaves",
        )
    });
    let cgroup = read("/proc/self/cgroup")
        .and_then(|t| cgroup_left(&t, &|p| read(p)))
        .map(|b| (b, "memory the cgroup's memory limit leaves"));
    [meminfo, address_space, cgroup]
        .into_iter()
        .flatten()
        .min_by_key(|&(bytes, _)| bytes)
}

fn parse_meminfo(text: &str) -> Option<u64> {
    status_kib(text, "MemAvailable:")
}

/// A `NAME:  value kB` line of /proc/meminfo or /proc/self/status, in bytes.
fn status_kib(text: &str, name: &str) -> Option<u64> {
    let line = text.lines().find(|l| l.starts_with(name))?;
    let mut words = line.split_whitespace().skip(1);
    let value: u64 = words.next()?.parse().ok()?;
    match words.next() {
        Some("kB") => value.checked_mul(1024),
        _ => None,
    }
}

/// The soft address-space limit, if any.
#[cfg(target_os = "linux")]
fn address_space_limit() -> Option<u64> {
    let mut limit = libc::rlimit {
        rlim_cur: 0,
        rlim_max: 0,
    };
    // SAFETY: getrlimit writes one rlimit into the struct it is given.
    let ok = unsafe { libc::getrlimit(libc::RLIMIT_AS, &mut limit) } == 0;
    (ok && limit.rlim_cur != libc::RLIM_INFINITY).then_some(limit.rlim_cur as u64)
}

#[cfg(not(target_os = "linux"))]
fn address_space_limit() -> Option<u64> {
    None
}

/// The least room left under the memory limits of the process's cgroups (`cgroup` is
/// /proc/self/cgroup), each folder up to the hierarchy's root; `read` reads a file. A limit
/// of "max" (v2) or beyond 2^62 (v1's "none") is no limit.
fn cgroup_left(cgroup: &str, read: &dyn Fn(&str) -> Option<String>) -> Option<u64> {
    let mut least: Option<u64> = None;
    for line in cgroup.lines() {
        let mut fields = line.splitn(3, ':');
        let (Some(id), Some(controllers), Some(path)) =
            (fields.next(), fields.next(), fields.next())
        else {
            continue;
        };
        let (root, limit_file, usage_file, inactive) = if id == "0" && controllers.is_empty() {
            (
                "/sys/fs/cgroup",
                "memory.max",
                "memory.current",
                "inactive_file ",
            )
        } else if controllers.split(',').any(|c| c == "memory") {
            (
                "/sys/fs/cgroup/memory",
                "memory.limit_in_bytes",
                "memory.usage_in_bytes",
                "total_inactive_file ",
            )
        } else {
            continue;
        };
        let mut dir = path.trim_end_matches('/').to_string();
        loop {
            let at = |file: &str| {
                read(&format!("{root}{dir}/{file}")).and_then(|t| t.trim().parse::<u64>().ok())
            };
            if let Some(limit) = at(limit_file).filter(|&l| l < 1 << 62) {
                // The use counts the page cache; what of it is inactive the kernel gives back
                // before it refuses an allocation.
                let cache = read(&format!("{root}{dir}/memory.stat"))
                    .and_then(|t| {
                        let line = t.lines().find(|l| l.starts_with(inactive))?;
                        line[inactive.len()..].trim().parse::<u64>().ok()
                    })
                    .unwrap_or(0);
                let used = at(usage_file).unwrap_or(0).saturating_sub(cache);
                let left = limit.saturating_sub(used);
                least = Some(least.map_or(left, |l| l.min(left)));
            }
            match dir.rfind('/') {
                Some(i) => dir.truncate(i),
                None => break,
            }
        }
    }
    least
}

/// Fails with a one-line reason when `needed` bytes (for `what`) exceed what is available
/// ([`available_bytes`]).
pub fn check_available(needed: u64, what: &str) -> Result<(), String> {
    match available() {
        Some((available, why)) if needed > available => Err(format!(
            "{what} needs about {}, more than the {} of {why}",
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
    fn cgroup_limits_are_read_up_to_the_root_in_either_version() {
        let files: std::collections::HashMap<&str, &str> = [
            ("/sys/fs/cgroup/a/b/memory.max", "max\n"),
            ("/sys/fs/cgroup/a/b/memory.current", "100\n"),
            ("/sys/fs/cgroup/a/memory.max", "1000\n"),
            ("/sys/fs/cgroup/a/memory.current", "500\n"),
            (
                "/sys/fs/cgroup/a/memory.stat",
                "active_file 9\ninactive_file 200\n",
            ),
            ("/sys/fs/cgroup/memory/p/memory.limit_in_bytes", "5000\n"),
            ("/sys/fs/cgroup/memory/p/memory.usage_in_bytes", "4000\n"),
            (
                "/sys/fs/cgroup/memory/memory.limit_in_bytes",
                "9223372036854771712\n",
            ),
        ]
        .into_iter()
        .collect();
        let read = |p: &str| files.get(p).map(|t| t.to_string());
        assert_eq!(cgroup_left("0::/a/b\n", &read), Some(700));
        assert_eq!(cgroup_left("4:memory:/p\n1:cpu:/\n", &read), Some(1000));
        assert_eq!(cgroup_left("4:memory:/p\n0::/a/b\n", &read), Some(700));
        assert_eq!(cgroup_left("0::/\n", &read), None);
        assert_eq!(cgroup_left("4:memory:/\n", &read), None);
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
