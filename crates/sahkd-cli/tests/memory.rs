//! Memory per triangle of the whole pipeline at one million triangles: the peak
//! resident memory `build --json` and `trace --json` report, from the OS's high-water mark,
//! held under a bound so that a change which makes sahkd hungrier shows up in CI.
//!
//! The bounds are about a fifth above today's figures on 2 threads, for allocator and
//! page-size variation: the build's 124-130 bytes per triangle (mesh freed before the build,
//! the builder's freed memory given back to the system) and the trace's 150 (the same tree
//! plus its trace layout: 51 bytes of triangle words and 28 of wide nodes per triangle here,
//! the boxes the wide nodes are made from freed and given back before the words are made). At
//! one million triangles a fixed part (code, thread stacks) still weighs. Two threads, as the
//! hybrid builder holds more subtrees at once on more.
#![cfg(target_os = "linux")]

use npyz::WriterBuilder;
use serde_json::Value;
use std::fs::File;
use std::io::BufWriter;
use std::process::Command;

const SCENE: &str = "spd:mount:1000000";
/// `build`: mesh, the builder's working arrays and the tree.
const BUILD_BOUND: f64 = 160.0;
/// `trace`: the same plus the trace layout, 1,000 rays and their answers.
const TRACE_BOUND: f64 = 180.0;

fn report(args: &[&str]) -> Value {
    let out = Command::new(env!("CARGO_BIN_EXE_sahkd"))
        .args(args)
        .output()
        .expect("cannot start the sahkd binary");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "sahkd {args:?} failed: {err}");
    serde_json::from_slice(&out.stdout).expect("one JSON report")
}

/// The report's peak per triangle, checked against the bytes and triangle count beside it.
fn per_triangle(r: &Value) -> f64 {
    let bytes = r["peak_resident_bytes"].as_f64().expect("a peak on Linux");
    let triangles = r["triangles"].as_f64().unwrap();
    let per = r["peak_resident_bytes_per_triangle"].as_f64().unwrap();
    assert!((per - bytes / triangles).abs() < 1e-6 * per);
    // The mesh alone (vertices and indices) is resident at the peak: a floor that a report
    // of some other quantity would miss.
    assert!(
        per > 24.0,
        "{per} bytes per triangle is below the mesh itself"
    );
    per
}

#[test]
fn the_pipeline_stays_under_its_bytes_per_triangle_at_a_million_triangles() {
    let build = per_triangle(&report(&[
        "build",
        SCENE,
        "--threads",
        "2",
        "--json",
        "--quiet",
    ]));
    eprintln!("build: {build:.0} peak resident bytes per triangle");
    assert!(
        build <= BUILD_BOUND,
        "build: {build:.0} B/tri > {BUILD_BOUND}"
    );

    let dir = tempfile::tempdir().unwrap();
    let rays = dir.path().join("rays.npy");
    let mut w = npyz::WriteOptions::new()
        .default_dtype()
        .shape(&[1000, 6])
        .writer(BufWriter::new(File::create(&rays).unwrap()))
        .begin_nd()
        .unwrap();
    for i in 0..1000 {
        let x = (i % 40) as f32 / 40.0 - 0.5;
        let y = (i / 40) as f32 / 25.0 - 0.5;
        w.extend([x, y, 10.0f32, 0.0, 0.0, -1.0]).unwrap();
    }
    w.finish().unwrap();
    let out = dir.path().join("hits.npz");
    let trace = report(&[
        "trace",
        SCENE,
        "--threads",
        "2",
        "--rays",
        rays.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--json",
        "--quiet",
    ]);
    let traced = per_triangle(&trace);
    eprintln!("trace: {traced:.0} peak resident bytes per triangle");
    assert!(traced >= build * 0.9, "tracing holds at least the tree");
    assert!(
        traced <= TRACE_BOUND,
        "trace: {traced:.0} B/tri > {TRACE_BOUND}"
    );
}
