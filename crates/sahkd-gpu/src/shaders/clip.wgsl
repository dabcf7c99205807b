// A triangle clipped to a box, bit for bit the CPU's `sahkd::clip::clipped_bounds`: the same
// Sutherland-Hodgman pass in IEEE f64, emulated with integers since WGSL has no f64, then the
// bounds rounded outwards to f32 and intersected with the box. A library: no bindings, no entry
// point; every name starts with `f64_`, `clip_` so it can be put in front of other kernels.
//
// Entry: `clip_bounds(tri: array<vec3<f32>, 3>, box_lo: vec3<f32>, box_hi: vec3<f32>)
// -> ClipResult`. The f32s are only moved and bitcast, never computed on, so subnormals keep
// their bits on GPUs that flush them in arithmetic.
//
// Soft f64. A value is its IEEE bit pattern as vec2<u32>: x = sign, 11 exponent bits and the
// top 20 mantissa bits; y = the low 32 mantissa bits. Add, sub, mul and div are correctly
// rounded to nearest, ties to even, with IEEE signs of zero (x - x = +0, -0 + -0 = -0, signs of
// products and quotients by xor) and gradual underflow, like the CPU's SSE2 arithmetic.
//
// Why no infinity or NaN can arise from finite f32 inputs (vertices are validated finite,
// boxes are finite): every coordinate starts as an f32 (|c| < 2^128); a new vertex is
// p + t (q - p) with t = (bound - p[axis]) / (q[axis] - p[axis]) in [0, 1] (the numerator is
// at most the denominator in magnitude and of the same sign, and rounding is monotonic), so
// coordinates stay within the f32 range up to a few ulps and differences below 2^130; the
// divisor is nonzero because p and q lie strictly on opposite sides of the plane. So nothing
// overflows, no 0/0 or inf - inf occurs; those inputs are unreachable and only get some
// finite or infinite answer, without hanging (every loop is bounded by a constant) or
// indexing outside an array.
// Subnormals: differences of f32s are multiples of 2^-149, so >= 2^-149 when nonzero;
// quotients t are then >= 2^-149 / 2^130 = 2^-279 and products t (q - p) >= 2^-428, so the
// first plane's new coordinates lie on a grid of about 2^-480. A later plane crossing an edge
// between such vertices multiplies a quotient of differences on that grid by another such
// difference, and the bound drops below 2^-1022 at the very next plane (six may chain). That
// argument does not close, so instead the rounding implements gradual underflow exactly (one
// extra shift in f64_round_pack), checked against the CPU's arithmetic in tests/clip.rs.
//
// No floating-point operation is used, so no compiler may fuse, reassociate or flush anything.

alias f64_bits = vec2<u32>;

const F64_SIGN: u32 = 0x80000000u;
const F64_ABS: u32 = 0x7fffffffu;
// The implicit leading one of a significand, bit 52, in the high word.
const F64_ONE_HI: u32 = 0x00100000u;

// --- 64-bit unsigned integers as vec2<u32>(high, low). WGSL masks shift counts to 0..31, so
// the zero and >= 32 shifts are separate cases.

fn clip_u64_shl(a: vec2<u32>, s: u32) -> vec2<u32> {
    if (s == 0u) {
        return a;
    }
    if (s >= 64u) {
        return vec2<u32>(0u, 0u);
    }
    if (s >= 32u) {
        return vec2<u32>(a.y << (s - 32u), 0u);
    }
    return vec2<u32>((a.x << s) | (a.y >> (32u - s)), a.y << s);
}

fn clip_u64_shr(a: vec2<u32>, s: u32) -> vec2<u32> {
    if (s == 0u) {
        return a;
    }
    if (s >= 64u) {
        return vec2<u32>(0u, 0u);
    }
    if (s >= 32u) {
        return vec2<u32>(0u, a.x >> (s - 32u));
    }
    return vec2<u32>(a.x >> s, (a.y >> s) | (a.x << (32u - s)));
}

