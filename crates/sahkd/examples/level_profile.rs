//! Profiles one build of a shared-scene PLY or a procedural scene (`spd:KIND:N`): build time
//! (median of runs), tree statistics, a digest of the tree and the per-level report.
//!
//! ```text
//! cargo run --release -p sahkd --example level_profile -- FILE.ply|spd:KIND:N \
//!     [--algorithm level|naive|sweep] [--counting scan|space-tree] [--axes longest|all] \
//!     [--clip on|off] [--threads N] [--runs 3] [--levels]
//! ```

use sahkd::{build, Algorithm, Axes, BuildOptions, Counting};

fn main() {
    if let Err(e) = run() {
        eprintln!("level_profile: {e}");
        std::process::exit(2);
    }
}

fn run() -> Result<(), String> {
    let mut args = std::env::args().skip(1);
    let mut file = None;
    let mut options = BuildOptions::default();
    let mut runs = 3usize;
    let mut levels = false;
    while let Some(a) = args.next() {
        let mut value = || args.next().ok_or(format!("{a} needs a value"));
        match a.as_str() {
            "--algorithm" => {
                options.algorithm = match value()?.as_str() {
                    "level" => Algorithm::Level,
                    "naive" => Algorithm::Naive,
                    "sweep" => Algorithm::Sweep,
                    v => return Err(format!("unknown algorithm {v}")),
                }
            }
            "--counting" => {
                options.counting = match value()?.as_str() {
                    "scan" => Counting::Scan,
                    "space-tree" => Counting::SpaceTree,
                    v => return Err(format!("unknown counting {v}")),
                }
            }
            "--axes" => {
                options.axes = match value()?.as_str() {
                    "longest" => Axes::Longest,
                    "all" => Axes::All,
                    v => return Err(format!("unknown axes {v}")),
                }
            }
            "--clip" => options.clip = value()? == "on",
            "--threads" => {
                options.threads = Some(value()?.parse().map_err(|e| format!("--threads: {e}"))?)
            }
            "--runs" => runs = value()?.parse().map_err(|e| format!("--runs: {e}"))?,
            "--levels" => levels = true,
            _ if file.is_none() => file = Some(a),
            _ => return Err(format!("unexpected argument {a}")),
        }
    }
    let file = file.ok_or("usage: level_profile FILE.ply|spd:KIND:N [options]")?;
    let mesh = if file.starts_with("spd:") {
        sahkd::scenes::generate(&file)?
    } else {
        sahkd::Mesh::load(&file).map_err(|e| e.to_string())?
    };
    let mut times = Vec::new();
    let mut last = None;
    for _ in 0..runs.max(1) {
        let b = build(&mesh, &options).map_err(|e| e.to_string())?;
        times.push(b.report.build_ms);
        last = Some(b);
    }
    let b = last.unwrap();
    times.sort_by(f64::total_cmp);
    let stats = b.tree.stats(&options.cost);
    println!(
        "{file}: {} triangles, {:?} {:?} {:?} clip {} threads {:?}",
        mesh.triangles.len(),
        options.algorithm,
        options.counting,
        options.axes,
        options.clip,
        options.threads
    );
    println!(
        "build ms: median {:.1} of {:?} (presort {:.1}), peak working MB {:.1}",
        times[times.len() / 2],
        times
            .iter()
            .map(|t| (t * 10.0).round() / 10.0)
            .collect::<Vec<_>>(),
        b.report.presort_ms,
        b.report.peak_working_bytes as f64 / 1e6
    );
    println!(
        "tree: SAH {:.3}, nodes {}, leaves {} ({} empty), refs {} (x{:.2}), depth {}, mean leaf {:.2}",
        stats.sah_cost,
        stats.nodes,
        stats.leaves,
        stats.empty_leaves,
        stats.references,
        stats.duplication,
        stats.max_depth,
        stats.mean_leaf_size
    );
    // A digest of the node and reference arrays: equal digests before and after a change to
    // a builder say it still writes the same tree.
    let digest = {
        use std::hash::{Hash, Hasher};
        let mut h = std::collections::hash_map::DefaultHasher::new();
        b.tree.nodes().hash(&mut h);
        b.tree.refs().hash(&mut h);
        h.finish()
    };
    println!("tree digest {digest:016x}");
    let sum = |f: &dyn Fn(&sahkd::builders::LevelReport) -> f64| -> f64 {
        b.report.levels.iter().map(f).sum()
    };
    println!(
        "phases ms: candidates {:.1}, space trees {:.1}, counting {:.1}, decision {:.1}, partition {:.1}; candidates {}, walk steps {}, cut {}",
        sum(&|l| l.ms.candidates),
        sum(&|l| l.ms.space_trees),
        sum(&|l| l.ms.counting),
        sum(&|l| l.ms.decision),
        sum(&|l| l.ms.partition),
        sum(&|l| l.candidates as f64),
        sum(&|l| l.walk_steps as f64),
        sum(&|l| l.cut_primitives as f64),
    );
    if levels {
        println!(
            "depth nodes leaves refs candidates walk_steps cut | ms: cand trees count decide part"
        );
        for l in &b.report.levels {
            println!(
                "{:3} {:7} {:7} {:8} {:8} {:10} {:8} | {:6.2} {:6.2} {:6.2} {:6.2} {:6.2}",
                l.depth,
                l.nodes,
                l.leaves,
                l.references,
                l.candidates,
                l.walk_steps,
                l.cut_primitives,
                l.ms.candidates,
                l.ms.space_trees,
                l.ms.counting,
                l.ms.decision,
                l.ms.partition
            );
        }
    }
    Ok(())
}
