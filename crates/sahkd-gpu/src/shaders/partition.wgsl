// Stable split of segmented elements into left and right outputs, by flags, scans and a
// scatter. An element of segment s with side bit 1 goes to its segment's left output, with bit
// 2 to its right output (both for a straddler, neither for 0), in input order: its rank among
// the segment's left elements is the exclusive scan of the left flags at the element minus the
// same scan at the segment's first element.

struct Params { n: u32, pad0: u32, pad1: u32, pad2: u32 }

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> side: array<u32>;
// Two flags per element: left at [0, n], right at [n + 1, 2n + 1] (each half with a trailing
// 0). One exclusive scan over all 2n + 2 runs between this kernel and the scatter: the right
// half's ranks are then offset by the left total, which cancels in the scatter's differences.
@group(0) @binding(2) var<storage, read_write> flags: array<u32>;

@compute @workgroup_size(256)
fn set_flags(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let i = thread_index(wid, nwg, lid);
    if (i > params.n) {
        return;
    }
    var s = 0u;
    if (i < params.n) {
        s = side[i];
    }
    flags[i] = s & 1u;
    flags[params.n + 1u + i] = (s >> 1u) & 1u;
}
