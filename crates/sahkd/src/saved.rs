//! The `.sahkd` file: a built tree and how it was built, saved once and opened many times
//! (the CLI's `build --save`, Python's `save`/`load` and pickling).
//!
//! Layout (versions 1 and 2), all little-endian:
//!
//! | bytes | content |
//! |---|---|
//! | 8 | magic `SAHKDTRE` |
//! | 4 | format version (`u32`, 2; version 1 files are still read) |
//! | 4 | length `m` of the metadata (`u32`) |
//! | m | metadata: JSON with the build options and the build's timings |
//! | 24 | triangle, node and reference counts (`u64` each) |
//! | 24 | scene bounds: lo and hi (`f32` x 6) |
//! | 36 T | triangles: three corners of three `f32` |
//! | 8 N | nodes: the two `u32` words of the in-memory layout (see [`crate::tree`]) |
//! | 4 R | references (`u32`) |
//! | 8 | checksum of everything before it (below) |
//!
//! The versions differ in the checksum only. Version 1 sums FNV-1a 64 byte by byte: one
//! multiply per byte in one dependency chain, slower on a large tree than everything else
//! opening does. Version 2 sums 64-bit words (the bytes little-endian,
//! the last word padded with zeros) in four interleaved lanes, word `k` into lane `k % 4`:
//! `lane = ((lane ^ word) * P).rotate_left(29)` with the FNV prime `P` and lane `i` starting at
//! the FNV offset basis plus `i`; then `h = basis`, and for each lane and finally the byte
//! length, `h = (h ^ x) * P`. Each step is a bijection of the lane, so any change to one word
//! changes the sum, like version 1; the lanes run side by side, about 20 times faster.
//!
//! Nothing read from a file is trusted: the counts must add up to the file's length before
//! anything is allocated, and one pass over the nodes checks what makes every query safe
//! (children after their parent and in range, one parent each, leaf ranges and references in
//! bounds, depth within the traversal's stack) while the checksum is summed beside it. No
//! builder runs. Then splits are checked against their boxes and leaves for sorted references
//! (one walk, subtrees in parallel), and completeness on a fixed sample of triangles, so
//! opening stays linear; [`KdTree::validate`] checks it all.

use crate::builders::{BuildOptions, BuildReport};
use crate::cost::MAX_DEPTH_CAP;
use crate::geometry::{Aabb, Triangle, Vec3};
use crate::tree::{validate, KdTree, Node};
use serde_json::{json, Value};
use std::fmt;
use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::path::Path;
use std::sync::OnceLock;

/// The first bytes of every tree file; commands tell a saved tree from a mesh by them.
pub const MAGIC: &[u8; 8] = b"SAHKDTRE";
/// The format version this library writes; it reads this one and version 1.
pub const VERSION: u32 = 2;

/// Triangles whose leaves are checked when a file is opened (all of them in smaller trees).
const LOAD_COMPLETENESS_SAMPLE: usize = 4096;

/// What is stored beside the tree: how it was built.
#[derive(Clone, Debug, PartialEq)]
pub struct TreeMeta {
    /// The options as given (`threads: None` means every core of whoever loads it).
    pub options: BuildOptions,
    pub build_ms: f64,
    pub presort_ms: f64,
    /// The build's phases after the presort (`BuildReport`'s binned top, exact subtrees and
    /// layout); 0 in files from before they were recorded.
    pub binned_ms: f64,
    pub subtrees_ms: f64,
    pub layout_ms: f64,
    /// Worker threads the build ran on.
    pub build_threads: usize,
}

impl TreeMeta {
    /// What is stored of a build with `options` that reported `report` on `build_threads`.
    pub fn new(options: BuildOptions, report: &BuildReport, build_threads: usize) -> TreeMeta {
        TreeMeta {
            options,
            build_ms: report.build_ms,
            presort_ms: report.presort_ms,
            binned_ms: report.binned_ms,
            subtrees_ms: report.subtrees_ms,
            layout_ms: report.layout_ms,
            build_threads,
        }
    }
}

