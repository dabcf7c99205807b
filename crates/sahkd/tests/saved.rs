//! Saved trees (`.sahkd` files): what is saved comes back entry for entry, the bytes are the
//! documented layout (written here by a second, independent encoder), and damaged or forged
//! files are refused with a message, never a panic or an allocation the file cannot back.

mod common;

use common::{all_variants, describe, mesh_of, random_triangles, rng};
use sahkd::saved::{is_tree_file, MAGIC};
use sahkd::{build, BuildOptions, KdTree, LoadError, Mesh, TreeMeta};
use std::path::PathBuf;

fn meta(options: &BuildOptions) -> TreeMeta {
    TreeMeta {
        options: *options,
        build_ms: 12.345678901234567,
        presort_ms: 0.1,
        binned_ms: 1.5,
        subtrees_ms: 7.25,
        layout_ms: 0.5,
        build_threads: 3,
    }
}

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("sahkd-saved-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn assert_same(a: &KdTree, b: &KdTree, what: &str) {
    assert_eq!(a.nodes(), b.nodes(), "{what}: nodes");
    assert_eq!(a.refs(), b.refs(), "{what}: refs");
    let bits = |t: &KdTree| -> Vec<u32> {
        t.triangles()
            .iter()
            .flat_map(|t| t.iter().flat_map(|v| v.0.map(f32::to_bits)))
            .collect()
    };
    assert_eq!(bits(a), bits(b), "{what}: triangles");
    assert_eq!(
        [a.bounds().lo.0, a.bounds().hi.0],
        [b.bounds().lo.0, b.bounds().hi.0],
        "{what}: bounds"
    );
}

fn scenes() -> Vec<(String, Mesh)> {
    vec![
        (
            "random 300".into(),
            mesh_of(&random_triangles(&mut rng(7), 300)),
        ),
        (
            "spd:sphere:600".into(),
            sahkd::scenes::generate("spd:sphere:600").unwrap(),
        ),
        (
            "one triangle".into(),
            mesh_of(&random_triangles(&mut rng(8), 1)),
        ),
    ]
}

/// The metadata a file gives back: the options with the bins the tree was built with, so a
/// later change of the builder's default does not change what an old file says.
fn as_stored(m: &TreeMeta) -> TreeMeta {
    let mut m = m.clone();
    m.options.bins = Some(m.options.resolved_bins());
    m
}

#[test]
fn every_builders_tree_comes_back_entry_for_entry() {
    let dir = scratch("round-trip");
    let path = dir.join("tree.sahkd");
    for (name, mesh) in scenes() {
        for options in all_variants() {
            let what = format!("{name}, {}", describe(&options));
            let tree = build(&mesh, &options).unwrap().tree;
            let m = meta(&options);
            let bytes = tree.to_bytes(&m);
            let (back, back_meta) = KdTree::from_bytes(&bytes).unwrap();
            assert_same(&tree, &back, &what);
            assert_eq!(back_meta, as_stored(&m), "{what}: metadata");

            tree.save(&path, &m).unwrap();
            assert_eq!(std::fs::read(&path).unwrap(), bytes, "{what}: file bytes");
            assert!(is_tree_file(&path));
            let (loaded, loaded_meta) = KdTree::load(&path).unwrap();
            assert_same(&tree, &loaded, &what);
            assert_eq!(loaded_meta, as_stored(&m), "{what}: metadata");
            loaded.validate().unwrap();
        }
    }
    let empty = KdTree::empty();
    let m = meta(&BuildOptions::default());
    let (back, _) = KdTree::from_bytes(&empty.to_bytes(&m)).unwrap();
    assert_same(&empty, &back, "empty tree");
    std::fs::remove_dir_all(dir).unwrap();
}

// --- A second encoder of the documented layout, so that the bytes are checked against the
// documentation and not against the library's own writer, and forged files can carry a
// correct checksum.

const BASIS: u64 = 0xcbf2_9ce4_8422_2325;
const PRIME: u64 = 0x100_0000_01b3;

/// Version 1's checksum: FNV-1a 64 over the bytes.
fn fnv1a(bytes: &[u8]) -> u64 {
    bytes
        .iter()
        .fold(BASIS, |h, &b| (h ^ u64::from(b)).wrapping_mul(PRIME))
}

/// Version 2's, as documented: words padded, word k into lane k % 4, lanes then length.
fn lanes(bytes: &[u8]) -> u64 {
    let mut padded = bytes.to_vec();
    padded.resize(bytes.len().div_ceil(8) * 8, 0);
    let mut lane = [BASIS, BASIS + 1, BASIS + 2, BASIS + 3];
    for (k, w) in padded.chunks(8).enumerate() {
        let w = u64::from_le_bytes(w.try_into().unwrap());
        lane[k % 4] = ((lane[k % 4] ^ w).wrapping_mul(PRIME)).rotate_left(29);
    }
    lane.iter()
        .chain([&(bytes.len() as u64)])
        .fold(BASIS, |h, &x| (h ^ x).wrapping_mul(PRIME))
}

