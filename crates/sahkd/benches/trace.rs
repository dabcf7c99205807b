//! Single-thread ray throughput of the traversal: the fixed `front` camera's primary rays
//! (256 x 256) and the shadow rays of their hits, on a procedural scene and on the bunny and
//! dragon when ../shared/scenes is present. `cargo bench -p sahkd --bench trace`; the
//! `trace_throughput` example measures whole 1024 x 1024 pictures against Embree.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use sahkd::render::{Camera, SUN_DIRECTION};
use sahkd::{build, BuildOptions, KdTree, Mesh, Ray};
use std::path::PathBuf;

fn scenes() -> Vec<(String, Mesh)> {
    let mut out = vec![(
        "spd-toys-100k".to_string(),
        sahkd::scenes::generate("spd:toys:100000").expect("procedural scene"),
    )];
    let dir = std::env::var_os("SAHKD_SCENES")
        .map(PathBuf::from)
        .unwrap_or_else(|| {
            PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/scenes")
        });
    for name in ["bunny", "dragon"] {
        match Mesh::load(dir.join(format!("{name}.ply"))) {
            Ok(mesh) => out.push((name.to_string(), mesh)),
            Err(e) => eprintln!("{name} skipped: {e}"),
        }
    }
    out
}

/// The front camera's primary rays, and a shadow ray towards the sun from each hit.
fn rays(tree: &KdTree) -> (Vec<Ray>, Vec<Ray>) {
    let camera = Camera::front(tree.bounds());
    let n = 256;
    let primary: Vec<Ray> = (0..n * n)
        .map(|i| camera.primary_ray(n, n, (i % n) as f32 + 0.5, (i / n) as f32 + 0.5))
        .collect();
    let offset = 1e-5 * tree.bounds().diagonal();
    let shadow = primary
        .iter()
        .filter_map(|r| tree.intersect(r).map(|h| r.at(h.t)))
        .map(|p| Ray::new(p + SUN_DIRECTION * offset, SUN_DIRECTION))
        .collect();
    (primary, shadow)
}

fn bench_trace(c: &mut Criterion) {
    let mut group = c.benchmark_group("trace");
    group.sample_size(10);
    for (scene, mesh) in scenes() {
        let tree = build(&mesh, &BuildOptions::default()).unwrap().tree;
        let (primary, shadow) = rays(&tree);
        group.throughput(Throughput::Elements(primary.len() as u64));
        group.bench_with_input(BenchmarkId::new("primary", &scene), &primary, |b, rays| {
            b.iter(|| rays.iter().filter(|r| tree.intersect(r).is_some()).count())
        });
        group.throughput(Throughput::Elements(shadow.len() as u64));
        group.bench_with_input(BenchmarkId::new("occlusion", &scene), &shadow, |b, rays| {
            b.iter(|| rays.iter().filter(|r| tree.occluded(r)).count())
        });
    }
    group.finish();
}

criterion_group!(benches, bench_trace);
criterion_main!(benches);
