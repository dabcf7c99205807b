//! The `sahkd` binary, run as a user would: results checked against the library and the
//! brute-force oracle, and every mistake checked to end in one clean `error:` line.

use npyz::npz::NpzArchive;
use npyz::WriterBuilder;
use sahkd::trace::{brute, precise};
use sahkd::{scenes, BuildOptions, Mesh, Ray, Ray64, Triangle, Vec3};
use serde_json::Value;
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

const SCENE: &str = "spd:sphere:2000";

fn sahkd(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_sahkd"))
        .args(args)
        .output()
        .expect("cannot start the sahkd binary")
}

fn stdout(out: &Output) -> String {
    String::from_utf8_lossy(&out.stdout).into_owned()
}

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// Runs a command that must succeed and print one JSON object on one line of stdout.
fn json(args: &[&str]) -> Value {
    let out = sahkd(args);
    assert!(
        out.status.success(),
        "sahkd {args:?} failed: {}",
        stderr(&out)
    );
    let text = stdout(&out);
    assert_eq!(text.lines().count(), 1, "not one line of JSON: {text}");
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("not JSON ({e}): {text}"))
}

/// Runs a command that must fail with `status` and exactly one `error:` line naming every
/// one of `fragments`. Returns that line.
fn fails(args: &[&str], status: i32, fragments: &[&str]) -> String {
    let out = sahkd(args);
    let err = stderr(&out);
    assert_eq!(
        out.status.code(),
        Some(status),
        "sahkd {args:?}: wrong exit status; stderr: {err}"
    );
    assert!(!err.contains("panicked"), "sahkd {args:?} panicked: {err}");
    assert!(!err.contains("backtrace"), "sahkd {args:?}: {err}");
    let lines: Vec<&str> = err.lines().collect();
    assert_eq!(lines.len(), 1, "sahkd {args:?}: not one line: {err}");
    assert!(lines[0].starts_with("error: "), "sahkd {args:?}: {err}");
    for f in fragments {
        assert!(lines[0].contains(f), "sahkd {args:?}: '{f}' not in: {err}");
    }
    assert!(
        out.stdout.is_empty(),
        "sahkd {args:?} wrote to stdout: {}",
        stdout(&out)
    );
    lines[0].to_string()
}

fn scene(spec: &str) -> Mesh {
    scenes::generate(spec).expect("the test scene exists")
}

fn path_str(p: &Path) -> &str {
    p.to_str().expect("temp paths are UTF-8")
}

// ---------------------------------------------------------------------------------------
// build

const BUILD_KEYS: &[&str] = &[
    "triangles",
    "algorithm",
    "axes",
    "counting",
    "clip",
    "threads",
    "load_ms",
    "build_ms",
    "presort_ms",
    "sah_cost",
    "nodes",
    "leaves",
    "empty_leaves",
    "references",
    "duplication",
    "max_depth",
    "mean_leaf_size",
    "bytes",
    "peak_working_bytes",
    "levels",
    "bins",
];

#[test]
fn build_json_has_every_key_and_sane_values() {
    let report = json(&["build", SCENE, "--json", "--threads", "2"]);
    for key in BUILD_KEYS {
        assert!(report.get(key).is_some(), "no '{key}' in {report}");
    }
    let n = scene(SCENE).triangles.len() as u64;
    assert_eq!(report["triangles"], n);
    assert_eq!(report["threads"], 2);
    let defaults = BuildOptions::default();
    assert_eq!(report["clip"], defaults.clip);
    assert!(report["nodes"].as_u64().unwrap() >= 1);
    assert_eq!(
        report["nodes"].as_u64(),
        Some(report["interior"].as_u64().unwrap() + report["leaves"].as_u64().unwrap())
    );
    assert!(report["leaves"].as_u64().unwrap() >= 1);
    assert!(report["empty_leaves"].as_u64() <= report["leaves"].as_u64());
    assert!(report["references"].as_u64().unwrap() >= 1);
    let cost = report["sah_cost"].as_f64().unwrap();
    assert!(cost.is_finite() && cost > 0.0, "{cost}");
    for key in ["load_ms", "build_ms", "presort_ms"] {
        let ms = report[key].as_f64().unwrap();
        assert!(ms.is_finite() && ms >= 0.0, "{key} = {ms}");
    }
    assert!(report["levels"].is_array());
    assert!(report["valid"].is_null(), "validated without --validate");
}

