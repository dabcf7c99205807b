//! Software f64 in WGSL ([`CLIP_WGSL`], see `shaders/clip.wgsl`), for clipping triangles on
//! the GPU bit for bit like [`sahkd::clip::clipped_bounds`], and a test-facing launch of it.

use crate::kernel::{Arg, Kernel};
use crate::{Gpu, GpuError};

/// The library: the `f64_*` operations. No bindings or entry points; every name starts with `f64_`, `clip_` or `F64_`.
pub const CLIP_WGSL: &str = include_str!("shaders/clip.wgsl");

/// Entry point over host data: `f64_ops` (each operation on two f64s and one f32).
const KERNELS: &str = r#"
struct ClipParams {
    n: u32,
    pad0: u32,
    pad1: u32,
    pad2: u32,
}

@group(0) @binding(0) var<uniform> clip_params: ClipParams;
@group(0) @binding(1) var<storage, read> clip_in0: array<u32>;
@group(0) @binding(2) var<storage, read> clip_in1: array<u32>;
@group(0) @binding(3) var<storage, read_write> clip_out: array<u32>;

// Case i: a, b (f64, high word first) and c (f32) at in0[5i..]; out[17i..] = a + b, a - b,
// a * b, a / b, a.min(b), a.max(b) (2 words each), flags (lt, le, ge, eq in bits 0..3),
// round_down(a), round_up(a), c as f64 (2 words).
@compute @workgroup_size(256)
fn f64_ops(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let i = (wid.y * nwg.x + wid.x) * 256u + lid;
    if (i >= clip_params.n) {
        return;
    }
    let a = vec2<u32>(clip_in0[5u * i], clip_in0[5u * i + 1u]);
    let b = vec2<u32>(clip_in0[5u * i + 2u], clip_in0[5u * i + 3u]);
    let c = bitcast<f32>(clip_in0[5u * i + 4u]);
    let results = array<vec2<u32>, 6>(
        f64_add(a, b), f64_sub(a, b), f64_mul(a, b), f64_div(a, b), f64_min(a, b), f64_max(a, b),
    );
    let o = 17u * i;
    for (var k = 0u; k < 6u; k = k + 1u) {
        clip_out[o + 2u * k] = results[k].x;
        clip_out[o + 2u * k + 1u] = results[k].y;
    }
    clip_out[o + 12u] = u32(f64_lt(a, b)) | (u32(f64_le(a, b)) << 1u)
        | (u32(f64_ge(a, b)) << 2u) | (u32(f64_eq(a, b)) << 3u);
    clip_out[o + 13u] = f64_to_f32_directed(a, false);
    clip_out[o + 14u] = f64_to_f32_directed(a, true);
    let w = f64_from_f32(c);
    clip_out[o + 15u] = w.x;
    clip_out[o + 16u] = w.y;
}
"#;

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Params {
    n: u32,
    pad: [u32; 3],
}

const ARGS: [Arg; 4] = [Arg::Uniform, Arg::Read, Arg::Read, Arg::Write];

fn run(
    gpu: &Gpu,
    entry: &str,
    n: usize,
    inputs: [&wgpu::Buffer; 2],
    out_words: usize,
) -> Result<Vec<u32>, GpuError> {
    let module = gpu.module("clip", &format!("{CLIP_WGSL}\n{KERNELS}"));
    let kernel = Kernel::new(gpu, &module, entry, &ARGS);
    let params = gpu.uniform(&Params {
        n: n as u32,
        pad: [0; 3],
    });
    let out = gpu.storage("clip out", n * out_words)?;
    let mut encoder = gpu.encoder();
    kernel.dispatch(
        gpu,
        &mut encoder,
        &[&params, inputs[0], inputs[1], &out],
        n as u64,
    );
    gpu.submit(encoder);
    gpu.download(&out, n * out_words)
}

/// What the library's soft-f64 operations give for one case `(a, b, c)` (see [`f64_ops`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct F64Ops {
    pub add: f64,
    pub sub: f64,
    pub mul: f64,
    pub div: f64,
    /// `a.min(b)`, `a.max(b)` as the clip uses them.
    pub min: f64,
    pub max: f64,
    pub lt: bool,
    pub le: bool,
    pub ge: bool,
    pub eq: bool,
    /// The f32 nearest `a` towards -inf and +inf.
    pub down: f32,
    pub up: f32,
    /// `c as f64`.
    pub widened: f64,
}

/// Runs every soft-f64 operation of the library on each case `(a, b, c)` (finite values), for
/// tests against the CPU's own f64 arithmetic.
pub fn f64_ops(gpu: &Gpu, cases: &[(f64, f64, f32)]) -> Result<Vec<F64Ops>, GpuError> {
    let split = |x: f64| [(x.to_bits() >> 32) as u32, x.to_bits() as u32];
    let words: Vec<u32> = cases
        .iter()
        .flat_map(|&(a, b, c)| {
            let (a, b) = (split(a), split(b));
            [a[0], a[1], b[0], b[1], c.to_bits()]
        })
        .collect();
    let inputs = [gpu.upload("cases", &words), gpu.upload("unused", &[0u32])];
    let out = run(gpu, "f64_ops", cases.len(), [&inputs[0], &inputs[1]], 17)?;
    Ok(out
        .chunks_exact(17)
        .map(|w| {
            let d = |k: usize| f64::from_bits((w[k] as u64) << 32 | w[k + 1] as u64);
            let flag = |k: u32| w[12] >> k & 1 == 1;
            F64Ops {
                add: d(0),
                sub: d(2),
                mul: d(4),
                div: d(6),
                min: d(8),
                max: d(10),
                lt: flag(0),
                le: flag(1),
                ge: flag(2),
                eq: flag(3),
                down: f32::from_bits(w[13]),
                up: f32::from_bits(w[14]),
                widened: d(15),
            }
        })
        .collect())
}