/// Why a tree file could not be opened.
#[derive(Debug)]
pub enum LoadError {
    /// The file could not be read.
    Io(io::Error),
    /// The bytes are not a sound tree file; the message says what is wrong.
    Invalid(String),
}

impl fmt::Display for LoadError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            LoadError::Io(e) => e.fmt(f),
            LoadError::Invalid(s) => f.write_str(s),
        }
    }
}

impl std::error::Error for LoadError {}

impl From<io::Error> for LoadError {
    fn from(e: io::Error) -> Self {
        LoadError::Io(e)
    }
}

/// Whether `path` starts with the tree file's magic bytes (false for anything unreadable or
/// shorter), whatever its name.
pub fn is_tree_file(path: &Path) -> bool {
    use std::io::Read;
    let mut head = [0u8; 8];
    File::open(path)
        .and_then(|mut f| f.read_exact(&mut head))
        .is_ok()
        && &head == MAGIC
}

const FNV_BASIS: u64 = 0xcbf2_9ce4_8422_2325;
const FNV_PRIME: u64 = 0x0000_0100_0000_01b3;

/// Version 1's checksum, FNV-1a 64 byte by byte. Checksums tell a damaged file from a good
/// one; they are no protection against deliberate tampering (the structural checks are).
fn fnv1a(bytes: &[u8]) -> u64 {
    bytes
        .iter()
        .fold(FNV_BASIS, |h, &b| (h ^ b as u64).wrapping_mul(FNV_PRIME))
}

/// Version 2's checksum (see the module's description), as a running state so that the
/// writer sums its pieces as they go out.
#[derive(Clone)]
struct Lanes {
    lanes: [u64; 4],
    /// Words summed so far.
    words: u64,
    /// Bytes of an incomplete word.
    pending: [u8; 8],
    pending_len: usize,
    len: u64,
}

impl Lanes {
    fn new() -> Lanes {
        Lanes {
            lanes: [0, 1, 2, 3].map(|i| FNV_BASIS.wrapping_add(i)),
            words: 0,
            pending: [0; 8],
            pending_len: 0,
            len: 0,
        }
    }

    #[inline(always)]
    fn step(lane: u64, word: u64) -> u64 {
        (lane ^ word).wrapping_mul(FNV_PRIME).rotate_left(29)
    }

    fn word(&mut self, word: u64) {
        let i = (self.words % 4) as usize;
        self.lanes[i] = Self::step(self.lanes[i], word);
        self.words += 1;
    }

    fn add(&mut self, mut bytes: &[u8]) {
        self.len += bytes.len() as u64;
        if self.pending_len > 0 {
            let n = (8 - self.pending_len).min(bytes.len());
            self.pending[self.pending_len..self.pending_len + n].copy_from_slice(&bytes[..n]);
            self.pending_len += n;
            bytes = &bytes[n..];
            if self.pending_len < 8 {
                return;
            }
            self.word(u64::from_le_bytes(self.pending));
            self.pending_len = 0;
        }
        while self.words % 4 != 0 && bytes.len() >= 8 {
            self.word(u64::from_le_bytes(bytes[..8].try_into().expect("8 bytes")));
            bytes = &bytes[8..];
        }
        // The bulk: four words at a time, one per lane, in registers.
        let mut blocks = bytes.chunks_exact(32);
        let [mut a, mut b, mut c, mut d] = self.lanes;
        let w = |x: &[u8], k: usize| u64::from_le_bytes(x[8 * k..8 * k + 8].try_into().unwrap());
        for x in &mut blocks {
            a = Self::step(a, w(x, 0));
            b = Self::step(b, w(x, 1));
            c = Self::step(c, w(x, 2));
            d = Self::step(d, w(x, 3));
        }
        self.lanes = [a, b, c, d];
        self.words += 4 * (bytes.len() / 32) as u64;
        let mut rest = blocks.remainder();
        while rest.len() >= 8 {
            self.word(u64::from_le_bytes(rest[..8].try_into().expect("8 bytes")));
            rest = &rest[8..];
        }
        self.pending[..rest.len()].copy_from_slice(rest);
        self.pending_len = rest.len();
    }