// a >> s, or-ing every bit shifted out into bit 0 (the "sticky" bit of rounding).
fn clip_u64_shr_sticky(a: vec2<u32>, s: u32) -> vec2<u32> {
    if (s == 0u) {
        return a;
    }
    if (s >= 64u) {
        return vec2<u32>(0u, u32(a.x != 0u || a.y != 0u));
    }
    var r: vec2<u32>;
    var lost: u32;
    if (s >= 32u) {
        let k = s - 32u;
        lost = a.y | (a.x & ((1u << k) - 1u));
        r = vec2<u32>(0u, a.x >> k);
    } else {
        lost = a.y & ((1u << s) - 1u);
        r = vec2<u32>(a.x >> s, (a.y >> s) | (a.x << (32u - s)));
    }
    r.y = r.y | u32(lost != 0u);
    return r;
}

fn clip_u64_add(a: vec2<u32>, b: vec2<u32>) -> vec2<u32> {
    let lo = a.y + b.y;
    return vec2<u32>(a.x + b.x + u32(lo < a.y), lo);
}

// a - b for a >= b.
fn clip_u64_sub(a: vec2<u32>, b: vec2<u32>) -> vec2<u32> {
    return vec2<u32>(a.x - b.x - u32(a.y < b.y), a.y - b.y);
}

fn clip_u64_lt(a: vec2<u32>, b: vec2<u32>) -> bool {
    return a.x < b.x || (a.x == b.x && a.y < b.y);
}

fn clip_u64_clz(a: vec2<u32>) -> u32 {
    if (a.x != 0u) {
        return countLeadingZeros(a.x);
    }
    return 32u + countLeadingZeros(a.y);
}

// --- Soft f64.

// A nonzero finite value as sign bit, exponent and 53-bit significand (leading one at bit
// 52): |value| = m * 2^(e - 52). Subnormals are normalised (e below -1022).
struct F64Parts {
    sign: u32,
    e: i32,
    m: vec2<u32>,
}

fn f64_is_zero(a: f64_bits) -> bool {
    return (a.x & F64_ABS) == 0u && a.y == 0u;
}

fn f64_unpack(a: f64_bits) -> F64Parts {
    let field = i32((a.x >> 20u) & 0x7ffu);
    let mant = vec2<u32>(a.x & 0x000fffffu, a.y);
    if (field == 0) {
        let shift = clip_u64_clz(mant) - 11u;
        return F64Parts(a.x & F64_SIGN, -1022 - i32(shift), clip_u64_shl(mant, shift));
    }
    return F64Parts(a.x & F64_SIGN, field - 1023, vec2<u32>(mant.x | F64_ONE_HI, mant.y));
}

// Rounds |value| = m * 2^(e - 62), m with its leading one at bit 62 and any bits lost earlier
// or-ed into bit 0, to the nearest f64 (ties to even), subnormal or infinite as IEEE says.
fn f64_round_pack(sign: u32, e: i32, m_in: vec2<u32>) -> f64_bits {
    let biased = e + 1023;
    if (biased >= 2047) {
        return vec2<u32>(sign | 0x7ff00000u, 0u);
    }
    var m = m_in;
    // The significand's leading one adds 1 to the exponent field, so a normal number starts
    // from biased - 1; a subnormal one is shifted down to the fixed exponent of 2^-1074 and
    // starts from 0 (a carry out of rounding then makes it the smallest normal, as it should).
    var field = 0u;
    if (biased >= 1) {
        field = u32(biased - 1);
    } else {
        m = clip_u64_shr_sticky(m, u32(min(1 - biased, 64)));
    }
    // 10 bits below the 53 kept: round half = bit 9.
    var keep = clip_u64_shr(m, 10u);
    let rest = m.y & 0x3ffu;
    if (rest > 0x200u || (rest == 0x200u && (keep.y & 1u) == 1u)) {
        keep = clip_u64_add(keep, vec2<u32>(0u, 1u));
    }
    let bits = clip_u64_add(vec2<u32>(field << 20u, 0u), keep);
    return vec2<u32>(sign | bits.x, bits.y);
}

