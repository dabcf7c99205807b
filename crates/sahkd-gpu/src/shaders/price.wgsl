// The SAH cost of every candidate plane, bit for bit the f32 operations of the CPU's
// CostModel::split_cost and the level builder's pricing rule. WGSL promises correctly rounded
// +, -, * but lets compilers fuse a*b+c into one fma (one rounding instead of two) and gives
// division only 2.5 ulp, so:
// - every product goes through `mul`, whose result is xor-ed with a zero the compiler cannot
//   see (a uniform): nothing can be fused across it;
// - every division goes through `div`, an integer long division with round-to-nearest-even;
// - NaN and infinity checks look at the bits, since WGSL lets compilers assume finite math.
// Not covered: subnormal intermediates (WGSL may flush them to zero where the CPU does not);
// they need node extents below ~1e-38 relative to the node's size, or above ~1e38.

struct Params {
    traversal: f32,
    intersection: f32,
    empty_bonus: f32,
    // 0, unknown to the compiler: keeps products unfused.
    zero: u32,
    n: u32,
    // First candidate of axis 1's and axis 2's blocks.
    first1: u32,
    first2: u32,
    pad: u32,
}

@group(0) @binding(0) var<uniform> params: Params;
// Per node: lo.x, lo.y, lo.z, hi.x, hi.y, hi.z.
@group(0) @binding(1) var<storage, read> boxes: array<f32>;
@group(0) @binding(2) var<storage, read> pos: array<f32>;
@group(0) @binding(3) var<storage, read> owner: array<u32>;
// Per candidate: L, R, P (primitives left of, right of, and in the plane).
@group(0) @binding(4) var<storage, read> counts: array<u32>;
@group(0) @binding(5) var<storage, read_write> cost: array<u32>;
// Per candidate: (L + R + P) << 1 | planar_left.
@group(0) @binding(6) var<storage, read_write> packed: array<u32>;

const HOLE: u32 = 0xffffffffu;
const INF: u32 = 0x7f800000u;

fn mul(a: f32, b: f32) -> f32 {
    return bitcast<f32>(bitcast<u32>(a * b) ^ params.zero);
}

fn is_finite(x: f32) -> bool {
    return (bitcast<u32>(x) & INF) != INF;
}

// Significand (with its leading one) and unbiased-plus-127 exponent of a nonzero finite
// float, subnormals normalised.
fn unpack(bits: u32) -> vec2<i32> {
    let e = i32((bits >> 23u) & 0xffu);
    let m = bits & 0x7fffffu;
    if (e == 0) {
        let shift = i32(countLeadingZeros(m)) - 8;
        return vec2<i32>(i32(m << u32(shift)), 1 - shift);
    }
    return vec2<i32>(i32(m | 0x800000u), e);
}

// a / b correctly rounded (to nearest, ties to even), for finite a and finite nonzero b.
fn div(a: f32, b: f32) -> f32 {
    let ua = bitcast<u32>(a);
    let ub = bitcast<u32>(b);
    let sign = (ua ^ ub) & 0x80000000u;
    if ((ua & 0x7fffffffu) == 0u) {
        return bitcast<f32>(sign);
    }
    let x = unpack(ua & 0x7fffffffu);
    let y = unpack(ub & 0x7fffffffu);
    var ma = u32(x.x);
    let mb = u32(y.x);
    var e = x.y - y.y + 127;
    if (ma < mb) {
        ma = ma << 1u;
        e = e - 1;
    }
    // ma / mb is in [1, 2): 26 quotient bits are the 24 of the significand, a guard bit and
    // one more; the remainder tells whether anything is left below them.
    var r = ma;
    var q = 0u;
    for (var i = 0; i < 26; i = i + 1) {
        q = q << 1u;
        if (r >= mb) {
            r = r - mb;
            q = q | 1u;
        }
        r = r << 1u;
    }
    // Normal results drop 2 bits; subnormal ones (e < 1) drop 2 + (1 - e).
    var drop = 2u;
    if (e < 1) {
        drop = u32(min(3 - e, 31));
    }
    var sig = q >> drop;
    let guard = (q >> (drop - 1u)) & 1u;
    let rest = (q & ((1u << (drop - 1u)) - 1u)) | r;
    if (guard == 1u && (rest != 0u || (sig & 1u) == 1u)) {
        sig = sig + 1u;
    }
    if (e < 1) {
        // sig < 2^23 (or exactly 2^23 after rounding up: the smallest normal).
        return bitcast<f32>(sign | sig);
    }
    // The significand's leading one adds 1 to the exponent field; a carry out of rounding
    // moves into the exponent as it should.
    let bits = (u32(e - 1) << 23u) + sig;
    if (e >= 255 || bits >= INF) {
        return bitcast<f32>(sign | INF);
    }
    return bitcast<f32>(sign | bits);
}

