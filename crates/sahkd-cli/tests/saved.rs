//! Saved trees on the command line: `build --save`, then `trace`, `query`, `render` and
//! `info` on the file, checked against the same commands on the mesh built fresh; damaged
//! files end in one `error:` line naming the file, and no output is written.

use npyz::WriterBuilder;
use serde_json::Value;
use std::fs::File;
use std::io::BufWriter;
use std::path::Path;
use std::process::{Command, Output};

const SCENE: &str = "spd:sphere:2000";

fn sahkd(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_sahkd"))
        .args(args)
        .output()
        .expect("cannot start the sahkd binary")
}

fn s(p: &Path) -> &str {
    p.to_str().expect("temp paths are UTF-8")
}

fn succeeds(args: &[&str]) -> String {
    let out = sahkd(args);
    assert!(
        out.status.success(),
        "sahkd {args:?} failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

fn json(args: &[&str]) -> Value {
    serde_json::from_str(&succeeds(args)).expect("one JSON object")
}

/// Runs a command that must fail with exactly one `error:` line naming every fragment.
fn fails(args: &[&str], fragments: &[&str]) -> String {
    let out = sahkd(args);
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(!out.status.success(), "sahkd {args:?} succeeded");
    assert!(!err.contains("panicked"), "sahkd {args:?} panicked: {err}");
    let lines: Vec<&str> = err.lines().collect();
    assert_eq!(lines.len(), 1, "sahkd {args:?}: not one line: {err}");
    assert!(lines[0].starts_with("error: "), "sahkd {args:?}: {err}");
    for f in fragments {
        assert!(lines[0].contains(f), "sahkd {args:?}: '{f}' not in: {err}");
    }
    lines[0].to_string()
}

/// Rays from around the unit sphere toward points near it (most hit, some miss).
fn write_rays(path: &Path, count: usize) {
    let mut state = 0x2545_f491_4f6c_dd1du64;
    let mut unit = || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 40) as f32 / (1u64 << 24) as f32
    };
    let mut values = Vec::with_capacity(count * 6);
    for _ in 0..count {
        let o = [0; 3].map(|_| unit() * 6.0 - 3.0);
        let target = [0; 3].map(|_| unit() * 2.6 - 1.3);
        values.extend(o);
        values.extend([0, 1, 2].map(|a| target[a] - o[a]));
    }
    let mut w = npyz::WriteOptions::new()
        .default_dtype()
        .shape(&[count as u64, 6])
        .writer(BufWriter::new(File::create(path).unwrap()))
        .begin_nd()
        .unwrap();
    w.extend(values).unwrap();
    w.finish().unwrap();
}

/// Each member of an .npz (one .npy file per array: header and data) as bytes, by name.
fn members(path: &Path) -> Vec<(String, Vec<u8>)> {
    use std::io::Read;
    let mut zip = npyz::zip::ZipArchive::new(File::open(path).unwrap()).unwrap();
    let mut out = Vec::new();
    for i in 0..zip.len() {
        let mut member = zip.by_index(i).unwrap();
        let mut bytes = Vec::new();
        member.read_to_end(&mut bytes).unwrap();
        out.push((member.name().to_string(), bytes));
    }
    out.sort();
    out
}

/// The two .npz files hold the same arrays, dtype, shape and every bit (the archives
/// themselves differ in their time stamps).
fn assert_same_npz(a: &Path, b: &Path) {
    let (x, y) = (members(a), members(b));
    assert!(!x.is_empty(), "{}: no arrays", a.display());
    for ((name, xa), (other, ya)) in x.iter().zip(&y) {
        assert_eq!(name, other);
        assert!(
            xa == ya,
            "{name} differs between {} and {}",
            a.display(),
            b.display()
        );
    }
    assert_eq!(x.len(), y.len());
}

