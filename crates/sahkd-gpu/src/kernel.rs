//! A compute kernel with an explicit bind group layout (automatic layouts drop unused bindings
//! and then reject bind groups that have them), and the buffer moves every kernel needs.

use crate::device::{Gpu, GpuError};
use wgpu::util::DeviceExt;

/// Threads per workgroup of every kernel (`@workgroup_size(256)` in the shaders).
pub const GROUP: u32 = 256;
/// Workgroups per dispatch dimension (the WebGPU minimum); larger launches go 2-D.
const MAX_GROUPS: u32 = 65_535;

/// How a kernel sees one binding, as its WGSL declares it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Arg {
    /// Small parameters (`var<uniform>`).
    Uniform,
    /// `var<storage, read>`.
    Read,
    /// `var<storage, read_write>`.
    Write,
}

/// The WGSL every module starts with (`thread_index`, `order_key`): [`Gpu::module`] puts it in
/// front of the source.
pub const PRELUDE: &str = include_str!("shaders/prelude.wgsl");

/// The bindings a WGSL source declares (`@binding(i) var<...> name`), in binding order: name
/// and kind. Every binding of group 0 from 0 up, with no gap, or an error naming the problem.
pub fn declared_bindings(source: &str) -> Result<Vec<(String, Arg)>, String> {
    let mut found: Vec<(u32, String, Arg)> = Vec::new();
    for line in source.lines() {
        let line = line.trim();
        if line.starts_with("//") {
            continue;
        }
        let Some(at) = line.find("@binding(") else {
            continue;
        };
        let rest = &line[at + "@binding(".len()..];
        let (index, rest) = rest
            .split_once(')')
            .ok_or_else(|| format!("unreadable binding: {line}"))?;
        let index: u32 = index
            .trim()
            .parse()
            .map_err(|_| format!("unreadable binding index: {line}"))?;
        let rest = rest.trim_start();
        let rest = rest
            .strip_prefix("var<")
            .ok_or_else(|| format!("binding is not a var<...>: {line}"))?;
        let (kind, rest) = rest
            .split_once('>')
            .ok_or_else(|| format!("unreadable binding: {line}"))?;
        let kind: String = kind.chars().filter(|c| !c.is_whitespace()).collect();
        let arg = match kind.as_str() {
            "uniform" => Arg::Uniform,
            "storage" | "storage,read" => Arg::Read,
            "storage,read_write" => Arg::Write,
            _ => return Err(format!("unknown binding kind {kind:?}: {line}")),
        };
        let name = rest
            .trim_start()
            .split(|c: char| !(c.is_alphanumeric() || c == '_'))
            .next()
            .unwrap_or_default();
        if name.is_empty() {
            return Err(format!("binding without a name: {line}"));
        }
        found.push((index, name.to_string(), arg));
    }
    found.sort_by_key(|b| b.0);
    for (i, (index, name, _)) in found.iter().enumerate() {
        if *index != i as u32 {
            return Err(format!("binding {name} is number {index}, expected {i}"));
        }
        if found[..i].iter().any(|b| &b.1 == name) {
            return Err(format!("two bindings named {name}"));
        }
    }
    Ok(found.into_iter().map(|(_, n, a)| (n, a)).collect())
}

/// One entry point of a WGSL module, ready to dispatch, with the names and kinds of its
/// bindings read from the source: a launch binds its buffers by those names.
pub struct Kernel {
    entry: String,
    pipeline: wgpu::ComputePipeline,
    layout: wgpu::BindGroupLayout,
    bindings: Vec<(String, Arg)>,
}

impl Kernel {
    /// Compiles entry point `entry` of `source` (the prelude goes in front). The bind group
    /// layout is explicit, from the source's declarations (automatic layouts drop unused
    /// bindings and then reject bind groups that have them). A source whose declarations
    /// cannot be read is a bug of this crate: it panics, naming the kernel.
    pub fn new(gpu: &Gpu, source: &str, entry: &str) -> Kernel {
        let bindings = declared_bindings(source).unwrap_or_else(|e| panic!("kernel {entry}: {e}"));
        let module = gpu.module(entry, source);
        let entries: Vec<wgpu::BindGroupLayoutEntry> = bindings
            .iter()
            .enumerate()
            .map(|(i, (_, a))| wgpu::BindGroupLayoutEntry {
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
            module: &module,
            entry_point: Some(entry),
            compilation_options: Default::default(),
            cache: None,
        });
        Kernel {
            entry: entry.to_string(),
            pipeline,
            layout,
            bindings,
        }
    }

    /// The bindings as the WGSL declares them, in binding order.
    pub fn bindings(&self) -> &[(String, Arg)] {
        &self.bindings
    }

    /// The buffers of `given` (name, buffer) in binding order, each matched by name to the
    /// WGSL's declaration; a name missing, unknown or given twice is reported.
    fn bind<'b>(
        &self,
        given: &[(&str, &'b wgpu::Buffer)],
    ) -> Result<Vec<&'b wgpu::Buffer>, String> {
        for (i, (name, _)) in given.iter().enumerate() {
            if !self.bindings.iter().any(|(n, _)| n == name) {
                return Err(format!("kernel {} has no binding {name}", self.entry));
            }
            if given[..i].iter().any(|(n, _)| n == name) {
                return Err(format!("kernel {}: {name} bound twice", self.entry));
            }
        }
        self.bindings
            .iter()
            .map(|(name, _)| {
                given
                    .iter()
                    .find(|(n, _)| n == name)
                    .map(|(_, b)| *b)
                    .ok_or_else(|| format!("kernel {}: binding {name} not given", self.entry))
            })
            .collect()
    }

    /// Records a launch of at least `threads` invocations (whole workgroups, 2-D beyond
    /// 65 535 of them; shaders compute their index with the prelude's `thread_index` and
    /// ignore indices past their length). Buffers are bound by the names the WGSL gives them;
    /// a mismatch is a bug of this crate and panics, naming the kernel and the binding.
    pub fn dispatch(
        &self,
        gpu: &Gpu,
        encoder: &mut wgpu::CommandEncoder,
        buffers: &[(&str, &wgpu::Buffer)],
        threads: u64,
    ) {
        let buffers = self.bind(buffers).unwrap_or_else(|e| panic!("{e}"));
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
            label: Some(&self.entry),
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
    /// Compiles WGSL with the [`PRELUDE`] in front (errors surface at the next
    /// [`Gpu::finish`]).
    pub fn module(&self, label: &str, source: &str) -> wgpu::ShaderModule {
        self.device
            .create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some(label),
                source: wgpu::ShaderSource::Wgsl(format!("{PRELUDE}\n{source}").into()),
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
