//! The C and C++ examples and the hostile-caller test, compiled with the system's `cc` and
//! `c++` against the built libsahkd (found through its sahkd.pc), run with AddressSanitizer
//! (leaks and invalid accesses fail the run) where the compiler has it, and their answers
//! compared bit for bit with the Rust library's on the same rays.
//!
//! `SAHKD_C_SANITIZE=0` compiles without the sanitizer; under CI a compiler without it fails
//! the test instead of skipping the sanitizer.

use sahkd::{build, BuildOptions, KdTree, Mesh, Ray, Vec3};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

/// target/<profile>, where cargo puts libsahkd.so and build.rs sahkd.pc. `cargo test` builds
/// only what Rust links (not a cdylib), so the library is built here, once, with the test's
/// own profile: the C programs always link the sources under test.
fn lib_dir() -> PathBuf {
    static BUILT: OnceLock<PathBuf> = OnceLock::new();
    BUILT
        .get_or_init(|| {
            let exe = std::env::current_exe().unwrap();
            let dir = exe.parent().unwrap().parent().unwrap().to_path_buf();
            let mut cargo = Command::new(std::env::var_os("CARGO").unwrap_or("cargo".into()));
            cargo.args(["build", "--quiet", "-p", "sahkd-c"]);
            if dir.file_name().is_some_and(|n| n == "release") {
                cargo.arg("--release");
            }
            let status = cargo.status().expect("cannot run cargo");
            assert!(status.success(), "cargo build -p sahkd-c failed");
            assert!(
                dir.join("libsahkd.so").is_file() || dir.join("libsahkd.dylib").is_file(),
                "no libsahkd in {}",
                dir.display()
            );
            dir
        })
        .clone()
}

/// The compile and link flags `pkg-config --cflags --libs sahkd` gives for this build.
fn pkg_config_flags() -> Vec<String> {
    let out = Command::new("pkg-config")
        .args(["--cflags", "--libs", "sahkd"])
        .env("PKG_CONFIG_PATH", lib_dir())
        .output();
    let flags = match out {
        Ok(out) if out.status.success() => String::from_utf8(out.stdout).unwrap(),
        _ => {
            // Without pkg-config, the flags sahkd.pc holds, as the README spells them.
            println!("pkg-config not found; using the same flags by hand");
            format!(
                "-I{} -L{} -lsahkd",
                Path::new(env!("CARGO_MANIFEST_DIR"))
                    .join("include")
                    .display(),
                lib_dir().display()
            )
        }
    };
    assert!(flags.contains("-lsahkd"), "{flags}");
    flags.split_whitespace().map(String::from).collect()
}

fn sanitize() -> Vec<String> {
    if std::env::var("SAHKD_C_SANITIZE").as_deref() == Ok("0") {
        return vec![];
    }
    let dir = tempfile::tempdir().unwrap();
    let src = dir.path().join("probe.c");
    std::fs::write(&src, "int main(void) { return 0; }\n").unwrap();
    let flags = ["-fsanitize=address", "-fno-omit-frame-pointer"];
    let works = Command::new("cc")
        .args(flags)
        .arg(&src)
        .arg("-o")
        .arg(dir.path().join("probe"))
        .status()
        .is_ok_and(|s| s.success());
    if !works {
        assert!(
            std::env::var_os("CI").is_none(),
            "cc has no AddressSanitizer (set SAHKD_C_SANITIZE=0 to run without it)"
        );
        println!("cc has no AddressSanitizer: running the C programs without it");
        return vec![];
    }
    flags.map(String::from).to_vec()
}