#[test]
fn a_saved_tree_answers_exactly_as_the_mesh_built_fresh() {
    let dir = tempfile::tempdir().unwrap();
    let d = |name: &str| dir.path().join(name);
    let names = [
        "rays.npy",
        "points.npy",
        "fresh.npz",
        "saved.npz",
        "fresh.png",
        "saved.png",
    ];
    let [rays, points, fresh_npz, saved_npz, fresh_png, saved_png] =
        names.map(|n| s(&d(n)).to_string());
    let (rays, points) = (rays.as_str(), points.as_str());
    let (fresh_npz, saved_npz) = (fresh_npz.as_str(), saved_npz.as_str());
    let (fresh_png, saved_png) = (fresh_png.as_str(), saved_png.as_str());
    write_rays(Path::new(rays), 3000);
    let mut writer = npyz::WriteOptions::new()
        .default_dtype()
        .shape(&[500, 3])
        .writer(BufWriter::new(File::create(Path::new(points)).unwrap()))
        .begin_nd()
        .unwrap();
    writer
        .extend((0..1500).map(|i| ((i * 7919) % 1000) as f32 / 400.0 - 1.25))
        .unwrap();
    writer.finish().unwrap();

    for options in [
        &[][..],
        &["--algorithm", "sweep", "--clip", "off", "--axes", "all"][..],
        &["--algorithm", "median", "--leaf-size", "3", "--kt", "2"][..],
        &["--bins", "4", "--threads", "2"][..],
    ] {
        // No .sahkd extension: the file is told by its first bytes.
        let tree = d("tree.bin");
        let mut build = vec!["build", SCENE, "--save", s(&tree), "--json"];
        build.extend_from_slice(options);
        let built = json(&build);
        assert_eq!(built["saved"], s(&tree));

        let info = json(&["info", s(&tree), "--json"]);
        assert_eq!(info["kind"], "tree");
        for key in ["triangles", "nodes", "leaves", "references", "max_depth"] {
            assert_eq!(info[key], built[key], "{key} with {options:?}");
        }
        assert_eq!(info["algorithm"], built["algorithm"]);

        for extra in [&[][..], &["--any-hit"][..]] {
            let mut fresh = vec!["trace", SCENE, "--rays", rays];
            fresh.extend_from_slice(&["-o", fresh_npz, "-q"]);
            fresh.extend_from_slice(options);
            fresh.extend_from_slice(extra);
            succeeds(&fresh);
            let mut saved = vec!["trace", s(&tree), "--rays", rays];
            saved.extend_from_slice(&["-o", saved_npz, "--threads", "2"]);
            saved.extend_from_slice(extra);
            let report = json(&[&saved[..], &["--json"]].concat());
            assert_eq!(report["triangles"], built["triangles"]);
            assert_same_npz(Path::new(fresh_npz), Path::new(saved_npz));
        }

        let mut fresh = vec!["query", SCENE, "--points", points, "--signed"];
        fresh.extend_from_slice(&["-o", fresh_npz]);
        fresh.extend_from_slice(options);
        succeeds(&fresh);
        succeeds(&[
            "query",
            s(&tree),
            "--points",
            points,
            "--signed",
            "-o",
            saved_npz,
        ]);
        assert_same_npz(Path::new(fresh_npz), Path::new(saved_npz));

        let picture = ["--width", "40", "--height", "30", "--json"];
        let mut fresh = vec!["render", SCENE, "-o", fresh_png];
        fresh.extend_from_slice(&picture);
        fresh.extend_from_slice(options);
        let fresh_report = json(&fresh);
        let mut saved = vec!["render", s(&tree), "-o", saved_png];
        saved.extend_from_slice(&picture);
        let saved_report = json(&saved);
        assert_eq!(
            std::fs::read(Path::new(fresh_png)).unwrap(),
            std::fs::read(Path::new(saved_png)).unwrap()
        );
        // The saved tree's options are reported, as if built again.
        for key in ["algorithm", "axes", "clip", "bins", "nodes", "sah_cost"] {
            assert_eq!(
                saved_report["build"][key], fresh_report["build"][key],
                "{key}"
            );
        }
    }
}

#[test]
fn build_options_with_a_saved_tree_are_named_and_refused() {
    let dir = tempfile::tempdir().unwrap();
    let tree = dir.path().join("t.sahkd");
    let rays = dir.path().join("rays.npy");
    let hits = dir.path().join("hits.npz");
    write_rays(&rays, 10);
    succeeds(&["build", "spd:sphere:200", "--save", s(&tree), "-q"]);
    fails(
        &[
            "trace",
            s(&tree),
            "--rays",
            s(&rays),
            "-o",
            s(&hits),
            "--kt",
            "3",
            "--clip",
            "on",
        ],
        &[s(&tree), "--clip, --kt", "already built"],
    );
    fails(
        &[
            "render",
            s(&tree),
            "-o",
            s(&dir.path().join("p.png")),
            "--algorithm",
            "sweep",
        ],
        &["--algorithm"],
    );
    fails(&["build", s(&tree)], &[s(&tree), "saved tree"]);
    assert!(!hits.exists());
    // --threads sets the queries' threads too: allowed.
    succeeds(&[
        "trace",
        s(&tree),
        "--rays",
        s(&rays),
        "-o",
        s(&hits),
        "--threads",
        "1",
    ]);
}

