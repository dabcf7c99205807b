// Multi-pass exclusive prefix sum of u32 (wrapping): every workgroup scans its block of 1024
// (4 consecutive elements per thread, summed in registers, then the 256 thread totals in
// workgroup memory) and writes the block's total; the totals are scanned the same way (by the
// host, recursively) and added back. No workgroup ever waits on another.

struct Params { n: u32, pad0: u32, pad1: u32, pad2: u32 }

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read_write> data: array<u32>;
@group(0) @binding(2) var<storage, read_write> sums: array<u32>;

const PER_THREAD: u32 = 4u;
const BLOCK: u32 = 1024u;

var<workgroup> tile: array<u32, 256>;

@compute @workgroup_size(256)
fn scan_blocks(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let block = wid.y * nwg.x + wid.x;
    let first = block * BLOCK + lid * PER_THREAD;
    var before: array<u32, 4>;
    var total = 0u;
    for (var j = 0u; j < PER_THREAD; j = j + 1u) {
        before[j] = total;
        if (first + j < params.n) {
            total = total + data[first + j];
        }
    }
    tile[lid] = total;
    workgroupBarrier();
    // Hillis-Steele: after the step of distance d, tile[t] sums the 2d thread totals ending at t.
    for (var d = 1u; d < 256u; d = d << 1u) {
        var earlier = 0u;
        if (lid >= d) {
            earlier = tile[lid - d];
        }
        workgroupBarrier();
        tile[lid] = tile[lid] + earlier;
        workgroupBarrier();
    }
    let offset = tile[lid] - total;
    for (var j = 0u; j < PER_THREAD; j = j + 1u) {
        if (first + j < params.n) {
            data[first + j] = offset + before[j];
        }
    }
    if (lid == 255u && block * BLOCK < params.n) {
        sums[block] = tile[255];
    }
}

@compute @workgroup_size(256)
fn add_block_sums(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let block = wid.y * nwg.x + wid.x;
    let first = block * BLOCK + lid * PER_THREAD;
    for (var j = 0u; j < PER_THREAD; j = j + 1u) {
        if (first + j < params.n) {
            data[first + j] = data[first + j] + sums[block];
        }
    }
}
