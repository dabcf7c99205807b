//! Nothing silently wrong, nothing lost: lying headers, thread counts, size
//! limits, outputs that never clobber or half-write, inputs that load wrong, and messages
//! that say what is wrong. Each test failed before its fix.

use std::path::Path;
use std::process::{Command, Output};

fn sahkd(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_sahkd"))
        .args(args)
        .output()
        .expect("cannot start the sahkd binary")
}

/// Runs a command that must fail with `status` and one `error:` line naming every fragment.
fn fails(args: &[&str], status: i32, fragments: &[&str]) -> String {
    let out = sahkd(args);
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(status), "sahkd {args:?}: {err}");
    assert!(!err.contains("panicked"), "sahkd {args:?} panicked: {err}");
    let lines: Vec<&str> = err.lines().collect();
    assert_eq!(lines.len(), 1, "sahkd {args:?}: not one line: {err}");
    assert!(lines[0].starts_with("error: "), "sahkd {args:?}: {err}");
    for f in fragments {
        assert!(lines[0].contains(f), "sahkd {args:?}: '{f}' not in: {err}");
    }
    lines[0].to_string()
}

fn succeeds(args: &[&str]) {
    let out = sahkd(args);
    assert!(
        out.status.success(),
        "sahkd {args:?} failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

fn s(p: &Path) -> &str {
    p.to_str().expect("temp paths are UTF-8")
}

/// The names in a folder, sorted (hidden temporaries included).
fn entries(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

/// A version 1.0 .npy file whose header declares `shape` of float32, followed by `data`.
fn npy(shape: &str, data: &[f32]) -> Vec<u8> {
    let mut header =
        format!("{{'descr': '<f4', 'fortran_order': False, 'shape': {shape}, }}").into_bytes();
    while (10 + header.len() + 1) % 64 != 0 {
        header.push(b' ');
    }
    header.push(b'\n');
    let mut out = b"\x93NUMPY\x01\x00".to_vec();
    out.extend_from_slice(&(header.len() as u16).to_le_bytes());
    out.extend_from_slice(&header);
    for v in data {
        out.extend_from_slice(&v.to_le_bytes());
    }
    out
}

/// One ray straight down onto the unit sphere of `spd:sphere:N`.
const RAY: [f32; 6] = [0.0, 0.0, 5.0, 0.0, 0.0, -1.0];

// Lying .npy headers ------------------------------------------------------------------

#[test]
fn a_lying_npy_header_is_an_error_before_any_allocation() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("hits.npz");
    let good = dir.path().join("good.npy");
    std::fs::write(&good, npy("(1, 6)", &RAY)).unwrap();
    succeeds(&["trace", "spd:sphere:200", "--rays", s(&good), "-o", s(&out)]);

    // Rows x width overflows (was a "capacity overflow" panic), or merely exceeds the file.
    for (name, shape) in [
        ("overflow.npy", "(4611686018427387904, 6)"),
        ("huge.npy", "(1000000000000, 8)"),
        ("short.npy", "(2, 6)"),
    ] {
        let path = dir.path().join(name);
        std::fs::write(&path, npy(shape, &RAY)).unwrap();
        fails(
            &["trace", "spd:sphere:200", "--rays", s(&path), "-o", s(&out)],
            1,
            &[name, "more than the file's", "bytes of data hold"],
        );
    }
}

/// A version 2 header whose length field declares 1.98 GB: npyz allocated that much before
/// reading the header (found by the fuzz test of src/rays/fuzz.rs).
#[test]
fn a_lying_npy_header_length_is_an_error_before_any_allocation() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("hits.npz");
    let mut bytes = npy("(1, 6)", &RAY);
    let header = bytes.split_off(10);
    let mut lying = b"\x93NUMPY\x02\x00".to_vec();
    lying.extend_from_slice(&0x7600_0074u32.to_le_bytes());
    lying.extend_from_slice(&header);
    let path = dir.path().join("length.npy");
    std::fs::write(&path, lying).unwrap();
    fails(
        &["trace", "spd:sphere:200", "--rays", s(&path), "-o", s(&out)],
        1,
        &[
            "length.npy",
            "header of 1979711604 bytes",
            "more than the file's",
        ],
    );
}

/// A header npyz cannot parse gave a multi-line parser report (the header with a caret under
/// it), so `error:` was followed by more lines (found by the fuzz test of src/rays/fuzz.rs).
#[test]
fn an_unparsable_npy_header_is_one_error_line() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("hits.npz");
    let mut bytes = npy("(1, 6)", &RAY);
    let end = bytes.iter().position(|&b| b == b'}').unwrap();
    bytes[end + 2] = b'$';
    let path = dir.path().join("syntax.npy");
    std::fs::write(&path, bytes).unwrap();
    fails(
        &["trace", "spd:sphere:200", "--rays", s(&path), "-o", s(&out)],
        1,
        &[
            "syntax.npy",
            "not a readable .npy file",
            "syntax error at line:column 1:",
        ],
    );
}

