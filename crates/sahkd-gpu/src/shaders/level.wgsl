// The level builder's own kernels (see level.rs for the order they run in). This header goes
// in front of every kernel below; each section opened by a kernel marker line is compiled as
// its own module with only the bindings it uses.
//
// A kernel marked "with clip.wgsl" gets that library between this header and its body; every
// module starts with prelude.wgsl (`thread_index`, `order_key`). Each launch binds its buffers
// by the names declared here; a binding the kernel never writes is declared `read`.
//
// A level's references are a table in node order: per reference r its primitive
// `ref_prim[r]`, its node `ref_node[r]` and its box `ref_boxes[6r..6r+6]` (lo.xyz, hi.xyz;
// with clipping, the primitive's part inside the node). Node k's references are
// `starts[k] .. starts[k + 1]`, the same range as its segment of list 0.
// The references also sit in nine sorted lists of reference ids, concatenated in one `entries`
// array: list 3a + 0 holds every reference of every node sorted by its box's lo on axis a,
// list 3a + 1 sorted by hi, list 3a + 2 only the references flat on axis a (lo == hi), sorted
// by that value. Each node owns a contiguous segment of each list: `starts[j * (nodes + 1) +
// k]` is where node k's segment of list j begins. Stable partitions keep every segment sorted,
// so no level sorts again; only clipped straddlers, whose boxes change, are sorted on their own
// (few) and merged into their children's segments by rank.

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
    // Whether straddlers are clipped to the children (perfect splits).
    clip: u32,
    // Clipped straddlers' list entries, sorted (the `regen` records).
    regen: u32,
    pad1: u32,
    pad2: u32,
    pad3: u32,
}

// A sorted record of a clipped straddler's list entry: [group = list * next_nodes + child,
// order_key(value), new reference id, value bits].
const RECORD: u32 = 4u;

const HOLE: u32 = 0xffffffffu;