/// Every builder option reaches the library: the command's statistics equal those of the
/// library's own build with the same options (builds are deterministic).
#[test]
fn build_options_reach_the_library() {
    /// Flags, and what they should do to the default options.
    type Case = (&'static [&'static str], fn(&mut BuildOptions));
    let mesh = scene(SCENE);
    let cases: &[Case] = &[
        (&["--algorithm", "sweep"], |o| {
            o.algorithm = sahkd::Algorithm::Sweep
        }),
        (&["--algorithm", "naive", "--axes", "all"], |o| {
            o.algorithm = sahkd::Algorithm::Naive;
            o.axes = sahkd::Axes::All;
        }),
        (&["--algorithm", "median", "--large-node", "16"], |o| {
            o.algorithm = sahkd::Algorithm::Median;
            o.median_large_node = 16;
        }),
        (&["--counting", "space-tree", "--clip", "off"], |o| {
            o.counting = sahkd::Counting::SpaceTree;
            o.clip = false;
        }),
        (
            &[
                "--kt",
                "3",
                "--ki",
                "7",
                "--empty-bonus",
                "1",
                "--leaf-size",
                "4",
            ],
            |o| {
                o.cost.traversal = 3.0;
                o.cost.intersection = 7.0;
                o.cost.empty_bonus = 1.0;
                o.cost.leaf_size = 4;
            },
        ),
        (&["--algorithm", "sweep", "--bins", "2"], |o| {
            o.algorithm = sahkd::Algorithm::Sweep;
            o.bins = Some(2);
        }),
        (&["--bins", "4", "--axes", "all", "--clip", "off"], |o| {
            o.bins = Some(4);
            o.axes = sahkd::Axes::All;
            o.clip = false;
        }),
        (&["--bins", "0"], |o| o.bins = Some(0)),
        (&["--max-depth", "5", "--max-duplication", "1.5"], |o| {
            o.cost.max_depth = Some(5);
            o.cost.max_duplication = 1.5;
        }),
    ];
    for (flags, set) in cases {
        let mut options = BuildOptions::default();
        set(&mut options);
        let expected = sahkd::build(&mesh, &options)
            .unwrap()
            .tree
            .stats(&options.cost);
        let mut args = vec!["build", SCENE, "--json"];
        args.extend_from_slice(flags);
        let report = json(&args);
        let names = [
            (
                "algorithm",
                format!("{:?}", options.algorithm).to_lowercase(),
            ),
            ("axes", format!("{:?}", options.axes).to_lowercase()),
        ];
        for (key, name) in names {
            assert_eq!(report[key], name.as_str(), "{flags:?}");
        }
        assert_eq!(report["clip"], options.clip, "{flags:?}");
        assert_eq!(report["bins"], options.resolved_bins(), "{flags:?}");
        assert_eq!(report["nodes"], expected.nodes, "{flags:?}");
        assert_eq!(report["leaves"], expected.leaves, "{flags:?}");
        assert_eq!(report["empty_leaves"], expected.empty_leaves, "{flags:?}");
        assert_eq!(report["references"], expected.references, "{flags:?}");
        assert_eq!(report["max_depth"], expected.max_depth, "{flags:?}");
        // Through the same JSON text and parser as the report: serde_json's default float
        // parsing may be one ulp off the printed value.
        let expected_cost: Value =
            serde_json::from_str(&serde_json::to_string(&expected.sah_cost).unwrap()).unwrap();
        assert_eq!(report["sah_cost"], expected_cost, "{flags:?}");
    }
}

#[test]
fn build_counting_names_are_kebab_case() {
    let report = json(&["build", SCENE, "--json", "--counting", "space-tree"]);
    assert_eq!(report["counting"], "space-tree");
    let report = json(&["build", SCENE, "--json", "--counting", "scan"]);
    assert_eq!(report["counting"], "scan");
}

#[test]
fn build_without_a_mesh_uses_the_default_scene() {
    let report = json(&["build", "--json"]);
    assert_eq!(
        report["triangles"],
        scene(scenes::DEFAULT_SCENE).triangles.len() as u64
    );
}

