//! The process's peak resident memory, for the `peak_resident_bytes` of the JSON reports: the
//! whole pipeline (mesh, builder's arrays, tree, trace layout, answers) as the OS counted it,
//! where the builders' own `peak_working_bytes` counts their arrays only.

use serde::Serialize;

/// The high-water mark of resident memory (Linux `VmHWM`), in bytes; `None` where the system
/// does not say.
pub fn peak_bytes() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}

/// The peak so far and its share per triangle, as the JSON reports give them (flattened into
/// them; `null` where the system does not say or there are no triangles).
#[derive(Serialize, Clone, Copy, Debug)]
pub struct PeakResident {
    pub peak_resident_bytes: Option<u64>,
    pub peak_resident_bytes_per_triangle: Option<f64>,
}

impl PeakResident {
    pub fn now(triangles: usize) -> Self {
        let peak = peak_bytes();
        PeakResident {
            peak_resident_bytes: peak,
            peak_resident_bytes_per_triangle: peak
                .filter(|_| triangles > 0)
                .map(|b| b as f64 / triangles as f64),
        }
    }
}

#[cfg(test)]
mod tests {
    #[test]
    #[cfg(target_os = "linux")]
    fn the_peak_covers_what_was_touched() {
        let before = super::peak_bytes().unwrap();
        let block = vec![1u8; 64 << 20];
        std::hint::black_box(&block);
        let after = super::peak_bytes().unwrap();
        // 64 MiB written page by page is resident at once, so the mark rises to at least it.
        assert!(after >= (64 << 20), "peak {after} (before {before})");
        assert!(after >= before);
    }
}
