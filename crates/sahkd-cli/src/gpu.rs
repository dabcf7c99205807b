//! `--device gpu`: the level builder on a GPU (crates/sahkd-gpu), and its report.

use anyhow::Result;
use sahkd::{Build, BuildOptions, Mesh};
use serde::Serialize;

/// How a GPU build went, as `build --json` reports it.
#[derive(Clone, Debug, Serialize)]
pub struct GpuReport {
    pub adapter: String,
    pub upload_ms: f64,
    /// Presort of the nine root lists.
    pub presort_ms: f64,
    /// Where the presort ran: "host" or "device" (the device on a GPU, the host on a CPU
    /// adapter such as lavapipe, where it is faster).
    pub presort: &'static str,
    /// Per phase, summed over levels, in the order the phases run.
    pub phases_ms: Vec<(String, f64)>,
    pub download_ms: f64,
    pub levels: usize,
    /// Reads of GPU results by the host during the build.
    pub round_trips: usize,
    pub round_trips_per_level: f64,
}

/// Whether a GPU can build with `options`: one error line naming what it cannot do.
#[cfg(feature = "gpu")]
pub fn check(options: &BuildOptions) -> Result<()> {
    sahkd_gpu::check_options(options).map_err(|e| anyhow::anyhow!(e))
}

#[cfg(not(feature = "gpu"))]
pub fn check(_options: &BuildOptions) -> Result<()> {
    anyhow::bail!("this sahkd was built without GPU support (cargo feature `gpu`)")
}

#[cfg(feature = "gpu")]
pub fn build(mesh: &Mesh, options: &BuildOptions) -> Result<(Build, GpuReport)> {
    use anyhow::anyhow;
    check(options)?;
    mesh.validate()
        .map_err(|e| anyhow!(sahkd::builders::BuildError::InvalidMesh(e)))?;
    let gpu = sahkd_gpu::Gpu::new().map_err(|e| anyhow!(e))?;
    let built = sahkd_gpu::build(&gpu, mesh.corner_triangles(), options)
        .map_err(|e| anyhow!("GPU build failed on {}: {e}", gpu.describe()))?;
    let r = built.report;
    let report = GpuReport {
        adapter: r.adapter,
        upload_ms: r.upload_ms,
        presort_ms: r.presort_ms,
        presort: if r.presort_on_device {
            "device"
        } else {
            "host"
        },
        phases_ms: sahkd_gpu::level::PHASES
            .iter()
            .map(|s| s.to_string())
            .zip(r.phase_ms.iter().copied())
            .collect(),
        download_ms: r.download_ms,
        levels: r.levels,
        round_trips: r.round_trips,
        round_trips_per_level: r.round_trips as f64 / r.levels.max(1) as f64,
    };
    let build = Build {
        tree: built.tree,
        report: sahkd::BuildReport {
            build_ms: r.total_ms,
            presort_ms: r.presort_ms,
            // The GPU's working memory: its level buffers.
            peak_working_bytes: r.device_bytes,
            ..Default::default()
        },
    };
    Ok((build, report))
}

#[cfg(not(feature = "gpu"))]
pub fn build(_mesh: &Mesh, _options: &BuildOptions) -> Result<(Build, GpuReport)> {
    anyhow::bail!("this sahkd was built without GPU support (cargo feature `gpu`)")
}
