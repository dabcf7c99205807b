//! `sahkd bench`, run as a user would on small scenes: the files it writes are checked for
//! form and against the library (trees rebuilt directly), not for their timings; mistakes
//! must end in one clean `error:` line.

use sahkd::{build, scenes, Algorithm, BuildOptions, Mesh};
use serde_json::Value;
use std::collections::HashSet;
use std::io::Write;
use std::path::Path;
use std::process::{Command, Output};

fn sahkd(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_sahkd"))
        .args(args)
        .output()
        .expect("cannot start the sahkd binary")
}

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

fn path_str(p: &Path) -> &str {
    p.to_str().expect("temp paths are UTF-8")
}

/// Runs `sahkd bench` that must succeed, and returns results.json.
fn bench(args: &[&str]) -> Value {
    let out = sahkd(&[&["bench", "-q"][..], args].concat());
    assert!(
        out.status.success(),
        "sahkd bench {args:?} failed: {}",
        stderr(&out)
    );
    assert!(out.stderr.is_empty(), "--quiet printed: {}", stderr(&out));
    let dir = args[args.iter().position(|&a| a == "--out").unwrap() + 1];
    let text = std::fs::read_to_string(Path::new(dir).join("results.json")).unwrap();
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("results.json is not JSON ({e})"))
}

/// The PNG decodes, has the charts' size and is a picture, not a blank.
fn check_chart(path: &Path) {
    let img = image::open(path)
        .unwrap_or_else(|e| panic!("{} is not a PNG: {e}", path.display()))
        .to_rgb8();
    assert_eq!(img.dimensions(), (1400, 800), "{}", path.display());
    let colours: HashSet<[u8; 3]> = img.pixels().map(|p| p.0).collect();
    assert!(
        colours.len() > 20,
        "{} has only {} colours",
        path.display(),
        colours.len()
    );
}

fn algorithm(name: &str) -> Algorithm {
    name.parse()
        .unwrap_or_else(|e| panic!("unknown builder {name} in results.json: {e}"))
}

/// Whether `ray` hits any of `triangles` (Möller-Trumbore in f64, every triangle tried).
fn brute_force_hits(triangles: &[sahkd::Triangle], ray: &sahkd::Ray) -> bool {
    let v = |p: sahkd::Vec3| [p[0] as f64, p[1] as f64, p[2] as f64];
    let sub = |a: [f64; 3], b: [f64; 3]| [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    let cross = |a: [f64; 3], b: [f64; 3]| {
        [
            a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0],
        ]
    };
    let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let (o, d) = (v(ray.origin), v(ray.direction));
    triangles.iter().any(|t| {
        let (a, b, c) = (v(t[0]), v(t[1]), v(t[2]));
        let (e1, e2) = (sub(b, a), sub(c, a));
        let p = cross(d, e2);
        let det = dot(e1, p);
        if det.abs() < 1e-12 {
            return false;
        }
        let s = sub(o, a);
        let u = dot(s, p) / det;
        let q = cross(s, e1);
        let w = dot(d, q) / det;
        let t = dot(e2, q) / det;
        u >= 0.0 && w >= 0.0 && u + w <= 1.0 && t >= ray.t_min as f64 && t <= ray.t_max as f64
    })
}

fn f(v: &Value) -> f64 {
    v.as_f64().unwrap_or_else(|| panic!("not a number: {v}"))
}

/// A spread of `repeat` samples: min <= median <= max, every sample within.
fn check_spread(v: &Value, repeat: usize) {
    let samples = v["samples"].as_array().expect("samples");
    assert_eq!(samples.len(), repeat, "{v}");
    let (min, median, max) = (f(&v["min"]), f(&v["median"]), f(&v["max"]));
    assert!(min <= median && median <= max, "{v}");
    assert!(samples.iter().all(|s| (min..=max).contains(&f(s))), "{v}");
}

