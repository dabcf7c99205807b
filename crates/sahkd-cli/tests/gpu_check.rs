//! `scripts/gpu-check --quick` end to end on whatever adapter wgpu finds (lavapipe in CI): the
//! merged results.json, table1.md and log.txt, a part killed at its limit while the rest runs,
//! and clean refusals of bad arguments. The GPU tests part is skipped (`--no-tests`): those
//! tests run in the same suite already, and a cargo inside `cargo test` would wait on its lock.
//! Without an adapter the GPU runs skip, saying so, unless `CI` is set.

use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn script() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scripts/gpu-check")
}

fn gpu_check(args: &[&str]) -> Output {
    Command::new("bash")
        .arg(script())
        .args(args)
        .env("XDG_RUNTIME_DIR", "/tmp")
        .output()
        .expect("bash runs scripts/gpu-check")
}

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

/// Whether wgpu finds an adapter: false (skip) outside CI, a failure in CI.
fn have_adapter() -> bool {
    let out = Command::new(env!("CARGO_BIN_EXE_sahkd"))
        .args(["build", "spd:toys:200", "--device", "gpu", "--quiet"])
        .env("XDG_RUNTIME_DIR", "/tmp")
        .output()
        .expect("sahkd runs");
    let err = text(&out.stderr);
    if !out.status.success() && err.contains("no GPU adapter found") {
        assert!(std::env::var_os("CI").is_none(), "{err}");
        eprintln!("skipping: {err}");
        return false;
    }
    assert!(out.status.success(), "{err}");
    true
}

/// Runs the quick check into a fresh folder with extra arguments; returns the exit status,
/// results.json and the folder.
fn quick_run(extra: &[&str]) -> (Output, Value, tempfile::TempDir) {
    let dir = tempfile::tempdir().unwrap();
    let out_dir = dir.path().join("out");
    let args = [
        &[
            out_dir.to_str().unwrap(),
            "--quick",
            "--no-tests",
            "--binary",
            env!("CARGO_BIN_EXE_sahkd"),
        ][..],
        extra,
    ]
    .concat();
    let out = gpu_check(&args);
    let results = std::fs::read_to_string(out_dir.join("results.json"))
        .unwrap_or_else(|e| panic!("no results.json ({e}): {}", text(&out.stdout)));
    let results: Value = serde_json::from_str(&results)
        .unwrap_or_else(|e| panic!("results.json is not JSON ({e}): {results}"));
    (out, results, dir)
}

fn parts(results: &Value) -> Vec<(String, String)> {
    results["parts"]
        .as_array()
        .expect("parts")
        .iter()
        .map(|p| {
            (
                p["name"].as_str().unwrap().to_string(),
                p["status"].as_str().unwrap().to_string(),
            )
        })
        .collect()
}

const BENCH_PARTS: [&str; 3] = ["bench-paper", "bench-mount", "bench-mount-large"];

#[test]
fn quick_check_passes_every_part_and_writes_its_three_files() {
    if !have_adapter() {
        return;
    }
    let (out, results, dir) = quick_run(&[]);
    let log = text(&out.stdout);
    assert!(out.status.success(), "{log}");
    assert_eq!(results["passed"], true, "{results}");
    assert!(!results["adapter"].as_str().unwrap().is_empty());
    let names: Vec<String> = parts(&results).into_iter().map(|p| p.0).collect();
    assert_eq!(
        names,
        [
            "build",
            "test-build",
            "loader",
            "adapter",
            "tests",
            BENCH_PARTS[0],
            BENCH_PARTS[1],
            BENCH_PARTS[2]
        ]
    );
    for p in results["parts"].as_array().unwrap() {
        let (name, status) = (p["name"].as_str().unwrap(), p["status"].as_str().unwrap());
        // build, test-build and tests are skipped on request (--binary, --no-tests); the
        // rest must pass.
        let expected = if ["build", "test-build", "tests"].contains(&name) {
            "skipped"
        } else {
            "ok"
        };
        assert_eq!(status, expected, "{p}");
        assert!(p["seconds"].as_f64().is_some(), "{p}");
    }
    for p in &results["parts"].as_array().unwrap()[5..] {
        // Each bench part carries the bench's own results, built on the GPU.
        assert_eq!(p["result"]["settings"]["device"], "gpu", "{p}");
    }
    let out_dir = dir.path().join("out");
    let table = std::fs::read_to_string(out_dir.join("table1.md")).unwrap();
    for name in BENCH_PARTS {
        assert!(table.contains(&format!("## {name}")), "{table}");
    }
    let saved = std::fs::read_to_string(out_dir.join("log.txt")).unwrap();
    assert!(saved.contains("every part passed"), "{saved}");
}

