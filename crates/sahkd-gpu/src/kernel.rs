//! A compute kernel with an explicit bind group layout (automatic layouts drop unused bindings
//! and then reject bind groups that have them), and the buffer moves every kernel needs.

use crate::device::{Gpu, GpuError};
use std::cell::RefCell;
use std::collections::HashMap;
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

/// The values of `given` (name, value) in the order of `declared`, each matched by name to a
/// declaration of kernel `entry`; a name missing, unknown or given twice is an error.
pub(crate) fn bind_by_name<T: Copy>(
    entry: &str,
    declared: &[(String, Arg)],
    given: &[(&str, T)],
) -> Result<Vec<T>, String> {
    for (i, (name, _)) in given.iter().enumerate() {
        if !declared.iter().any(|(n, _)| n == name) {
            return Err(format!("kernel {entry} has no binding {name}"));
        }
        if given[..i].iter().any(|(n, _)| n == name) {
            return Err(format!("kernel {entry}: {name} bound twice"));
        }
    }
    declared
        .iter()
        .map(|(name, _)| {
            given
                .iter()
                .find(|(n, _)| n == name)
                .map(|(_, b)| *b)
                .ok_or_else(|| format!("kernel {entry}: binding {name} not given"))
        })
        .collect()
}

/// One entry point of a WGSL module, ready to dispatch, with the names and kinds of its
/// bindings read from the source: a launch binds its buffers by those names.
///
/// No size ceiling below a buffer's: a storage array larger than the device's largest binding
/// ([`Gpu::max_binding`]) is bound as consecutive sub-ranges of its buffer (offsets aligned to
/// `min_storage_buffer_offset_alignment`), and the kernel runs in a variant of its WGSL where
/// the array's declaration becomes one binding per part and every access `a[i]` goes through
/// generated accessors (`a_at(i)`, `a_put(i, v)`) that pick the part. Variants are compiled on
/// first use, per combination of part counts.
pub struct Kernel {
    entry: String,
    source: String,
    bindings: Vec<(String, Arg)>,
    /// Per binding: its array's element type and stride in bytes (uniforms: none).
    elements: Vec<Option<(String, u64)>>,
    /// Compiled variants by the number of parts of each binding (all ones: the source as is).
    variants: RefCell<HashMap<Vec<u64>, Variant>>,
}

struct Variant {
    pipeline: wgpu::ComputePipeline,
    layout: wgpu::BindGroupLayout,
}

/// The element type and its stride in bytes of a storage binding's `array<T>`.
fn element(source: &str, name: &str) -> Option<(String, u64)> {
    let line = source.lines().find(|l| {
        !l.trim_start().starts_with("//")
            && l.contains("@binding(")
            && l.contains(&format!("> {name}:"))
    })?;
    let ty = line.split_once("array<")?.1;
    let ty = ty.trim_end().trim_end_matches(';').trim_end();
    let ty = ty.strip_suffix('>')?.trim();
    let stride = match ty {
        "u32" | "f32" | "i32" | "atomic<u32>" | "atomic<i32>" => 4,
        "vec2<u32>" | "vec2<f32>" => 8,
        "vec4<u32>" | "vec4<f32>" => 16,
        // A struct of three 4-byte scalars (the space trees' `TreeNode`).
        "TreeNode" => 12,
        _ => return None,
    };
    Some((ty.to_string(), stride))
}

/// Bytes per part of an array of `stride`-byte elements: the most below `max_binding` that is
/// a multiple of both the stride and the offset alignment.
pub(crate) fn part_bytes(max_binding: u64, alignment: u64, stride: u64) -> u64 {
    let unit = lcm(alignment.max(4), stride);
    (max_binding / unit).max(1) * unit
}

fn lcm(a: u64, b: u64) -> u64 {
    let (mut x, mut y) = (a, b);
    while y != 0 {
        (x, y) = (y, x % y);
    }
    a / x * b
}

