//! A digest of the trees a builder makes, to check that a change keeps them bit-identical.
//!
//! `cargo run --release -p sahkd --example tree_digest -- [--preset fast] [--algorithm sweep]
//! [--threads 1] [--bins N] [--counting space-tree] bunny dragon_res2 dragon`
//!
//! Without `--preset` the options are the defaults with the sweep; with it, the preset's
//! (its builder too), and the flags given beside it override them.
//! For each scene and each of `--axes longest|all` x `--clip on|off` it prints one line: an
//! FNV-1a hash over every node (axis, split-position bits, child index or first reference and
//! count) and every reference, then the node and reference counts and the build time. Scenes
//! are read from `$SAHKD_SCENES` or `../shared/scenes` (relative to the workspace).

use sahkd::{build_triangles, Algorithm, Axes, BuildOptions, KdTree, Mesh, Preset};
use std::path::PathBuf;

fn scenes_dir() -> PathBuf {
    std::env::var_os("SAHKD_SCENES")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/scenes"))
}

/// FNV-1a over 32-bit words: simple, stable across Rust versions and platforms.
struct Fnv(u64);

impl Fnv {
    fn word(&mut self, w: u32) {
        for b in w.to_le_bytes() {
            self.0 ^= b as u64;
            self.0 = self.0.wrapping_mul(0x100_0000_01b3);
        }
    }
}

fn digest(tree: &KdTree) -> u64 {
    let mut h = Fnv(0xcbf2_9ce4_8422_2325);
    for node in tree.nodes() {
        if node.is_leaf() {
            h.word(3);
            h.word(node.first());
            h.word(node.count());
        } else {
            h.word(node.axis() as u32);
            h.word(node.split().to_bits());
            h.word(node.left());
        }
    }
    for &r in tree.refs() {
        h.word(r);
    }
    h.0
}

/// A library value by its serde name (`sweep`, `space-tree`, ...).
fn named<T: serde::de::DeserializeOwned>(v: &str) -> Option<T> {
    serde_json::from_value(serde_json::Value::String(v.to_string())).ok()
}

fn number<T: std::str::FromStr>(v: &str) -> Option<T> {
    v.parse().ok()
}

/// The value given after `flag`, or an error saying what the flag wants.
fn value<T>(flag: &str, v: Option<String>, parse: fn(&str) -> Option<T>, wants: &str) -> T {
    let v = v.unwrap_or_default();
    parse(&v).unwrap_or_else(|| {
        eprintln!("error: {flag} needs {wants}, got {v:?}");
        std::process::exit(2)
    })
}

fn main() {
    let mut preset: Option<Preset> = None;
    let mut algorithm = None;
    let mut threads = Some(1);
    let mut bins = None;
    let mut counting = None;
    let mut names = Vec::new();
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--preset" => preset = Some(value(&a, args.next(), named, "a preset's name")),
            "--algorithm" => algorithm = Some(value(&a, args.next(), named, "a builder's name")),
            "--counting" => counting = Some(value(&a, args.next(), named, "space-tree or scan")),
            "--threads" => threads = Some(value(&a, args.next(), number, "a positive number")),
            "--bins" => bins = Some(value(&a, args.next(), number, "a number (0: exact)")),
            _ => names.push(a),
        }
    }
    let base = match preset {
        Some(p) => p.options(),
        None => BuildOptions {
            algorithm: Algorithm::Sweep,
            ..BuildOptions::default()
        },
    };
    let dir = scenes_dir();
    println!("scene\taxes\tclip\tdigest\tnodes\trefs\tbuild ms");
    for name in &names {
        let tris = match Mesh::load(dir.join(format!("{name}.ply"))) {
            Ok(m) => m.corner_triangles(),
            Err(e) => {
                eprintln!("skipping {name}: {e}");
                continue;
            }
        };
        for axes in [Axes::Longest, Axes::All] {
            for clip in [true, false] {
                let options = BuildOptions {
                    algorithm: algorithm.unwrap_or(base.algorithm),
                    axes,
                    clip,
                    threads,
                    bins: bins.or(base.bins),
                    counting: counting.unwrap_or(base.counting),
                    ..base
                };
                let b = match build_triangles(tris.clone(), &options) {
                    Ok(b) => b,
                    Err(e) => {
                        eprintln!("error: {name}: {e}");
                        std::process::exit(1)
                    }
                };
                println!(
                    "{name}\t{axes:?}\t{}\t{:016x}\t{}\t{}\t{:.0}",
                    if clip { "on" } else { "off" },
                    digest(&b.tree),
                    b.tree.nodes().len(),
                    b.tree.refs().len(),
                    b.report.build_ms
                );
            }
        }
    }
}
