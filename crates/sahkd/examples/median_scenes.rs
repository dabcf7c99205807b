//! Build time and SAH cost of the median builder against the sweep builder on real scenes.
//!
//! `cargo run --release -p sahkd --example median_scenes -- [--runs 3] [--threads 1,2]
//! [--axes all|longest] [--clip on|off] [--large-node 64] bunny dragon_res2 dragon`
//!
//! Scenes are read from `$SAHKD_SCENES` or `../shared/scenes` (relative to the workspace).
//! Each configuration is built `runs` times in turn with the other builder, so that both see
//! the same machine load; the median wall time is printed.

use sahkd::{build, Algorithm, Axes, BuildOptions, Mesh};
use std::path::PathBuf;

fn scenes_dir() -> PathBuf {
    std::env::var_os("SAHKD_SCENES")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/scenes"))
}

fn median_of(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() {
    let mut runs = 3;
    let mut threads = vec![1, 2];
    let mut base = BuildOptions {
        axes: Axes::All,
        ..BuildOptions::default()
    };
    let mut names = Vec::new();
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        let mut value = || args.next().unwrap_or_else(|| panic!("{a} needs a value"));
        match a.as_str() {
            "--runs" => runs = value().parse().expect("--runs N"),
            "--threads" => {
                threads = value()
                    .split(',')
                    .map(|t| t.parse().expect("--threads 1,2,..."))
                    .collect()
            }
            "--axes" => {
                base.axes = match value().as_str() {
                    "all" => Axes::All,
                    "longest" => Axes::Longest,
                    _ => panic!("--axes all|longest"),
                }
            }
            "--clip" => base.clip = value() == "on",
            "--large-node" => base.median_large_node = value().parse().expect("--large-node N"),
            _ => names.push(a),
        }
    }
    let dir = scenes_dir();
    println!(
        "axes {:?}, clip {}, large node {}, median of {runs} runs",
        base.axes, base.clip, base.median_large_node
    );
    println!("scene\ttriangles\tthreads\talgorithm\tbuild ms\tmin-max ms\tsah_cost\tnodes\treferences\tmax_depth");
    for name in &names {
        let mesh = match Mesh::load(dir.join(format!("{name}.ply"))) {
            Ok(m) => m,
            Err(e) => {
                eprintln!("skipping {name}: {e}");
                continue;
            }
        };
        for &t in &threads {
            let algorithms = [Algorithm::Sweep, Algorithm::Median];
            let options = algorithms.map(|algorithm| BuildOptions {
                algorithm,
                threads: Some(t),
                ..base
            });
            let mut times = [Vec::new(), Vec::new()];
            let mut last = [None, None];
            for _ in 0..runs {
                for (k, o) in options.iter().enumerate() {
                    let b = build(&mesh, o).expect("build");
                    times[k].push(b.report.build_ms);
                    last[k] = Some(b);
                }
            }
            for k in 0..2 {
                let b = last[k].take().unwrap();
                let s = b.tree.stats(&options[k].cost);
                let (lo, hi) = times[k]
                    .iter()
                    .fold((f64::MAX, 0f64), |(lo, hi), &x| (lo.min(x), hi.max(x)));
                println!(
                    "{name}\t{}\t{t}\t{:?}\t{:.0}\t{lo:.0}-{hi:.0}\t{:.3}\t{}\t{}\t{}",
                    mesh.triangles.len(),
                    options[k].algorithm,
                    median_of(times[k].clone()),
                    s.sah_cost,
                    s.nodes,
                    s.references,
                    s.max_depth
                );
            }
        }
    }
}
