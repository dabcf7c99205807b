// The paper's counting on the GPU: a space tree (implicit interval tree) over every node's
// segment of the three lo-sorted lists, then a stack-free walk per candidate. The layout and
// the walk are the CPU's (sahkd/src/build/level/space_tree.rs): slot i (1-based in its
// segment) holds the i-th span of the lo-sorted segment, has height h = trailing_zeros(i),
// children i -+ 2^(h-1), and stores lo, hi and max, the largest hi of its subtree. Slots past
// the segment's length are absent; an absent slot's present descendants are all in its left
// subtree.
//
// Lists: `entries` holds nine lists of reference ids (3a + 0 sorted by lo on axis a, 3a + 1
// by hi, 3a + 2 the references flat on axis a), node k's segment of list j starting at
// `starts[j * (nodes + 1) + k]`. The trees array holds one slot per entry of lists 0, 3 and 6,
// axis a's block at a * refs, aligned with its list: the slot of entry e of list 3a is
// a * refs + e - starts[3a * (nodes + 1)].
//
// This header goes in front of every kernel below; each section opened by a kernel marker
// line is compiled as its own module with only the bindings it uses.

struct Params {
    nodes: u32,
    // Entries of each lo-sorted list: every reference of the level once.
    refs: u32,
    cands: u32,
    first1: u32,
    first2: u32,
    // The height `heights` builds, and its windows per axis: ceil(refs / 2^height).
    height: u32,
    windows: u32,
    pad: u32,
}

struct TreeNode {
    lo: f32,
    hi: f32,
    max: f32,
}

const HOLE: u32 = 0xffffffffu;


//! kernel leaves
// Per slot: its span (height 0: max = hi), and the node whose segment holds it, which the
// higher heights need to find their segment in O(1).
@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> ref_boxes: array<f32>;
@group(0) @binding(2) var<storage, read> entries: array<u32>;
@group(0) @binding(3) var<storage, read> starts: array<u32>;
@group(0) @binding(4) var<storage, read_write> trees: array<TreeNode>;
@group(0) @binding(5) var<storage, read_write> slot_node: array<u32>;

