// The prelude: concatenated in front of every shader module (`Gpu::module`), so the helpers
// that several kernels need are written once.

// The index of this invocation in a launch of workgroups of 256, 2-D beyond 65 535 workgroups
// (`Kernel::dispatch` lays launches out so; indices past the launch's length are ignored by
// each kernel).
fn thread_index(wid: vec3<u32>, nwg: vec3<u32>, lid: u32) -> u32 {
    return (wid.y * nwg.x + wid.x) * 256u + lid;
}

// Integer key ordered like the f32 of `bits` (compared as integers: no finite-math assumption
// applies); -0 and +0 share one, as they compare equal.
fn order_key(bits: u32) -> u32 {
    if (bits == 0x80000000u) {
        return 0x80000000u;
    }
    if ((bits & 0x80000000u) != 0u) {
        return ~bits;
    }
    return bits | 0x80000000u;
}