#[test]
fn build_validate_reports_a_valid_tree() {
    let report = json(&["build", SCENE, "--json", "--validate"]);
    assert_eq!(report["valid"], true);
    let out = sahkd(&["build", SCENE, "--validate"]);
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(stdout(&out).contains("validation"), "{}", stdout(&out));
}

#[test]
fn build_text_report_names_the_statistics() {
    let out = sahkd(&["build", SCENE, "--quiet"]);
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(out.stderr.is_empty(), "{}", stderr(&out));
    let text = stdout(&out);
    let n = scene(SCENE).triangles.len();
    let with_commas = n
        .to_string()
        .as_bytes()
        .rchunks(3)
        .rev()
        .map(|c| std::str::from_utf8(c).unwrap())
        .collect::<Vec<_>>()
        .join(",");
    assert!(text.contains(&with_commas), "{text}");
    for label in [
        "triangles",
        "load time",
        "build time",
        "pre-sort time",
        "SAH cost",
        "nodes",
        "leaves",
        "empty leaves",
        "references",
        "duplication",
        "max depth",
        "mean leaf size",
        "tree size",
        "peak working memory",
    ] {
        assert!(text.contains(label), "no '{label}' in:\n{text}");
    }
}

#[test]
fn help_shows_the_presets_and_that_options_default_to_the_presets() {
    let out = sahkd(&["build", "--help"]);
    assert!(out.status.success());
    let help = stdout(&out);
    let preset = help.split("--preset").nth(1).expect("no --preset");
    let preset = preset.split("\n      --").next().unwrap();
    for name in sahkd::Preset::NAMES {
        assert!(preset.contains(name), "--preset: no {name} in {preset}");
    }
    for flag in [
        "--kt",
        "--ki",
        "--empty-bonus",
        "--leaf-size",
        "--max-duplication",
        "--clip",
    ] {
        let section = help
            .split(flag)
            .nth(1)
            .unwrap_or_else(|| panic!("no {flag}"));
        let next = section.split("\n      --").next().unwrap();
        assert!(next.contains("[default: the preset's]"), "{flag}: {next}");
    }
}

// ---------------------------------------------------------------------------------------
// Input errors

#[test]
fn missing_and_malformed_meshes_are_clean_errors() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("missing.ply");
    fails(&["build", path_str(&missing)], 1, &["missing.ply"]);
    fails(&["info", path_str(&missing)], 1, &["missing.ply"]);

    let bad_ply = dir.path().join("bad.ply");
    std::fs::write(&bad_ply, "ply\nformat nonsense 9.9\nelement vertex x\n").unwrap();
    fails(&["build", path_str(&bad_ply)], 1, &["bad.ply"]);

    let bad_obj = dir.path().join("bad.obj");
    std::fs::write(&bad_obj, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n").unwrap();
    fails(&["build", path_str(&bad_obj)], 1, &["bad.obj"]);

    let unknown = dir.path().join("mesh.stl");
    std::fs::write(&unknown, "solid nothing\nendsolid\n").unwrap();
    fails(&["info", path_str(&unknown)], 1, &["mesh.stl"]);
}

#[test]
fn unknown_scene_specs_are_clean_errors() {
    fails(&["build", "spd:sphere:lots"], 1, &["spd:sphere:lots"]);
    fails(
        &["build", "no-such-mesh-or-scene"],
        1,
        &["no-such-mesh-or-scene"],
    );
    fails(
        &["info", "no-such-mesh-or-scene"],
        1,
        &["no-such-mesh-or-scene"],
    );
}

#[test]
fn bad_option_values_are_usage_errors() {
    for (args, fragment) in [
        (&["build", "--algorithm", "quick"][..], "quick"),
        (&["build", "--axes", "diagonal"], "diagonal"),
        (&["build", "--counting", "fast"], "fast"),
        (&["build", "--clip", "yes"], "yes"),
        (&["build", "--threads", "0"], "--threads"),
        (&["build", "--threads", "two"], "two"),
        (&["build", "--kt", "-1"], "--kt"),
        (&["build", "--ki", "0"], "--ki"),
        (&["build", "--empty-bonus", "2"], "--empty-bonus"),
        (&["build", "--max-depth", "deep"], "deep"),
        (&["build", "--max-duplication", "0.5"], "--max-duplication"),
        (&["build", "--no-such-flag"], "--no-such-flag"),
        (&["build", "--bins", "1"], "from 2 to 1024"),
        (&["build", "--bins", "1025"], "--bins"),
        (&["build", "--bins", "-8"], "--bins"),
        (
            &["trace", SCENE, "--bins", "1", "--rays", "r.npy"],
            "--bins",
        ),
        (&["trace", SCENE, "--output", "x.npz"], "--rays"),
        (&["no-such-command"], "no-such-command"),
    ] {
        fails(args, 2, &[fragment]);
    }
}