/// Where the counts start: after the metadata, whose length the header gives.
struct Offsets {
    counts: usize,
}

fn offsets(bytes: &[u8]) -> Offsets {
    let m = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
    Offsets { counts: 16 + m }
}

fn encode(tree: &KdTree, meta_json: &str, version: u32) -> Vec<u8> {
    let mut out = Vec::new();
    out.extend_from_slice(b"SAHKDTRE");
    out.extend_from_slice(&version.to_le_bytes());
    out.extend_from_slice(&(meta_json.len() as u32).to_le_bytes());
    out.extend_from_slice(meta_json.as_bytes());
    for n in [
        tree.triangles().len(),
        tree.nodes().len(),
        tree.refs().len(),
    ] {
        out.extend_from_slice(&(n as u64).to_le_bytes());
    }
    let b = tree.bounds();
    for c in b.lo.0.into_iter().chain(b.hi.0) {
        out.extend_from_slice(&c.to_le_bytes());
    }
    for c in tree.triangles().iter().flatten().flat_map(|v| v.0) {
        out.extend_from_slice(&c.to_le_bytes());
    }
    for w in tree.nodes().iter().flat_map(|n| n.words()) {
        out.extend_from_slice(&w.to_le_bytes());
    }
    for r in tree.refs() {
        out.extend_from_slice(&r.to_le_bytes());
    }
    resum(out)
}

/// Appends the checksum of the version the body says (version 2's for any other) so that only
/// the structural checks judge the bytes.
fn resum(mut body: Vec<u8>) -> Vec<u8> {
    let sum = match body.get(8..12) {
        Some([1, 0, 0, 0]) => fnv1a(&body),
        _ => lanes(&body),
    };
    body.extend_from_slice(&sum.to_le_bytes());
    body
}

fn small_tree() -> (KdTree, Vec<u8>) {
    let mesh = mesh_of(&random_triangles(&mut rng(3), 12));
    let options = BuildOptions::default();
    let tree = build(&mesh, &options).unwrap().tree;
    let bytes = tree.to_bytes(&meta(&options));
    (tree, bytes)
}

#[test]
fn the_bytes_are_the_documented_layout_and_version_1_still_opens() {
    for n in [0, 1, 5, 12, 40] {
        let mesh = mesh_of(&random_triangles(&mut rng(n), n as usize));
        let options = BuildOptions::default();
        let tree = build(&mesh, &options).unwrap().tree;
        let bytes = tree.to_bytes(&meta(&options));
        let Offsets { counts, .. } = offsets(&bytes);
        let json = std::str::from_utf8(&bytes[16..counts]).unwrap();
        assert_eq!(encode(&tree, json, 2), bytes, "{n} triangles");
        let (back, _) = KdTree::from_bytes(&encode(&tree, json, 1)).unwrap();
        assert_same(&tree, &back, "version 1");
    }
    let (tree, bytes) = small_tree();
    let Offsets { counts, .. } = offsets(&bytes);
    let json = std::str::from_utf8(&bytes[16..counts]).unwrap();
    // A file as the first version 1 writers wrote it (no thread count) still opens.
    let old = encode(
        &tree,
        &format!(
            r#"{{"options":{},"build_ms":1.5,"presort_ms":0.25}}"#,
            serde_json_options(json)
        ),
        1,
    );
    let (back, m) = KdTree::from_bytes(&old).unwrap();
    assert_same(&tree, &back, "old metadata");
    assert_eq!((m.build_ms, m.presort_ms, m.build_threads), (1.5, 0.25, 0));
    // Files from before binning was the hybrid's default have no bins: they were exact.
    let before_bins = encode(
        &tree,
        &format!(
            r#"{{"options":{},"build_ms":1.5,"presort_ms":0.25}}"#,
            serde_json::to_string(&BuildOptions::default()).unwrap()
        ),
        1,
    );
    let (_, m) = KdTree::from_bytes(&before_bins).unwrap();
    assert_eq!(m.options.bins, Some(0), "no bins in an old file: exact SAH");
}

/// The `options` object of a metadata string, cut out by hand (no JSON library here).
fn serde_json_options(json: &str) -> &str {
    let start = json.find("\"options\":").unwrap() + "\"options\":".len();
    let mut depth = 0;
    for (i, c) in json[start..].char_indices() {
        match c {
            '{' => depth += 1,
            '}' => {
                depth -= 1;
                if depth == 0 {
                    return &json[start..start + i + 1];
                }
            }
            _ => {}
        }
    }
    panic!("no options object in {json}")
}

fn refused(bytes: &[u8], what: &str) -> String {
    match KdTree::from_bytes(bytes) {
        Ok(_) => panic!("{what}: accepted"),
        Err(LoadError::Invalid(e)) => e,
        Err(LoadError::Io(e)) => panic!("{what}: an I/O error from memory: {e}"),
    }
}

