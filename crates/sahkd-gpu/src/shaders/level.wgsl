// The level builder's own kernels (see level.rs for the order they run in). This header goes
// in front of every kernel below; each section opened by a kernel marker line is compiled as
// its own module with only the bindings it uses.
//
// A level's references sit in nine sorted lists, concatenated in one `entries` array of
// primitive indices: list 3a + 0 holds every reference of every node sorted by its box's lo
// on axis a, list 3a + 1 sorted by hi, list 3a + 2 only the references flat on axis a
// (lo == hi), sorted by that value. Each node owns a contiguous segment of each list:
// `starts[j * (nodes + 1) + k]` is where node k's segment of list j begins. Stable partitions
// keep every segment sorted, so no level sorts again.

struct Params {
    nodes: u32,
    entries: u32,
    // Length of each full list (the level's references).
    refs: u32,
    depth: u32,
    max_depth: u32,
    leaf_size: u32,
    axes_all: u32,
    force_leaves: u32,
    intersection: f32,
    cands: u32,
    first1: u32,
    first2: u32,
    next_nodes: u32,
    node_base: u32,
    ref_base: u32,
    pad: u32,
}

const HOLE: u32 = 0xffffffffu;

fn thread_index(wid: vec3<u32>, nwg: vec3<u32>, lid: u32) -> u32 {
    return (wid.y * nwg.x + wid.x) * 256u + lid;
}

// Integer key ordered like the float; -0 and +0 share one.
fn order_key(bits: u32) -> u32 {
    if (bits == 0x80000000u) {
        return 0x80000000u;
    }
    if ((bits & 0x80000000u) != 0u) {
        return ~bits;
    }
    return bits | 0x80000000u;
}

//! kernel axes_in_use
// Per node: the axes it prices (0 for a leaf by size or depth) and, per axis, its candidate
// capacity (two slots per reference), scanned next into the candidate layout.
@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read_write> boxes: array<f32>;
@group(0) @binding(2) var<storage, read_write> starts: array<u32>;
@group(0) @binding(3) var<storage, read_write> uses: array<u32>;
@group(0) @binding(4) var<storage, read_write> caps: array<u32>;

@compute @workgroup_size(256)
fn axes_in_use(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>, @builtin(local_invocation_index) lid: u32) {
    let k = thread_index(wid, nwg, lid);
    let n = params.nodes;
    if (k == 0u) {
        caps[3u * n] = 0u;
    }
    if (k >= n) {
        return;
    }
    let len = starts[k + 1u] - starts[k];
    var u = 0u;
    if (len > params.leaf_size && params.depth < params.max_depth) {
        if (params.axes_all != 0u) {
            u = 7u;
        } else {
            let d0 = boxes[6u * k + 3u] - boxes[6u * k];
            let d1 = boxes[6u * k + 4u] - boxes[6u * k + 1u];
            let d2 = boxes[6u * k + 5u] - boxes[6u * k + 2u];
            // Ties to the lower axis, as Aabb::longest_axis.
            if (d0 >= d1 && d0 >= d2) {
                u = 1u;
            } else if (d1 >= d2) {
                u = 2u;
            } else {
                u = 4u;
            }
        }
    }
    uses[k] = u;
    for (var a = 0u; a < 3u; a = a + 1u) {
        caps[a * n + k] = select(0u, 2u * len, ((u >> a) & 1u) != 0u);
    }
}

//! kernel candidates
// Per (axis, reference of the lo list): the reference's lo and hi as candidates of its node
// when strictly inside the node's box, holes otherwise (positions at -0 written +0).
@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read_write> prim_boxes: array<f32>;
@group(0) @binding(2) var<storage, read_write> boxes: array<f32>;
@group(0) @binding(3) var<storage, read_write> starts: array<u32>;
@group(0) @binding(4) var<storage, read_write> entries: array<u32>;
@group(0) @binding(5) var<storage, read_write> owner: array<u32>;
@group(0) @binding(6) var<storage, read_write> uses: array<u32>;
@group(0) @binding(7) var<storage, read_write> caps: array<u32>;
@group(0) @binding(8) var<storage, read_write> cand_pos: array<u32>;
@group(0) @binding(9) var<storage, read_write> cand_owner: array<u32>;

