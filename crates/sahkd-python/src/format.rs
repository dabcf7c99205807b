//! The `.sahkd` file: a built tree and how it was built, for `save`/`load` and pickling.
//!
//! Layout, all little-endian:
//!
//! | bytes | content |
//! |---|---|
//! | 8 | magic `SAHKDTRE` |
//! | 4 | format version (`u32`, currently 1) |
//! | 4 | length `m` of the metadata (`u32`) |
//! | m | metadata: JSON with the build options and the build's timings |
//! | 24 | triangle, node and reference counts (`u64` each) |
//! | 24 | scene bounds: lo and hi (`f32` x 6) |
//! | 36 T | triangles: three corners of three `f32` |
//! | 8 N | nodes: the two `u32` words of the in-memory layout (see `sahkd::tree`) |
//! | 4 R | references (`u32`) |
//! | 8 | FNV-1a 64 checksum of everything before it |
//!
//! Nothing read from a file is trusted: sizes are checked against the file's length before
//! anything is allocated, the structure is checked before the tree is assembled (so that no
//! index can go out of range), and the assembled tree must pass `KdTree::validate`.

use sahkd::cost::MAX_DEPTH_CAP;
use sahkd::tree::NodeKind;
use sahkd::{Aabb, BuildOptions, KdTree, Node, Triangle, Vec3};
use serde_json::{json, Value};

const MAGIC: &[u8; 8] = b"SAHKDTRE";
const VERSION: u32 = 1;
const LEAF: u32 = 3;

/// What is stored beside the tree.
#[derive(Clone, Debug)]
pub struct Meta {
    pub options: BuildOptions,
    pub build_ms: f64,
    pub presort_ms: f64,
    /// Worker threads the build ran on.
    pub build_threads: usize,
}

/// FNV-1a, 64 bits: a few lines, enough to tell a damaged file from a good one (this is not
/// protection against deliberate tampering; the structural checks below are).
fn fnv1a(bytes: &[u8]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for &b in bytes {
        h ^= b as u64;
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    h
}

pub fn node_words(n: &Node) -> (u32, u32) {
    match n.kind() {
        NodeKind::Interior { axis, split, left } => (split.to_bits(), (left << 2) | axis as u32),
        NodeKind::Leaf { first, count } => (first, (count << 2) | LEAF),
    }
}

fn node_from_words(word: u32, bits: u32) -> Node {
    match bits & 3 {
        LEAF => Node::leaf(word, bits >> 2),
        axis => Node::interior(axis as usize, f32::from_bits(word), bits >> 2),
    }
}

pub fn to_bytes(tree: &KdTree, meta: &Meta) -> Vec<u8> {
    let json = json!({
        "options": meta.options,
        "build_ms": meta.build_ms,
        "presort_ms": meta.presort_ms,
        "build_threads": meta.build_threads,
    })
    .to_string();
    let (tris, nodes, refs) = (tree.triangles(), tree.nodes(), tree.refs());
    let mut out =
        Vec::with_capacity(80 + json.len() + tris.len() * 36 + nodes.len() * 8 + refs.len() * 4);
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&VERSION.to_le_bytes());
    out.extend_from_slice(&(json.len() as u32).to_le_bytes());
    out.extend_from_slice(json.as_bytes());
    for n in [tris.len(), nodes.len(), refs.len()] {
        out.extend_from_slice(&(n as u64).to_le_bytes());
    }
    let b = tree.bounds();
    for c in b.lo.0.iter().chain(&b.hi.0) {
        out.extend_from_slice(&c.to_le_bytes());
    }
    for t in tris {
        for c in t.iter().flat_map(|v| v.0) {
            out.extend_from_slice(&c.to_le_bytes());
        }
    }
    for n in nodes {
        let (word, bits) = node_words(n);
        out.extend_from_slice(&word.to_le_bytes());
        out.extend_from_slice(&bits.to_le_bytes());
    }
    for r in refs {
        out.extend_from_slice(&r.to_le_bytes());
    }
    let sum = fnv1a(&out);
    out.extend_from_slice(&sum.to_le_bytes());
    out
}

/// A cursor over the file's bytes that fails with a message instead of panicking.
struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl<'a> Reader<'a> {
    fn take(&mut self, n: usize) -> Result<&'a [u8], String> {
        let end = self.at.checked_add(n).filter(|&e| e <= self.bytes.len());
        let end = end.ok_or_else(|| {
            format!(
                "truncated: needs more than its {} bytes (reading {n} bytes at offset {})",
                self.bytes.len(),
                self.at
            )
        })?;
        let s = &self.bytes[self.at..end];
        self.at = end;
        Ok(s)
    }
    fn u32(&mut self) -> Result<u32, String> {
        Ok(u32::from_le_bytes(self.take(4)?.try_into().unwrap()))
    }
    fn u64(&mut self) -> Result<u64, String> {
        Ok(u64::from_le_bytes(self.take(8)?.try_into().unwrap()))
    }
    fn f32(&mut self) -> Result<f32, String> {
        Ok(f32::from_le_bytes(self.take(4)?.try_into().unwrap()))
    }
}

