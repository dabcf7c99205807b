//! A compute kernel with an explicit bind group layout (automatic layouts drop unused bindings
//! and then reject bind groups that have them), and the buffer moves every kernel needs.

use crate::device::{Gpu, GpuError};
use wgpu::util::DeviceExt;

/// Threads per workgroup of every kernel (`@workgroup_size(256)` in the shaders).
pub const GROUP: u32 = 256;
/// Workgroups per dispatch dimension (the WebGPU minimum); larger launches go 2-D.
const MAX_GROUPS: u32 = 65_535;

/// How a kernel sees one binding, in binding order.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Arg {
    /// Small parameters (`var<uniform>`).
    Uniform,
    /// `var<storage, read>`.
    Read,
    /// `var<storage, read_write>`.
    Write,
}

/// One entry point of a WGSL module, ready to dispatch.
pub struct Kernel {
    pipeline: wgpu::ComputePipeline,
    layout: wgpu::BindGroupLayout,
    args: Vec<Arg>,
}

impl Kernel {
    pub fn new(gpu: &Gpu, module: &wgpu::ShaderModule, entry: &str, args: &[Arg]) -> Kernel {
        let entries: Vec<wgpu::BindGroupLayoutEntry> = args
            .iter()
            .enumerate()
            .map(|(i, a)| wgpu::BindGroupLayoutEntry {
                binding: i as u32,
                visibility: wgpu::ShaderStages::COMPUTE,
                ty: wgpu::BindingType::Buffer {
                    ty: match a {
                        Arg::Uniform => wgpu::BufferBindingType::Uniform,
                        Arg::Read => wgpu::BufferBindingType::Storage { read_only: true },
                        Arg::Write => wgpu::BufferBindingType::Storage { read_only: false },
                    },
                    has_dynamic_offset: false,
                    min_binding_size: None,
                },
                count: None,
            })
            .collect();
        let device = &gpu.device;
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some(entry),
            entries: &entries,
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some(entry),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some(entry),
            layout: Some(&pipeline_layout),
            module,
            entry_point: Some(entry),
            compilation_options: Default::default(),
            cache: None,
        });
        Kernel {
            pipeline,
            layout,
            args: args.to_vec(),
        }
    }

    /// Records a launch of at least `threads` invocations (whole workgroups, 2-D beyond
    /// 65 535 of them; shaders compute their index as `(wid.y * nwg.x + wid.x) * 256 + lid.x`
    /// and ignore indices past their length).
    pub fn dispatch(
        &self,
        gpu: &Gpu,
        encoder: &mut wgpu::CommandEncoder,
        buffers: &[&wgpu::Buffer],
        threads: u64,
    ) {
        assert_eq!(buffers.len(), self.args.len(), "one buffer per binding");
        let groups = threads.div_ceil(GROUP as u64).max(1);
        let x = groups.min(MAX_GROUPS as u64);
        let y = groups.div_ceil(x);
        assert!(
            y <= MAX_GROUPS as u64,
            "launch of {threads} threads is too large"
        );
        let entries: Vec<wgpu::BindGroupEntry> = buffers
            .iter()
            .enumerate()
            .map(|(i, b)| wgpu::BindGroupEntry {
                binding: i as u32,
                resource: b.as_entire_binding(),
            })
            .collect();
        let group = gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: None,
            layout: &self.layout,
            entries: &entries,
        });
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor::default());
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &group, &[]);
        pass.dispatch_workgroups(x as u32, y as u32, 1);
    }
}

impl Gpu {
    /// Compiles WGSL (errors surface at the next [`Gpu::finish`]).
    pub fn module(&self, label: &str, source: &str) -> wgpu::ShaderModule {
        self.device
            .create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some(label),
                source: wgpu::ShaderSource::Wgsl(source.into()),
            })
    }

    /// A storage buffer holding `data` (at least 4 bytes: empty bindings are invalid).
    pub fn upload<T: bytemuck::Pod>(&self, label: &str, data: &[T]) -> wgpu::Buffer {
        let bytes: &[u8] = bytemuck::cast_slice(data);
        let mut padded;
        let contents = if bytes.len() < 4 {
            padded = bytes.to_vec();
            padded.resize(4, 0);
            &padded[..]
        } else {
            bytes
        };
        self.device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents,
                usage: wgpu::BufferUsages::STORAGE
                    | wgpu::BufferUsages::COPY_SRC
                    | wgpu::BufferUsages::COPY_DST,
            })
    }

    /// Small parameters for one launch.
    pub fn uniform<T: bytemuck::Pod>(&self, params: &T) -> wgpu::Buffer {
        self.device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("params"),
                contents: bytemuck::bytes_of(params),
                usage: wgpu::BufferUsages::UNIFORM,
            })
    }

    /// A zeroed storage buffer of `len` elements of 4 bytes, refusing sizes beyond one binding.
    pub fn storage(&self, label: &str, len: usize) -> Result<wgpu::Buffer, GpuError> {
        let size = (len.max(1) * 4) as u64;
        if size > self.max_binding {
            return Err(GpuError::Runtime(format!(
                "{label} needs {size} bytes, more than one binding allows ({})",
                self.max_binding
            )));
        }
        Ok(self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size,
            usage: wgpu::BufferUsages::STORAGE
                | wgpu::BufferUsages::COPY_SRC
                | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        }))
    }

    /// Copies the first `len` elements of `buffer` back (waits for all submitted work).
    pub fn download<T: bytemuck::Pod>(
        &self,
        buffer: &wgpu::Buffer,
        len: usize,
    ) -> Result<Vec<T>, GpuError> {
        let size = (len * std::mem::size_of::<T>()) as u64;
        if size == 0 {
            return Ok(Vec::new());
        }
        let staging = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("download"),
            size,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mut encoder = self.device.create_command_encoder(&Default::default());
        encoder.copy_buffer_to_buffer(buffer, 0, &staging, 0, size);
        self.queue.submit([encoder.finish()]);
        let slice = staging.slice(..);
        let (tx, rx) = std::sync::mpsc::channel();
        slice.map_async(wgpu::MapMode::Read, move |r| {
            let _ = tx.send(r);
        });
        self.finish()?;
        rx.recv()
            .map_err(|e| GpuError::Runtime(e.to_string()))?
            .map_err(|e| GpuError::Runtime(e.to_string()))?;
        let view = slice
            .get_mapped_range()
            .map_err(|e| GpuError::Runtime(e.to_string()))?;
        let out = bytemuck::cast_slice(&view).to_vec();
        drop(view);
        staging.unmap();
        Ok(out)
    }

    /// A command encoder; submit it with [`Gpu::submit`].
    pub fn encoder(&self) -> wgpu::CommandEncoder {
        self.device.create_command_encoder(&Default::default())
    }

    pub fn submit(&self, encoder: wgpu::CommandEncoder) {
        self.queue.submit([encoder.finish()]);
    }
}
