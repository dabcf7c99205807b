//! `--device gpu`: the same tree as `--device cpu`, the GPU report, and one clear error line
//! for what it cannot do. Without an adapter the tests skip, saying so, unless `CI` is set.

use serde_json::Value;
use std::process::{Command, Output};

fn sahkd(args: &[&str], env: &[(&str, &str)]) -> Output {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_sahkd"));
    cmd.args(args).env("XDG_RUNTIME_DIR", "/tmp");
    for (k, v) in env {
        cmd.env(k, v);
    }
    cmd.output().expect("sahkd runs")
}

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// The JSON report of a build, or `None` (skip) when no adapter exists outside CI.
fn build_json(args: &[&str]) -> Option<Value> {
    let mut all = vec!["build", "--json", "--quiet"];
    all.extend_from_slice(args);
    let out = sahkd(&all, &[]);
    if !out.status.success() && stderr(&out).contains("no GPU adapter found") {
        assert!(std::env::var_os("CI").is_none(), "{}", stderr(&out));
        eprintln!("skipping: {}", stderr(&out));
        return None;
    }
    assert!(out.status.success(), "{args:?}: {}", stderr(&out));
    Some(serde_json::from_slice(&out.stdout).unwrap())
}

#[test]
fn gpu_build_gives_the_cpu_tree_and_reports_its_phases() {
    // The defaults (triangle boxes, longest axis), perfect splits, and all axes.
    let cases: [&[&str]; 3] = [&[], &["--clip", "on"], &["--clip", "off", "--axes", "all"]];
    for options in cases {
        let common = [&["spd:toys:3000"][..], options].concat();
        let Some(gpu) = build_json(&[&common[..], &["--device", "gpu"]].concat()) else {
            return;
        };
        let cpu = build_json(&[&common[..], &["--device", "cpu"]].concat()).unwrap();
        assert_eq!(gpu["device"], "gpu");
        assert_eq!(cpu["device"], "cpu");
        assert!(cpu["gpu"].is_null());
        // Same tree: every statistic of it agrees (the library tests compare node by node).
        for key in [
            "nodes",
            "leaves",
            "references",
            "max_depth",
            "sah_cost",
            "empty_leaves",
        ] {
            assert_eq!(gpu[key], cpu[key], "{options:?}: {key}");
        }
        let report = &gpu["gpu"];
        assert!(!report["adapter"].as_str().unwrap().is_empty());
        if let Ok(expected) = std::env::var("SAHKD_GPU_ADAPTER") {
            assert!(report["adapter"].as_str().unwrap().contains(&expected));
        }
        let phases = report["phases_ms"].as_array().unwrap();
        let names: Vec<&str> = phases.iter().map(|p| p[0].as_str().unwrap()).collect();
        assert_eq!(
            names,
            [
                "layout",
                "candidates",
                "counting",
                "pricing",
                "best split",
                "decision",
                "sides",
                "partition",
                "output"
            ]
        );
        assert!(phases.iter().all(|p| p[1].as_f64().unwrap() >= 0.0));
        let levels = report["levels"].as_u64().unwrap();
        assert_eq!(levels, gpu["max_depth"].as_u64().unwrap() + 1);
        // One host read per level (the decision's totals).
        assert_eq!(report["round_trips"].as_u64().unwrap(), levels);
    }
}

#[test]
fn gpu_mistakes_are_one_clear_line() {
    // Only the level builder runs on the GPU: another is refused, not silently replaced.
    let out = sahkd(
        &[
            "build",
            "spd:toys:500",
            "--device",
            "gpu",
            "--algorithm",
            "sweep",
        ],
        &[],
    );
    assert_eq!(out.status.code(), Some(1));
    assert_eq!(
        stderr(&out).trim(),
        "error: --device gpu runs the level builder only, not Sweep"
    );
    // No adapter on the only backend allowed (Metal does not exist on Linux).
    if cfg!(target_os = "linux") {
        let out = sahkd(
            &["build", "spd:toys:500", "--device", "gpu", "--clip", "off"],
            &[("WGPU_BACKEND", "metal")],
        );
        assert_eq!(out.status.code(), Some(1));
        let err = stderr(&out);
        assert_eq!(err.lines().count(), 1, "{err}");
        assert!(
            err.starts_with("error: no GPU adapter found (backends tried: metal)"),
            "{err}"
        );
    }
}