    fn finish(mut self) -> u64 {
        if self.pending_len > 0 {
            self.pending[self.pending_len..].fill(0);
            self.word(u64::from_le_bytes(self.pending));
        }
        self.lanes
            .iter()
            .chain([&self.len])
            .fold(FNV_BASIS, |h, &x| (h ^ x).wrapping_mul(FNV_PRIME))
    }
}

/// A writer that sums what passes through it.
struct Summed<W> {
    inner: W,
    sum: Lanes,
}

impl<W: Write> Summed<W> {
    fn put(&mut self, bytes: &[u8]) -> io::Result<()> {
        self.sum.add(bytes);
        self.inner.write_all(bytes)
    }
    /// Writes the items' bytes through a buffer of whole items, to save a call per word.
    fn put_all<T, const N: usize>(
        &mut self,
        items: &[T],
        bytes: impl Fn(&T) -> [u8; N],
    ) -> io::Result<()> {
        let mut buffer = Vec::with_capacity(N * 4096);
        for chunk in items.chunks(4096) {
            buffer.clear();
            for item in chunk {
                buffer.extend_from_slice(&bytes(item));
            }
            self.put(&buffer)?;
        }
        Ok(())
    }
}

fn triangle_bytes(t: &Triangle) -> [u8; 36] {
    let mut out = [0u8; 36];
    for (slot, c) in out.chunks_exact_mut(4).zip(t.iter().flat_map(|v| v.0)) {
        slot.copy_from_slice(&c.to_le_bytes());
    }
    out
}

fn node_bytes(n: &Node) -> [u8; 8] {
    let [word, bits] = n.words();
    let mut out = [0u8; 8];
    out[..4].copy_from_slice(&word.to_le_bytes());
    out[4..].copy_from_slice(&bits.to_le_bytes());
    out
}

fn meta_json(meta: &TreeMeta) -> String {
    // The bins the tree was built with, not "the builder's default", which may change.
    let options = BuildOptions {
        bins: Some(meta.options.resolved_bins()),
        ..meta.options
    };
    json!({
        "options": options,
        "build_ms": meta.build_ms,
        "presort_ms": meta.presort_ms,
        "binned_ms": meta.binned_ms,
        "subtrees_ms": meta.subtrees_ms,
        "layout_ms": meta.layout_ms,
        "build_threads": meta.build_threads,
    })
    .to_string()
}

impl KdTree {
    /// Writes the tree and `meta` in the `.sahkd` format to `out` (buffer it: the words go
    /// out in pieces).
    pub fn write_to(&self, meta: &TreeMeta, out: impl Write) -> io::Result<()> {
        let json = meta_json(meta);
        let meta_len = u32::try_from(json.len())
            .map_err(|_| io::Error::other("the tree's metadata is over 4 GiB"))?;
        let mut out = Summed {
            inner: out,
            sum: Lanes::new(),
        };
        out.put(MAGIC)?;
        out.put(&VERSION.to_le_bytes())?;
        out.put(&meta_len.to_le_bytes())?;
        out.put(json.as_bytes())?;
        for n in [self.triangles.len(), self.nodes.len(), self.refs.len()] {
            out.put(&(n as u64).to_le_bytes())?;
        }
        for c in self.bounds.lo.0.iter().chain(&self.bounds.hi.0) {
            out.put(&c.to_le_bytes())?;
        }
        out.put_all(&self.triangles, triangle_bytes)?;
        out.put_all(&self.nodes, node_bytes)?;
        out.put_all(&self.refs, |r| r.to_le_bytes())?;
        let sum = out.sum.finish();
        out.inner.write_all(&sum.to_le_bytes())?;
        out.inner.flush()
    }