#[test]
fn bench_writes_every_file_and_its_trees_are_the_librarys() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("new/folder");
    let specs = ["spd:toys:2000", "spd:sphere:1200"];
    let results = bench(&[
        specs[0],
        specs[1],
        "--algorithms",
        "level,sweep,naive,median,hybrid",
        "--threads",
        "2,1",
        "--repeat",
        "2",
        "--naive-cap",
        "1500",
        "--width",
        "40",
        "--height",
        "30",
        "--ao-size",
        "16",
        "--ao-samples",
        "3",
        "--out",
        path_str(&out),
    ]);

    assert!(results["command"].as_str().unwrap().contains("bench"));
    assert!(results["machine"]["cores"].as_u64().unwrap() >= 1);
    assert_eq!(results["settings"]["threads"], serde_json::json!([1, 2]));
    let scenes = results["scenes"].as_array().unwrap();
    assert_eq!(scenes.len(), 2);
    for (scene, spec) in scenes.iter().zip(specs) {
        let mesh = scenes::generate(spec).unwrap();
        assert_eq!(scene["triangles"], mesh.triangles.len());
        let naive_skipped = mesh.triangles.len() > 1500;
        let builds = scene["builds"].as_array().unwrap();
        // level, median, naive and hybrid at 1 and 2 threads, the serial sweep once.
        assert_eq!(builds.len(), 9, "{spec}");
        for b in builds {
            let name = b["algorithm"].as_str().unwrap();
            let threads = b["threads"].as_u64().unwrap() as usize;
            if name == "sweep" {
                assert_eq!(threads, 1);
            }
            if name == "naive" && naive_skipped {
                assert!(b["measured"].is_null());
                assert!(b["skipped"].as_str().unwrap().contains("n > cap"), "{b}");
                continue;
            }
            let m = &b["measured"];
            check_spread(&m["build_ms"], 2);
            check_spread(&m["presort_ms"], 2);
            // The same tree as the library builds directly.
            let options = BuildOptions {
                algorithm: algorithm(name),
                threads: Some(threads),
                ..BuildOptions::default()
            };
            let tree = build(&mesh, &options).unwrap().tree;
            let stats = tree.stats(&options.cost);
            assert_eq!(m["nodes"], stats.nodes, "{spec} {name}");
            assert_eq!(m["leaves"], stats.leaves, "{spec} {name}");
            assert_eq!(m["references"], stats.references, "{spec} {name}");
            assert_eq!(m["depth"], stats.max_depth, "{spec} {name}");
            assert_eq!(m["tree_bytes"], stats.bytes, "{spec} {name}");
            assert!((f(&m["sah_cost"]) - stats.sah_cost).abs() <= 1e-9 * stats.sah_cost);
        }
        let rays = scene["rays"].as_array().unwrap();
        assert_eq!(rays.len(), if naive_skipped { 4 } else { 5 }, "{spec}");
        // One shadow and one bounce ray per primary hit of the same 40 x 30 picture, counted
        // here by brute force over every triangle.
        let tree = build(&mesh, &BuildOptions::default()).unwrap().tree;
        let camera = sahkd::render::Camera::front(tree.bounds());
        let hits = (0..30)
            .flat_map(|y| (0..40).map(move |x| (x, y)))
            .filter(|&(x, y)| {
                let ray = camera.primary_ray(40, 30, x as f32 + 0.5, y as f32 + 0.5);
                brute_force_hits(tree.triangles(), &ray)
            })
            .count();
        assert!(hits > 0 && hits < 40 * 30, "{spec}: {hits} hits");
        for r in rays {
            assert_eq!(r["primary"]["rays"], 40 * 30, "{r}");
            check_spread(&r["primary_mrays"], 2);
            check_spread(&r["ao_mrays"], 2);
            check_spread(&r["shadow_mrays"], 2);
            check_spread(&r["bounce_mrays"], 2);
            assert_eq!(r["shadow"]["rays"], hits, "{r}");
            assert_eq!(r["bounce"]["rays"], hits, "{r}");
            assert!(f(&r["bounce"]["nodes_per_ray"]) > 0.0, "{r}");
            let ao = r["ao"]["rays"].as_u64().unwrap();
            assert!(ao > 0 && ao <= 16 * 16 * 3 && ao % 3 == 0, "{r}");
            // Some rays miss the scene box and visit no node; the counted ones hit it.
            assert!(f(&r["primary"]["nodes_per_ray"]) > 0.0, "{r}");
        }
    }
    // Fig. 1 on the larger scene: both curves, 7 levels, P_1 = 1.
    let levels = results["levels"].as_array().unwrap();
    let names: Vec<&str> = levels
        .iter()
        .map(|c| c["algorithm"].as_str().unwrap())
        .collect();
    assert_eq!(names, ["sweep", "level"]);
    for c in levels {
        assert_eq!(c["scene"], "spd:toys:2000");
        let points = c["points"].as_array().unwrap();
        assert_eq!(points.len(), 7);
        assert_eq!(f(&points[0]["p"]), 1.0);
        for (i, p) in points.iter().enumerate() {
            assert_eq!(p["level"], i + 1);
            check_spread(&p["t_ms"], 2);
            check_spread(&p["after_sort_ms"], 2);
            let ratio = f(&p["after_sort_ms"]["median"]) / f(&points[0]["after_sort_ms"]["median"]);
            assert!((f(&p["p"]) - ratio).abs() < 1e-12, "{p}");
        }
    }

    let table = std::fs::read_to_string(out.join("table1.md")).unwrap();
    assert!(table.starts_with("# Table 1"), "{table}");
    for needle in [
        "| spd:toys:2000 |",
        "| spd:sphere:1200 |",
        "skipped (n > cap",
        "sahkd default (hybrid)",
        "## Fig. 1",
        "## Fig. 2",
        "## Ray throughput",
    ] {
        assert!(table.contains(needle), "'{needle}' not in table1.md");
    }
    // Every table row has as many cells as its header.
    for block in table.split("\n\n").filter(|b| b.starts_with('|')) {
        let cells: Vec<usize> = block.lines().map(|l| l.matches('|').count()).collect();
        assert!(
            cells.iter().all(|&c| c == cells[0]),
            "ragged table:\n{block}"
        );
    }
    for chart in ["table1.png", "fig1_levels.png", "fig2_speedup.png"] {
        check_chart(&out.join(chart));
    }
}