@compute @workgroup_size(256)
fn candidates(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>, @builtin(local_invocation_index) lid: u32) {
    let t = thread_index(wid, nwg, lid);
    if (t >= 3u * params.refs) {
        return;
    }
    let a = t / params.refs;
    let stride = params.nodes + 1u;
    let e = starts[3u * a * stride] + t % params.refs;
    let k = owner[e];
    if (((uses[k] >> a) & 1u) == 0u) {
        return;
    }
    let slot = caps[a * params.nodes + k] + 2u * (e - starts[3u * a * stride + k]);
    let p = entries[e];
    let node_lo = boxes[6u * k + a];
    let node_hi = boxes[6u * k + 3u + a];
    for (var side = 0u; side < 2u; side = side + 1u) {
        let v = prim_boxes[6u * p + 3u * side + a];
        var bits = bitcast<u32>(v);
        if (bits == 0x80000000u) {
            bits = 0u;
        }
        if (node_lo < v && v < node_hi) {
            cand_pos[slot + side] = bits;
            cand_owner[slot + side] = k;
        } else {
            cand_pos[slot + side] = 0u;
            cand_owner[slot + side] = HOLE;
        }
    }
}

//! kernel count
// Per candidate: L = #(lo < p), R = #(hi > p), P = #(lo == p == hi) in its node, by binary
// searches of the node's sorted segments.
@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read_write> prim_boxes: array<f32>;
@group(0) @binding(2) var<storage, read_write> starts: array<u32>;
@group(0) @binding(3) var<storage, read_write> entries: array<u32>;
@group(0) @binding(4) var<storage, read_write> cand_pos: array<f32>;
@group(0) @binding(5) var<storage, read_write> cand_owner: array<u32>;
@group(0) @binding(6) var<storage, read_write> counts: array<u32>;

// How many entries of node k's segment of list j have value (lo or hi on axis a) below p, or
// at most p when `inclusive`.
fn rank(j: u32, k: u32, value: u32, p: f32, inclusive: bool) -> u32 {
    let stride = params.nodes + 1u;
    let first = starts[j * stride + k];
    var lo = first;
    var hi = starts[j * stride + k + 1u];
    while (lo < hi) {
        let mid = lo + (hi - lo) / 2u;
        let v = prim_boxes[6u * entries[mid] + value];
        if (v < p || (inclusive && v == p)) {
            lo = mid + 1u;
        } else {
            hi = mid;
        }
    }
    return lo - first;
}

@compute @workgroup_size(256)
fn count(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>, @builtin(local_invocation_index) lid: u32) {
    let i = thread_index(wid, nwg, lid);
    if (i >= params.cands) {
        return;
    }
    let k = cand_owner[i];
    if (k == HOLE) {
        counts[3u * i] = 0u;
        counts[3u * i + 1u] = 0u;
        counts[3u * i + 2u] = 0u;
        return;
    }
    let a = u32(i >= params.first1) + u32(i >= params.first2);
    let p = cand_pos[i];
    let stride = params.nodes + 1u;
    let len = starts[3u * a * stride + k + 1u] - starts[3u * a * stride + k];
    counts[3u * i] = rank(3u * a, k, a, p, false);
    counts[3u * i + 1u] = len - rank(3u * a + 1u, k, 3u + a, p, true);
    counts[3u * i + 2u] = rank(3u * a + 2u, k, a, p, true) - rank(3u * a + 2u, k, a, p, false);
}

//! kernel fill
@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read_write> out: array<u32>;

@compute @workgroup_size(256)
fn fill(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>, @builtin(local_invocation_index) lid: u32) {
    let i = thread_index(wid, nwg, lid);
    if (i < 3u * params.nodes) {
        out[i] = 0xffffffffu;
    }
}

//! kernel decide
// Per node: split at its best candidate when that costs strictly less than the leaf (and the
// level is not forced to leaves by the reference budget); the per-node values that the scans
// turn into child ranks, leaf reference offsets and the next level's reference count.
@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read_write> uses: array<u32>;
@group(0) @binding(2) var<storage, read_write> starts: array<u32>;
@group(0) @binding(3) var<storage, read_write> best: array<u32>;
@group(0) @binding(4) var<storage, read_write> cost: array<u32>;
@group(0) @binding(5) var<storage, read_write> packed: array<u32>;
@group(0) @binding(6) var<storage, read_write> cand_pos: array<u32>;
// Per node: split (0/1), axis, position bits, planar_left.
@group(0) @binding(7) var<storage, read_write> split: array<u32>;
@group(0) @binding(8) var<storage, read_write> split_scan: array<u32>;
@group(0) @binding(9) var<storage, read_write> leaf_scan: array<u32>;
@group(0) @binding(10) var<storage, read_write> next_scan: array<u32>;

