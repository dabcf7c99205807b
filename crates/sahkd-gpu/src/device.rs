//! The adapter and device: chosen once, errors named, validation errors collected.

use std::fmt;
use std::sync::{Arc, Mutex};

/// What can go wrong before or while running kernels.
#[derive(Debug, Clone, PartialEq)]
pub enum GpuError {
    /// No adapter on any of the backends tried (named, e.g. "vulkan, metal, dx12, gl").
    NoAdapter { backends: String },
    /// The adapter refused the device we asked for.
    Device(String),
    /// wgpu reported an error (validation, out of memory) while running kernels.
    Runtime(String),
}

impl fmt::Display for GpuError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            GpuError::NoAdapter { backends } => write!(
                f,
                "no GPU adapter found (backends tried: {backends}); on Linux without a GPU, \
                 install Mesa's software Vulkan driver (Debian: mesa-vulkan-drivers)"
            ),
            GpuError::Device(e) => write!(f, "the GPU adapter refused a device: {e}"),
            GpuError::Runtime(e) => write!(f, "GPU error: {e}"),
        }
    }
}

impl std::error::Error for GpuError {}

/// One GPU device and its queue, with the adapter's description.
pub struct Gpu {
    pub device: wgpu::Device,
    pub queue: wgpu::Queue,
    pub adapter: wgpu::AdapterInfo,
    /// The largest storage binding the device allows, in bytes (128 MiB on lavapipe). An
    /// array larger than this is bound as several sub-ranges of its buffer (see
    /// [`crate::Kernel::dispatch`]).
    pub max_binding: u64,
    /// The largest buffer the device allows, in bytes: the ceiling of one array.
    pub max_buffer: u64,
    /// Offsets of bound sub-ranges are multiples of this (`min_storage_buffer_offset_alignment`).
    pub offset_alignment: u64,
    /// Storage bindings one kernel may have (an array split into parts takes one per part).
    pub max_storage_bindings: u32,
    pub(crate) errors: Arc<Mutex<Vec<String>>>,
}

impl Gpu {
    /// Picks the default adapter (high performance first) on every backend wgpu was built
    /// with, honouring `WGPU_BACKEND` / `WGPU_ADAPTER_NAME` from the environment.
    pub fn new() -> Result<Gpu, GpuError> {
        pollster::block_on(Self::start())
    }

    async fn start() -> Result<Gpu, GpuError> {
        let desc = wgpu::InstanceDescriptor::new_without_display_handle_from_env();
        let backends = backend_names(desc.backends);
        let instance = wgpu::Instance::new(desc);
        let options = wgpu::RequestAdapterOptions {
            power_preference: wgpu::PowerPreference::HighPerformance,
            ..Default::default()
        };
        let adapter = instance
            .request_adapter(&options)
            .await
            .map_err(|_| GpuError::NoAdapter { backends })?;
        // The adapter's own limits, not the defaults: the largest bindings and buffers it has.
        let required = adapter.limits();
        let (device, queue) = adapter
            .request_device(&wgpu::DeviceDescriptor {
                label: Some("sahkd"),
                required_limits: required.clone(),
                ..Default::default()
            })
            .await
            .map_err(|e| GpuError::Device(e.to_string()))?;
        let errors = Arc::new(Mutex::new(Vec::new()));
        let sink = errors.clone();
        device.on_uncaptured_error(Arc::new(move |e: wgpu::Error| {
            sink.lock().unwrap().push(e.to_string());
        }));
        Ok(Gpu {
            device,
            queue,
            adapter: adapter.get_info(),
            max_binding: (required.max_storage_buffer_binding_size as u64)
                .min(required.max_buffer_size),
            max_buffer: required.max_buffer_size,
            offset_alignment: required.min_storage_buffer_offset_alignment as u64,
            max_storage_bindings: required.max_storage_buffers_per_shader_stage,
            errors,
        })
    }

    /// Lowers the largest binding to `bytes` (tests: arrays beyond it are split across
    /// bindings as on a device whose bindings are that small).
    #[cfg(test)]
    pub(crate) fn limit_binding(&mut self, bytes: u64) {
        self.max_binding = self.max_binding.min(bytes);
    }

    /// Records an error to be returned by the next [`Gpu::finish`].
    pub(crate) fn report_error(&self, error: String) {
        self.errors.lock().unwrap().push(error);
    }

    /// "name (backend, device type)", for reports.
    pub fn describe(&self) -> String {
        let a = &self.adapter;
        format!("{} ({:?}, {:?})", a.name, a.backend, a.device_type)
    }

    /// Waits for all submitted work, then fails with every error wgpu reported since the last
    /// check (validation errors would otherwise only be logged).
    pub fn finish(&self) -> Result<(), GpuError> {
        self.device
            .poll(wgpu::PollType::Wait {
                submission_index: None,
                timeout: None,
            })
            .map_err(|e| GpuError::Runtime(e.to_string()))?;
        let mut errors = self.errors.lock().unwrap();
        if errors.is_empty() {
            Ok(())
        } else {
            Err(GpuError::Runtime(std::mem::take(&mut *errors).join("; ")))
        }
    }
}

fn backend_names(backends: wgpu::Backends) -> String {
    let all = [
        (wgpu::Backends::VULKAN, "vulkan"),
        (wgpu::Backends::METAL, "metal"),
        (wgpu::Backends::DX12, "dx12"),
        (wgpu::Backends::GL, "gl"),
        (wgpu::Backends::BROWSER_WEBGPU, "webgpu"),
    ];
    let names: Vec<&str> = all
        .iter()
        .filter(|(b, _)| backends.contains(*b))
        .map(|(_, n)| *n)
        .collect();
    if names.is_empty() {
        "none".to_string()
    } else {
        names.join(", ")
    }
}