    /// The tree and `meta` as the bytes of a `.sahkd` file.
    pub fn to_bytes(&self, meta: &TreeMeta) -> Vec<u8> {
        let size =
            88 + self.triangles.len() * 36 + self.nodes.len() * 8 + self.refs.len() * 4 + 256;
        let mut out = Vec::with_capacity(size);
        self.write_to(meta, &mut out)
            .expect("writing to memory cannot fail");
        out
    }

    /// Writes `path` whole or not at all (temporary beside it, fsync, rename: see
    /// [`crate::output`]).
    pub fn save(&self, path: &Path, meta: &TreeMeta) -> io::Result<()> {
        crate::output::write_atomically(path, |file| {
            self.write_to(meta, BufWriter::with_capacity(1 << 20, file))
        })
    }

    /// Reads a tree written by [`KdTree::to_bytes`] or [`KdTree::save`], checking
    /// everything (see the module's description); the error says what is wrong.
    pub fn from_bytes(bytes: &[u8]) -> Result<(KdTree, TreeMeta), LoadError> {
        read(bytes).map_err(LoadError::Invalid)
    }

    /// Opens a saved tree by mapping the file into memory: one pass reads and checks it into
    /// the tree's arrays while the checksum is summed on another thread; no builder runs.
    pub fn load(path: &Path) -> Result<(KdTree, TreeMeta), LoadError> {
        if let Some(what) = crate::mesh::not_a_file(path) {
            // An I/O error, as opening a directory is: the file is fine, it is not one.
            return Err(LoadError::Io(std::io::Error::other(format!(
                "is {what}, not a saved tree"
            ))));
        }
        let file = File::open(path)?;
        if file.metadata()?.len() == 0 {
            return Self::from_bytes(&[]);
        }
        // Safety: the map is only read, and only within this call. Another process changing
        // the file meanwhile could change what is read (caught by the checksum, or it reads
        // as a different sound tree) or, by truncating it, fault the read, as with any map.
        // Every page is read, so they are mapped in one call rather than one fault each.
        let map = unsafe { memmap2::MmapOptions::new().populate().map(&file)? };
        Self::from_bytes(&map)
    }
}

/// A cursor over the header that fails with a message instead of panicking.
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
    fn array<const N: usize>(&mut self) -> Result<[u8; N], String> {
        Ok(self.take(N)?.try_into().expect("took N bytes"))
    }
    fn u32(&mut self) -> Result<u32, String> {
        Ok(u32::from_le_bytes(self.array()?))
    }
    fn u64(&mut self) -> Result<u64, String> {
        Ok(u64::from_le_bytes(self.array()?))
    }
}

fn read(bytes: &[u8]) -> Result<(KdTree, TreeMeta), String> {
    if !bytes.starts_with(MAGIC) {
        if bytes.is_empty() {
            return Err("not a sahkd tree file: it is empty (0 bytes)".into());
        }
        return Err("not a sahkd tree file (it does not start with SAHKDTRE)".into());
    }
    let mut r = Reader { bytes, at: 8 };
    let version = r.u32()?;
    if version != 1 && version != VERSION {
        return Err(format!(
            "format version {version}, but this sahkd reads versions 1 and {VERSION} only"
        ));
    }
    if bytes.len() < r.at + 8 {
        return Err("truncated: no checksum".into());
    }
    let (body, sum) = bytes.split_at(bytes.len() - 8);
    let stored = u64::from_le_bytes(sum.try_into().expect("8 bytes"));
    // The sum and the parse run side by side. A damaged file is reported as damaged, whatever
    // the parse made of it.
    let (summed, parsed) = rayon::join(
        || match version {
            1 => fnv1a(body),
            _ => {
                let mut sum = Lanes::new();
                sum.add(body);
                sum.finish()
            }
        },
        || {
            parse(
                Reader {
                    bytes: body,
                    at: r.at,
                },
                bytes.len(),
            )
        },
    );
    if summed != stored {
        return Err("corrupt: checksum mismatch (the file was damaged or truncated)".into());
    }
    parsed
}