@compute @workgroup_size(256)
fn decide(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>, @builtin(local_invocation_index) lid: u32) {
    let k = thread_index(wid, nwg, lid);
    let n = params.nodes;
    if (k == 0u) {
        split_scan[n] = 0u;
        leaf_scan[n] = 0u;
        next_scan[n] = 0u;
    }
    if (k >= n) {
        return;
    }
    let len = starts[k + 1u] - starts[k];
    let i = best[3u * k + 2u];
    var is_split = false;
    if (uses[k] != 0u && i != HOLE && params.force_leaves == 0u) {
        let leaf_cost = params.intersection * f32(len);
        is_split = order_key(cost[i]) < order_key(bitcast<u32>(leaf_cost));
    }
    if (is_split) {
        split[4u * k] = 1u;
        split[4u * k + 1u] = u32(i >= params.first1) + u32(i >= params.first2);
        split[4u * k + 2u] = cand_pos[i];
        split[4u * k + 3u] = packed[i] & 1u;
        split_scan[k] = 1u;
        leaf_scan[k] = 0u;
        next_scan[k] = packed[i] >> 1u;
    } else {
        split[4u * k] = 0u;
        split_scan[k] = 0u;
        leaf_scan[k] = len;
        next_scan[k] = 0u;
    }
}

//! kernel classify
// Per entry of every list: whether it goes to its node's left child, right child, or both
// (the CPU's rule: lo < p left, hi > p right, in-plane to the planar side).
@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read_write> prim_boxes: array<f32>;
@group(0) @binding(2) var<storage, read_write> entries: array<u32>;
@group(0) @binding(3) var<storage, read_write> owner: array<u32>;
@group(0) @binding(4) var<storage, read_write> split: array<u32>;
@group(0) @binding(5) var<storage, read_write> lflags: array<u32>;
@group(0) @binding(6) var<storage, read_write> rflags: array<u32>;

@compute @workgroup_size(256)
fn classify(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>, @builtin(local_invocation_index) lid: u32) {
    let e = thread_index(wid, nwg, lid);
    if (e > params.entries) {
        return;
    }
    var left = false;
    var right = false;
    if (e < params.entries) {
        let k = owner[e];
        if (split[4u * k] != 0u) {
            let a = split[4u * k + 1u];
            let pos = bitcast<f32>(split[4u * k + 2u]);
            let planar_left = split[4u * k + 3u] != 0u;
            let p = entries[e];
            let lo = prim_boxes[6u * p + a];
            let hi = prim_boxes[6u * p + 3u + a];
            let in_plane = lo == pos && hi == pos;
            left = lo < pos || (in_plane && planar_left);
            right = hi > pos || (in_plane && !planar_left);
        }
    }
    lflags[e] = u32(left);
    rflags[e] = u32(right);
}

//! kernel emit_nodes
// Per node, its output record: (3, first reference, count) for a leaf, (axis, position bits,
// left child) for an interior node; the children of a level follow it, in parent order.
@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read_write> starts: array<u32>;
@group(0) @binding(2) var<storage, read_write> split: array<u32>;
@group(0) @binding(3) var<storage, read_write> split_scan: array<u32>;
@group(0) @binding(4) var<storage, read_write> leaf_scan: array<u32>;
@group(0) @binding(5) var<storage, read_write> out_nodes: array<u32>;

@compute @workgroup_size(256)
fn emit_nodes(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>, @builtin(local_invocation_index) lid: u32) {
    let k = thread_index(wid, nwg, lid);
    if (k >= params.nodes) {
        return;
    }
    let o = 3u * (params.node_base + k);
    if (split[4u * k] != 0u) {
        out_nodes[o] = split[4u * k + 1u];
        out_nodes[o + 1u] = split[4u * k + 2u];
        out_nodes[o + 2u] = params.node_base + params.nodes + 2u * split_scan[k];
    } else {
        out_nodes[o] = 3u;
        out_nodes[o + 1u] = params.ref_base + leaf_scan[k];
        out_nodes[o + 2u] = starts[k + 1u] - starts[k];
    }
}

//! kernel emit_refs
// Per reference of a leaf (taken from list 0): its primitive, at the leaf's offset.
@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read_write> starts: array<u32>;
@group(0) @binding(2) var<storage, read_write> entries: array<u32>;
@group(0) @binding(3) var<storage, read_write> owner: array<u32>;
@group(0) @binding(4) var<storage, read_write> split: array<u32>;
@group(0) @binding(5) var<storage, read_write> leaf_scan: array<u32>;
@group(0) @binding(6) var<storage, read_write> out_refs: array<u32>;

