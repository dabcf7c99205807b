//! `sahkd query` run as a user would: every answer checked against the library's brute
//! force and the sphere's face planes, and every mistake ending in one clean `error:` line.

use npyz::npz::NpzArchive;
use npyz::WriterBuilder;
use sahkd::query::brute;
use sahkd::{scenes, Triangle, Vec3};
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

fn json(args: &[&str]) -> Value {
    let out = sahkd(args);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "sahkd {args:?} failed: {err}");
    let text = String::from_utf8_lossy(&out.stdout);
    assert_eq!(text.lines().count(), 1, "not one line of JSON: {text}");
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("not JSON ({e}): {text}"))
}

fn fails(args: &[&str], status: i32, fragments: &[&str]) {
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
    assert!(out.stdout.is_empty(), "sahkd {args:?} wrote to stdout");
}

fn s(p: &Path) -> &str {
    p.to_str().expect("temp paths are UTF-8")
}

fn write_points<T: npyz::AutoSerialize + Copy>(path: &Path, rows: &[[f32; 3]], f: fn(f32) -> T) {
    let file = BufWriter::new(File::create(path).unwrap());
    let mut w = npyz::WriteOptions::new()
        .default_dtype()
        .shape(&[rows.len() as u64, 3])
        .writer(file)
        .begin_nd()
        .unwrap();
    for r in rows {
        w.extend(r.iter().map(|&x| f(x))).unwrap();
    }
    w.finish().unwrap();
}

fn read_npz<T: npyz::Deserialize>(path: &Path, name: &str, dtype: &str, shape: &[u64]) -> Vec<T> {
    let mut npz = NpzArchive::open(path).unwrap();
    let array = npz
        .by_name(name)
        .unwrap()
        .unwrap_or_else(|| panic!("no '{name}' in {}", path.display()));
    assert_eq!(
        array.dtype().descr(),
        format!("'{dtype}'"),
        "dtype of {name}"
    );
    assert_eq!(array.shape(), shape, "shape of {name}");
    array.into_vec().unwrap()
}

fn array_names(path: &Path) -> Vec<String> {
    let npz = NpzArchive::open(path).unwrap();
    let mut names: Vec<String> = npz.array_names().map(str::to_string).collect();
    names.sort();
    names
}

/// Points in and around the unit sphere from a fixed LCG, plus corners of the mesh, one
/// far point and one with a NaN coordinate.
fn point_rows(mesh_vertices: &[[f32; 3]], n: usize) -> Vec<[f32; 3]> {
    let mut state = 0x2545F4914F6CDD1Du64;
    let mut unit = || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (state >> 40) as f32 / (1u64 << 24) as f32
    };
    let mut rows: Vec<[f32; 3]> = (0..n).map(|_| [0; 3].map(|_| unit() * 3.2 - 1.6)).collect();
    rows.extend(mesh_vertices.iter().step_by(97).copied());
    rows.push([40.0, -3.0, 7.0]);
    rows.push([f32::NAN, 0.0, 0.0]);
    rows
}

/// Inside the convex sphere mesh exactly when behind every face plane (outward winding).
fn inside_convex(tris: &[Triangle], p: [f32; 3]) -> bool {
    let d = |v: Vec3| v.0.map(f64::from);
    let p = p.map(f64::from);
    tris.iter().all(|t| {
        let (a, b, c) = (d(t[0]), d(t[1]), d(t[2]));
        let (u, v) = (
            [0, 1, 2].map(|k| b[k] - a[k]),
            [0, 1, 2].map(|k| c[k] - a[k]),
        );
        let n = [
            u[1] * v[2] - u[2] * v[1],
            u[2] * v[0] - u[0] * v[2],
            u[0] * v[1] - u[1] * v[0],
        ];
        let h: f64 = (0..3).map(|k| n[k] * (p[k] - a[k])).sum();
        n == [0.0; 3] || h < 0.0
    })
}

