//! Build time of every builder on a small procedural scene (naive included), and of the fast
//! builders on a larger one and on the bunny when ../shared/scenes is present.
//! `cargo bench -p sahkd --bench build`; compare builders as ratios of one run.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use sahkd::{build, Algorithm, BuildOptions, Counting, Mesh};
use std::path::PathBuf;

fn scenes() -> Vec<(String, Mesh)> {
    let mut out = vec![(
        "spd-sphere-100k".to_string(),
        sahkd::scenes::generate("spd:sphere:100000").expect("procedural scene"),
    )];
    let dir = std::env::var_os("SAHKD_SCENES")
        .map(PathBuf::from)
        .unwrap_or_else(|| {
            PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/scenes")
        });
    match Mesh::load(dir.join("bunny.ply")) {
        Ok(mesh) => out.push(("bunny".to_string(), mesh)),
        Err(e) => eprintln!("bunny skipped: {e}"),
    }
    out
}

/// Small enough for the naive builder (O(n^2) per node), so every builder runs on it.
const EVERY_BUILDER_SCENE: &str = "spd:toys:10000";

fn builders() -> Vec<(&'static str, BuildOptions)> {
    let level = |counting| BuildOptions {
        algorithm: Algorithm::Level,
        counting,
        ..BuildOptions::default()
    };
    vec![
        ("sweep", BuildOptions::sweep()),
        ("level-scan", level(Counting::Scan)),
        ("level-space-tree", level(Counting::SpaceTree)),
        ("paper", BuildOptions::paper()),
        (
            "median",
            BuildOptions {
                algorithm: Algorithm::Median,
                ..BuildOptions::default()
            },
        ),
    ]
}

/// The naive builder: the level framework with brute-force counting.
fn naive() -> (&'static str, BuildOptions) {
    (
        "naive",
        BuildOptions {
            algorithm: Algorithm::Naive,
            ..BuildOptions::default()
        },
    )
}

fn bench_builds(c: &mut Criterion) {
    let mut group = c.benchmark_group("build");
    group.sample_size(10);
    let toys = sahkd::scenes::generate(EVERY_BUILDER_SCENE).expect("procedural scene");
    for (name, options) in builders().into_iter().chain([naive()]) {
        group.bench_with_input(BenchmarkId::new(name, "spd-toys-10k"), &toys, |b, mesh| {
            b.iter(|| build(mesh, &options).unwrap())
        });
    }
    for (scene, mesh) in scenes() {
        for (name, options) in builders() {
            group.bench_with_input(BenchmarkId::new(name, &scene), &mesh, |b, mesh| {
                b.iter(|| build(mesh, &options).unwrap())
            });
        }
    }
    group.finish();
}

criterion_group!(benches, bench_builds);
criterion_main!(benches);