fn f64_from_f32(x: f32) -> f64_bits {
    let bits = bitcast<u32>(x);
    let sign = bits & F64_SIGN;
    let mag = bits & F64_ABS;
    if (mag == 0u) {
        return vec2<u32>(sign, 0u);
    }
    var field = i32(mag >> 23u);
    var m = mag & 0x7fffffu;
    if (field == 255) {
        // Unreachable (inputs are finite); keeps inf and NaN as such.
        return vec2<u32>(sign | 0x7ff00000u | (m >> 3u), m << 29u);
    }
    if (field == 0) {
        // Subnormal: move the leading one to bit 23 (then dropped as the implicit one).
        let shift = countLeadingZeros(m) - 8u;
        m = (m << shift) & 0x7fffffu;
        field = 1 - i32(shift);
    }
    let e = u32(field - 127 + 1023);
    return vec2<u32>(sign | (e << 20u) | (m >> 3u), m << 29u);
}

fn f64_neg(a: f64_bits) -> f64_bits {
    return vec2<u32>(a.x ^ F64_SIGN, a.y);
}

fn f64_add(a: f64_bits, b: f64_bits) -> f64_bits {
    let za = f64_is_zero(a);
    let zb = f64_is_zero(b);
    if (za && zb) {
        // -0 only when both are -0.
        return vec2<u32>(a.x & b.x & F64_SIGN, 0u);
    }
    if (za) {
        return b;
    }
    if (zb) {
        return a;
    }
    // Larger magnitude first (magnitudes order like their bit patterns).
    var big = a;
    var small = b;
    if (clip_u64_lt(vec2<u32>(a.x & F64_ABS, a.y), vec2<u32>(b.x & F64_ABS, b.y))) {
        big = b;
        small = a;
    }
    let x = f64_unpack(big);
    let y = f64_unpack(small);
    // 10 spare bits below the significands, then the smaller one aligned with a sticky bit:
    // enough for correct rounding, as the sticky bit stays below the half-ulp position.
    let mx = clip_u64_shl(x.m, 10u);
    let my = clip_u64_shr_sticky(clip_u64_shl(y.m, 10u), u32(min(x.e - y.e, 64)));
    var e = x.e;
    var m: vec2<u32>;
    if (x.sign == y.sign) {
        m = clip_u64_add(mx, my);
        if ((m.x & F64_SIGN) != 0u) {
            m = clip_u64_shr_sticky(m, 1u);
            e = e + 1;
        }
    } else {
        m = clip_u64_sub(mx, my);
        if (m.x == 0u && m.y == 0u) {
            return vec2<u32>(0u, 0u);
        }
        // Only exact differences (alignment by at most 1) lose more than one leading bit.
        let shift = clip_u64_clz(m) - 1u;
        m = clip_u64_shl(m, shift);
        e = e - i32(shift);
    }
    return f64_round_pack(x.sign, e, m);
}

fn f64_sub(a: f64_bits, b: f64_bits) -> f64_bits {
    return f64_add(a, f64_neg(b));
}