/// `source` with each array of `split` (name, element type, parts, elements per part, whether
/// writable) declared as `parts` bindings and accessed through generated accessors; bindings
/// renumbered in declaration order (`declared` gives the original order).
pub(crate) fn split_source(
    source: &str,
    declared: &[(String, Arg)],
    split: &[(String, String, u64, u64, bool)],
) -> String {
    let parts_of = |name: &str| split.iter().find(|s| s.0 == name).map_or(1, |s| s.2);
    // New binding numbers: each original binding's parts take consecutive numbers.
    let mut first = Vec::new();
    let mut next = 0u64;
    for (name, _) in declared {
        first.push(next);
        next += parts_of(name);
    }
    let mut out = String::new();
    for line in source.lines() {
        let declaration = !line.trim_start().starts_with("//") && line.contains("@binding(");
        let which = declaration
            .then(|| {
                declared
                    .iter()
                    .position(|(n, _)| line.contains(&format!("> {n}:")))
            })
            .flatten();
        match which {
            Some(i) => {
                let name = &declared[i].0;
                let (_, rest) = line.split_once("var<").unwrap_or_default();
                let parts = parts_of(name);
                for p in 0..parts {
                    let renamed = if parts > 1 {
                        rest.replacen(&format!("> {name}:"), &format!("> {name}_{p}:"), 1)
                    } else {
                        rest.to_string()
                    };
                    out.push_str(&format!(
                        "@group(0) @binding({}) var<{renamed}\n",
                        first[i] + p
                    ));
                }
            }
            None => {
                out.push_str(line);
                out.push('\n');
            }
        }
    }
    let names: Vec<&str> = split.iter().map(|s| s.0.as_str()).collect();
    let mut out = rewrite_accesses(&out, &names);
    for (name, ty, parts, per_part, writable) in split {
        let pick = |body: &dyn Fn(u64) -> String| -> String {
            let mut s =
                format!("    let part = i / {per_part}u;\n    let j = i - part * {per_part}u;\n");
            for p in 0..parts - 1 {
                s.push_str(&format!("    if (part == {p}u) {{\n{}    }}\n", body(p)));
            }
            s.push_str(&body(parts - 1));
            s
        };
        out.push_str(&format!(
            "\nfn {name}_at(i: u32) -> {ty} {{\n{}}}\n",
            pick(&|p| format!("        return {name}_{p}[j];\n"))
        ));
        if *writable {
            out.push_str(&format!(
                "\nfn {name}_put(i: u32, v: {ty}) {{\n{}}}\n",
                pick(&|p| format!("        {name}_{p}[j] = v;\n        return;\n"))
            ));
        }
    }
    out
}

/// Rewrites every `a[i]` of an array named in `names` outside comments: `a[i] = v;` becomes
/// `a_put(i, v);`, any other `a[i]` becomes `a_at(i)` (indices and values rewritten too).
pub(crate) fn rewrite_accesses(source: &str, names: &[&str]) -> String {
    let bytes = source.as_bytes();
    let ident = |c: u8| c.is_ascii_alphanumeric() || c == b'_';
    let mut out = String::with_capacity(source.len());
    let mut i = 0;
    while i < bytes.len() {
        if source[i..].starts_with("//") {
            let end = source[i..].find('\n').map_or(bytes.len(), |e| i + e);
            out.push_str(&source[i..end]);
            i = end;
            continue;
        }
        let hit = (i == 0 || !(ident(bytes[i - 1]) || bytes[i - 1] == b'.'))
            .then(|| {
                names
                    .iter()
                    .find(|n| source[i..].starts_with(&format!("{n}[")))
            })
            .flatten();
        let Some(name) = hit else {
            let c = source[i..].chars().next().unwrap_or(' ');
            out.push(c);
            i += c.len_utf8();
            continue;
        };
        // The index: up to the matching bracket.
        let open = i + name.len() + 1;
        let mut depth = 1;
        let mut close = open;
        while close < bytes.len() {
            match bytes[close] {
                b'[' => depth += 1,
                b']' => {
                    depth -= 1;
                    if depth == 0 {
                        break;
                    }
                }
                _ => {}
            }
            close += 1;
        }
        let index = rewrite_accesses(&source[open..close], names);
        let after = close + 1;
        let rest = &source[after..];
        let trimmed = rest.trim_start();
        if trimmed.starts_with('=') && !trimmed.starts_with("==") {
            let value_start = after + (rest.len() - trimmed.len()) + 1;
            let value_end = source[value_start..]
                .find(';')
                .map_or(bytes.len(), |e| value_start + e);
            let value = rewrite_accesses(source[value_start..value_end].trim(), names);
            out.push_str(&format!("{name}_put({index}, {value})"));
            i = value_end;
        } else {
            out.push_str(&format!("{name}_at({index})"));
            i = after;
        }
    }
    out
}