/// Compiles one source of this crate with `compiler` into `dir`.
fn compile(compiler: &str, source: &str, dir: &Path, extra: &[&str]) -> PathBuf {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join(source);
    let exe = dir.join(src.file_stem().unwrap());
    let lib = lib_dir();
    let out = Command::new(compiler)
        .args(["-O1", "-g", "-Wall", "-Wextra", "-Werror"])
        .args(extra)
        .args(sanitize())
        .arg(&src)
        .arg("-o")
        .arg(&exe)
        .args(pkg_config_flags())
        .arg(format!("-Wl,-rpath,{}", lib.display()))
        .args(["-lm", "-lpthread"])
        .output()
        .unwrap_or_else(|e| panic!("cannot run {compiler}: {e}"));
    assert!(
        out.status.success(),
        "{compiler} {source} failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    exe
}

/// Runs a compiled program; a sanitizer report fails it (non-zero exit).
fn run(exe: &Path, args: &[&Path]) -> String {
    let out = Command::new(exe)
        .args(args)
        // Leaks are errors; rayon's worker threads live until exit and are not leaks.
        .env(
            "ASAN_OPTIONS",
            "detect_leaks=1:abort_on_error=0:exitcode=23",
        )
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(
        out.status.success(),
        "{} {args:?} failed ({}):\n{stdout}\n{}",
        exe.display(),
        out.status,
        String::from_utf8_lossy(&out.stderr)
    );
    stdout
}

/// An ASCII PLY of a mesh: the C programs read it, and so does the Rust side.
fn write_ply(mesh: &Mesh, path: &Path) {
    let mut f = std::io::BufWriter::new(std::fs::File::create(path).unwrap());
    write!(
        f,
        "ply\nformat ascii 1.0\nelement vertex {}\nproperty float x\nproperty float y\n\
         property float z\nelement face {}\nproperty list uchar int vertex_indices\nend_header\n",
        mesh.vertices.len(),
        mesh.triangles.len()
    )
    .unwrap();
    for v in &mesh.vertices {
        writeln!(f, "{} {} {}", v[0], v[1], v[2]).unwrap();
    }
    for t in &mesh.triangles {
        writeln!(f, "3 {} {} {}", t[0], t[1], t[2]).unwrap();
    }
}

/// Reads a raw array the C programs dumped (`#[repr(C)]` records of `N` 4-byte words).
fn words<const N: usize>(path: &Path) -> Vec<[u32; N]> {
    let bytes = std::fs::read(path).unwrap();
    assert_eq!(bytes.len() % (4 * N), 0, "{}", path.display());
    bytes
        .chunks_exact(4 * N)
        .map(|c| {
            std::array::from_fn(|i| u32::from_ne_bytes(c[4 * i..4 * i + 4].try_into().unwrap()))
        })
        .collect()
}

fn ray(w: &[u32; 8]) -> Ray {
    let f = |i: usize| f32::from_bits(w[i]);
    Ray::new(Vec3::new(f(0), f(1), f(2)), Vec3::new(f(4), f(5), f(6))).with_range(f(3), f(7))
}

/// The dumped camera and shadow rays answered by the Rust library, compared bit for bit.
fn check_dump(tree: &KdTree, dump: &Path) -> (usize, usize) {
    let file = |s: &str| PathBuf::from(format!("{}.{s}", dump.display()));
    let rays = words::<8>(&file("rays"));
    let hits = words::<5>(&file("hits"));
    assert_eq!(rays.len(), hits.len());
    let mut hit_count = 0;
    for (i, (r, h)) in rays.iter().zip(&hits).enumerate() {
        let want = match tree.intersect(&ray(r)) {
            Some(hit) => {
                hit_count += 1;
                [
                    hit.t.to_bits(),
                    hit.u.to_bits(),
                    hit.v.to_bits(),
                    hit.prim,
                    0,
                ]
            }
            None => [f32::INFINITY.to_bits(), 0, 0, u32::MAX, u32::MAX],
        };
        assert_eq!(*h, want, "ray {i}: C answered {h:?}, Rust {want:?}");
    }
    let shadow = words::<8>(&file("shadow_rays"));
    let shadowed = std::fs::read(file("shadowed")).unwrap();
    assert_eq!(shadow.len(), shadowed.len());
    let mut dark = 0;
    for (i, (r, &s)) in shadow.iter().zip(&shadowed).enumerate() {
        let want = tree.occluded(&ray(r));
        assert_eq!(s, want as u8, "shadow ray {i}");
        dark += want as usize;
    }
    (hit_count, dark)
}

fn meshes(dir: &Path) -> Vec<PathBuf> {
    let generated = dir.join("toys.ply");
    write_ply(
        &sahkd::scenes::generate("spd:toys:20000").unwrap(),
        &generated,
    );
    let mut meshes = vec![generated];
    let scenes = match std::env::var_os("SAHKD_SCENES") {
        Some(d) => PathBuf::from(d),
        None => PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/scenes"),
    };
    let bunny = scenes.join("bunny.ply");
    if bunny.is_file() {
        meshes.push(bunny);
    } else {
        println!("skipping bunny: no {} (set SAHKD_SCENES)", bunny.display());
    }
    meshes
}

#[test]
fn c_example_renders_and_agrees_with_rust_bit_for_bit() {
    let dir = tempfile::tempdir().unwrap();
    let exe = compile("cc", "examples/render.c", dir.path(), &["-std=c11"]);
    for mesh in meshes(dir.path()) {
        let ppm = dir.path().join("out.ppm");
        let dump = dir.path().join("render.dump");
        let (w, h) = (Path::new("96"), Path::new("64"));
        let said = run(&exe, &[&mesh, &ppm, w, h, &dump]);
        let tree = build(&Mesh::load(&mesh).unwrap(), &BuildOptions::default())
            .unwrap()
            .tree;
        let (hits, dark) = check_dump(&tree, &dump);
        assert!(
            hits > 96 * 64 / 10 && dark > 0,
            "{}: {hits} hits, {dark} shadowed",
            mesh.display()
        );
        assert!(said.contains(&format!("{hits} hits")), "{said}");
        let picture = std::fs::read(&ppm).unwrap();
        assert!(picture.starts_with(b"P6\n96 64\n255\n"));
        assert_eq!(picture.len(), "P6\n96 64\n255\n".len() + 3 * 96 * 64);
    }
}

#[test]
fn cpp_example_on_several_threads_agrees_with_rust_bit_for_bit() {
    let dir = tempfile::tempdir().unwrap();
    let exe = compile(
        "c++",
        "examples/threads.cpp",
        dir.path(),
        &["-std=c++17", "-pthread"],
    );
    for mesh in meshes(dir.path()) {
        let tree = build(&Mesh::load(&mesh).unwrap(), &BuildOptions::default())
            .unwrap()
            .tree;
        for threads in ["1", "4"] {
            let dump = dir.path().join(format!("threads{threads}.dump"));
            let said = run(&exe, &[&mesh, Path::new(threads), &dump]);
            let (hits, dark) = check_dump(&tree, &dump);
            assert!(hits > 0, "{}: no hits", mesh.display());
            assert!(
                said.contains(&format!("{hits} hits, {dark} in shadow")),
                "{said}"
            );
        }
    }
}

#[test]
fn hostile_callers_get_statuses_not_crashes() {
    let dir = tempfile::tempdir().unwrap();
    let exe = compile(
        "cc",
        "tests/c/hostile.c",
        dir.path(),
        &["-std=c11", "-pthread"],
    );
    let said = run(&exe, &[]);
    assert!(said.contains("all checks passed"), "{said}");
}