/// Writes `mesh` as a binary little-endian PLY.
fn write_ply(path: &Path, mesh: &Mesh) {
    let mut bytes = format!(
        "ply\nformat binary_little_endian 1.0\nelement vertex {}\nproperty float x\n\
         property float y\nproperty float z\nelement face {}\n\
         property list uchar int vertex_indices\nend_header\n",
        mesh.vertices.len(),
        mesh.triangles.len()
    )
    .into_bytes();
    for v in &mesh.vertices {
        for c in v {
            bytes.extend_from_slice(&c.to_le_bytes());
        }
    }
    for t in &mesh.triangles {
        bytes.push(3);
        for i in t {
            bytes.extend_from_slice(&(*i as i32).to_le_bytes());
        }
    }
    std::fs::File::create(path)
        .and_then(|mut f| f.write_all(&bytes))
        .unwrap();
}

#[test]
fn with_no_scene_named_it_runs_the_papers_table_from_the_scenes_folder() {
    // Small meshes under the stand-ins' names, so the test is quick.
    let scenes_dir = tempfile::tempdir().unwrap();
    let files = [
        ("dragon_res4.ply", "spd:sphere:300"),
        ("bunny.ply", "spd:sphere:500"),
        ("dragon_res2.ply", "spd:toys:700"),
        ("dragon.ply", "spd:toys:900"),
    ];
    for (file, spec) in files {
        write_ply(
            &scenes_dir.path().join(file),
            &scenes::generate(spec).unwrap(),
        );
    }
    let out = tempfile::tempdir().unwrap();
    let results = bench(&[
        "--scenes-dir",
        path_str(scenes_dir.path()),
        "--algorithms",
        "level,sweep",
        "--threads",
        "1",
        "--repeat",
        "1",
        "--width",
        "8",
        "--height",
        "8",
        "--ao-size",
        "4",
        "--ao-samples",
        "1",
        "--out",
        path_str(out.path()),
    ]);
    let labels: Vec<&str> = results["scenes"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s["label"].as_str().unwrap())
        .collect();
    assert_eq!(labels, ["Toys", "Bunny", "Dragon", "Buddha"]);
    for (scene, (file, spec)) in results["scenes"].as_array().unwrap().iter().zip(files) {
        assert!(scene["source"].as_str().unwrap().ends_with(file));
        assert_eq!(
            scene["triangles"],
            scenes::generate(spec).unwrap().triangles.len()
        );
    }
    // Fig. 1 runs on the largest scene.
    assert_eq!(results["levels"][0]["scene"], "Buddha");
    let table = std::fs::read_to_string(out.path().join("table1.md")).unwrap();
    // The paper's own numbers (Table 1, ms) beside ours, with its speed-ups; it has no hybrid.
    for row in [
        "| Toys | 11 k | paper | 31 | 37 | 27 | 28 | — | 1.32 | 1.11 | 0.96 |",
        "| Bunny | 69 k | paper | 87 | 233 | 240 | 54 | — | 4.31 | 1.61 | 4.44 |",
        "| Dragon | 252 k | paper | 193 | 641 | 810 | 110 | — | 5.83 | 1.75 | 7.36 |",
        "| Buddha | 1 M | paper | 790 | 2554 | 2840 | 410 | — | 6.23 | 1.93 | 6.93 |",
    ] {
        assert!(table.contains(row), "'{row}' not in:\n{table}");
    }
    assert!(table.contains("the 1M Buddha is not available"));
}

