//! Build times and tree statistics of the sweep builder on the real scenes.
//!
//! `cargo run --release -p sahkd --example sweep_scenes -- [--runs 3] [--axes all|longest]
//! [--clip on|off|both] bunny dragon_res2 dragon`
//!
//! Scenes are read from `$SAHKD_SCENES` or `../shared/scenes` (relative to the workspace).
//! The binary PLY layout is the one described in that folder's README; this small reader
//! stands in until the library's reader lands.

use sahkd::{build_triangles, Algorithm, Axes, BuildOptions, Triangle, Vec3};
use std::path::PathBuf;

fn scenes_dir() -> PathBuf {
    std::env::var_os("SAHKD_SCENES")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/scenes"))
}

/// Reads the scenes' binary little-endian PLY: float x, y, z vertices; uchar-int faces.
fn load_ply(path: &std::path::Path) -> Result<Vec<Triangle>, String> {
    let bytes = std::fs::read(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let end = b"end_header\n";
    let header_len = bytes
        .windows(end.len())
        .position(|w| w == end)
        .ok_or("no end_header")?
        + end.len();
    let header = std::str::from_utf8(&bytes[..header_len]).map_err(|e| e.to_string())?;
    let count = |element: &str| -> Result<usize, String> {
        header
            .lines()
            .find_map(|l| l.strip_prefix(&format!("element {element} ")))
            .ok_or(format!("no {element} element"))?
            .trim()
            .parse()
            .map_err(|e| format!("{e}"))
    };
    let (nv, nf) = (count("vertex")?, count("face")?);
    let body = &bytes[header_len..];
    if body.len() < nv * 12 + nf * 13 {
        return Err("file shorter than its header says".into());
    }
    let f32_at = |o: usize| f32::from_le_bytes(body[o..o + 4].try_into().unwrap());
    let verts: Vec<Vec3> = (0..nv)
        .map(|i| Vec3::new(f32_at(i * 12), f32_at(i * 12 + 4), f32_at(i * 12 + 8)))
        .collect();
    let faces = &body[nv * 12..];
    (0..nf)
        .map(|f| {
            let rec = &faces[f * 13..f * 13 + 13];
            if rec[0] != 3 {
                return Err(format!("face {f} is not a triangle"));
            }
            let idx = |k: usize| u32::from_le_bytes(rec[1 + 4 * k..5 + 4 * k].try_into().unwrap());
            let corner = |k: usize| {
                verts
                    .get(idx(k) as usize)
                    .copied()
                    .ok_or(format!("face {f} index out of range"))
            };
            Ok([corner(0)?, corner(1)?, corner(2)?])
        })
        .collect()
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