@compute @workgroup_size(256)
fn leaves(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>, @builtin(local_invocation_index) lid: u32) {
    let t = thread_index(wid, nwg, lid);
    if (t >= 3u * params.refs) {
        return;
    }
    let a = t / params.refs;
    let first = 3u * a * (params.nodes + 1u);
    let e = starts[first] + t % params.refs;
    // The last node whose segment starts at or before e (empty segments share their start
    // with the next one, so the last is the one holding e).
    var lo = 0u;
    var hi = params.nodes;
    while (hi - lo > 1u) {
        let mid = lo + (hi - lo) / 2u;
        if (starts[first + mid] <= e) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    slot_node[t] = lo;
    let r = entries[e];
    let span_hi = ref_boxes[6u * r + 3u + a];
    trees[t] = TreeNode(ref_boxes[6u * r + a], span_hi, span_hi);
}

//! kernel heights
// Per window of 2^height slots of an axis block: the max of the slots of that height in it.
// A segment shorter than 2^height has no such slot, and a longer one has at most one per
// window, so only the segments holding the window's two ends can have one: one thread per
// window instead of one per slot (over all heights about one thread per slot, not 25).
@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> starts: array<u32>;
@group(0) @binding(2) var<storage, read> slot_node: array<u32>;
@group(0) @binding(3) var<storage, read_write> trees: array<TreeNode>;

// max of the subtree at slot c of a segment of n slots whose slot 1 is trees[base]; -inf
// when it has no present slot.
fn subtree_max(base: u32, n: u32, slot: u32) -> f32 {
    var c = slot;
    while (c > n && (c & 1u) == 0u) {
        c = c - (1u << (countTrailingZeros(c) - 1u));
    }
    if (c > n) {
        return bitcast<f32>(0xff800000u);
    }
    return trees[base + c - 1u].max;
}

// The slot of height `params.height` of node k's segment (axis a) in axis-local window
// [x0, x1], if any.
fn build_slot(a: u32, k: u32, x0: u32, x1: u32) {
    let h = params.height;
    let first = 3u * a * (params.nodes + 1u);
    let s = starts[first + k] - starts[first];
    let n = starts[first + k + 1u] - starts[first + k];
    // The window's slots are x - s + 1 for x in [x0, x1]; the one of height h is an odd
    // multiple of 2^h, and there is at most one multiple of 2^h among 2^h of them.
    let lowest = select(1u, x0 - s + 1u, x0 >= s);
    let i = ((lowest + (1u << h) - 1u) >> h) << h;
    if (i > min(x1 - s + 1u, n) || ((i >> h) & 1u) == 0u) {
        return;
    }
    let base = a * params.refs + s;
    let half = 1u << (h - 1u);
    let below = max(trees[base + i - half - 1u].max, subtree_max(base, n, i + half));
    let slot = trees[base + i - 1u];
    trees[base + i - 1u] = TreeNode(slot.lo, slot.hi, max(slot.hi, below));
}

@compute @workgroup_size(256)
fn heights(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>, @builtin(local_invocation_index) lid: u32) {
    let t = thread_index(wid, nwg, lid);
    if (t >= 3u * params.windows) {
        return;
    }
    let a = t / params.windows;
    let x0 = (t % params.windows) << params.height;
    let x1 = min(x0 + (1u << params.height), params.refs) - 1u;
    let k0 = slot_node[a * params.refs + x0];
    let k1 = slot_node[a * params.refs + x1];
    build_slot(a, k0, x0, x1);
    if (k1 != k0) {
        build_slot(a, k1, x0, x1);
    }
}

//! kernel count
// Per candidate: L = #(lo < p) and #(lo <= p) by binary searches of its node's tree (the lo
// order), R = #(hi > p) by the walk, P = #(lo == p) - touching; holes count zero. Walk steps
// and cut spans are summed per workgroup, then once per workgroup into `stats`: steps (lo,
// hi words), cut (lo, hi words), candidates walked.
@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> starts: array<u32>;
@group(0) @binding(2) var<storage, read> trees: array<TreeNode>;
@group(0) @binding(3) var<storage, read> cand_pos: array<f32>;
@group(0) @binding(4) var<storage, read> cand_owner: array<u32>;
@group(0) @binding(5) var<storage, read_write> counts: array<u32>;
@group(0) @binding(6) var<storage, read_write> stats: array<atomic<u32>>;

var<workgroup> group_sums: array<atomic<u32>, 5>;

// Slots of the n-slot tree at base with lo below p (or at most p when `inclusive`).
fn rank(base: u32, n: u32, p: f32, inclusive: bool) -> u32 {
    var lo = 0u;
    var hi = n;
    while (lo < hi) {
        let mid = lo + (hi - lo) / 2u;
        let v = trees[base + mid].lo;
        if (v < p || (inclusive && v == p)) {
            lo = mid + 1u;
        } else {
            hi = mid;
        }
    }
    return lo;
}

// The walk: (slots right of p counted in bulk, cut, touching, steps). A subtree with max <= p
// is skipped; a slot with lo > p is right of p with its whole right subtree, and only its
// left subtree is walked; any other slot is classified itself and both subtrees are walked.
fn walk(base: u32, n: u32, p: f32) -> vec4<u32> {
    var out = vec4<u32>(0u);
    if (n == 0u) {
        return out;
    }
    let root = 1u << firstLeadingBit(n);
    var i = root;
    var down = true;
    loop {
        if (down) {
            out.w = out.w + 1u;
            let h = countTrailingZeros(i);
            var deeper = true;
            if (i <= n) {
                let s = trees[base + i - 1u];
                if (s.max <= p) {
                    deeper = false;
                } else if (s.lo > p) {
                    out.x = out.x + min(i + (1u << h) - 1u, n) - i + 1u;
                } else if (s.hi > p) {
                    if (s.lo < p) {
                        out.y = out.y + 1u;
                    } else {
                        out.z = out.z + 1u;
                    }
                }
            }
            if (deeper && h > 0u) {
                i = i - (1u << (h - 1u));
                continue;
            }
            down = false;
        }
        // Up one slot; from a left child, into the parent's right subtree when the parent was
        // classified itself (present, max > p, lo <= p).
        if (i == root) {
            break;
        }
        let h = countTrailingZeros(i);
        if (((i >> (h + 1u)) & 1u) == 0u) {
            let parent = i + (1u << h);
            if (parent <= n) {
                let s = trees[base + parent - 1u];
                if (s.max > p && s.lo <= p) {
                    i = parent + (1u << h);
                    down = true;
                    continue;
                }
            }
            i = parent;
        } else {
            i = i - (1u << h);
        }
    }
    return out;
}

// Adds v to the 64-bit sum in words (w, w + 1) of the workgroup's sums.
fn add_to_group(w: u32, v: u32) {
    let old = atomicAdd(&group_sums[w], v);
    if (old + v < old) {
        atomicAdd(&group_sums[w + 1u], 1u);
    }
}

@compute @workgroup_size(256)
fn count(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>, @builtin(local_invocation_index) lid: u32) {
    let i = thread_index(wid, nwg, lid);
    var walked = vec4<u32>(0u);
    var priced = 0u;
    if (i < params.cands) {
        let k = cand_owner[i];
        var c = vec3<u32>(0u);
        if (k != HOLE) {
            let a = u32(i >= params.first1) + u32(i >= params.first2);
            let p = cand_pos[i];
            let first = 3u * a * (params.nodes + 1u);
            let s = starts[first + k];
            let n = starts[first + k + 1u] - s;
            let base = a * params.refs + s - starts[first];
            let below = rank(base, n, p, false);
            let through = rank(base, n, p, true);
            walked = walk(base, n, p);
            priced = 1u;
            c = vec3<u32>(below, walked.x + walked.y + walked.z, through - below - walked.z);
        }
        counts[3u * i] = c.x;
        counts[3u * i + 1u] = c.y;
        counts[3u * i + 2u] = c.z;
    }
    // A walk visits each slot of its tree's perfect cover (< 2n slots) at most once, so a
    // thread's steps fit a u32; the sums carry into a second word.
    add_to_group(0u, walked.w);
    add_to_group(2u, walked.y);
    atomicAdd(&group_sums[4], priced);
    workgroupBarrier();
    if (lid == 0u) {
        for (var w = 0u; w < 4u; w = w + 2u) {
            let v = atomicLoad(&group_sums[w]);
            let old = atomicAdd(&stats[w], v);
            atomicAdd(&stats[w + 1u], atomicLoad(&group_sums[w + 1u]) + u32(old + v < old));
        }
        atomicAdd(&stats[4], atomicLoad(&group_sums[4]));
    }
}
