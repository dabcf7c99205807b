// Bitonic sort of 16-byte records (k0, k1, k2, payload), ascending by (k0, k1, k2), in the
// variant whose comparators all put the smaller record at the lower index: stage k (sorted
// runs of k/2 become runs of k) starts with a "flip" step pairing each index with its mirror
// in its k-block (i ^ (k - 1)), then half-cleaners at distances k/4 .. 1 (i ^ d).
//
// The network is that of N = max(512, next power of two >= n) records, the N - n past the
// end being virtual maxima. Because every comparator sends the minimum down, a comparator
// (i < n <= j) leaves a real record at i and the maximum at j: the virtual records never
// move, so they are never stored, and nothing is padded or allocated.
//
// Each thread does up to four consecutive steps of a stage in registers, on a set of 16
// records closed under them: a "phase". Phases inside a tile of 512 records (closed under
// every distance < 512) run in workgroup memory, a barrier between phases; phases at
// distances >= 512 are one dispatch each. (A barrier is what a CPU adapter such as lavapipe
// runs slowest: one per compare-exchange step cost as much as a step over the whole array in
// memory, so four steps share one.)

struct Params {
    n: u32,
    // The phase: stage k, its first distance d (d = k / 2 for the flip), r steps.
    k: u32,
    d: u32,
    r: u32,
    // Threads of a global phase: N / 16.
    sets: u32,
    pad0: u32,
    pad1: u32,
    pad2: u32,
}

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read_write> data: array<vec4<u32>>;

const TILE: u32 = 512u;
// Invocations of the tile kernels: 16 records each.
const TILE_THREADS: u32 = 32u;
const MAX: vec4<u32> = vec4<u32>(0xffffffffu, 0xffffffffu, 0xffffffffu, 0xffffffffu);

var<workgroup> tile: array<vec4<u32>, 512>;
var<private> regs: array<vec4<u32>, 16>;


// Whether a goes after b: lexicographic on the three key words, payload ignored; equal keys
// never swap.
fn after(a: vec4<u32>, b: vec4<u32>) -> bool {
    if (a.x != b.x) {
        return a.x > b.x;
    }
    if (a.y != b.y) {
        return a.y > b.y;
    }
    return a.z > b.z;
}

// One step on the 16 registers: every pair (p, p ^ mask) with p < p ^ mask, the smaller key
// to p, or to p ^ mask where `desc` says the registers hold descending indices (the upper
// half of a flip phase's sets, see `slot`). Called with constant masks only, so that the
// unrolled loop indexes registers by constants (a run-time index costs a ladder of selects
// per access on lavapipe).
fn step(mask: u32, flip: bool, h: u32) {
    for (var p = 0u; p < 16u; p = p + 1u) {
        let q = p ^ mask;
        if (q > p) {
            let a = regs[p];
            let b = regs[q];
            let desc = flip && (p & h) != 0u;
            if (select(after(a, b), after(b, a), desc)) {
                regs[p] = b;
                regs[q] = a;
            }
        }
    }
}

// The r steps of a phase on each 2^r-register set of the 16: masks 2^(r-1) .. 1.
fn phase_steps(flip: bool, r: u32) {
    let h = 1u << (r - 1u);
    if (r >= 4u) {
        step(8u, flip, h);
    }
    if (r >= 3u) {
        step(4u, flip, h);
    }
    if (r >= 2u) {
        step(2u, flip, h);
    }
    step(1u, flip, h);
}

// Index of register p of thread g in the phase (k, d, r). A set of 2^r records at stride
// q = 2d / 2^r in a block of 2d is closed under the phase's steps: the step at distance d
// pairs registers h = 2^(r-1) apart, the last step adjacent ones. In a flip phase (2d = k)
// register h + j holds the mirror of register j, so the flip pairs registers h apart too and
// the upper half holds descending indices. A thread holds 2^(4-r) consecutive sets.
fn slot(g: u32, p: u32, k: u32, d: u32, r: u32) -> u32 {
    let s = (g << (4u - r)) + (p >> r);
    let h = 1u << (r - 1u);
    let at = p & (2u * h - 1u);
    let q = (2u * d) >> r;
    let o = s & (q - 1u);
    let base = (s - o) << r;
    if (2u * d == k && at >= h) {
        return base + k - 1u - o - (at - h) * q;
    }
    return base + o + at * q;
}

@compute @workgroup_size(256)
fn global_phase(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>, @builtin(local_invocation_index) lid: u32) {
    let g = thread_index(wid, nwg, lid);
    if (g >= params.sets) {
        return;
    }
    for (var p = 0u; p < 16u; p = p + 1u) {
        let i = slot(g, p, params.k, params.d, params.r);
        if (i < params.n) {
            regs[p] = data[i];
        } else {
            regs[p] = MAX;
        }
    }
    phase_steps(2u * params.d == params.k, params.r);
    for (var p = 0u; p < 16u; p = p + 1u) {
        let i = slot(g, p, params.k, params.d, params.r);
        if (i < params.n) {
            data[i] = regs[p];
        }
    }
}

// One phase over the tile: 32 threads of 16 records cover it.
fn tile_phase(lid: u32, k: u32, d: u32, r: u32) {
    for (var p = 0u; p < 16u; p = p + 1u) {
        regs[p] = tile[slot(lid, p, k, d, r)];
    }
    phase_steps(2u * d == k, r);
    for (var p = 0u; p < 16u; p = p + 1u) {
        tile[slot(lid, p, k, d, r)] = regs[p];
    }
    workgroupBarrier();
}

// The steps of stage k from distance d0 down to 1, in phases of at most four; the short
// phase goes first so that the last one is the stride-1 one.
fn tile_steps(lid: u32, k: u32, d0: u32) {
    var m = countTrailingZeros(d0) + 1u;
    var d = d0;
    var r = m - 4u * ((m - 1u) / 4u);
    loop {
        tile_phase(lid, k, d, r);
        m = m - r;
        if (m == 0u) {
            break;
        }
        d = d >> r;
        r = 4u;
    }
}

fn tile_base(wid: vec3<u32>, nwg: vec3<u32>) -> u32 {
    return (wid.y * nwg.x + wid.x) * TILE;
}

fn load_tile(base: u32, lid: u32) {
    for (var l = lid; l < TILE; l = l + TILE_THREADS) {
        if (base + l < params.n) {
            tile[l] = data[base + l];
        } else {
            tile[l] = MAX;
        }
    }
    workgroupBarrier();
}

fn store_tile(base: u32, lid: u32) {
    for (var l = lid; l < TILE; l = l + TILE_THREADS) {
        if (base + l < params.n) {
            data[base + l] = tile[l];
        }
    }
}

// Every stage up to 512: each tile sorted.
@compute @workgroup_size(32)
fn sort_tiles(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>, @builtin(local_invocation_index) lid: u32) {
    let base = tile_base(wid, nwg);
    if (base >= params.n) {
        return;
    }
    load_tile(base, lid);
    for (var k = 2u; k <= TILE; k = k << 1u) {
        tile_steps(lid, k, k >> 1u);
    }
    store_tile(base, lid);
}

// The steps at distances 256 .. 1 that end a stage k > 512.
@compute @workgroup_size(32)
fn merge_tiles(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>, @builtin(local_invocation_index) lid: u32) {
    let base = tile_base(wid, nwg);
    if (base >= params.n) {
        return;
    }
    load_tile(base, lid);
    tile_steps(lid, params.k, TILE >> 1u);
    store_tile(base, lid);
}