@compute @workgroup_size(256)
fn emit_refs(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>, @builtin(local_invocation_index) lid: u32) {
    let e = thread_index(wid, nwg, lid);
    if (e >= params.refs) {
        return;
    }
    let k = owner[e];
    if (split[4u * k] != 0u) {
        return;
    }
    out_refs[params.ref_base + leaf_scan[k] + e - starts[k]] = entries[e];
}

//! kernel next_level
// Per (list, node) of a split node: the children's segment starts in the next level's lists
// (from the scanned flags: everything flagged before a segment lands before it), and, once
// per node, the children's boxes. One extra thread per list writes its end.
@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read_write> boxes: array<f32>;
@group(0) @binding(2) var<storage, read_write> starts: array<u32>;
@group(0) @binding(3) var<storage, read_write> split: array<u32>;
@group(0) @binding(4) var<storage, read_write> split_scan: array<u32>;
@group(0) @binding(5) var<storage, read_write> lscan: array<u32>;
@group(0) @binding(6) var<storage, read_write> rscan: array<u32>;
@group(0) @binding(7) var<storage, read_write> next_starts: array<u32>;
@group(0) @binding(8) var<storage, read_write> next_boxes: array<f32>;

@compute @workgroup_size(256)
fn next_level(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>, @builtin(local_invocation_index) lid: u32) {
    let t = thread_index(wid, nwg, lid);
    let stride = params.nodes + 1u;
    if (t >= 9u * stride) {
        return;
    }
    let j = t / stride;
    let k = t % stride;
    let next_stride = params.next_nodes + 1u;
    let s = starts[j * stride + k];
    if (k == params.nodes) {
        next_starts[j * next_stride + params.next_nodes] = lscan[s] + rscan[s];
        return;
    }
    if (split[4u * k] == 0u) {
        return;
    }
    let r = split_scan[k];
    let end = starts[j * stride + k + 1u];
    next_starts[j * next_stride + 2u * r] = lscan[s] + rscan[s];
    next_starts[j * next_stride + 2u * r + 1u] = lscan[end] + rscan[s];
    if (j == 0u) {
        let a = split[4u * k + 1u];
        let pos = bitcast<f32>(split[4u * k + 2u]);
        for (var c = 0u; c < 6u; c = c + 1u) {
            let v = boxes[6u * k + c];
            next_boxes[6u * (2u * r) + c] = select(v, pos, c == 3u + a);
            next_boxes[6u * (2u * r + 1u) + c] = select(v, pos, c == a);
        }
    }
}

//! kernel scatter
// Per entry: its place in the children's segments, left: lscan[e] + rscan[segment start],
// right: lscan[segment end] + rscan[e] (the flagged entries before it in every list).
@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read_write> starts: array<u32>;
@group(0) @binding(2) var<storage, read_write> entries: array<u32>;
@group(0) @binding(3) var<storage, read_write> owner: array<u32>;
@group(0) @binding(4) var<storage, read_write> split_scan: array<u32>;
@group(0) @binding(5) var<storage, read_write> lscan: array<u32>;
@group(0) @binding(6) var<storage, read_write> rscan: array<u32>;
@group(0) @binding(7) var<storage, read_write> out_entries: array<u32>;
@group(0) @binding(8) var<storage, read_write> out_owner: array<u32>;

@compute @workgroup_size(256)
fn scatter(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>, @builtin(local_invocation_index) lid: u32) {
    let e = thread_index(wid, nwg, lid);
    if (e >= params.entries) {
        return;
    }
    let left = lscan[e + 1u] - lscan[e];
    let right = rscan[e + 1u] - rscan[e];
    if (left + right == 0u) {
        return;
    }
    let stride = params.nodes + 1u;
    // The list holding e: the last whose first segment starts at or before it.
    var j = 0u;
    for (var l = 1u; l < 9u; l = l + 1u) {
        if (starts[l * stride] <= e) {
            j = l;
        }
    }
    let k = owner[e];
    let s = starts[j * stride + k];
    let end = starts[j * stride + k + 1u];
    let child = 2u * split_scan[k];
    if (left != 0u) {
        let d = lscan[e] + rscan[s];
        out_entries[d] = entries[e];
        out_owner[d] = child;
    }
    if (right != 0u) {
        let d = lscan[end] + rscan[e];
        out_entries[d] = entries[e];
        out_owner[d] = child + 1u;
    }
}