fn split_cost(k: u32, axis: u32, p: f32, nl: u32, nr: u32) -> f32 {
    let inf = bitcast<f32>(INF);
    let lo = boxes[6u * k + axis];
    let hi = boxes[6u * k + 3u + axis];
    if (!(p > lo && p < hi)) {
        return inf;
    }
    let b = (axis + 1u) % 3u;
    let c = (axis + 2u) % 3u;
    let d0 = hi - lo;
    let d1 = boxes[6u * k + 3u + b] - boxes[6u * k + b];
    let d2 = boxes[6u * k + 3u + c] - boxes[6u * k + c];
    if (!(is_finite(d0) && is_finite(d1) && is_finite(d2))) {
        return inf;
    }
    let scale = max(max(d0, d1), d2);
    if (!(scale > 0.0)) {
        return inf;
    }
    let inv = div(1.0, scale);
    let db = mul(d1, inv);
    let dc = mul(d2, inv);
    let face = mul(db, dc);
    let perimeter = db + dc;
    let area = face + mul(mul(d0, inv), perimeter);
    if (!(area > 0.0)) {
        return inf;
    }
    let area_l = face + mul(mul(p - lo, inv), perimeter);
    let area_r = face + mul(mul(hi - p, inv), perimeter);
    var bonus = 1.0;
    if (nl == 0u || nr == 0u) {
        bonus = params.empty_bonus;
    }
    let sum = mul(area_l, f32(nl)) + mul(area_r, f32(nr));
    return mul(bonus, params.traversal + div(mul(params.intersection, sum), area));
}


fn finite_or_inf(x: f32) -> u32 {
    let bits = bitcast<u32>(x);
    if ((bits & 0x7fffffffu) > INF) {
        return INF;
    }
    return bits;
}

@compute @workgroup_size(256)
fn price(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let i = thread_index(wid, nwg, lid);
    if (i >= params.n) {
        return;
    }
    let k = owner[i];
    if (k == HOLE) {
        cost[i] = INF;
        packed[i] = 0u;
        return;
    }
    let axis = u32(i >= params.first1) + u32(i >= params.first2);
    // A plane at -0 is the plane at +0.
    var bits = bitcast<u32>(pos[i]);
    if (bits == 0x80000000u) {
        bits = 0u;
    }
    let p = bitcast<f32>(bits);
    let l = counts[3u * i];
    let r = counts[3u * i + 1u];
    let planar = counts[3u * i + 2u];
    let left = finite_or_inf(split_cost(k, axis, p, l + planar, r));
    var best = left;
    var planar_left = 1u;
    if (planar != 0u) {
        let right = finite_or_inf(split_cost(k, axis, p, l, r + planar));
        if (order_key(right) < order_key(left)) {
            best = right;
            planar_left = 0u;
        }
    }
    cost[i] = best;
    packed[i] = ((l + r + planar) << 1u) | planar_left;
}

// Tests only: cost[i] = div(a, b) for the bit patterns a = counts[2i], b = counts[2i + 1].
@compute @workgroup_size(256)
fn divide(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let i = thread_index(wid, nwg, lid);
    if (i >= params.n) {
        return;
    }
    cost[i] = bitcast<u32>(div(bitcast<f32>(counts[2u * i]), bitcast<f32>(counts[2u * i + 1u])));
}
