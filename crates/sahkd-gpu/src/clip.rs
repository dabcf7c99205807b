//! Triangles clipped to boxes on the GPU, bit for bit [`sahkd::clip::clipped_bounds`]: the
//! WGSL library [`CLIP_WGSL`] (software f64, see `shaders/clip.wgsl`) for the level builder's
//! kernels, and test-facing launches of it over host data.

#[cfg(feature = "testing")]
use crate::{kernel::Kernel, price::box_words, Gpu, GpuError};
#[cfg(feature = "testing")]
use sahkd::{Aabb, Triangle, Vec3};

/// The library: `clip_bounds(tri: array<vec3<f32>, 3>, box_lo: vec3<f32>, box_hi: vec3<f32>)
/// -> ClipResult { lo: vec3<f32>, hi: vec3<f32>, empty: bool }` and the `f64_*` operations.
/// No bindings or entry points; every name starts with `f64_`, `clip_` or `F64_`.
pub const CLIP_WGSL: &str = include_str!("shaders/clip.wgsl");

#[cfg(feature = "testing")]
/// Entry points over host data: `clip_pairs` (9 f32 corners and 6 f32 box bounds in, lo, hi
/// and the empty flag out) and `f64_ops` (each operation on two f64s and one f32).
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

fn clip_f32_at(i: u32) -> f32 {
    return bitcast<f32>(clip_in0[i]);
}

// Pair i: corners at in0[9i..], box (lo.xyz, hi.xyz) at in1[6i..]; out[7i..] = lo, hi, empty.
@compute @workgroup_size(256)
fn clip_pairs(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let i = (wid.y * nwg.x + wid.x) * 256u + lid;
    if (i >= clip_params.n) {
        return;
    }
    let t = 9u * i;
    let tri = array<vec3<f32>, 3>(
        vec3<f32>(clip_f32_at(t), clip_f32_at(t + 1u), clip_f32_at(t + 2u)),
        vec3<f32>(clip_f32_at(t + 3u), clip_f32_at(t + 4u), clip_f32_at(t + 5u)),
        vec3<f32>(clip_f32_at(t + 6u), clip_f32_at(t + 7u), clip_f32_at(t + 8u)),
    );
    let b = 6u * i;
    let lo = bitcast<vec3<f32>>(vec3<u32>(clip_in1[b], clip_in1[b + 1u], clip_in1[b + 2u]));
    let hi = bitcast<vec3<f32>>(vec3<u32>(clip_in1[b + 3u], clip_in1[b + 4u], clip_in1[b + 5u]));
    let r = clip_bounds(tri, lo, hi);
    let o = 7u * i;
    let rl = bitcast<vec3<u32>>(r.lo);
    let rh = bitcast<vec3<u32>>(r.hi);
    clip_out[o] = rl.x;
    clip_out[o + 1u] = rl.y;
    clip_out[o + 2u] = rl.z;
    clip_out[o + 3u] = rh.x;
    clip_out[o + 4u] = rh.y;
    clip_out[o + 5u] = rh.z;
    clip_out[o + 6u] = u32(r.empty);
}

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

#[cfg(feature = "testing")]
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Params {
    n: u32,
    pad: [u32; 3],
}

#[cfg(feature = "testing")]
fn run(
    gpu: &Gpu,
    entry: &str,
    n: usize,
    inputs: [&wgpu::Buffer; 2],
    out_words: usize,
) -> Result<Vec<u32>, GpuError> {
    let kernel = Kernel::new(gpu, &format!("{CLIP_WGSL}\n{KERNELS}"), entry);
    let params = gpu.uniform(&Params {
        n: n as u32,
        pad: [0; 3],
    });
    let out = gpu.storage("clip out", n * out_words)?;
    let mut encoder = gpu.encoder();
    kernel.dispatch(
        gpu,
        &mut encoder,
        &[
            ("clip_params", &params),
            ("clip_in0", inputs[0]),
            ("clip_in1", inputs[1]),
            ("clip_out", &out),
        ],
        n as u64,
    );
    gpu.submit(encoder);
    gpu.download(&out, n * out_words)
}

#[cfg(feature = "testing")]
/// `clipped_bounds(&tris[i], &boxes[i])` for every i, computed on the GPU, with the kernel's
/// own empty flag (which must equal `is_empty()` of the box).
pub fn clip_triangles(
    gpu: &Gpu,
    tris: &[Triangle],
    boxes: &[Aabb],
) -> Result<Vec<(Aabb, bool)>, GpuError> {
    assert_eq!(tris.len(), boxes.len(), "one box per triangle");
    let corners: Vec<f32> = tris
        .iter()
        .flat_map(|t| t.iter().flat_map(|v| v.0))
        .collect();
    let inputs = [
        gpu.upload("triangles", &corners),
        gpu.upload("boxes", &box_words(boxes)),
    ];
    let words = run(gpu, "clip_pairs", tris.len(), [&inputs[0], &inputs[1]], 7)?;
    Ok(words
        .chunks_exact(7)
        .map(|w| {
            let f = |k: usize| f32::from_bits(w[k]);
            let b = Aabb::new(Vec3::new(f(0), f(1), f(2)), Vec3::new(f(3), f(4), f(5)));
            (b, w[6] != 0)
        })
        .collect())
}

#[cfg(feature = "testing")]
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

#[cfg(feature = "testing")]
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