/// Bins with a builder that has none: refused by the library's rules, before any input is
/// read, on every command that builds.
#[test]
fn bins_with_other_builders_are_refused() {
    for algorithm in ["level", "naive", "median"] {
        fails(
            &["build", SCENE, "--algorithm", algorithm, "--bins", "16"],
            1,
            &["bins", algorithm],
        );
    }
    fails(
        &[
            "trace",
            SCENE,
            "--algorithm",
            "level",
            "--bins",
            "16",
            "--rays",
            "no-such.npy",
            "--output",
            "never-written.npz",
        ],
        1,
        &["bins", "level"],
    );
}

// ---------------------------------------------------------------------------------------
// trace

/// A small deterministic generator (xorshift64*), so the tests need no random crate.
struct Rng(u64);

impl Rng {
    fn unit(&mut self) -> f32 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        let x = self.0.wrapping_mul(0x2545_f491_4f6c_dd1d);
        (x >> 40) as f32 / (1u64 << 24) as f32
    }
    fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.unit()
    }
}

/// Rays from around the unit sphere toward points near it (most hit, some miss), plus
/// awkward ones: from the centre, axis-parallel, zero direction (a NaN origin is refused, as
/// `rays_the_library_refuses_...` in tests/reliability.rs checks).
fn ray_rows(count: usize, with_range: bool) -> Vec<[f32; 8]> {
    let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
    let mut rows = Vec::with_capacity(count + 4);
    for _ in 0..count {
        let o = [0; 3].map(|_| rng.range(-3.0, 3.0));
        let target = [0; 3].map(|_| rng.range(-1.3, 1.3));
        let d = [0, 1, 2].map(|a| target[a] - o[a]);
        let t_min = rng.range(0.0, 0.5);
        let t_max = if rng.unit() < 0.2 {
            f32::INFINITY
        } else {
            t_min + rng.range(0.0, 1.5)
        };
        rows.push([o[0], o[1], o[2], d[0], d[1], d[2], t_min, t_max]);
    }
    let inf = f32::INFINITY;
    rows.push([0.0, 0.0, 0.0, 0.3, -0.2, 0.9, 0.0, inf]);
    rows.push([0.1, 0.2, -5.0, 0.0, 0.0, 1.0, 0.0, inf]);
    rows.push([0.1, 0.2, -5.0, 0.0, 0.0, 0.0, 0.0, inf]);
    // An empty range.
    rows.push([0.0, 0.0, -5.0, 0.0, 0.0, 1.0, 3.0, 2.0]);
    if !with_range {
        for r in &mut rows {
            r[6] = 0.0;
            r[7] = inf;
        }
    }
    rows
}

fn to_ray(r: &[f32; 8]) -> Ray {
    Ray::new(Vec3::new(r[0], r[1], r[2]), Vec3::new(r[3], r[4], r[5])).with_range(r[6], r[7])
}

/// Writes the first `width` columns of `rows` as a C-order (R, width) array of `T`.
fn write_npy<T: npyz::AutoSerialize + Copy>(
    path: &Path,
    rows: &[[f32; 8]],
    width: usize,
    convert: fn(f32) -> T,
) {
    let file = BufWriter::new(File::create(path).unwrap());
    let mut w = npyz::WriteOptions::new()
        .default_dtype()
        .shape(&[rows.len() as u64, width as u64])
        .writer(file)
        .begin_nd()
        .unwrap();
    for r in rows {
        w.extend(r[..width].iter().map(|&x| convert(x))).unwrap();
    }
    w.finish().unwrap();
}

/// Reads one array of an .npz, checking its dtype and length.
fn read_npz<T: npyz::Deserialize>(path: &Path, name: &str, dtype: &str, len: usize) -> Vec<T> {
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
    assert_eq!(array.shape(), &[len as u64], "shape of {name}");
    array.into_vec().unwrap()
}

