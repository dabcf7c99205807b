//! Build times and tree statistics of the sweep builder on the real scenes.
//!
//! `cargo run --release -p sahkd --example sweep_scenes -- [--runs 3] [--axes all|longest]
//! [--clip on|off|both] bunny dragon_res2 dragon`
//!
//! Scenes are read from `$SAHKD_SCENES` or `../shared/scenes` (relative to the workspace).

use sahkd::{build_triangles, Algorithm, Axes, BuildOptions, Mesh, Triangle};
use std::path::PathBuf;

fn scenes_dir() -> PathBuf {
    std::env::var_os("SAHKD_SCENES")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/scenes"))
}

fn load_ply(path: &std::path::Path) -> Result<Vec<Triangle>, String> {
    Mesh::load(path)
        .map(|m| m.corner_triangles())
        .map_err(|e| e.to_string())
}

/// CPU time of this thread in milliseconds (Linux; 0 elsewhere): on a shared machine it
/// is steadier than wall time.
pub fn thread_cpu_ms() -> f64 {
    std::fs::read_to_string("/proc/thread-self/schedstat")
        .ok()
        .and_then(|s| s.split_whitespace().next()?.parse::<f64>().ok())
        .map_or(0.0, |ns| ns / 1e6)
}

fn main() {
    let mut runs = 3;
    let mut axes = Axes::All;
    let mut clips = vec![true, false];
    let mut names = Vec::new();
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--runs" => runs = args.next().and_then(|v| v.parse().ok()).expect("--runs N"),
            "--axes" => {
                axes = match args.next().as_deref() {
                    Some("all") => Axes::All,
                    Some("longest") => Axes::Longest,
                    _ => panic!("--axes all|longest"),
                }
            }
            "--clip" => {
                clips = match args.next().as_deref() {
                    Some("on") => vec![true],
                    Some("off") => vec![false],
                    Some("both") => vec![true, false],
                    _ => panic!("--clip on|off|both"),
                }
            }
            _ => names.push(a),
        }
    }
    let dir = scenes_dir();
    println!("scene\tclip\taxes\twall ms\tcpu ms (medians of {runs})\tpresort ms\tpeak MB\tsah_cost\tnodes\tleaves\treferences\tmax_depth");
    for name in &names {
        let tris = match load_ply(&dir.join(format!("{name}.ply"))) {
            Ok(t) => t,
            Err(e) => {
                eprintln!("skipping {name}: {e}");
                continue;
            }
        };
        for &clip in &clips {
            let options = BuildOptions {
                algorithm: Algorithm::Sweep,
                axes,
                clip,
                threads: None,
                ..BuildOptions::default()
            };
            let mut times = Vec::new();
            let mut cpu = Vec::new();
            let mut last = None;
            for _ in 0..runs {
                let input = tris.clone();
                let start = thread_cpu_ms();
                let b = build_triangles(input, &options).expect("build");
                cpu.push(thread_cpu_ms() - start);
                times.push(b.report.build_ms);
                last = Some(b);
            }
            times.sort_by(f64::total_cmp);
            cpu.sort_by(f64::total_cmp);
            let b = last.unwrap();
            let s = b.tree.stats(&options.cost);
            println!(
                "{name}\t{}\t{axes:?}\t{:.0}\t{:.0}\t{:.0}\t{:.0}\t{:.3}\t{}\t{}\t{}\t{}",
                if clip { "on" } else { "off" },
                times[times.len() / 2],
                cpu[cpu.len() / 2],
                b.report.presort_ms,
                b.report.peak_working_bytes as f64 / 1e6,
                s.sah_cost,
                s.nodes,
                s.leaves,
                s.references,
                s.max_depth
            );
        }
    }
}