// Thread counts ------------------------------------------------------------------------

#[test]
fn thread_counts_beyond_the_cap_are_refused_by_every_command() {
    let dir = tempfile::tempdir().unwrap();
    let rays = dir.path().join("rays.npy");
    std::fs::write(&rays, npy("(1, 6)", &RAY)).unwrap();
    let out = dir.path().join("hits.npz");
    let png = dir.path().join("p.png");
    let max = sahkd::threads::max_threads().to_string();
    let over = (sahkd::threads::max_threads() + 1).to_string();
    for threads in ["100000", over.as_str()] {
        for args in [
            &["build", "spd:sphere:200", "--threads", threads][..],
            &[
                "render",
                "spd:sphere:200",
                "-o",
                s(&png),
                "--threads",
                threads,
            ],
            &[
                "trace",
                "spd:sphere:200",
                "--rays",
                s(&rays),
                "-o",
                s(&out),
                "--threads",
                threads,
            ],
            &[
                "bench",
                "spd:sphere:200",
                "--threads",
                &format!("1,{threads}"),
                "--out",
                s(dir.path()),
            ],
        ] {
            fails(args, 2, &[threads, &format!("at most {max}")]);
        }
    }
    succeeds(&["build", "spd:sphere:200", "--threads", &max]);
}

// Memory ------------------------------------------------------------------------------

#[test]
fn a_scene_larger_than_the_memory_is_refused_up_front() {
    let spec = format!("spd:sphere:{}", sahkd::scenes::MAX_TRIANGLES);
    match sahkd::scenes::available_bytes() {
        Some(available) if available < sahkd::scenes::MAX_TRIANGLES * 72 => {
            fails(&["info", &spec], 1, &[&spec, "needs about", "available"]);
        }
        _ => eprintln!("skipped: this machine could hold {spec}, or cannot say its memory"),
    }
}

// Outputs -----------------------------------------------------------------------------

#[test]
fn outputs_never_overwrite_an_input() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = dir.path().join("tri.ply");
    let text = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
                property float z\nelement face 1\nproperty list uchar int vertex_indices\n\
                end_header\n-1 -1 0\n1 -1 0\n0 1 0\n3 0 1 2\n";
    std::fs::write(&mesh, text).unwrap();
    let rays = dir.path().join("rays.npy");
    let ray_bytes = npy("(1, 6)", &RAY);
    std::fs::write(&rays, &ray_bytes).unwrap();
    // The same file under another spelling is still the input.
    let mesh_again = dir.path().join(".").join("tri.ply");
    for target in [&mesh, &rays, &mesh_again] {
        fails(
            &["trace", s(&mesh), "--rays", s(&rays), "-o", s(target)],
            1,
            &["is the input"],
        );
    }
    assert_eq!(std::fs::read_to_string(&mesh).unwrap(), text);
    assert_eq!(std::fs::read(&rays).unwrap(), ray_bytes);
}