fn array_names(path: &Path) -> Vec<String> {
    let npz = NpzArchive::open(path).unwrap();
    let mut names: Vec<String> = npz.array_names().map(str::to_string).collect();
    names.sort();
    names
}

/// Traces `rows` through the command with closest-hit queries and compares every answer with
/// the brute-force oracle, bit for bit.
fn check_trace_matches_brute(width: usize, extra: &[&str]) {
    let dir = tempfile::tempdir().unwrap();
    let rays_path = dir.path().join("rays.npy");
    let hits_path = dir.path().join("hits.npz");
    let rows = ray_rows(1500, width == 8);
    write_npy(&rays_path, &rows, width, |x| x);
    let mut args = vec![
        "trace",
        SCENE,
        "--rays",
        path_str(&rays_path),
        "--output",
        path_str(&hits_path),
        "--json",
    ];
    args.extend_from_slice(extra);
    let report = json(&args);

    let triangles: Vec<Triangle> = scene(SCENE).corner_triangles();
    let n = rows.len();
    assert_eq!(array_names(&hits_path), ["prim", "t", "u", "v"]);
    let t: Vec<f32> = read_npz(&hits_path, "t", "<f4", n);
    let prim: Vec<i64> = read_npz(&hits_path, "prim", "<i8", n);
    let u: Vec<f32> = read_npz(&hits_path, "u", "<f4", n);
    let v: Vec<f32> = read_npz(&hits_path, "v", "<f4", n);
    let mut hits = 0;
    for (i, row) in rows.iter().enumerate() {
        let expected = brute::intersect(&triangles, &to_ray(row));
        let got = (t[i].to_bits(), prim[i], u[i].to_bits(), v[i].to_bits());
        let want = match expected {
            Some(h) => {
                hits += 1;
                (h.t.to_bits(), h.prim as i64, h.u.to_bits(), h.v.to_bits())
            }
            None => (f32::INFINITY.to_bits(), -1, 0f32.to_bits(), 0f32.to_bits()),
        };
        assert_eq!(got, want, "ray {i} {row:?}: got {:?}", (t[i], prim[i]));
    }
    assert!(hits > n / 10 && hits < n, "{hits} hits of {n}: a weak test");
    assert_eq!(report["rays"], n);
    assert_eq!(report["hits"], hits);
    assert_eq!(report["triangles"], triangles.len());
    for key in ["build_ms", "layout_ms", "trace_ms", "mrays_per_s"] {
        let x = report[key].as_f64().unwrap();
        assert!(x.is_finite() && x >= 0.0, "{key} = {x}");
    }
}

#[test]
fn trace_of_origin_direction_rows_matches_brute_force() {
    check_trace_matches_brute(6, &[]);
}

#[test]
fn trace_of_rows_with_ranges_matches_brute_force() {
    check_trace_matches_brute(8, &["--threads", "1"]);
}

#[test]
fn trace_with_other_builder_options_matches_brute_force() {
    check_trace_matches_brute(
        8,
        &["--algorithm", "sweep", "--axes", "all", "--clip", "off"],
    );
}

#[test]
fn binned_trace_matches_brute_force() {
    check_trace_matches_brute(8, &["--bins", "2", "--threads", "2"]);
    check_trace_matches_brute(8, &["--algorithm", "sweep", "--bins", "3"]);
}

#[test]
fn any_hit_trace_matches_brute_force() {
    let dir = tempfile::tempdir().unwrap();
    let rays_path = dir.path().join("rays.npy");
    let hits_path = dir.path().join("hits.npz");
    let rows = ray_rows(1500, true);
    write_npy(&rays_path, &rows, 8, |x| x);
    let report = json(&[
        "trace",
        SCENE,
        "--rays",
        path_str(&rays_path),
        "-o",
        path_str(&hits_path),
        "--any-hit",
        "--json",
    ]);
    let triangles = scene(SCENE).corner_triangles();
    assert_eq!(array_names(&hits_path), ["hit"]);
    let hit: Vec<bool> = read_npz(&hits_path, "hit", "|b1", rows.len());
    let mut count = 0;
    for (i, row) in rows.iter().enumerate() {
        let expected = brute::occluded(&triangles, &to_ray(row));
        assert_eq!(hit[i], expected, "ray {i} {row:?}");
        count += expected as usize;
    }
    assert!(count > 0 && count < rows.len());
    assert_eq!(report["hits"], count);
}