/// `sahkd bench` of a small scene on `device` (level builder only, tiny pictures): results.json
/// and table1.md, or `None` (skip) when no adapter exists outside CI.
fn bench_level(device: &str, clip: &str, out: &std::path::Path) -> Option<(Value, String)> {
    let out_dir = out.to_str().unwrap();
    #[rustfmt::skip]
    let args = [
        "bench", "--quiet", "spd:toys:500", "--device", device, "--clip", clip,
        "--algorithms", "level", "--threads", "1", "--repeat", "1",
        "--width", "32", "--height", "32", "--ao-size", "16", "--ao-samples", "2",
        "--out", out_dir,
    ];
    let out = sahkd(&args, &[]);
    if !out.status.success() && stderr(&out).contains("no GPU adapter found") {
        assert!(std::env::var_os("CI").is_none(), "{}", stderr(&out));
        eprintln!("skipping: {}", stderr(&out));
        return None;
    }
    assert!(out.status.success(), "{args:?}: {}", stderr(&out));
    let read = |name: &str| std::fs::read_to_string(std::path::Path::new(out_dir).join(name));
    let results = serde_json::from_str(&read("results.json").unwrap()).unwrap();
    Some((results, read("table1.md").unwrap()))
}

#[test]
fn bench_on_the_gpu_gives_the_cpu_tree_and_reports_each_build() {
    for clip in ["off", "on"] {
        bench_on_the_gpu_with_clip(clip);
    }
}

fn bench_on_the_gpu_with_clip(clip: &str) {
    let dir = tempfile::tempdir().unwrap();
    let Some((gpu, gpu_md)) = bench_level("gpu", clip, &dir.path().join("gpu")) else {
        return;
    };
    let (cpu, cpu_md) = bench_level("cpu", clip, &dir.path().join("cpu")).unwrap();
    assert_eq!(gpu["settings"]["device"], "gpu");
    assert_eq!(cpu["settings"]["device"], "cpu");
    assert_eq!(gpu["settings"]["build_options"]["clip"], clip == "on");
    let row = |r: &Value| r["scenes"][0]["builds"][0]["measured"].clone();
    let (g, c) = (row(&gpu), row(&cpu));
    assert!(c["gpu"].is_null());
    // Same tree: its statistics agree (tests/gpu.rs's build test and the library compare more).
    for key in [
        "sah_cost",
        "nodes",
        "leaves",
        "references",
        "depth",
        "tree_bytes",
    ] {
        assert_eq!(g[key], c[key], "{key}");
    }
    let report = &g["gpu"];
    let adapter = report["adapter"].as_str().unwrap();
    assert!(!adapter.is_empty());
    // lavapipe is a CPU adapter: the host's presort runs there.
    assert_eq!(report["presort"], "host");
    for key in ["upload_ms", "download_ms"] {
        assert!(report[key].as_f64().unwrap() >= 0.0, "{key}");
    }
    let phases = report["phases_ms"].as_array().unwrap();
    assert_eq!(phases.len(), 9);
    assert!(phases.iter().all(|p| p[1].as_f64().unwrap() >= 0.0));
    let levels = report["levels"].as_u64().unwrap();
    assert_eq!(levels, g["depth"].as_u64().unwrap() + 1);
    // One host read per level: the decision's totals (the candidate layout stays on the GPU).
    assert_eq!(report["round_trips"].as_u64().unwrap(), levels);
    assert_eq!(report["round_trips_per_level"].as_f64().unwrap(), 1.0);
    // table1.md says where the builds ran and tabulates the GPU report.
    assert!(gpu_md.contains(&format!(
        "level builder's trees built on the GPU ({adapter}"
    )));
    assert!(gpu_md.contains("## GPU builds"));
    let gpu_row = gpu_md
        .lines()
        .find(|l| l.starts_with("| spd:toys:500 | 1 | "))
        .expect("a GPU build row");
    assert!(
        gpu_row.ends_with(&format!(" {levels} | {levels} | 1.0 |")),
        "{gpu_row}"
    );
    assert!(cpu_md.contains("Device: every build on the CPU."));
    assert!(!cpu_md.contains("## GPU builds"));
}