/// Reads a tree written by [`to_bytes`], checking everything; the error says what is wrong.
pub fn from_bytes(bytes: &[u8]) -> Result<(KdTree, Meta), String> {
    if !bytes.starts_with(MAGIC) {
        return Err("not a sahkd tree file (it does not start with SAHKDTRE)".into());
    }
    let mut r = Reader { bytes, at: 8 };
    let version = r.u32()?;
    if version != VERSION {
        return Err(format!(
            "format version {version}, but this sahkd reads version {VERSION} only"
        ));
    }
    if bytes.len() < r.at + 8 {
        return Err("truncated: no checksum".into());
    }
    let (body, sum) = bytes.split_at(bytes.len() - 8);
    if fnv1a(body) != u64::from_le_bytes(sum.try_into().unwrap()) {
        return Err("corrupt: checksum mismatch (the file was damaged or truncated)".into());
    }
    let mut r = Reader {
        bytes: body,
        at: r.at,
    };
    let meta_len = r.u32()? as usize;
    let meta = parse_meta(r.take(meta_len)?)?;
    let (nt, nn, nr) = (r.u64()?, r.u64()?, r.u64()?);
    let expected = [(nt, 36u64), (nn, 8), (nr, 4)]
        .iter()
        .try_fold(24u64, |acc, &(n, size)| {
            n.checked_mul(size).and_then(|b| acc.checked_add(b))
        });
    let remaining = (body.len() - r.at) as u64;
    if expected != Some(remaining) {
        return Err(format!(
            "corrupt: counts of {nt} triangles, {nn} nodes and {nr} references do not fit the file's {} bytes",
            bytes.len()
        ));
    }
    let mut corner = || -> Result<Vec3, String> { Ok(Vec3([r.f32()?, r.f32()?, r.f32()?])) };
    let bounds = Aabb::new(corner()?, corner()?);
    let mut triangles: Vec<Triangle> = Vec::with_capacity(nt as usize);
    for _ in 0..nt {
        triangles.push([corner()?, corner()?, corner()?]);
    }
    let mut nodes = Vec::with_capacity(nn as usize);
    for _ in 0..nn {
        let (word, bits) = (r.u32()?, r.u32()?);
        nodes.push(node_from_words(word, bits));
    }
    let refs = (0..nr).map(|_| r.u32()).collect::<Result<Vec<u32>, _>>()?;
    check_parts(&triangles, &bounds, &nodes, &refs)?;
    let tree = KdTree::from_parts(triangles, bounds, nodes, refs);
    tree.validate().map_err(|e| format!("invalid tree: {e}"))?;
    Ok((tree, meta))
}

fn parse_meta(bytes: &[u8]) -> Result<Meta, String> {
    let v: Value = serde_json::from_slice(bytes).map_err(|e| format!("corrupt metadata: {e}"))?;
    let options = serde_json::from_value(v["options"].clone())
        .map_err(|e| format!("corrupt metadata (build options): {e}"))?;
    let ms = |k: &str| v[k].as_f64().unwrap_or(0.0);
    Ok(Meta {
        options,
        build_ms: ms("build_ms"),
        presort_ms: ms("presort_ms"),
        build_threads: v["build_threads"].as_u64().unwrap_or(0) as usize,
    })
}

/// The checks that make assembling and walking the tree safe: finite triangles, the scene
/// box they span, one root, every other node the child of exactly one node before it, leaf
/// ranges and references in bounds, and no deeper than traversal stacks allow.
fn check_parts(
    triangles: &[Triangle],
    bounds: &Aabb,
    nodes: &[Node],
    refs: &[u32],
) -> Result<(), String> {
    if let Some(i) = triangles
        .iter()
        .position(|t| !t.iter().all(|v| v.is_finite()))
    {
        return Err(format!("corrupt: triangle {i} has a non-finite corner"));
    }
    let span = triangles
        .iter()
        .flatten()
        .fold(Aabb::EMPTY, |b, &p| b.grow(p));
    let same = |a: Vec3, b: Vec3| (0..3).all(|k| a[k].to_bits() == b[k].to_bits());
    if !(same(span.lo, bounds.lo) && same(span.hi, bounds.hi)) {
        return Err("corrupt: the stored scene bounds are not those of the triangles".into());
    }
    if nodes.is_empty() {
        return Err("corrupt: the tree has no root node".into());
    }
    let mut parents = vec![0u8; nodes.len()];
    for (i, n) in nodes.iter().enumerate() {
        if n.is_leaf() {
            let end = n.first() as u64 + n.count() as u64;
            if end > refs.len() as u64 {
                return Err(format!(
                    "corrupt: leaf {i} ends at reference {end}, but there are {}",
                    refs.len()
                ));
            }
        } else {
            let left = n.left() as usize;
            if left <= i || left + 1 >= nodes.len() {
                return Err(format!(
                    "corrupt: node {i} has children {left} and {}, not after it among the {} nodes",
                    left + 1,
                    nodes.len()
                ));
            }
            for c in [left, left + 1] {
                parents[c] = parents[c].saturating_add(1);
            }
        }
    }
    if let Some(i) = (1..nodes.len()).find(|&i| parents[i] != 1) {
        return Err(format!(
            "corrupt: node {i} has {} parents instead of one",
            parents[i]
        ));
    }
    if let Some(&r) = refs.iter().find(|&&r| r as usize >= triangles.len()) {
        return Err(format!(
            "corrupt: reference to triangle {r}, but there are {}",
            triangles.len()
        ));
    }
    // Parents come before children, so depths fill in one pass.
    let mut depth = vec![0u32; nodes.len()];
    for (i, n) in nodes.iter().enumerate() {
        if !n.is_leaf() {
            let d = depth[i] + 1;
            if d > MAX_DEPTH_CAP {
                return Err(format!(
                    "corrupt: the tree is deeper than the limit of {MAX_DEPTH_CAP}"
                ));
            }
            depth[n.left() as usize] = d;
            depth[n.left() as usize + 1] = d;
        }
    }
    Ok(())
}