//! kernel axes_in_use
// Per node: the axes it prices (0 for a leaf by size or depth) and, per axis, its candidate
// capacity (two slots per reference), scanned next into the candidate layout.
@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> boxes: array<f32>;
@group(0) @binding(2) var<storage, read> starts: array<u32>;
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
@group(0) @binding(1) var<storage, read> ref_boxes: array<f32>;
@group(0) @binding(2) var<storage, read> boxes: array<f32>;
@group(0) @binding(3) var<storage, read> starts: array<u32>;
@group(0) @binding(4) var<storage, read> entries: array<u32>;
@group(0) @binding(5) var<storage, read> ref_node: array<u32>;
@group(0) @binding(6) var<storage, read> uses: array<u32>;
@group(0) @binding(7) var<storage, read> caps: array<u32>;
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
    let r = entries[e];
    let k = ref_node[r];
    if (((uses[k] >> a) & 1u) == 0u) {
        return;
    }
    let slot = caps[a * params.nodes + k] + 2u * (e - starts[3u * a * stride + k]);
    let node_lo = boxes[6u * k + a];
    let node_hi = boxes[6u * k + 3u + a];
    for (var side = 0u; side < 2u; side = side + 1u) {
        let v = ref_boxes[6u * r + 3u * side + a];
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
@group(0) @binding(1) var<storage, read> ref_boxes: array<f32>;
@group(0) @binding(2) var<storage, read> starts: array<u32>;
@group(0) @binding(3) var<storage, read> entries: array<u32>;
@group(0) @binding(4) var<storage, read> cand_pos: array<f32>;
@group(0) @binding(5) var<storage, read> cand_owner: array<u32>;
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
        let v = ref_boxes[6u * entries[mid] + value];
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
@group(0) @binding(1) var<storage, read> uses: array<u32>;
@group(0) @binding(2) var<storage, read> starts: array<u32>;
@group(0) @binding(3) var<storage, read> best: array<u32>;
@group(0) @binding(4) var<storage, read> cost: array<u32>;
@group(0) @binding(5) var<storage, read> packed: array<u32>;
@group(0) @binding(6) var<storage, read> cand_pos: array<u32>;
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

//! kernel sides with clip.wgsl
// Per reference (one extra thread writes the scans' last elements): the children it goes to
// (the CPU's rule: lo < p left, hi > p right, in-plane to the planar side). With clipping, a
// straddler is clipped to each child's box and goes only where its clipped box is not empty;
// it is "moved": its list entries are dropped from the partition and rebuilt from the clipped
// boxes (`regen_count` of them, scanned into the records' offsets).
@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> ref_boxes: array<f32>;
@group(0) @binding(2) var<storage, read> ref_prim: array<u32>;
@group(0) @binding(3) var<storage, read> ref_node: array<u32>;
@group(0) @binding(4) var<storage, read> triangles: array<f32>;
@group(0) @binding(5) var<storage, read> boxes: array<f32>;
@group(0) @binding(6) var<storage, read> split: array<u32>;
@group(0) @binding(7) var<storage, read_write> go_l: array<u32>;
@group(0) @binding(8) var<storage, read_write> go_r: array<u32>;
@group(0) @binding(9) var<storage, read_write> moved: array<u32>;
@group(0) @binding(10) var<storage, read_write> regen_count: array<u32>;
// Per moved reference: its clipped boxes in the left and right child (12 f32).
@group(0) @binding(11) var<storage, read_write> clip_boxes: array<f32>;

// The clipped box of a triangle (9 corner coordinates) in a box (lo.xyz, hi.xyz), by the
// bit-exact clip of clip.wgsl.
fn clip_to_box(tri: array<f32, 9>, b: array<f32, 6>) -> array<f32, 6> {
    let corners = array<vec3<f32>, 3>(
        vec3<f32>(tri[0], tri[1], tri[2]),
        vec3<f32>(tri[3], tri[4], tri[5]),
        vec3<f32>(tri[6], tri[7], tri[8]),
    );
    let c = clip_bounds(corners, vec3<f32>(b[0], b[1], b[2]), vec3<f32>(b[3], b[4], b[5]));
    return array<f32, 6>(c.lo.x, c.lo.y, c.lo.z, c.hi.x, c.hi.y, c.hi.z);
}

@compute @workgroup_size(256)
fn sides(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>, @builtin(local_invocation_index) lid: u32) {
    let r = thread_index(wid, nwg, lid);
    let n = params.refs;
    if (r > n) {
        return;
    }
    var left = false;
    var right = false;
    var is_moved = 0u;
    var regen = 0u;
    if (r < n) {
        let k = ref_node[r];
        if (split[4u * k] != 0u) {
            let a = split[4u * k + 1u];
            let pos = bitcast<f32>(split[4u * k + 2u]);
            let planar_left = split[4u * k + 3u] != 0u;
            let lo = ref_boxes[6u * r + a];
            let hi = ref_boxes[6u * r + 3u + a];
            let in_plane = lo == pos && hi == pos;
            left = lo < pos || (in_plane && planar_left);
            right = hi > pos || (in_plane && !planar_left);
            if (left && right && params.clip != 0u) {
                is_moved = 1u;
                let p = ref_prim[r];
                var tri: array<f32, 9>;
                for (var i = 0u; i < 9u; i = i + 1u) {
                    tri[i] = triangles[9u * p + i];
                }
                for (var side = 0u; side < 2u; side = side + 1u) {
                    var b: array<f32, 6>;
                    for (var c = 0u; c < 6u; c = c + 1u) {
                        b[c] = boxes[6u * k + c];
                    }
                    // The child's box: the left one ends at the plane, the right one starts there.
                    b[select(a, 3u + a, side == 0u)] = pos;
                    var clipped = clip_to_box(tri, b);
                    var kept = true;
                    var flat = 0u;
                    for (var c = 0u; c < 3u; c = c + 1u) {
                        kept = kept && clipped[c] <= clipped[3u + c];
                        flat = flat + u32(clipped[c] == clipped[3u + c]);
                    }
                    for (var c = 0u; c < 6u; c = c + 1u) {
                        clip_boxes[12u * r + 6u * side + c] = clipped[c];
                    }
                    if (side == 0u) {
                        left = kept;
                    } else {
                        right = kept;
                    }
                    // A lo and a hi entry per axis, and a flat entry per flat axis.
                    regen = regen + select(0u, 6u + flat, kept);
                }
            }
        }
        moved[r] = is_moved;
    }
    go_l[r] = u32(left);
    go_r[r] = u32(right);
    regen_count[r] = regen;
}

//! kernel classify
// Per entry of every list: whether it goes to its node's left child, right child, or both, as
// its reference does; entries of moved references go nowhere (they are rebuilt).
@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> entries: array<u32>;
@group(0) @binding(2) var<storage, read> moved: array<u32>;
// The scanned `go_l`, `go_r` of `sides`.
@group(0) @binding(3) var<storage, read> go_l: array<u32>;
@group(0) @binding(4) var<storage, read> go_r: array<u32>;
@group(0) @binding(5) var<storage, read_write> lflags: array<u32>;
@group(0) @binding(6) var<storage, read_write> rflags: array<u32>;

@compute @workgroup_size(256)
fn classify(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>, @builtin(local_invocation_index) lid: u32) {
    let e = thread_index(wid, nwg, lid);
    if (e > params.entries) {
        return;
    }
    var left = 0u;
    var right = 0u;
    if (e < params.entries) {
        let r = entries[e];
        if (moved[r] == 0u) {
            left = go_l[r + 1u] - go_l[r];
            right = go_r[r + 1u] - go_r[r];
        }
    }
    lflags[e] = left;
    rflags[e] = right;
}

//! kernel emit_nodes
// Per node, its output record: (3, first reference, count) for a leaf, (axis, position bits,
// left child) for an interior node; the children of a level follow it, in parent order.
@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> starts: array<u32>;
@group(0) @binding(2) var<storage, read> split: array<u32>;
@group(0) @binding(3) var<storage, read> split_scan: array<u32>;
@group(0) @binding(4) var<storage, read> leaf_scan: array<u32>;
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
// Per reference of a leaf: its primitive, at the leaf's offset.
@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> starts: array<u32>;
@group(0) @binding(2) var<storage, read> ref_prim: array<u32>;
@group(0) @binding(3) var<storage, read> ref_node: array<u32>;
@group(0) @binding(4) var<storage, read> split: array<u32>;
@group(0) @binding(5) var<storage, read> leaf_scan: array<u32>;
@group(0) @binding(6) var<storage, read_write> out_refs: array<u32>;

@compute @workgroup_size(256)
fn emit_refs(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>, @builtin(local_invocation_index) lid: u32) {
    let r = thread_index(wid, nwg, lid);
    if (r >= params.refs) {
        return;
    }
    let k = ref_node[r];
    if (split[4u * k] != 0u) {
        return;
    }
    out_refs[params.ref_base + leaf_scan[k] + r - starts[k]] = ref_prim[r];
}

//! kernel scatter_refs
// Per reference of a split node: its entry in each child's part of the next level's reference
// table (the table stays in node order: children in their parents' order, a left child's
// references before its sibling's), with its box there (clipped for a moved reference), and
// its new id, which the list entries take.
@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> starts: array<u32>;
@group(0) @binding(2) var<storage, read> ref_prim: array<u32>;
@group(0) @binding(3) var<storage, read> ref_node: array<u32>;
@group(0) @binding(4) var<storage, read> ref_boxes: array<f32>;
@group(0) @binding(5) var<storage, read> moved: array<u32>;
@group(0) @binding(6) var<storage, read> clip_boxes: array<f32>;
@group(0) @binding(7) var<storage, read> go_l: array<u32>;
@group(0) @binding(8) var<storage, read> go_r: array<u32>;
@group(0) @binding(9) var<storage, read> split_scan: array<u32>;
@group(0) @binding(10) var<storage, read_write> next_prim: array<u32>;
@group(0) @binding(11) var<storage, read_write> next_node: array<u32>;
@group(0) @binding(12) var<storage, read_write> next_boxes: array<f32>;
@group(0) @binding(13) var<storage, read_write> new_id: array<u32>;

@compute @workgroup_size(256)
fn scatter_refs(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>, @builtin(local_invocation_index) lid: u32) {
    let r = thread_index(wid, nwg, lid);
    if (r >= params.refs) {
        return;
    }
    let k = ref_node[r];
    let s = starts[k];
    let end = starts[k + 1u];
    for (var side = 0u; side < 2u; side = side + 1u) {
        var d: u32;
        if (side == 0u) {
            if (go_l[r + 1u] == go_l[r]) {
                continue;
            }
            d = go_l[r] + go_r[s];
        } else {
            if (go_r[r + 1u] == go_r[r]) {
                continue;
            }
            d = go_l[end] + go_r[r];
        }
        new_id[2u * r + side] = d;
        next_prim[d] = ref_prim[r];
        next_node[d] = 2u * split_scan[k] + side;
        // (An if, not a select: a select would read both, and without clipping `clip_boxes`
        // holds one word.)
        for (var c = 0u; c < 6u; c = c + 1u) {
            if (moved[r] != 0u) {
                next_boxes[6u * d + c] = clip_boxes[12u * r + 6u * side + c];
            } else {
                next_boxes[6u * d + c] = ref_boxes[6u * r + c];
            }
        }
    }
}

//! kernel regen_emit
// Per moved reference: the records of its list entries in each child it goes to, at its offset
// from the scanned `regen_count`; sorted next, they are merged into the children's lists.
@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> ref_node: array<u32>;
@group(0) @binding(2) var<storage, read> moved: array<u32>;
@group(0) @binding(3) var<storage, read> clip_boxes: array<u32>;
@group(0) @binding(4) var<storage, read> go_l: array<u32>;
@group(0) @binding(5) var<storage, read> go_r: array<u32>;
@group(0) @binding(6) var<storage, read> regen_scan: array<u32>;
@group(0) @binding(7) var<storage, read> split_scan: array<u32>;
@group(0) @binding(8) var<storage, read> new_id: array<u32>;
@group(0) @binding(9) var<storage, read_write> records: array<u32>;

@compute @workgroup_size(256)
fn regen_emit(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>, @builtin(local_invocation_index) lid: u32) {
    let r = thread_index(wid, nwg, lid);
    if (r >= params.refs || moved[r] == 0u) {
        return;
    }
    let k = ref_node[r];
    var o = regen_scan[r];
    for (var side = 0u; side < 2u; side = side + 1u) {
        let kept = select(go_r[r + 1u] - go_r[r], go_l[r + 1u] - go_l[r], side == 0u);
        if (kept == 0u) {
            continue;
        }
        let c = 2u * split_scan[k] + side;
        let b = 12u * r + 6u * side;
        for (var j = 0u; j < 9u; j = j + 1u) {
            let a = j / 3u;
            let t = j % 3u;
            let bits = clip_boxes[b + select(a, 3u + a, t == 1u)];
            if (t == 2u && bitcast<f32>(clip_boxes[b + a]) != bitcast<f32>(clip_boxes[b + 3u + a])) {
                continue;
            }
            records[RECORD * o] = j * params.next_nodes + c;
            records[RECORD * o + 1u] = order_key(bits);
            records[RECORD * o + 2u] = new_id[2u * r + side];
            records[RECORD * o + 3u] = bits;
            o = o + 1u;
        }
    }
}

//! kernel next_level
// Per (list, node) of a split node: the children's segment starts in the next level's lists:
// the kept entries flagged before a segment (scanned flags) and the sorted records of the
// groups before it land before it. One extra thread per list writes its end. Once per node,
// the children's boxes and parent.
@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> boxes: array<f32>;
@group(0) @binding(2) var<storage, read> starts: array<u32>;
@group(0) @binding(3) var<storage, read> split: array<u32>;
@group(0) @binding(4) var<storage, read> split_scan: array<u32>;
@group(0) @binding(5) var<storage, read> lscan: array<u32>;
@group(0) @binding(6) var<storage, read> rscan: array<u32>;
@group(0) @binding(7) var<storage, read> records: array<u32>;
@group(0) @binding(8) var<storage, read_write> next_starts: array<u32>;
@group(0) @binding(9) var<storage, read_write> next_boxes: array<f32>;
@group(0) @binding(10) var<storage, read_write> parent: array<u32>;

// Records of the groups before `g`.
fn records_before(g: u32) -> u32 {
    var lo = 0u;
    var hi = params.regen;
    while (lo < hi) {
        let mid = lo + (hi - lo) / 2u;
        if (records[RECORD * mid] < g) {
            lo = mid + 1u;
        } else {
            hi = mid;
        }
    }
    return lo;
}

@compute @workgroup_size(256)
fn next_level(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>, @builtin(local_invocation_index) lid: u32) {
    let t = thread_index(wid, nwg, lid);
    let stride = params.nodes + 1u;
    if (t >= 9u * stride) {
        return;
    }
    let j = t / stride;
    let k = t % stride;
    let nn = params.next_nodes;
    let next_stride = nn + 1u;
    let s = starts[j * stride + k];
    if (k == params.nodes) {
        next_starts[j * next_stride + nn] = lscan[s] + rscan[s] + records_before(j * nn + nn);
        return;
    }
    if (split[4u * k] == 0u) {
        return;
    }
    let r = split_scan[k];
    let end = starts[j * stride + k + 1u];
    let g = j * nn + 2u * r;
    next_starts[j * next_stride + 2u * r] = lscan[s] + rscan[s] + records_before(g);
    next_starts[j * next_stride + 2u * r + 1u] = lscan[end] + rscan[s] + records_before(g + 1u);
    if (j == 0u) {
        parent[2u * r] = k;
        parent[2u * r + 1u] = k;
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
// Per kept entry: its place in the children's segments. Left: lscan[e] + rscan[segment start],
// right: lscan[segment end] + rscan[e] (the kept entries before it in every list), plus the
// sorted records before it: those of earlier groups and those of its own group with a smaller
// value (a record lands after the kept entries of equal value).
@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> starts: array<u32>;
@group(0) @binding(2) var<storage, read> entries: array<u32>;
@group(0) @binding(3) var<storage, read> ref_node: array<u32>;
@group(0) @binding(4) var<storage, read> ref_boxes: array<u32>;
@group(0) @binding(5) var<storage, read> split_scan: array<u32>;
@group(0) @binding(6) var<storage, read> lscan: array<u32>;
@group(0) @binding(7) var<storage, read> rscan: array<u32>;
@group(0) @binding(8) var<storage, read> records: array<u32>;
@group(0) @binding(9) var<storage, read> new_id: array<u32>;
@group(0) @binding(10) var<storage, read_write> out_entries: array<u32>;

// Records ordered before (group g, value key).
fn records_before(g: u32, key: u32) -> u32 {
    var lo = 0u;
    var hi = params.regen;
    while (lo < hi) {
        let mid = lo + (hi - lo) / 2u;
        let mg = records[RECORD * mid];
        if (mg < g || (mg == g && records[RECORD * mid + 1u] < key)) {
            lo = mid + 1u;
        } else {
            hi = mid;
        }
    }
    return lo;
}

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
    let r = entries[e];
    let k = ref_node[r];
    let s = starts[j * stride + k];
    let end = starts[j * stride + k + 1u];
    let a = j / 3u;
    let key = order_key(ref_boxes[6u * r + select(a, 3u + a, j % 3u == 1u)]);
    let g = j * params.next_nodes + 2u * split_scan[k];
    if (left != 0u) {
        out_entries[lscan[e] + rscan[s] + records_before(g, key)] = new_id[2u * r];
    }
    if (right != 0u) {
        out_entries[lscan[end] + rscan[e] + records_before(g + 1u, key)] = new_id[2u * r + 1u];
    }
}

//! kernel regen_place
// Per sorted record: its entry's place in its child's segment: the records before it, and the
// kept entries before its segment and those of its segment of at most its value (found by a
// binary search of the parent's sorted segment, counted by the scanned flags).
@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> starts: array<u32>;
@group(0) @binding(2) var<storage, read> entries: array<u32>;
@group(0) @binding(3) var<storage, read> ref_boxes: array<f32>;
@group(0) @binding(4) var<storage, read> lscan: array<u32>;
@group(0) @binding(5) var<storage, read> rscan: array<u32>;
@group(0) @binding(6) var<storage, read> records: array<u32>;
@group(0) @binding(7) var<storage, read> parent: array<u32>;
@group(0) @binding(8) var<storage, read_write> out_entries: array<u32>;

@compute @workgroup_size(256)
fn regen_place(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>, @builtin(local_invocation_index) lid: u32) {
    let i = thread_index(wid, nwg, lid);
    if (i >= params.regen) {
        return;
    }
    let g = records[RECORD * i];
    let j = g / params.next_nodes;
    let c = g % params.next_nodes;
    let k = parent[c];
    let value = bitcast<f32>(records[RECORD * i + 3u]);
    let a = j / 3u;
    let vi = select(a, 3u + a, j % 3u == 1u);
    let stride = params.nodes + 1u;
    let s = starts[j * stride + k];
    let end = starts[j * stride + k + 1u];
    // The first entry of the parent's segment with a greater value.
    var lo = s;
    var hi = end;
    while (lo < hi) {
        let mid = lo + (hi - lo) / 2u;
        if (ref_boxes[6u * entries[mid] + vi] <= value) {
            lo = mid + 1u;
        } else {
            hi = mid;
        }
    }
    var kept: u32;
    if ((c & 1u) == 0u) {
        kept = lscan[lo] + rscan[s];
    } else {
        kept = lscan[end] + rscan[lo];
    }
    out_entries[i + kept] = records[RECORD * i + 2u];
}

//! kernel payloads
// The device presort's last step: list entry i is the primitive of sorted record i (records
// `(list, value key, primitive, primitive)`, see level/presort.rs).
@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> records: array<u32>;
@group(0) @binding(2) var<storage, read_write> out_entries: array<u32>;

@compute @workgroup_size(256)
fn payloads(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>, @builtin(local_invocation_index) lid: u32) {
    let i = thread_index(wid, nwg, lid);
    if (i >= params.entries) {
        return;
    }
    out_entries[i] = records[RECORD * i + 3u];
}