#[test]
fn every_truncation_is_refused_from_memory_and_from_a_file() {
    let (_, bytes) = small_tree();
    let dir = scratch("truncated");
    let path = dir.join("cut.sahkd");
    for len in 0..bytes.len() {
        let e = refused(&bytes[..len], &format!("first {len} bytes"));
        assert!(
            e.contains("not a sahkd tree file")
                || e.contains("truncated")
                || e.contains("checksum mismatch"),
            "{len}: {e}"
        );
        std::fs::write(&path, &bytes[..len]).unwrap();
        match KdTree::load(&path) {
            Err(LoadError::Invalid(f)) => assert_eq!(e, f, "{len}"),
            other => panic!("{len}: {:?}", other.map(|_| ())),
        }
    }
    std::fs::remove_dir_all(dir).unwrap();
}

#[test]
fn every_flipped_byte_is_refused_and_forged_ones_never_panic() {
    let (_, bytes) = small_tree();
    for at in 0..bytes.len() {
        for mask in [0x01u8, 0x80, 0xff] {
            let mut damaged = bytes.clone();
            damaged[at] ^= mask;
            let e = refused(&damaged, &format!("byte {at} ^ {mask:#x}"));
            if at >= 12 {
                // Past the magic and the version, the checksum catches it.
                assert!(e.contains("checksum mismatch"), "byte {at}: {e}");
            }
            // With the checksum made right, the structural checks alone judge the header and
            // the nodes: a refusal or a tree that passes the full validation (the load checks
            // every triangle of a tree this small), never a panic.
            if at < bytes.len() - 8 {
                let forged = resum(damaged[..bytes.len() - 8].to_vec());
                if let Ok((tree, _)) = KdTree::from_bytes(&forged) {
                    tree.validate()
                        .unwrap_or_else(|e| panic!("byte {at} ^ {mask:#x} loaded: {e}"));
                }
            }
        }
    }
}

#[test]
fn a_wrong_version_is_named() {
    let (_, bytes) = small_tree();
    let mut v = bytes.clone();
    v[8..12].copy_from_slice(&3u32.to_le_bytes());
    let e = refused(&resum(v[..v.len() - 8].to_vec()), "version 3");
    assert!(e.contains("format version 3"), "{e}");
    // A version 2 file that says it is version 1 is summed the other way.
    v[8..12].copy_from_slice(&1u32.to_le_bytes());
    assert!(refused(&v, "relabelled").contains("checksum mismatch"));
    assert!(MAGIC.starts_with(b"SAHKD"));
}

#[test]
fn lying_counts_are_refused_before_anything_is_allocated() {
    let (tree, bytes) = small_tree();
    let Offsets { counts, .. } = offsets(&bytes);
    let (nt, nn, nr) = (
        tree.triangles().len() as u64,
        tree.nodes().len() as u64,
        tree.refs().len() as u64,
    );
    let huge = [
        u64::MAX,
        u64::MAX / 4,
        1 << 62,
        1 << 40,
        u32::MAX as u64 + 1,
    ];
    let mut cases = Vec::new();
    for field in 0..3 {
        for &h in &huge {
            cases.push((field, h));
        }
    }
    // Off by one each way, and shifting bytes between the arrays (same total length).
    cases.extend([
        (0, nt + 1),
        (0, nt - 1),
        (1, nn + 1),
        (2, nr - 1),
        (2, nr + 9),
    ]);
    for (field, value) in cases {
        let mut v = bytes[..bytes.len() - 8].to_vec();
        let at = counts + 8 * field;
        v[at..at + 8].copy_from_slice(&value.to_le_bytes());
        let e = refused(&resum(v), &format!("count {field} = {value}"));
        assert!(e.contains("do not fit the file"), "{field} = {value}: {e}");
    }
    // Triangles traded for references: the lengths add up, the structure does not.
    let mut v = bytes[..bytes.len() - 8].to_vec();
    v[counts..counts + 8].copy_from_slice(&(nt - 1).to_le_bytes());
    v[counts + 16..counts + 24].copy_from_slice(&(nr + 9).to_le_bytes());
    let e = refused(&resum(v), "traded counts");
    assert!(e.contains("corrupt"), "{e}");
    // A metadata length past the end.
    let mut v = bytes[..bytes.len() - 8].to_vec();
    v[12..16].copy_from_slice(&u32::MAX.to_le_bytes());
    let e = refused(&resum(v), "metadata length");
    assert!(e.contains("truncated"), "{e}");
}

#[test]
fn files_that_are_not_trees_are_named_so() {
    let dir = scratch("not-trees");
    let ply = dir.join("mesh.sahkd");
    std::fs::write(&ply, "ply\nformat ascii 1.0\n").unwrap();
    assert!(!is_tree_file(&ply));
    let e = KdTree::load(&ply).unwrap_err().to_string();
    assert!(e.contains("not a sahkd tree file"), "{e}");
    assert!(matches!(
        KdTree::load(&dir.join("missing.sahkd")),
        Err(LoadError::Io(_))
    ));
    // A directory (or a device, or a named pipe) is named as what it is.
    let e = KdTree::load(&dir).unwrap_err();
    assert!(matches!(e, LoadError::Io(_)), "{e}");
    assert!(e.to_string().contains("is a directory"), "{e}");
    std::fs::remove_dir_all(dir).unwrap();
}