#[test]
fn outputs_replace_old_files_whole_and_leave_no_temporaries() {
    let dir = tempfile::tempdir().unwrap();
    let rays = dir.path().join("rays.npy");
    std::fs::write(&rays, npy("(1, 6)", &RAY)).unwrap();
    let out = dir.path().join("hits.npz");
    let png = dir.path().join("p.png");
    std::fs::write(&out, "an old file").unwrap();
    succeeds(&["trace", "spd:sphere:200", "--rays", s(&rays), "-o", s(&out)]);
    succeeds(&[
        "render",
        "spd:sphere:200",
        "-o",
        s(&png),
        "--width",
        "8",
        "--height",
        "8",
    ]);
    assert!(std::fs::read(&out).unwrap().starts_with(b"PK"), "not a zip");
    assert!(std::fs::read(&png).unwrap().starts_with(b"\x89PNG"));
    assert_eq!(entries(dir.path()), ["hits.npz", "p.png", "rays.npy"]);
}

#[test]
fn a_failed_bench_leaves_no_empty_output_folder() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("new").join("results");
    let missing = dir.path().join("missing.ply");
    fails(
        &["bench", s(&missing), "--out", s(&out), "--repeat", "1"],
        1,
        &["missing.ply"],
    );
    assert_eq!(entries(dir.path()), Vec::<String>::new());
}

// Meshes read as written ----------------------------------------------------------------

/// `info --json`'s vertex and triangle counts of an OBJ file are the file's: every `v` line is
/// one vertex, used or not, whichever objects use it (tobj dropped unused vertices and
/// repeated shared ones per object: 7 vertices and 2 triangles here read as 6 and 2).
#[test]
fn info_counts_the_vertices_of_an_obj_file_as_written() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("objects.obj");
    let text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nv 5 5 5\nv 6 6 6\nv 7 7 7\n\
                o first\nf 1 2 3\no second\ng part\nf 2 4 3\n";
    std::fs::write(&path, text).unwrap();
    // Hand count: 7 v lines; triangles (1 2 3) and (2 4 3); vertices 5, 6, 7 unused.
    let out = sahkd(&["info", s(&path), "--json"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(report["vertices"], 7, "{report}");
    assert_eq!(report["triangles"], 2, "{report}");
    assert_eq!(report["unreferenced_vertices"], 3, "{report}");
    assert_eq!(report["bounds"]["lo"], serde_json::json!([0.0, 0.0, 0.0]));
    assert_eq!(report["bounds"]["hi"], serde_json::json!([1.0, 1.0, 0.0]));

    // An OBJ error names the file and the line.
    let bad = dir.path().join("bad.obj");
    std::fs::write(&bad, "v 0 0 0\nv 1 0 0\nv 0 1 0\n# a comment\nf 1 2 4\n").unwrap();
    fails(&["info", s(&bad)], 1, &["bad.obj", "line 5", "vertex 4"]);
}

// Inputs that are not meshes, and their messages -----------------------------------------

#[test]
fn a_directory_or_a_device_given_as_a_mesh_says_what_it_is() {
    let dir = tempfile::tempdir().unwrap();
    fails(
        &["info", s(dir.path())],
        1,
        &[s(dir.path()), "is a directory"],
    );
    if Path::new("/dev/null").exists() {
        fails(
            &["build", "/dev/null"],
            1,
            &["/dev/null", "is a character device"],
        );
    }
}

#[test]
fn errors_about_a_mesh_name_the_file_and_float32_overflow() {
    let dir = tempfile::tempdir().unwrap();
    let head = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
                property float z\nelement face 1\nproperty list uchar int vertex_indices\n\
                end_header\n";
    let nan = dir.path().join("nan.ply");
    std::fs::write(&nan, format!("{head}0 0 0\n1 0 nan\n0 1 0\n3 0 1 2\n")).unwrap();
    fails(
        &["build", s(&nan)],
        1,
        &["nan.ply", "vertex 1", "non-finite"],
    );
    let index = dir.path().join("index.ply");
    std::fs::write(&index, format!("{head}0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n")).unwrap();
    fails(&["info", s(&index)], 1, &["index.ply", "vertex 7"]);
    let big = dir.path().join("big.ply");
    std::fs::write(&big, format!("{head}0 0 0\n1e39 0 0\n0 1 0\n3 0 1 2\n")).unwrap();
    fails(
        &["info", s(&big)],
        1,
        &["big.ply", "line 11", "beyond the float32 range"],
    );
}

#[test]
fn the_picture_size_is_checked_before_the_mesh_is_loaded() {
    let dir = tempfile::tempdir().unwrap();
    let png = dir.path().join("p.png");
    let missing = dir.path().join("missing.ply");
    let line = fails(
        &[
            "render",
            s(&missing),
            "-o",
            s(&png),
            "--width",
            "65536",
            "--height",
            "65536",
        ],
        1,
        &["65536x65536", "too large"],
    );
    assert!(!line.contains("missing.ply"), "{line}");
}

// Rays: the library's one rule for rays given as input ---------------------------------

#[test]
fn rays_the_library_refuses_are_errors_naming_the_row_and_part() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("hits.npy");
    let down = [0.0, 0.0, 5.0, 0.0, 0.0, -1.0];
    for (range, part, why) in [
        ([0.0, f32::NAN], "t_max", "NaN"),
        ([f32::NEG_INFINITY, 10.0], "t_min", "not finite"),
        ([f32::INFINITY, 10.0], "t_min", "not finite"),
    ] {
        // The first row is a good ray, the second the bad one.
        let data = [&down[..], &[0.0, f32::INFINITY], &down, &range].concat();
        let path = dir.path().join("rays.npy");
        std::fs::write(&path, npy("(2, 8)", &data)).unwrap();
        fails(
            &["trace", "spd:sphere:200", "--rays", s(&path), "-o", s(&out)],
            1,
            &["ray 1", &format!("its {part} is {why}")],
        );
        assert!(!out.exists(), "no output for refused rays");
    }
    // +inf t_max and t_min > t_max are rays, not errors.
    let path = dir.path().join("open.npy");
    let mut data = down.to_vec();
    data.extend([0.0, f32::INFINITY]);
    data.extend_from_slice(&down);
    data.extend([3.0, 1.0]);
    std::fs::write(&path, npy("(2, 8)", &data)).unwrap();
    succeeds(&["trace", "spd:sphere:200", "--rays", s(&path), "-o", s(&out)]);
}

