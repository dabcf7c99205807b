//! Checks of the level builder's plumbing that need no GPU: every kernel's bindings are read
//! from its WGSL, and the phases keep the names the CLI prints.

use super::kernels::level_sources;
use super::{Phase, PHASES};
use crate::kernel::{declared_bindings, Arg};

#[test]
fn every_level_kernel_declares_readable_bindings() {
    let sources = level_sources();
    assert_eq!(sources.len(), 15, "kernels in level.wgsl");
    for (name, source) in sources {
        let bindings = declared_bindings(&source).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(bindings[0], ("params".to_string(), Arg::Uniform), "{name}");
        assert!(
            source.contains(&format!("fn {name}(")),
            "{name}: entry point in its section"
        );
        // Read-only exactly where the kernel never writes (naga rejects a write to a
        // read-only binding, but only when a device compiles the module).
        for (binding, arg) in &bindings[1..] {
            let writes = writes_to(&source, binding);
            match arg {
                Arg::Read => assert!(!writes, "{name}: {binding} is written"),
                Arg::Write => assert!(
                    writes,
                    "{name}: {binding} is never written: declare it read"
                ),
                Arg::Uniform => panic!("{name}: {binding}: one uniform, the first"),
            }
        }
    }
}

#[test]
fn phases_keep_their_names_and_order() {
    let names: Vec<&str> = Phase::ALL.iter().map(|p| p.name()).collect();
    assert_eq!(names, PHASES);
    for (i, p) in Phase::ALL.iter().enumerate() {
        assert_eq!(*p as usize, i);
    }
}

/// Whether `source` assigns an element of `array` (`array[...] =`) or takes its address (for
/// atomics).
fn writes_to(source: &str, array: &str) -> bool {
    let bytes = source.as_bytes();
    let word = |i: usize| bytes[i].is_ascii_alphanumeric() || bytes[i] == b'_';
    let pattern = format!("{array}[");
    let mut from = 0;
    while let Some(at) = source[from..].find(&pattern) {
        let start = from + at;
        from = start + pattern.len();
        if start > 0 && (word(start - 1) || bytes[start - 1] == b'&') {
            if bytes[start - 1] == b'&' {
                return true;
            }
            continue;
        }
        let mut depth = 1;
        let mut i = from;
        while i < bytes.len() && depth > 0 {
            match bytes[i] {
                b'[' => depth += 1,
                b']' => depth -= 1,
                _ => {}
            }
            i += 1;
        }
        let rest = source[i..].trim_start();
        if rest.starts_with('=') && !rest.starts_with("==") {
            return true;
        }
    }
    false
}

/// The GPU of the tests (as `tests/common`): `SAHKD_GPU_ADAPTER` names the adapter that must
/// run them; without an adapter the test is skipped, saying so, unless `CI` is set.
fn gpu() -> Option<crate::Gpu> {
    match crate::Gpu::new() {
        Ok(gpu) => {
            if let Ok(expected) = std::env::var("SAHKD_GPU_ADAPTER") {
                assert!(gpu.adapter.name.contains(&expected), "{}", gpu.describe());
            }
            Some(gpu)
        }
        Err(e @ crate::GpuError::NoAdapter { .. }) if std::env::var_os("CI").is_none() => {
            eprintln!("skipping: {e}");
            None
        }
        Err(e) => panic!("{e}"),
    }
}

/// No size ceiling: with bindings of 128 KiB, the root's reference boxes, lists and the
/// clipped boxes are each larger than one binding; they are bound in parts, and the tree is
/// still the CPU level builder's.
#[test]
fn arrays_larger_than_one_binding_give_the_cpu_tree() {
    use sahkd::builders::{Algorithm, Axes, BuildOptions, Counting};
    let Some(mut gpu) = gpu() else { return };
    let limit = 128 * 1024;
    gpu.limit_binding(limit);
    let triangles = sahkd::scenes::generate("spd:toys:10000")
        .unwrap()
        .corner_triangles();
    eprintln!(
        "{} triangles, bindings of at most {} bytes, at most {} storage bindings per kernel",
        triangles.len(),
        gpu.max_binding,
        gpu.max_storage_bindings
    );
    assert!(
        24 * triangles.len() as u64 > limit,
        "the root's reference boxes ({} triangles) span several bindings",
        triangles.len()
    );
    let level = BuildOptions {
        algorithm: Algorithm::Level,
        ..BuildOptions::default()
    };
    for options in [
        level,
        BuildOptions {
            axes: Axes::All,
            clip: false,
            ..level
        },
        BuildOptions {
            counting: Counting::SpaceTree,
            ..level
        },
    ] {
        let cpu = sahkd::build_triangles(triangles.clone(), &options).unwrap();
        let built = super::build(&gpu, triangles.clone(), &options)
            .unwrap_or_else(|e| panic!("{options:?}: {e}"));
        if let Some(d) = cpu.tree.first_difference(&built.tree) {
            panic!("{options:?}: GPU tree differs from the CPU's at {d}");
        }
        assert!(built.report.device_bytes as u64 > 8 * limit);
    }
}

/// The device presort gives the host's nine lists exactly (ties by primitive, -0 before +0 as
/// `total_cmp`, flat entries only for flat boxes), and a build with it the CPU's tree.
#[test]
fn device_presort_equals_the_hosts() {
    use super::buffers::Grow;
    use super::kernels::Kernels;
    use super::presort;
    use sahkd::builders::{Algorithm, BuildOptions};
    use sahkd::{Aabb, Vec3};
    let Some(gpu) = gpu() else { return };
    // Few distinct values: ties everywhere, -0 and +0 both, many flat boxes.
    let values = [-1.0f32, -0.0, 0.0, 0.5, 2.0];
    let mut state = 12345u32;
    let mut pick = || {
        state = state.wrapping_mul(1_103_515_245).wrapping_add(12_345);
        values[(state >> 16) as usize % values.len()]
    };
    let boxes: Vec<Aabb> = (0..5000)
        .map(|_| {
            let a: [f32; 3] = std::array::from_fn(|_| pick());
            let b: [f32; 3] = std::array::from_fn(|_| pick());
            let lo = std::array::from_fn(|i| a[i].min(b[i]));
            let hi = std::array::from_fn(|i| a[i].max(b[i]));
            Aabb::new(Vec3(lo), Vec3(hi))
        })
        .collect();
    let (host, host_starts) = presort::root_lists(&boxes);
    let kernels = Kernels::new(&gpu);
    let mut entries = Grow::new("entries");
    let (n, starts) = presort::on_device(&gpu, &kernels, &boxes, &mut entries).unwrap();
    assert_eq!(starts, host_starts);
    assert_eq!(n, host.len());
    assert_eq!(gpu.download::<u32>(entries.get(), n).unwrap(), host);

    let triangles = sahkd::scenes::generate("spd:toys:3000")
        .unwrap()
        .corner_triangles();
    let options = BuildOptions {
        algorithm: Algorithm::Level,
        ..BuildOptions::default()
    };
    let cpu = sahkd::build_triangles(triangles.clone(), &options).unwrap();
    for presort in [super::Presort::Device, super::Presort::Host] {
        let built = super::build_with(&gpu, triangles.clone(), &options, presort).unwrap();
        assert_eq!(
            built.report.presort_on_device,
            presort == super::Presort::Device
        );
        if let Some(d) = cpu.tree.first_difference(&built.tree) {
            panic!("{presort:?} presort: GPU tree differs from the CPU's at {d}");
        }
    }
}
