// Multi-pass exclusive prefix sum of u32 (wrapping): every workgroup scans its block of 256 in
// workgroup memory and writes the block's total; the totals are scanned the same way (by the
// host, recursively) and added back. No workgroup ever waits on another.

struct Params { n: u32, pad0: u32, pad1: u32, pad2: u32 }

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read_write> data: array<u32>;
@group(0) @binding(2) var<storage, read_write> sums: array<u32>;

var<workgroup> tile: array<u32, 256>;

@compute @workgroup_size(256)
fn scan_blocks(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let block = wid.y * nwg.x + wid.x;
    let i = block * 256u + lid;
    var x = 0u;
    if (i < params.n) {
        x = data[i];
    }
    tile[lid] = x;
    workgroupBarrier();
    // Hillis-Steele: after the step of distance d, tile[j] sums the 2d inputs ending at j.
    for (var d = 1u; d < 256u; d = d << 1u) {
        var before = 0u;
        if (lid >= d) {
            before = tile[lid - d];
        }
        workgroupBarrier();
        tile[lid] = tile[lid] + before;
        workgroupBarrier();
    }
    if (i < params.n) {
        data[i] = tile[lid] - x;
    }
    if (lid == 255u && block * 256u < params.n) {
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
    let i = block * 256u + lid;
    if (i < params.n) {
        data[i] = data[i] + sums[block];
    }
}