impl Kernel {
    /// Compiles entry point `entry` of `source` (the prelude goes in front). The bind group
    /// layout is explicit, from the source's declarations (automatic layouts drop unused
    /// bindings and then reject bind groups that have them). A source whose declarations
    /// cannot be read is a bug of this crate: it panics, naming the kernel.
    pub fn new(gpu: &Gpu, source: &str, entry: &str) -> Kernel {
        let bindings = declared_bindings(source).unwrap_or_else(|e| panic!("kernel {entry}: {e}"));
        let elements = bindings
            .iter()
            .map(|(name, arg)| match arg {
                Arg::Uniform => None,
                _ => Some(element(source, name).unwrap_or_else(|| {
                    panic!("kernel {entry}: binding {name} is not an array this crate splits")
                })),
            })
            .collect();
        let kernel = Kernel {
            entry: entry.to_string(),
            source: source.to_string(),
            bindings,
            elements,
            variants: RefCell::new(HashMap::new()),
        };
        let whole = vec![1; kernel.bindings.len()];
        let variant = kernel.compile(gpu, &whole);
        kernel.variants.borrow_mut().insert(whole, variant);
        kernel
    }

    /// The variant of the kernel with `parts[b]` bindings for binding b.
    fn compile(&self, gpu: &Gpu, parts: &[u64]) -> Variant {
        let mut split = Vec::new();
        let mut kinds = Vec::new();
        for (b, (name, arg)) in self.bindings.iter().enumerate() {
            for _ in 0..parts[b] {
                kinds.push(*arg);
            }
            if parts[b] > 1 {
                let (ty, stride) = self.elements[b].clone().unwrap_or_default();
                let per_part = part_bytes(gpu.max_binding, gpu.offset_alignment, stride) / stride;
                split.push((name.clone(), ty, parts[b], per_part, *arg == Arg::Write));
            }
        }
        let source = if split.is_empty() {
            self.source.clone()
        } else {
            split_source(&self.source, &self.bindings, &split)
        };
        let module = gpu.module(&self.entry, &source);
        let entries: Vec<wgpu::BindGroupLayoutEntry> = kinds
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
        let label = Some(self.entry.as_str());
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label,
            entries: &entries,
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label,
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label,
            layout: Some(&pipeline_layout),
            module: &module,
            entry_point: label,
            compilation_options: Default::default(),
            cache: None,
        });
        Variant { pipeline, layout }
    }

    /// The bindings as the WGSL declares them, in binding order.
    pub fn bindings(&self) -> &[(String, Arg)] {
        &self.bindings
    }

    /// Records a launch of at least `threads` invocations (whole workgroups, 2-D beyond
    /// 65 535 of them; shaders compute their index with the prelude's `thread_index` and
    /// ignore indices past their length). Buffers are bound by the names the WGSL gives them;
    /// a mismatch is a bug of this crate and panics, naming the kernel and the binding. A
    /// buffer larger than one binding is bound in parts; one the device cannot bind at all
    /// (atomics, or more parts than bindings allowed) is an error at the next [`Gpu::finish`].
    pub fn dispatch(
        &self,
        gpu: &Gpu,
        encoder: &mut wgpu::CommandEncoder,
        buffers: &[(&str, &wgpu::Buffer)],
        threads: u64,
    ) {
        let buffers =
            bind_by_name(&self.entry, &self.bindings, buffers).unwrap_or_else(|e| panic!("{e}"));
        let groups = threads.div_ceil(GROUP as u64).max(1);
        let x = groups.min(MAX_GROUPS as u64);
        let y = groups.div_ceil(x);
        if y > MAX_GROUPS as u64 {
            gpu.report_error(format!(
                "kernel {}: a launch of {threads} threads is too large",
                self.entry
            ));
            return;
        }
        // Bytes per part of each binding; the number of parts.
        let part: Vec<u64> = self
            .elements
            .iter()
            .map(|e| {
                e.as_ref().map_or(u64::MAX, |(_, s)| {
                    part_bytes(gpu.max_binding, gpu.offset_alignment, *s)
                })
            })
            .collect();
        let parts: Vec<u64> = buffers
            .iter()
            .zip(&part)
            .map(|(b, p)| b.size().div_ceil(*p).max(1))
            .collect();
        if let Err(e) = self.check_parts(gpu, &parts) {
            gpu.report_error(e);
            return;
        }
        let mut variants = self.variants.borrow_mut();
        let variant = variants
            .entry(parts.clone())
            .or_insert_with(|| self.compile(gpu, &parts));
        let mut entries = Vec::new();
        for (b, buffer) in buffers.iter().enumerate() {
            if parts[b] == 1 {
                entries.push(wgpu::BindGroupEntry {
                    binding: entries.len() as u32,
                    resource: buffer.as_entire_binding(),
                });
                continue;
            }
            for p in 0..parts[b] {
                let offset = p * part[b];
                let size = part[b].min(buffer.size() - offset);
                entries.push(wgpu::BindGroupEntry {
                    binding: entries.len() as u32,
                    resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                        buffer,
                        offset,
                        size: wgpu::BufferSize::new(size),
                    }),
                });
            }
        }
        let group = gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some(&self.entry),
            layout: &variant.layout,
            entries: &entries,
        });
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor::default());
        pass.set_pipeline(&variant.pipeline);
        pass.set_bind_group(0, &group, &[]);
        pass.dispatch_workgroups(x as u32, y as u32, 1);
    }

    /// Whether the device can bind `parts` parts of each binding.
    fn check_parts(&self, gpu: &Gpu, parts: &[u64]) -> Result<(), String> {
        for (b, (name, _)) in self.bindings.iter().enumerate() {
            let atomic = self.elements[b]
                .as_ref()
                .is_some_and(|(ty, _)| ty.starts_with("atomic"));
            if parts[b] > 1 && atomic {
                return Err(format!(
                    "kernel {}: {name} (atomic) is larger than one binding ({} bytes)",
                    self.entry, gpu.max_binding
                ));
            }
        }
        let storage: u64 = self
            .bindings
            .iter()
            .zip(parts)
            .filter(|((_, a), _)| *a != Arg::Uniform)
            .map(|(_, p)| p)
            .sum();
        if storage > gpu.max_storage_bindings as u64 {
            return Err(format!(
                "kernel {}: its arrays need {storage} storage bindings of at most {} bytes, \
                 more than the device's {}",
                self.entry, gpu.max_binding, gpu.max_storage_bindings
            ));
        }
        Ok(())
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
                // COPY_DST: words computed on the device can be copied in (see `DeviceLayout`).
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            })
    }

    /// A zeroed storage buffer of `len` elements of 4 bytes, refusing sizes beyond one buffer
    /// (larger than one binding is fine: kernels bind it in parts).
    pub fn storage(&self, label: &str, len: usize) -> Result<wgpu::Buffer, GpuError> {
        let size = (len.max(1) * 4) as u64;
        if size > self.max_buffer {
            return Err(GpuError::Runtime(format!(
                "{label} needs {size} bytes, more than one buffer of this device allows ({})",
                self.max_buffer
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

#[cfg(test)]
mod tests {
    use super::*;

    const SOURCE: &str = "
@group(0) @binding(0) var<uniform> params: Params;
// @binding(9) in a comment is not a binding
@group(0) @binding(2) var<storage, read_write> out: array<u32>;
@group(0) @binding(1) var<storage, read> values: array<f32>;
";

    #[test]
    fn bindings_are_read_from_the_source_in_binding_order() {
        let b = declared_bindings(SOURCE).unwrap();
        let names: Vec<(&str, Arg)> = b.iter().map(|(n, a)| (n.as_str(), *a)).collect();
        assert_eq!(
            names,
            [
                ("params", Arg::Uniform),
                ("values", Arg::Read),
                ("out", Arg::Write)
            ]
        );
        let gap = "@group(0) @binding(0) var<uniform> p: P;\n@group(0) @binding(2) var<storage, read> x: array<u32>;";
        assert!(declared_bindings(gap).unwrap_err().contains("expected 1"));
        let twice = "@group(0) @binding(0) var<uniform> p: P;\n@group(0) @binding(1) var<storage, read> p: array<u32>;";
        assert!(declared_bindings(twice)
            .unwrap_err()
            .contains("two bindings"));
    }

    #[test]
    fn launches_bind_by_name_in_declaration_order() {
        let declared = declared_bindings(SOURCE).unwrap();
        let bound = bind_by_name("k", &declared, &[("out", 3), ("params", 1), ("values", 2)]);
        assert_eq!(bound.unwrap(), [1, 2, 3]);
        let missing = bind_by_name("k", &declared, &[("out", 3), ("params", 1)]).unwrap_err();
        assert!(missing.contains("binding values not given"), "{missing}");
        let unknown = bind_by_name("k", &declared, &[("out", 3), ("params", 1), ("vals", 2)]);
        assert!(unknown.unwrap_err().contains("has no binding vals"));
        let twice = bind_by_name("k", &declared, &[("out", 3), ("out", 1), ("values", 2)]);
        assert!(twice.unwrap_err().contains("bound twice"));
    }
}

#[cfg(test)]
mod split_tests {
    use super::*;

    #[test]
    fn split_arrays_get_one_binding_per_part_and_accessors() {
        let source = "\
@group(0) @binding(0) var<uniform> params: P;
@group(0) @binding(1) var<storage, read> keys: array<u32>;
@group(0) @binding(2) var<storage, read_write> out: array<f32>;
// out[i] in a comment stays
fn f(i: u32) {
    out[keys[i] + 1u] = f32(keys[keys[i]]);
    let x = out[i] == 0.0;
}
";
        let declared = declared_bindings(source).unwrap();
        let split = [
            ("keys".to_string(), "u32".to_string(), 3, 64, false),
            ("out".to_string(), "f32".to_string(), 2, 64, true),
        ];
        let got = split_source(source, &declared, &split);
        let names: Vec<(String, Arg)> = declared_bindings(&got).unwrap();
        let names: Vec<&str> = names.iter().map(|(n, _)| n.as_str()).collect();
        assert_eq!(
            names,
            ["params", "keys_0", "keys_1", "keys_2", "out_0", "out_1"]
        );
        assert!(
            got.contains("out_put(keys_at(i) + 1u, f32(keys_at(keys_at(i))));"),
            "{got}"
        );
        assert!(got.contains("let x = out_at(i) == 0.0;"), "{got}");
        assert!(got.contains("// out[i] in a comment stays"));
        assert!(got.contains("fn keys_at(i: u32) -> u32"));
        assert!(
            !got.contains("fn keys_put"),
            "read-only arrays get no writer"
        );
        assert!(got.contains("fn out_put(i: u32, v: f32)"));
        assert_eq!(part_bytes(1000, 256, 4), 768);
        assert_eq!(part_bytes(1000, 256, 12), 768);
        assert_eq!(part_bytes(128 << 20, 256, 16), 128 << 20);
    }
}