// Memory limits: the address-space limit is part of the memory check ---------------------

/// Under `prlimit --as=4000000000` a 300M-triangle scene aborted on its first large
/// allocation (SIGABRT) on a machine whose MemAvailable could hold it.
#[test]
fn a_scene_beyond_the_address_space_limit_is_refused_up_front() {
    let spec = "spd:sphere:300000000";
    let out = match Command::new("prlimit")
        .args(["--as=4000000000", env!("CARGO_BIN_EXE_sahkd"), "info", spec])
        .output()
    {
        Ok(out) => out,
        Err(e) => return eprintln!("skipped: no prlimit here ({e})"),
    };
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    let lines: Vec<&str> = err.lines().collect();
    assert_eq!(lines.len(), 1, "{err}");
    assert!(lines[0].starts_with("error: "), "{err}");
    assert!(lines[0].contains("needs about"), "{err}");
    assert!(lines[0].contains("GiB of memory"), "{err}");
}

// Bench outputs: all or nothing ---------------------------------------------------------

/// A bench whose outputs cannot all be written (here table1.png is taken by a folder; a full
/// disk at a chart did the same) leaves none of its files, no temporary, and one plain
/// error line naming the file.
#[test]
fn a_bench_failing_at_a_chart_leaves_none_of_its_files() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("results");
    std::fs::create_dir_all(out.join("table1.png").join("taken")).unwrap();
    let line = fails(
        &[
            "bench",
            "spd:toys:300",
            "--out",
            s(&out),
            "--algorithms",
            "sweep",
            "--threads",
            "1",
            "--repeat",
            "1",
            "--width",
            "16",
            "--height",
            "16",
            "--ao-size",
            "4",
            "--ao-samples",
            "1",
        ],
        1,
        &["table1.png"],
    );
    // The file itself is named, not a temporary beside it.
    let named = format!("cannot write {}: ", out.join("table1.png").display());
    assert!(line.contains(&named) && !line.contains("Error("), "{line}");
    assert_eq!(entries(&out), ["table1.png"], "{line}");
}

