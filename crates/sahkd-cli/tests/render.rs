//! `sahkd render`, run as a user would: the PNG it writes decoded and checked pixel by pixel
//! against the brute-force first hit of each camera ray, and every mistake checked to end in
//! one `error:` line with nothing written.

use sahkd::render::{background, normal_colour, to_rgb8, Camera};
use sahkd::trace::brute;
use sahkd::{scenes, Vec3};
use serde_json::Value;
use std::path::Path;
use std::process::{Command, Output};

const SCENE: &str = "spd:tetra:1000";

fn sahkd_in(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_sahkd"))
        .args(args)
        .current_dir(dir)
        .output()
        .expect("cannot start the sahkd binary")
}

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

fn succeeds(dir: &Path, args: &[&str]) -> String {
    let out = sahkd_in(dir, args);
    assert!(
        out.status.success(),
        "sahkd {args:?} failed: {}",
        stderr(&out)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// The names in a directory, sorted.
fn listing(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

fn decode(path: &Path) -> image::RgbImage {
    image::open(path)
        .unwrap_or_else(|e| panic!("{}: not a picture: {e}", path.display()))
        .to_rgb8()
}

fn vector(v: &Value) -> Vec3 {
    let c: [f32; 3] = serde_json::from_value(v.clone()).unwrap();
    Vec3::new(c[0], c[1], c[2])
}

/// Checks every pixel of a normal-shaded picture of `SCENE` against the brute-force first
/// hit of the camera's ray through its centre. Returns how many pixels show the scene.
fn check_against_brute_force(picture: &image::RgbImage, camera: &Camera) -> u32 {
    let triangles = scenes::generate(SCENE).unwrap().corner_triangles();
    let (w, h) = picture.dimensions();
    let mut hits = 0;
    for y in 0..h {
        for x in 0..w {
            let ray = camera.primary_ray(w, h, x as f32 + 0.5, y as f32 + 0.5);
            let expected = match brute::intersect(&triangles, &ray) {
                Some(hit) => {
                    hits += 1;
                    normal_colour(&triangles[hit.prim as usize], &ray)
                }
                None => background(&ray),
            };
            assert_eq!(
                picture.get_pixel(x, y).0,
                to_rgb8(expected),
                "pixel ({x}, {y})"
            );
        }
    }
    hits
}

#[test]
fn an_explicit_camera_renders_the_brute_force_first_hits() {
    let dir = tempfile::tempdir().unwrap();
    let args = [
        "render",
        SCENE,
        "-o",
        "tetra.png",
        "--width",
        "56",
        "--height",
        "40",
        "--shading",
        "normal",
        "--eye",
        "-0.6,1.4,2.2",
        "--look-at",
        "0.5,0.4,0.5",
        "--up",
        "0.1,1,0",
        "--fov",
        "38",
    ];
    let text = succeeds(dir.path(), &args);
    assert!(text.contains("tetra.png"), "output not named: {text}");
    assert!(text.contains("primary rays"), "{text}");
    assert!(text.contains("SAH cost"), "no build statistics: {text}");
    let picture = decode(&dir.path().join("tetra.png"));
    assert_eq!(picture.dimensions(), (56, 40));
    let camera = Camera {
        eye: Vec3::new(-0.6, 1.4, 2.2),
        look_at: Vec3::new(0.5, 0.4, 0.5),
        up: Vec3::new(0.1, 1.0, 0.0),
        fov_y_degrees: 38.0,
    };
    let hits = check_against_brute_force(&picture, &camera);
    assert!(hits > 200 && hits < 56 * 40, "{hits} hits");
    // Only the picture is left: no temporary file.
    assert_eq!(listing(dir.path()), ["tetra.png"]);
}

#[test]
fn the_auto_camera_frames_the_scene_and_the_json_report_says_how() {
    let dir = tempfile::tempdir().unwrap();
    let text = succeeds(
        dir.path(),
        &[
            "render",
            SCENE,
            "-o",
            "auto.png",
            "--width",
            "48",
            "--height",
            "36",
            "--shading",
            "normal",
            "--json",
        ],
    );
    assert_eq!(text.lines().count(), 1, "not one line of JSON: {text}");
    let report: Value = serde_json::from_str(&text).unwrap();
    let triangles = scenes::generate(SCENE).unwrap().triangles.len();
    assert_eq!(report["build"]["triangles"], triangles);
    assert_eq!(report["width"], 48);
    assert_eq!(report["shading"], "normal");
    assert_eq!(report["primary"]["rays"], 48 * 36);
    assert_eq!(report["occlusion"]["rays"], 0);
    assert!(report["primary"]["nodes_per_ray"].as_f64().unwrap() > 0.0);
    for key in ["layout_ms", "render_ms"] {
        assert!(report[key].as_f64().unwrap() >= 0.0, "{key}");
    }
    let c = &report["camera"];
    let camera = Camera {
        eye: vector(&c["eye"]),
        look_at: vector(&c["look_at"]),
        up: vector(&c["up"]),
        fov_y_degrees: serde_json::from_value(c["fov_y_degrees"].clone()).unwrap(),
    };
    let picture = decode(&dir.path().join("auto.png"));
    assert_eq!(picture.dimensions(), (48, 36));
    let hits = check_against_brute_force(&picture, &camera);
    // Framed: the (sparse) tetrahedron covers a fair part of the picture but not all of it.
    assert!(hits > 48 * 36 / 10 && hits < 48 * 36, "{hits} hits");
}

#[test]
fn the_default_output_is_sahkd_png_and_pictures_do_not_depend_on_threads() {
    let dir = tempfile::tempdir().unwrap();
    let small = ["--width", "40", "--height", "30", "--shading", "ao"];
    let text = succeeds(
        dir.path(),
        &[&["render", "spd:toys:600", "--threads", "1"][..], &small].concat(),
    );
    assert!(text.contains("sahkd.png"), "{text}");
    assert!(text.contains("occlusion rays"), "{text}");
    let one = decode(&dir.path().join("sahkd.png"));
    assert_eq!(one.dimensions(), (40, 30));
    succeeds(
        dir.path(),
        &[
            &["render", "spd:toys:600", "--threads", "2", "-o", "two.png"][..],
            &small,
        ]
        .concat(),
    );
    assert!(one == decode(&dir.path().join("two.png")));
}

/// Runs a command that must fail with `status` and one `error:` line naming every one of
/// `fragments`, leaving the directory as it was.
fn fails(args: &[&str], status: i32, fragments: &[&str]) {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("old.png"), b"keep me").unwrap();
    let out = sahkd_in(dir.path(), args);
    let err = stderr(&out);
    assert_eq!(
        out.status.code(),
        Some(status),
        "sahkd {args:?}: wrong exit status; stderr: {err}"
    );
    assert!(!err.contains("panicked"), "sahkd {args:?} panicked: {err}");
    let lines: Vec<&str> = err.lines().collect();
    assert_eq!(lines.len(), 1, "sahkd {args:?}: not one line: {err}");
    assert!(lines[0].starts_with("error: "), "sahkd {args:?}: {err}");
    for f in fragments {
        assert!(lines[0].contains(f), "sahkd {args:?}: '{f}' not in: {err}");
    }
    assert!(out.stdout.is_empty(), "sahkd {args:?} printed on stdout");
    assert_eq!(listing(dir.path()), ["old.png"], "sahkd {args:?}");
    assert_eq!(
        std::fs::read(dir.path().join("old.png")).unwrap(),
        b"keep me"
    );
}

#[test]
fn mistakes_end_in_one_error_line_and_write_nothing() {
    // Every mistake is found before anything is rendered, so the default size costs nothing.
    let r = |extra: &[&'static str]| -> Vec<&'static str> {
        [&["render", "spd:sphere:200"][..], extra].concat()
    };
    // Output: a missing directory, a format other than PNG, a directory.
    fails(
        &r(&["-o", "missing/x.png"]),
        1,
        &["missing", "does not exist"],
    );
    fails(&r(&["-o", "x.jpg"]), 1, &["x.jpg", ".jpg", ".png"]);
    fails(&r(&["-o", "x"]), 1, &["x", ".png"]);
    fails(&r(&["-o", "."]), 1, &["."]);
    // Picture size and samples.
    fails(&r(&["--width", "0"]), 2, &["--width", "0"]);
    fails(&r(&["--height", "-3"]), 2, &["--height"]);
    fails(&r(&["--spp", "0"]), 2, &["--spp"]);
    fails(&r(&["--shading", "phong"]), 2, &["phong", "diffuse"]);
    // Camera.
    fails(&r(&["--eye", "1,2"]), 2, &["--eye", "1,2", "three"]);
    fails(&r(&["--look-at", "a,b,c"]), 2, &["--look-at"]);
    fails(&r(&["--up", "0,1,nan"]), 2, &["--up"]);
    fails(&r(&["--fov", "180"]), 2, &["--fov", "180"]);
    fails(&r(&["--fov", "0"]), 2, &["--fov"]);
    fails(&r(&["--camera", "top"]), 2, &["top", "auto"]);
    fails(
        &r(&["--camera", "front", "--up", "0,0,-2"]),
        1,
        &["up", "parallel"],
    );
    fails(
        &r(&["--eye", "1,1,1", "--look-at", "1,1,1"]),
        1,
        &["looks at"],
    );
    // Input, after the output was checked: the old picture stays untouched.
    fails(
        &["render", "spd:nothing:10", "-o", "old.png"],
        1,
        &["nothing"],
    );
    fails(
        &["render", "missing.ply", "-o", "old.png"],
        1,
        &["missing.ply"],
    );
}