/// `--precision f64`: float64 `t`, `u`, `v`, each the f64 brute force's answer bit for bit,
/// and the same any-hit answers.
#[test]
fn f64_trace_matches_the_f64_brute_force() {
    let dir = tempfile::tempdir().unwrap();
    let rays_path = dir.path().join("rays.npy");
    let hits_path = dir.path().join("hits.npz");
    let any_path = dir.path().join("any.npz");
    let rows = ray_rows(1500, true);
    write_npy(&rays_path, &rows, 8, |x| x);
    let run = |out: &Path, extra: &[&str]| {
        let mut args = vec![
            "trace",
            SCENE,
            "--rays",
            path_str(&rays_path),
            "-o",
            path_str(out),
            "--precision",
            "f64",
            "--json",
        ];
        args.extend_from_slice(extra);
        json(&args)
    };
    let report = run(&hits_path, &[]);
    assert_eq!(report["precision"], "f64");
    run(&any_path, &["--any-hit"]);
    let triangles = scene(SCENE).corner_triangles();
    let n = rows.len();
    let t: Vec<f64> = read_npz(&hits_path, "t", "<f8", n);
    let prim: Vec<i64> = read_npz(&hits_path, "prim", "<i8", n);
    let u: Vec<f64> = read_npz(&hits_path, "u", "<f8", n);
    let v: Vec<f64> = read_npz(&hits_path, "v", "<f8", n);
    let hit: Vec<bool> = read_npz(&any_path, "hit", "|b1", n);
    let mut hits = 0;
    for (i, row) in rows.iter().enumerate() {
        let ray = Ray64::from(&to_ray(row));
        let want = match precise::brute_intersect(&triangles, &ray) {
            Some(h) => {
                hits += 1;
                (h.t.to_bits(), h.prim as i64, h.u.to_bits(), h.v.to_bits())
            }
            None => (f64::INFINITY.to_bits(), -1, 0f64.to_bits(), 0f64.to_bits()),
        };
        let got = (t[i].to_bits(), prim[i], u[i].to_bits(), v[i].to_bits());
        assert_eq!(got, want, "ray {i} {row:?}");
        assert_eq!(hit[i], want.1 >= 0, "any hit, ray {i} {row:?}");
    }
    assert!(hits > n / 10 && hits < n, "{hits} hits of {n}: a weak test");
    assert_eq!(report["hits"], hits);
}

#[test]
fn trace_summary_goes_to_stderr_unless_quiet() {
    let dir = tempfile::tempdir().unwrap();
    let rays_path = dir.path().join("rays.npy");
    let hits_path = dir.path().join("hits.npz");
    write_npy(&rays_path, &ray_rows(50, false), 6, |x| x);
    let args = [
        "trace",
        SCENE,
        "--rays",
        path_str(&rays_path),
        "-o",
        path_str(&hits_path),
    ];
    let out = sahkd(&args);
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(out.stdout.is_empty());
    let err = stderr(&out);
    assert!(err.contains("Mrays/s") && err.contains("54 rays"), "{err}");
    let mut quiet = args.to_vec();
    quiet.push("--quiet");
    let out = sahkd(&quiet);
    assert!(out.status.success());
    assert!(
        out.stdout.is_empty() && out.stderr.is_empty(),
        "{}",
        stderr(&out)
    );
}