fn f64_mul(a: f64_bits, b: f64_bits) -> f64_bits {
    let sign = (a.x ^ b.x) & F64_SIGN;
    if (f64_is_zero(a) || f64_is_zero(b)) {
        return vec2<u32>(sign, 0u);
    }
    let x = f64_unpack(a);
    let y = f64_unpack(b);
    // 53 x 53 bits in 16-bit limbs: each partial product fits 32 bits; its halves go to two
    // 16-bit columns, whose sums (at most 8 halves) cannot overflow before the carry pass.
    let la = array<u32, 4>(x.m.y & 0xffffu, x.m.y >> 16u, x.m.x & 0xffffu, x.m.x >> 16u);
    let lb = array<u32, 4>(y.m.y & 0xffffu, y.m.y >> 16u, y.m.x & 0xffffu, y.m.x >> 16u);
    var col = array<u32, 8>(0u, 0u, 0u, 0u, 0u, 0u, 0u, 0u);
    for (var i = 0u; i < 4u; i = i + 1u) {
        for (var j = 0u; j < 4u; j = j + 1u) {
            let p = la[i] * lb[j];
            col[i + j] = col[i + j] + (p & 0xffffu);
            col[i + j + 1u] = col[i + j + 1u] + (p >> 16u);
        }
    }
    var carry = 0u;
    for (var k = 0u; k < 8u; k = k + 1u) {
        let v = col[k] + carry;
        col[k] = v & 0xffffu;
        carry = v >> 16u;
    }
    let w0 = col[0] | (col[1] << 16u);
    let w1 = col[2] | (col[3] << 16u);
    let w2 = col[4] | (col[5] << 16u);
    let w3 = col[6] | (col[7] << 16u);
    // The product (< 2^106, leading one at bit 104 or 105) shifted down by 42, lost bits
    // sticky: its leading one lands at bit 62 or 63.
    var m = vec2<u32>((w2 >> 10u) | (w3 << 22u), (w1 >> 10u) | (w2 << 22u));
    m.y = m.y | u32(w0 != 0u || (w1 & 0x3ffu) != 0u);
    var e = x.e + y.e;
    if ((m.x & F64_SIGN) != 0u) {
        m = clip_u64_shr_sticky(m, 1u);
        e = e + 1;
    }
    return f64_round_pack(sign, e, m);
}

fn f64_div(a: f64_bits, b: f64_bits) -> f64_bits {
    let sign = (a.x ^ b.x) & F64_SIGN;
    if (f64_is_zero(b)) {
        // Unreachable (see the top): some answer, without dividing.
        return vec2<u32>(sign | 0x7ff00000u, 0u);
    }
    if (f64_is_zero(a)) {
        return vec2<u32>(sign, 0u);
    }
    let x = f64_unpack(a);
    let y = f64_unpack(b);
    var r = x.m;
    var e = x.e - y.e;
    if (clip_u64_lt(r, y.m)) {
        r = clip_u64_shl(r, 1u);
        e = e - 1;
    }
    // r / m in [1, 2): 55 quotient bits by restoring division (the 53 kept, a guard bit and
    // one more), then whatever remains is sticky.
    var q = vec2<u32>(0u, 0u);
    for (var i = 0; i < 55; i = i + 1) {
        q = clip_u64_shl(q, 1u);
        if (!clip_u64_lt(r, y.m)) {
            r = clip_u64_sub(r, y.m);
            q.y = q.y | 1u;
        }
        r = clip_u64_shl(r, 1u);
    }
    q = clip_u64_shl(q, 8u);
    q.y = q.y | u32(r.x != 0u || r.y != 0u);
    return f64_round_pack(sign, e, q);
}

// Integer key ordered like the value (no NaN); -0 and +0 share one, as they compare equal.
fn f64_key(a: f64_bits) -> vec2<u32> {
    if (f64_is_zero(a)) {
        return vec2<u32>(F64_SIGN, 0u);
    }
    if ((a.x & F64_SIGN) != 0u) {
        return ~a;
    }
    return vec2<u32>(a.x | F64_SIGN, a.y);
}

fn f64_lt(a: f64_bits, b: f64_bits) -> bool {
    return clip_u64_lt(f64_key(a), f64_key(b));
}

fn f64_le(a: f64_bits, b: f64_bits) -> bool {
    return !f64_lt(b, a);
}

fn f64_ge(a: f64_bits, b: f64_bits) -> bool {
    return !f64_lt(a, b);
}

fn f64_eq(a: f64_bits, b: f64_bits) -> bool {
    return all(f64_key(a) == f64_key(b));
}

