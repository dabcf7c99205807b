//! The GPU every test runs on: a missing adapter fails the test under CI (`CI` set) and skips
//! it, saying so, elsewhere; `SAHKD_GPU_ADAPTER`, when set, names the adapter that must run
//! the tests (CI sets `llvmpipe`, Mesa's software Vulkan driver).

use sahkd::Mesh;
use sahkd_gpu::{Gpu, GpuError};
use std::path::PathBuf;

pub fn gpu() -> Option<Gpu> {
    match Gpu::new() {
        Ok(gpu) => {
            let name = &gpu.adapter.name;
            eprintln!("GPU tests run on {}", gpu.describe());
            if let Ok(expected) = std::env::var("SAHKD_GPU_ADAPTER") {
                assert!(
                    name.contains(&expected),
                    "adapter {name:?} is not the expected {expected:?}"
                );
            }
            Some(gpu)
        }
        Err(e @ GpuError::NoAdapter { .. }) if std::env::var_os("CI").is_none() => {
            eprintln!("skipping: {e}");
            None
        }
        Err(e) => panic!("{e}"),
    }
}

/// A mesh of the shared scenes folder (`SAHKD_SCENES`, else `../shared/scenes` beside the
/// checkout), or `None`, saying so, when it is missing.
#[allow(dead_code)] // not every test file loads scenes
pub fn scene(file: &str) -> Option<Mesh> {
    let dir = std::env::var_os("SAHKD_SCENES")
        .map(PathBuf::from)
        .unwrap_or_else(|| {
            PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/scenes")
        });
    let path = dir.join(file);
    if !path.is_file() {
        eprintln!("SKIPPED: {} is missing (set SAHKD_SCENES)", path.display());
        return None;
    }
    Some(Mesh::load(&path).unwrap_or_else(|e| panic!("{file}: {e}")))
}