fn parse(mut r: Reader<'_>, file_len: usize) -> Result<(KdTree, TreeMeta), String> {
    let meta_len = r.u32()? as usize;
    let meta = parse_meta(r.take(meta_len)?)?;
    let (nt, nn, nr) = (r.u64()?, r.u64()?, r.u64()?);
    let expected = [(nt, 36u64), (nn, 8), (nr, 4)]
        .iter()
        .try_fold(24u64, |acc, &(n, size)| {
            n.checked_mul(size).and_then(|b| acc.checked_add(b))
        });
    let remaining = (r.bytes.len() - r.at) as u64;
    if expected != Some(remaining) {
        return Err(format!(
            "corrupt: counts of {nt} triangles, {nn} nodes and {nr} references do not fit the file's {file_len} bytes"
        ));
    }
    // The counts now fit the file, so every allocation below is bounded by its size.
    let (nt, nn, nr) = (nt as usize, nn as usize, nr as usize);
    let b = r.take(24)?;
    let c = |k: usize| f32::from_le_bytes(b[4 * k..4 * k + 4].try_into().expect("4 bytes"));
    let (lo, hi) = (Vec3([c(0), c(1), c(2)]), Vec3([c(3), c(4), c(5)]));
    let bounds = Aabb::new(lo, hi);
    let (t, n, f) = (r.take(nt * 36)?, r.take(nn * 8)?, r.take(nr * 4)?);
    let (triangles, (nodes, refs)) = rayon::join(
        || read_triangles(t, &bounds),
        || rayon::join(|| read_nodes(n, nr), || read_refs(f, nt)),
    );
    let (triangles, nodes, refs) = (triangles?, nodes?, refs?);
    // Leaves are stored sorted (as `from_parts` leaves them): checked in the walk below
    // rather than sorted again in another pass over every leaf.
    let tree = KdTree {
        nodes,
        refs,
        triangles,
        bounds,
        layout: OnceLock::new(),
    };
    let (splits, complete) = rayon::join(
        || validate::check_splits(&tree),
        || validate::check_completeness(&tree, LOAD_COMPLETENESS_SAMPLE),
    );
    splits
        .and(complete)
        .map_err(|e| format!("invalid tree: {e}"))?;
    Ok((tree, meta))
}

fn parse_meta(bytes: &[u8]) -> Result<TreeMeta, String> {
    let v: Value = serde_json::from_slice(bytes).map_err(|e| format!("corrupt metadata: {e}"))?;
    let mut options: BuildOptions = serde_json::from_value(v["options"].clone())
        .map_err(|e| format!("corrupt metadata (build options): {e}"))?;
    // Files written before binning was the hybrid's default leave out exact SAH's bins 0.
    options.bins.get_or_insert(0);
    let ms = |k: &str| v[k].as_f64().unwrap_or(0.0);
    Ok(TreeMeta {
        options,
        build_ms: ms("build_ms"),
        presort_ms: ms("presort_ms"),
        binned_ms: ms("binned_ms"),
        subtrees_ms: ms("subtrees_ms"),
        layout_ms: ms("layout_ms"),
        build_threads: v["build_threads"].as_u64().unwrap_or(0) as usize,
    })
}