// `a.min(b)` and `a.max(b)` as the CPU's clip compiles them: between -0 and +0, `a` (the
// running bound) is kept, so the first zero met wins. Rust leaves this open and LLVM may swap
// the operands of a min; it is what rustc 1.95 makes of clipped_bounds at opt-level 2 and 3
// (thin LTO), and tests/clip.rs fails if a compiler ever changes it.
fn f64_min(a: f64_bits, b: f64_bits) -> f64_bits {
    if (f64_lt(b, a)) {
        return b;
    }
    return a;
}

fn f64_max(a: f64_bits, b: f64_bits) -> f64_bits {
    if (f64_lt(a, b)) {
        return b;
    }
    return a;
}

// The f32 nearest to `a` towards -inf (`up` false) or +inf (`up` true), as bits: what the CPU's
// round_down / round_up give (rounding to nearest, then one step if that went the wrong way,
// is rounding towards the infinity). Exact values, zeros included, keep their sign.
fn f64_to_f32_directed(a: f64_bits, up: bool) -> u32 {
    let sign = a.x & F64_SIGN;
    if (f64_is_zero(a)) {
        return sign;
    }
    let x = f64_unpack(a);
    // Away from zero when rounding towards the infinity of the value's sign.
    let away = up == (sign == 0u);
    let biased = x.e + 127;
    if (biased >= 255) {
        // |a| >= 2^128: the largest finite f32 towards zero, infinity away from it.
        if (away) {
            return sign | 0x7f800000u;
        }
        return sign | 0x7f7fffffu;
    }
    // Keep 24 bits of a normal f32, fewer of a subnormal one (fixed exponent 2^-149); the
    // significand's leading one carries into the exponent field as in f64_round_pack.
    var drop = 29u;
    var field = 0u;
    if (biased >= 1) {
        field = u32(biased - 1);
    } else {
        drop = u32(min(30 - biased, 64));
    }
    let kept = clip_u64_shr(x.m, drop);
    let inexact = any(clip_u64_shl(kept, drop) != x.m);
    // Carrying out of 0x7f7fffff away from zero gives infinity, as it should.
    return sign | ((field << 23u) + kept.y + u32(away && inexact));
}

// --- The clip.

// The clipped box; `lo`/`hi` are Aabb::EMPTY (+inf, -inf) when the triangle misses the box.
// `empty` is Aabb::is_empty of the box: some axis without lo <= hi.
struct ClipResult {
    lo: vec3<f32>,
    hi: vec3<f32>,
    empty: bool,
}

// f32 bits ordered like the value (no NaN); -0 and +0 share a key.
fn clip_f32_key(bits: u32) -> u32 {
    if ((bits & F64_ABS) == 0u) {
        return F64_SIGN;
    }
    if ((bits & F64_SIGN) != 0u) {
        return ~bits;
    }
    return bits | F64_SIGN;
}

// `a.max(b)` / `a.min(b)` of f32 as Aabb::intersection compiles in the CPU's clip: `a` (the
// clipped bound) is kept between -0 and +0.
fn clip_f32_max(a: u32, b: u32) -> u32 {
    return select(a, b, clip_f32_key(a) < clip_f32_key(b));
}

fn clip_f32_min(a: u32, b: u32) -> u32 {
    return select(a, b, clip_f32_key(b) < clip_f32_key(a));
}

fn clip_inside(c: f64_bits, bound: f64_bits, keep_below: bool) -> bool {
    if (keep_below) {
        return f64_le(c, bound);
    }
    return f64_ge(c, bound);
}

fn clip_empty() -> ClipResult {
    let lo = bitcast<vec3<f32>>(vec3<u32>(0x7f800000u));
    let hi = bitcast<vec3<f32>>(vec3<u32>(0xff800000u));
    return ClipResult(lo, hi, true);
}

// -0 as +0, as the CPU's clip returns it: which zero a min or max of -0 and +0 keeps is the
// compiler's choice on the CPU, so both sides normalise instead of copying that choice.
fn clip_plus_zero(bits: u32) -> u32 {
    return select(bits, 0u, bits == 0x80000000u);
}