fn check_query(extra: &[&str]) {
    let dir = tempfile::tempdir().unwrap();
    let points = dir.path().join("points.npy");
    let out = dir.path().join("answers.npz");
    let mesh = scenes::generate(SCENE).unwrap();
    let rows = point_rows(&mesh.vertices, 1500);
    write_points(&points, &rows, |x| x);
    let mut args = vec![
        "query",
        SCENE,
        "--points",
        s(&points),
        "-o",
        s(&out),
        "--json",
    ];
    args.extend_from_slice(extra);
    let signed = extra.contains(&"--signed");
    let report = json(&args);

    let tris = mesh.corner_triangles();
    let n = rows.len() as u64;
    let mut names = vec!["distance", "point", "prim"];
    if signed {
        names.extend(["inside", "signed_distance"]);
        names.sort();
    }
    assert_eq!(array_names(&out), names);
    let point: Vec<f64> = read_npz(&out, "point", "<f8", &[n, 3]);
    let distance: Vec<f64> = read_npz(&out, "distance", "<f8", &[n]);
    let prim: Vec<i64> = read_npz(&out, "prim", "<i8", &[n]);
    let mut inside_count = 0;
    for (i, r) in rows.iter().enumerate() {
        let got = (point[3 * i..3 * i + 3].to_vec(), distance[i], prim[i]);
        match brute::closest_point(&tris, Vec3(*r)) {
            Some(c) => assert_eq!(
                got,
                (c.point.to_vec(), c.distance, c.prim as i64),
                "point {i}"
            ),
            None => {
                assert!(r[0].is_nan());
                assert!(got.0.iter().all(|x| x.is_nan()) && got.1.is_nan() && got.2 == -1);
            }
        }
    }
    if signed {
        let signed_distance: Vec<f64> = read_npz(&out, "signed_distance", "<f8", &[n]);
        let inside: Vec<bool> = read_npz(&out, "inside", "|b1", &[n]);
        for (i, r) in rows.iter().enumerate() {
            inside_count += inside[i] as usize;
            if r[0].is_nan() {
                assert!(!inside[i] && signed_distance[i].is_nan());
                continue;
            }
            if distance[i] > 1e-6 {
                assert_eq!(inside[i], inside_convex(&tris, *r), "point {i} {r:?}");
            }
            let want = if inside[i] { -distance[i] } else { distance[i] };
            assert_eq!(signed_distance[i], want, "point {i}");
        }
        assert!(inside_count > 100, "a weak test: {inside_count} inside");
        assert_eq!(report["inside"], inside_count);
    } else {
        assert_eq!(report["inside"], Value::Null);
    }
    assert_eq!(report["points"], n);
    assert_eq!(report["triangles"], tris.len());
    for key in ["build_ms", "layout_ms", "query_ms", "mpoints_per_s"] {
        let x = report[key].as_f64().unwrap();
        assert!(x.is_finite() && x >= 0.0, "{key} = {x}");
    }
}

#[test]
fn closest_points_match_brute_force() {
    check_query(&[]);
}

#[test]
fn signed_queries_match_the_face_planes_with_either_inside_test() {
    check_query(&["--signed", "--threads", "1"]);
    check_query(&["--signed", "--inside-test", "winding"]);
}

#[test]
fn bad_inputs_and_outputs_are_clean_errors() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("answers.npz");
    let rows = [[0.0f32, 0.0, 0.0], [2.0, 0.0, 0.0]];

    let doubles = dir.path().join("doubles.npy");
    write_points(&doubles, &rows, f64::from);
    fails(
        &["query", SCENE, "--points", s(&doubles), "-o", s(&out)],
        1,
        &["doubles.npy", "float32", "float64"],
    );

    let rays = dir.path().join("rays.npy");
    let file = BufWriter::new(File::create(&rays).unwrap());
    let mut w = npyz::WriteOptions::new()
        .default_dtype()
        .shape(&[1, 6])
        .writer(file)
        .begin_nd()
        .unwrap();
    w.extend([0f32; 6]).unwrap();
    w.finish().unwrap();
    fails(
        &["query", SCENE, "--points", s(&rays), "-o", s(&out)],
        1,
        &["rays.npy", "(N, 3)", "(1, 6)"],
    );

    let missing = dir.path().join("missing.npy");
    fails(
        &["query", SCENE, "--points", s(&missing), "-o", s(&out)],
        1,
        &["missing.npy"],
    );

    let good = dir.path().join("good.npy");
    write_points(&good, &rows, |x| x);
    let before = std::fs::read(&good).unwrap();
    fails(
        &["query", SCENE, "--points", s(&good), "-o", s(&good)],
        1,
        &["is the input"],
    );
    assert_eq!(
        std::fs::read(&good).unwrap(),
        before,
        "the input was changed"
    );
    let nowhere = dir.path().join("no-such-dir").join("a.npz");
    fails(
        &["query", SCENE, "--points", s(&good), "-o", s(&nowhere)],
        1,
        &["no-such-dir"],
    );
    fails(
        &[
            "query",
            SCENE,
            "--points",
            s(&good),
            "-o",
            s(&out),
            "--signed",
            "--inside-test",
            "vote",
        ],
        2,
        &["vote"],
    );
    assert!(!out.exists(), "an output was written after an error");
}