/// Finite corners, spanning exactly the stored scene box. Decoded first and checked after,
/// in two plain loops the compiler vectorizes (one loop with an early return and a running
/// box took 138 instructions a triangle).
fn read_triangles(bytes: &[u8], bounds: &Aabb) -> Result<Vec<Triangle>, String> {
    let float = |b: &[u8]| f32::from_le_bytes([b[0], b[1], b[2], b[3]]);
    let corner = |b: &[u8]| Vec3([float(&b[0..4]), float(&b[4..8]), float(&b[8..12])]);
    let triangles: Vec<Triangle> = bytes
        .chunks_exact(36)
        .map(|t| [corner(&t[0..12]), corner(&t[12..24]), corner(&t[24..36])])
        .collect();
    // An exponent of all ones is an infinity or a NaN.
    let non_finite = |v: &Vec3| v.0.iter().any(|c| c.to_bits() & 0x7f80_0000 == 0x7f80_0000);
    if let Some(i) = triangles.iter().position(|t| t.iter().any(non_finite)) {
        return Err(format!("corrupt: triangle {i} has a non-finite corner"));
    }
    // Nine running minima and maxima (one per coordinate of a triangle), folded at the end:
    // no dependency from one corner to the next. The corners are finite, so comparisons are
    // total, and the box is compared by value (-0 and +0 alike).
    let (mut lo, mut hi) = ([f32::INFINITY; 9], [f32::NEG_INFINITY; 9]);
    for t in &triangles {
        for k in 0..9 {
            let x = t[k / 3].0[k % 3];
            lo[k] = if x < lo[k] { x } else { lo[k] };
            hi[k] = if x > hi[k] { x } else { hi[k] };
        }
    }
    let fold = |v: &[f32; 9], a: usize, f: fn(f32, f32) -> f32| f(f(v[a], v[a + 3]), v[a + 6]);
    let span_lo = Vec3(std::array::from_fn(|a| fold(&lo, a, f32::min)));
    let span_hi = Vec3(std::array::from_fn(|a| fold(&hi, a, f32::max)));
    if !(span_lo == bounds.lo && span_hi == bounds.hi) {
        return Err("corrupt: the stored scene bounds are not those of the triangles".into());
    }
    Ok(triangles)
}

/// The nodes, checked in one pass: parents come before children, so when node `i` is reached
/// every node that could name it as a child has been seen, and `depth[i]` (its depth plus one,
/// set by its parent; 0 for none) says whether it has exactly one parent.
fn read_nodes(bytes: &[u8], refs: usize) -> Result<Vec<Node>, String> {
    let n = bytes.len() / 8;
    if n == 0 {
        return Err("corrupt: the tree has no root node".into());
    }
    let mut nodes = Vec::with_capacity(n);
    // Depths fit a byte: they are checked against the cap (60) before being stored.
    let mut depth = vec![0u8; n];
    depth[0] = 1;
    for (i, w) in bytes.chunks_exact(8).enumerate() {
        let word = u32::from_le_bytes(w[..4].try_into().expect("4 bytes"));
        let bits = u32::from_le_bytes(w[4..].try_into().expect("4 bytes"));
        let node = Node::from_words([word, bits]);
        let d = depth[i];
        if d == 0 {
            return Err(format!("corrupt: node {i} has 0 parents instead of one"));
        }
        if node.is_leaf() {
            let end = node.first() as u64 + node.count() as u64;
            if end > refs as u64 {
                return Err(format!(
                    "corrupt: leaf {i} ends at reference {end}, but there are {refs}"
                ));
            }
        } else {
            let left = node.left() as usize;
            if left <= i || left + 1 >= n {
                return Err(format!(
                    "corrupt: node {i} has children {left} and {}, not after it among the {n} nodes",
                    left + 1
                ));
            }
            // `d` is this node's depth plus one, so its children's depth.
            if u32::from(d) > MAX_DEPTH_CAP {
                return Err(format!(
                    "corrupt: the tree is deeper than the limit of {MAX_DEPTH_CAP}"
                ));
            }
            for c in [left, left + 1] {
                if depth[c] != 0 {
                    return Err(format!(
                        "corrupt: node {c} has 2 parents or more instead of one"
                    ));
                }
                depth[c] = d + 1;
            }
        }
        nodes.push(node);
    }
    Ok(nodes)
}

fn read_refs(bytes: &[u8], triangles: usize) -> Result<Vec<u32>, String> {
    let refs: Vec<u32> = bytes
        .chunks_exact(4)
        .map(|c| u32::from_le_bytes(c.try_into().expect("4 bytes")))
        .collect();
    // One comparison against the largest, then the search only on a failure.
    if refs.iter().copied().max().unwrap_or(0) as usize >= triangles && !refs.is_empty() {
        let r = refs
            .iter()
            .find(|&&r| r as usize >= triangles)
            .expect("max");
        return Err(format!(
            "corrupt: reference to triangle {r}, but there are {triangles}"
        ));
    }
    Ok(refs)
}