#[test]
fn wrong_ray_files_are_rejected_with_what_was_expected_and_found() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("hits.npz");
    let out = path_str(&out);
    let rows = ray_rows(10, false);
    let n = rows.len().to_string();

    let doubles = dir.path().join("doubles.npy");
    write_npy(&doubles, &rows, 6, f64::from);
    let line = fails(
        &["trace", SCENE, "--rays", path_str(&doubles), "-o", out],
        1,
        &["doubles.npy", "float32", "float64"],
    );
    assert!(line.find("float32") < line.find("float64"), "{line}");

    let five = dir.path().join("five.npy");
    write_npy(&five, &rows, 5, |x| x);
    fails(
        &["trace", SCENE, "--rays", path_str(&five), "-o", out],
        1,
        &["five.npy", "(R, 6) or (R, 8)", &format!("({n}, 5)")],
    );

    let flat = dir.path().join("flat.npy");
    let file = BufWriter::new(File::create(&flat).unwrap());
    let mut w = npyz::WriteOptions::new()
        .default_dtype()
        .shape(&[6])
        .writer(file)
        .begin_nd()
        .unwrap();
    w.extend([0f32; 6]).unwrap();
    w.finish().unwrap();
    fails(
        &["trace", SCENE, "--rays", path_str(&flat), "-o", out],
        1,
        &["(R, 6) or (R, 8)", "(6,)"],
    );

    let junk = dir.path().join("junk.npy");
    std::fs::write(&junk, "not an array").unwrap();
    fails(
        &["trace", SCENE, "--rays", path_str(&junk), "-o", out],
        1,
        &["junk.npy"],
    );

    let missing = dir.path().join("missing.npy");
    fails(
        &["trace", SCENE, "--rays", path_str(&missing), "-o", out],
        1,
        &["missing.npy"],
    );

    let good = dir.path().join("good.npy");
    write_npy(&good, &rows, 6, |x| x);
    let nowhere = dir.path().join("no-such-dir").join("hits.npz");
    fails(
        &[
            "trace",
            SCENE,
            "--rays",
            path_str(&good),
            "-o",
            path_str(&nowhere),
        ],
        1,
        &["no-such-dir"],
    );
    assert!(
        !Path::new(out).exists(),
        "an output was written after an error"
    );
}

// ---------------------------------------------------------------------------------------
// info, and meshes from files

/// `info --json` against the library's mesh and a hand count of unreferenced vertices.
fn check_info(arg: &str, mesh: &Mesh, file_bytes: Option<u64>) -> Value {
    let report = json(&["info", arg, "--json"]);
    assert_eq!(report["vertices"], mesh.vertices.len());
    assert_eq!(report["triangles"], mesh.triangles.len());
    assert_eq!(report["zero_area_triangles"], mesh.zero_area_triangles());
    let used: std::collections::HashSet<u32> = mesh.triangles.iter().flatten().copied().collect();
    assert_eq!(
        report["unreferenced_vertices"],
        mesh.vertices.len() - used.len()
    );
    let mut lo = [f32::INFINITY; 3];
    let mut hi = [f32::NEG_INFINITY; 3];
    for &i in &used {
        for a in 0..3 {
            lo[a] = lo[a].min(mesh.vertices[i as usize][a]);
            hi[a] = hi[a].max(mesh.vertices[i as usize][a]);
        }
    }
    let as_f32 = |v: &Value| -> Vec<f32> {
        v.as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap() as f32)
            .collect()
    };
    assert_eq!(as_f32(&report["bounds"]["lo"]), lo);
    assert_eq!(as_f32(&report["bounds"]["hi"]), hi);
    assert_eq!(report["file_bytes"].as_u64(), file_bytes);
    report
}

#[test]
fn info_of_a_scene_matches_the_library() {
    let report = check_info(SCENE, &scene(SCENE), None);
    assert_eq!(report["kind"], "scene");
    let out = sahkd(&["info", SCENE]);
    assert!(out.status.success());
    let text = stdout(&out);
    for label in [
        "vertices",
        "triangles",
        "bounds",
        "zero-area triangles",
        "unreferenced vertices",
        "load time",
    ] {
        assert!(text.contains(label), "no '{label}' in:\n{text}");
    }
}

/// A unit cube (12 triangles), a collinear triangle and a vertex no face uses.
const CUBE_OBJ: &str = "\
v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n\
v 2 0 0\nv 3 0 0\nv 4 0 0\n\
f 1 3 2\nf 1 4 3\nf 5 6 7\nf 5 7 8\nf 1 2 6\nf 1 6 5\n\
f 2 3 7\nf 2 7 6\nf 3 4 8\nf 3 8 7\nf 4 1 5\nf 4 5 8\n\
f 9 10 11\n";