// A full disk while writing an archive: one error line, nothing from the zip writer -------

/// Writing hits under a 1 KiB file-size limit (as a full disk does, the write fails with
/// the archive half written) printed "ZipWriter drop failed: Io(...)" before the error
/// line, on the same line. The limit's signal is ignored, so the write fails instead.
#[test]
fn a_failed_archive_write_is_one_error_line() {
    let dir = tempfile::tempdir().unwrap();
    let rays = dir.path().join("rays.npy");
    let data: Vec<f32> = (0..500).flat_map(|_| RAY).collect();
    std::fs::write(&rays, npy("(500, 6)", &data)).unwrap();
    let hits = dir.path().join("hits.npz");
    let script = format!(
        "trap '' XFSZ; ulimit -f 1; exec '{}' trace spd:sphere:200 --rays '{}' -o '{}'",
        env!("CARGO_BIN_EXE_sahkd"),
        s(&rays),
        s(&hits)
    );
    let out = Command::new("bash").args(["-c", &script]).output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    let lines: Vec<&str> = err.lines().collect();
    assert_eq!(lines.len(), 1, "{err}");
    assert!(lines[0].starts_with("error: cannot write"), "{err}");
    assert!(!err.contains("ZipWriter"), "{err}");
    assert_eq!(entries(dir.path()), ["rays.npy"], "no output, no temporary");
}

// Messages ------------------------------------------------------------------------------

/// A zero-byte `.sahkd` file was called "unknown mesh format".
#[test]
fn an_empty_saved_tree_says_it_is_empty() {
    let dir = tempfile::tempdir().unwrap();
    let empty = dir.path().join("tree.sahkd");
    std::fs::write(&empty, b"").unwrap();
    fails(
        &["info", s(&empty)],
        1,
        &["tree.sahkd", "not a sahkd tree file: it is empty (0 bytes)"],
    );
}

// Named pipes: refused as what they are, never waited on ---------------------------------

/// A FIFO given as a mesh, a saved tree or a ray file waited forever on its open (no writer)
/// and, read, a tree through it was "unknown mesh format". Each is refused as a named pipe;
/// `timeout` turns a hang back into a failure of this test (status 124).
#[test]
fn a_named_pipe_is_refused_as_what_it_is() {
    let dir = tempfile::tempdir().unwrap();
    let made = |name: &str| {
        let path = dir.path().join(name);
        let ok = Command::new("mkfifo").arg(&path).status();
        ok.is_ok_and(|s| s.success()).then_some(path)
    };
    let (Some(ply), Some(tree), Some(rays)) = (made("f.ply"), made("t.sahkd"), made("r.npy"))
    else {
        return eprintln!("skipped: no mkfifo here");
    };
    let out = dir.path().join("hits.npz");
    for (args, named) in [
        (vec!["info", s(&ply)], &ply),
        (vec!["info", s(&tree)], &tree),
        (
            vec!["trace", "spd:sphere:200", "--rays", s(&rays), "-o", s(&out)],
            &rays,
        ),
    ] {
        let run = Command::new("timeout")
            .arg("20")
            .arg(env!("CARGO_BIN_EXE_sahkd"))
            .args(&args)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&run.stderr);
        assert_eq!(run.status.code(), Some(1), "{args:?}: {err}");
        assert_eq!(err.lines().count(), 1, "{args:?}: {err}");
        assert!(
            err.contains(s(named)) && err.contains("is a named pipe (FIFO)"),
            "{err}"
        );
    }
}
