// Each node's best candidate: the cheapest, then the smallest position, then the lowest index
// (the candidate array holds axis 0's block before axis 1's before axis 2's, so the lowest
// index among equals is the lowest axis). Three launches of atomic minima, one per key, each
// considering only candidates that tie on the keys before it. Costs are >= 0 or +inf, so their
// bits order like the values; positions are mapped to order-preserving u32.

struct Params { n: u32, pad0: u32, pad1: u32, pad2: u32 }

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> cost: array<u32>;
@group(0) @binding(2) var<storage, read> pos: array<u32>;
@group(0) @binding(3) var<storage, read> owner: array<u32>;
// Per node: [best cost bits, best position key, best index], initialised to 0xffffffff.
@group(0) @binding(4) var<storage, read_write> best: array<atomic<u32>>;

const HOLE: u32 = 0xffffffffu;



@compute @workgroup_size(256)
fn min_cost(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let i = thread_index(wid, nwg, lid);
    if (i >= params.n || owner[i] == HOLE) {
        return;
    }
    atomicMin(&best[3u * owner[i]], cost[i]);
}

@compute @workgroup_size(256)
fn min_pos(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let i = thread_index(wid, nwg, lid);
    if (i >= params.n || owner[i] == HOLE) {
        return;
    }
    let k = owner[i];
    if (cost[i] == atomicLoad(&best[3u * k])) {
        atomicMin(&best[3u * k + 1u], order_key(pos[i]));
    }
}

@compute @workgroup_size(256)
fn min_index(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let i = thread_index(wid, nwg, lid);
    if (i >= params.n || owner[i] == HOLE) {
        return;
    }
    let k = owner[i];
    if (cost[i] == atomicLoad(&best[3u * k]) && order_key(pos[i]) == atomicLoad(&best[3u * k + 1u])) {
        atomicMin(&best[3u * k + 2u], i);
    }
}
