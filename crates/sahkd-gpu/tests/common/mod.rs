//! The GPU every test runs on: a missing adapter fails the test under CI (`CI` set) and skips
//! it, saying so, elsewhere; `SAHKD_GPU_ADAPTER`, when set, names the adapter that must run
//! the tests (CI sets `llvmpipe`, Mesa's software Vulkan driver).

use sahkd_gpu::{Gpu, GpuError};

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
