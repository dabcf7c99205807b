// The scatter of the stable split (see partition.wgsl).

struct Params { n: u32, pad0: u32, pad1: u32, pad2: u32 }

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> side: array<u32>;
@group(0) @binding(2) var<storage, read> flags: array<u32>;
@group(0) @binding(3) var<storage, read> values: array<u32>;
@group(0) @binding(4) var<storage, read> owner: array<u32>;
// Per segment: its first element, and the first slots of its left and right outputs.
@group(0) @binding(5) var<storage, read> segments: array<vec4<u32>>;
@group(0) @binding(6) var<storage, read_write> out: array<u32>;

@compute @workgroup_size(256)
fn scatter(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let i = thread_index(wid, nwg, lid);
    if (i >= params.n) {
        return;
    }
    let s = side[i];
    let seg = segments[owner[i]];
    let right = params.n + 1u;
    if ((s & 1u) != 0u) {
        out[seg.y + flags[i] - flags[seg.x]] = values[i];
    }
    if ((s & 2u) != 0u) {
        out[seg.z + flags[right + i] - flags[right + seg.x]] = values[i];
    }
}