// The bounds of the part of the triangle inside the closed box, as the CPU computes them:
// for each plane in the order x lo, x hi, y lo, ..., z hi, planes that cut nothing skipped,
// each kept vertex and then each crossing of an edge (p, q) emitted in edge order, a crossing
// p + t (q - p) with t = (bound - p) / (q - p) on the plane's axis and exactly `bound` on it.
fn clip_bounds(tri: array<vec3<f32>, 3>, box_lo: vec3<f32>, box_hi: vec3<f32>) -> ClipResult {
    // Two polygons of up to 9 vertices used in turn: coordinate a of vertex i of polygon k
    // at 27 k + 3 i + a.
    var poly: array<f64_bits, 54>;
    var corners = tri;
    for (var i = 0u; i < 3u; i = i + 1u) {
        for (var a = 0u; a < 3u; a = a + 1u) {
            poly[3u * i + a] = f64_from_f32(corners[i][a]);
        }
    }
    var n = 3u;
    var src = 0u;
    for (var plane = 0u; plane < 6u; plane = plane + 1u) {
        let axis = plane / 2u;
        let keep_below = (plane & 1u) == 1u;
        let bound = f64_from_f32(select(box_lo[axis], box_hi[axis], keep_below));
        var cuts = false;
        for (var i = 0u; i < n; i = i + 1u) {
            cuts = cuts || !clip_inside(poly[src + 3u * i + axis], bound, keep_below);
        }
        if (!cuts) {
            continue;
        }
        let dst = 27u - src;
        var m = 0u;
        for (var i = 0u; i < n; i = i + 1u) {
            let j = select(i + 1u, 0u, i + 1u == n);
            let p = src + 3u * i;
            let q = src + 3u * j;
            let pin = clip_inside(poly[p + axis], bound, keep_below);
            let qin = clip_inside(poly[q + axis], bound, keep_below);
            // The CPU has no bound check here (it would panic past 9 vertices, which convex
            // polygons never reach); this one only keeps the GPU inside the array.
            if (pin && m < 9u) {
                for (var a = 0u; a < 3u; a = a + 1u) {
                    poly[dst + 3u * m + a] = poly[p + a];
                }
                m = m + 1u;
            }
            if (pin != qin && m < 9u) {
                let t = f64_div(f64_sub(bound, poly[p + axis]), f64_sub(poly[q + axis], poly[p + axis]));
                for (var a = 0u; a < 3u; a = a + 1u) {
                    var x = bound;
                    if (a != axis) {
                        let pa = poly[p + a];
                        x = f64_add(pa, f64_mul(t, f64_sub(poly[q + a], pa)));
                    }
                    poly[dst + 3u * m + a] = x;
                }
                m = m + 1u;
            }
        }
        n = m;
        if (n == 0u) {
            return clip_empty();
        }
        src = dst;
    }
    // min/max from +-inf: the first vertex sets the bounds (finite, so strictly inside).
    var lo = vec3<u32>();
    var hi = vec3<u32>();
    for (var a = 0u; a < 3u; a = a + 1u) {
        var l = poly[src + a];
        var h = l;
        for (var i = 1u; i < n; i = i + 1u) {
            let c = poly[src + 3u * i + a];
            l = f64_min(l, c);
            h = f64_max(h, c);
        }
        lo[a] = clip_plus_zero(clip_f32_max(f64_to_f32_directed(l, false), bitcast<u32>(box_lo[a])));
        hi[a] = clip_plus_zero(clip_f32_min(f64_to_f32_directed(h, true), bitcast<u32>(box_hi[a])));
    }
    var empty = false;
    for (var a = 0u; a < 3u; a = a + 1u) {
        empty = empty || clip_f32_key(hi[a]) < clip_f32_key(lo[a]);
    }
    return ClipResult(bitcast<vec3<f32>>(lo), bitcast<vec3<f32>>(hi), empty);
}