/// Needs the OBJ reader: before it lands the command must fail cleanly instead.
#[test]
fn a_small_obj_builds_and_is_described() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("cube.obj");
    std::fs::write(&path, CUBE_OBJ).unwrap();
    let arg = path_str(&path);
    match Mesh::load(&path) {
        Ok(mesh) => {
            assert_eq!(mesh.triangles.len(), 13);
            assert_eq!(mesh.zero_area_triangles(), 1);
            let report = json(&["build", arg, "--json", "--validate"]);
            assert_eq!(report["triangles"], 13);
            assert_eq!(report["valid"], true);
            let info = check_info(arg, &mesh, Some(CUBE_OBJ.len() as u64));
            assert_eq!(info["kind"], "file");
            assert_eq!(info["bounds"]["hi"], serde_json::json!([4.0, 1.0, 1.0]));
        }
        Err(e) => {
            eprintln!("the OBJ reader cannot read the cube yet ({e}); checking the error only");
            fails(&["build", arg], 1, &["cube.obj"]);
            fails(&["info", arg], 1, &["cube.obj"]);
        }
    }
}

/// Four vertices in use, one unused; a square of two triangles and a zero-area one.
const SQUARE_PLY: &str = "\
ply\nformat ascii 1.0\nelement vertex 5\nproperty float x\nproperty float y\nproperty float z\n\
element face 3\nproperty list uchar int vertex_indices\nend_header\n\
0 0 0\n1 0 0\n1 1 0\n0 1 0\n9 9 9\n3 0 1 2\n3 0 2 3\n3 0 1 1\n";

/// Needs the PLY reader: before it lands the command must fail cleanly instead.
#[test]
fn info_counts_unused_vertices_and_zero_area_triangles_of_a_ply() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("square.ply");
    std::fs::write(&path, SQUARE_PLY).unwrap();
    let arg = path_str(&path);
    if Mesh::load(&path).is_err() {
        eprintln!("the PLY reader cannot read the square yet; checking the error only");
        fails(&["info", arg], 1, &["square.ply"]);
        return;
    }
    let report = json(&["info", arg, "--json"]);
    assert_eq!(report["vertices"], 5);
    assert_eq!(report["triangles"], 3);
    assert_eq!(report["zero_area_triangles"], 1);
    assert_eq!(report["unreferenced_vertices"], 1);
    assert_eq!(report["bounds"]["lo"], serde_json::json!([0.0, 0.0, 0.0]));
    assert_eq!(report["bounds"]["hi"], serde_json::json!([1.0, 1.0, 0.0]));
    assert_eq!(report["file_bytes"], SQUARE_PLY.len());
}

fn scenes_dir() -> Option<PathBuf> {
    let dir = match std::env::var_os("SAHKD_SCENES") {
        Some(d) => PathBuf::from(d),
        None => Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/scenes"),
    };
    dir.is_dir().then_some(dir)
}

/// `info` on the bunny against the statistics in the scenes' README (measured independently).
#[test]
fn info_of_the_bunny_matches_the_scenes_readme() {
    let Some(dir) = scenes_dir() else {
        eprintln!("skipped: no scenes folder (set SAHKD_SCENES)");
        return;
    };
    let path = dir.join("bunny.ply");
    let readme = std::fs::read_to_string(dir.join("README.md")).unwrap_or_default();
    let Some(row) = readme.lines().find(|l| l.starts_with("| `bunny.ply`")) else {
        eprintln!("skipped: no bunny row in the scenes README");
        return;
    };
    let cells: Vec<u64> = row
        .split('|')
        .map(|c| c.trim().replace(',', ""))
        .filter_map(|c| c.parse().ok())
        .collect();
    // triangles, vertices, zero-area triangles, unreferenced vertices, bytes.
    let [triangles, vertices, zero_area, unreferenced, bytes] = cells[..] else {
        panic!("unexpected README row: {row}");
    };
    let arg = path_str(&path);
    if Mesh::load(&path).is_err() {
        eprintln!("the PLY reader cannot read the bunny yet; checking the error only");
        fails(&["info", arg], 1, &["bunny.ply"]);
        return;
    }
    let report = json(&["info", arg, "--json"]);
    assert_eq!(report["triangles"], triangles);
    assert_eq!(report["vertices"], vertices);
    assert_eq!(report["zero_area_triangles"], zero_area);
    assert_eq!(report["unreferenced_vertices"], unreferenced);
    assert_eq!(report["file_bytes"], bytes);
}