#[test]
fn save_follows_the_rules_of_every_output() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = dir.path().join("tri.ply");
    let text = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
                property float z\nelement face 1\nproperty list uchar int vertex_indices\n\
                end_header\n-1 -1 0\n1 -1 0\n0 1 0\n3 0 1 2\n";
    std::fs::write(&mesh, text).unwrap();
    fails(&["build", s(&mesh), "--save", s(&mesh)], &["is the input"]);
    assert_eq!(std::fs::read_to_string(&mesh).unwrap(), text);
    fails(
        &[
            "build",
            s(&mesh),
            "--save",
            s(&dir.path().join("no").join("t.sahkd")),
        ],
        &["does not exist"],
    );
    // A file replaced whole, and no temporary left beside it.
    let tree = dir.path().join("t.sahkd");
    std::fs::write(&tree, "an old file").unwrap();
    succeeds(&["build", s(&mesh), "--save", s(&tree), "-q"]);
    assert!(std::fs::read(&tree).unwrap().starts_with(b"SAHKDTRE"));
    let mut names: Vec<String> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    assert_eq!(names, ["t.sahkd", "tri.ply"]);
}

fn fnv1a(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325u64, |h, &b| {
        (h ^ u64::from(b)).wrapping_mul(0x100_0000_01b3)
    })
}

/// `body` (a file without its checksum) made a version 1 file (the version whose checksum is
/// short to write here) with a correct checksum.
fn resum(body: &[u8]) -> Vec<u8> {
    let mut out = body.to_vec();
    if out[8..12] == 2u32.to_le_bytes() {
        out[8..12].copy_from_slice(&1u32.to_le_bytes());
    }
    let sum = fnv1a(&out);
    out.extend_from_slice(&sum.to_le_bytes());
    out
}

#[test]
fn damaged_tree_files_end_in_one_error_line_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let good = dir.path().join("good.sahkd");
    succeeds(&["build", "spd:sphere:12", "--save", s(&good), "-q"]);
    let bytes = std::fs::read(&good).unwrap();
    let rays = dir.path().join("rays.npy");
    write_rays(&rays, 5);
    let hits = dir.path().join("hits.npz");
    let bad = dir.path().join("bad.sahkd");

    let check = |data: &[u8], fragment: &str| {
        std::fs::write(&bad, data).unwrap();
        let line = fails(
            &["trace", s(&bad), "--rays", s(&rays), "-o", s(&hits)],
            &[s(&bad), fragment],
        );
        assert!(!hits.exists(), "{line}: an output was written");
    };
    // Every truncation: shorter than the magic, the file is not a tree (so it is read as a
    // mesh, and refused as one); past it, a truncated tree.
    for len in 0..bytes.len() {
        check(&bytes[..len], "");
        if len >= 8 {
            let line = fails(&["info", s(&bad)], &[s(&bad)]);
            assert!(
                line.contains("truncated") || line.contains("checksum mismatch"),
                "{len} bytes: {line}"
            );
        }
    }
    let m = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
    let body = &bytes[..bytes.len() - 8];
    let mut flipped = bytes.clone();
    flipped[16 + m + 60] ^= 0x10;
    check(&flipped, "checksum mismatch");
    let mut version = body.to_vec();
    version[8..12].copy_from_slice(&7u32.to_le_bytes());
    check(&resum(&version), "format version 7");
    for (field, value) in [(0, u64::MAX), (1, 1 << 40), (2, u32::MAX as u64 + 3)] {
        let mut lying = body.to_vec();
        let at = 16 + m + 8 * field;
        lying[at..at + 8].copy_from_slice(&value.to_le_bytes());
        check(&resum(&lying), "do not fit the file");
    }
    // The same damage seen by the other commands.
    std::fs::write(&bad, &flipped).unwrap();
    fails(&["info", s(&bad)], &[s(&bad), "checksum mismatch"]);
    fails(
        &["render", s(&bad), "-o", s(&dir.path().join("p.png"))],
        &[s(&bad), "checksum mismatch"],
    );
    assert!(!dir.path().join("p.png").exists());
}