#[test]
fn a_part_past_its_limit_is_recorded_as_timed_out_and_the_rest_still_runs() {
    if !have_adapter() {
        return;
    }
    let (out, results, _dir) = quick_run(&["--part-limit", "bench-paper=1"]);
    assert_eq!(out.status.code(), Some(1), "{}", text(&out.stdout));
    assert_eq!(results["passed"], false);
    let parts = parts(&results);
    let status = |name: &str| &parts.iter().find(|p| p.0 == name).unwrap().1;
    assert_eq!(status("bench-paper"), "timed out");
    assert_eq!(status("bench-mount"), "ok");
    assert_eq!(status("bench-mount-large"), "ok");
}

#[test]
fn bad_arguments_are_refused_with_one_clear_line() {
    for (args, says) in [
        (&[][..], "missing OUT_DIR"),
        (&["/tmp/unused", "--bogus"][..], "unknown option '--bogus'"),
        (
            &["/tmp/unused", "--budget", "soon"][..],
            "--budget wants whole seconds",
        ),
        (&["/tmp/unused", "--binary"][..], "--binary needs a value"),
        (
            &["/tmp/unused", "--part-limit", "nosuch=3"][..],
            "no part 'nosuch'",
        ),
    ] {
        let out = gpu_check(args);
        assert_eq!(out.status.code(), Some(2), "{args:?}");
        assert!(
            text(&out.stderr).contains(says),
            "{args:?}: {}",
            text(&out.stderr)
        );
    }
}

/// The GPU tests are compiled before the tests part's clock starts: a compile longer than the
/// tests' limit (a cold checkout on a small machine) must not time the tests out. A stand-in
/// `cargo` first on the PATH takes 3 s to compile and none to run; the tests part has 2 s.
#[test]
fn the_gpu_tests_compile_before_the_tests_clock_starts() {
    let dir = tempfile::tempdir().unwrap();
    let bin = dir.path().join("bin");
    std::fs::create_dir(&bin).unwrap();
    let calls = dir.path().join("calls.txt");
    let cargo = bin.join("cargo");
    std::fs::write(
        &cargo,
        format!(
            "#!/bin/sh\necho \"$*\" >> '{}'\ncase \"$*\" in *--no-run*) sleep 3 ;; esac\nexit 0\n",
            calls.display()
        ),
    )
    .unwrap();
    use std::os::unix::fs::PermissionsExt;
    std::fs::set_permissions(&cargo, std::fs::Permissions::from_mode(0o755)).unwrap();
    let out_dir = dir.path().join("out");
    let path = format!(
        "{}:{}",
        bin.display(),
        std::env::var("PATH").unwrap_or_default()
    );
    let out = Command::new("bash")
        .arg(script())
        .args([
            out_dir.to_str().unwrap(),
            "--quick",
            "--binary",
            env!("CARGO_BIN_EXE_sahkd"),
            "--part-limit",
            "tests=2",
            "--part-limit",
            "bench-paper=1",
            "--part-limit",
            "bench-mount=1",
            "--part-limit",
            "bench-mount-large=1",
        ])
        .env("PATH", path)
        .env("XDG_RUNTIME_DIR", "/tmp")
        .output()
        .unwrap();
    let results = std::fs::read_to_string(out_dir.join("results.json"))
        .unwrap_or_else(|e| panic!("no results.json ({e}): {}", text(&out.stdout)));
    let results: Value = serde_json::from_str(&results).unwrap();
    let parts = parts(&results);
    let status = |name: &str| parts.iter().find(|p| p.0 == name).unwrap().1.clone();
    assert_eq!(status("test-build"), "ok", "{results}");
    assert_eq!(status("tests"), "ok", "{results}");
    let calls = std::fs::read_to_string(&calls).unwrap();
    assert_eq!(
        calls.lines().collect::<Vec<_>>(),
        [
            "test -p sahkd-gpu --test kernels --no-run",
            "test -p sahkd-gpu --test kernels"
        ],
        "{calls}"
    );
}