/// A bench that must fail with `status` and one `error:` line naming every fragment.
fn fails(args: &[&str], status: i32, fragments: &[&str]) {
    let out = sahkd(&[&["bench"][..], args].concat());
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(status), "bench {args:?}: {err}");
    assert!(!err.contains("panicked"), "bench {args:?} panicked: {err}");
    let lines: Vec<&str> = err.lines().collect();
    assert_eq!(lines.len(), 1, "bench {args:?}: not one line: {err}");
    assert!(lines[0].starts_with("error: "), "bench {args:?}: {err}");
    for f in fragments {
        assert!(lines[0].contains(f), "bench {args:?}: '{f}' not in: {err}");
    }
}

#[test]
fn mistakes_end_in_one_error_line() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let out = path_str(&out);
    let scene = "spd:sphere:200";
    fails(
        &[scene, "--algorithms", "level,quick", "--out", out],
        2,
        &["quick", "level"],
    );
    fails(&[scene, "--threads", "1,0", "--out", out], 2, &["0"]);
    fails(&[scene, "--threads", "1,two", "--out", out], 2, &["two"]);
    fails(&[scene, "--repeat", "0", "--out", out], 2, &["repeat"]);
    let missing = dir.path().join("missing.ply");
    fails(&[path_str(&missing), "--out", out], 1, &["missing.ply"]);
    fails(
        &[
            "--scenes-dir",
            path_str(&dir.path().join("nowhere")),
            "--out",
            out,
        ],
        1,
        &["nowhere", "no such folder"],
    );
    // An output folder that cannot be made: its parent is a file.
    let file = dir.path().join("a-file");
    std::fs::write(&file, b"not a folder").unwrap();
    let blocked = file.join("out");
    fails(
        &[scene, "--out", path_str(&blocked)],
        1,
        &["cannot create the output folder", "a-file"],
    );
}
