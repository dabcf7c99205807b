//! Times opening a saved tree (`KdTree::load`): wall time, and the CPU time of the process
//! (all threads, from /proc/self/stat on Linux), which a busy machine does not inflate the
//! way it does the wall time. `cargo run --release --example open_tree -- TREE.sahkd [RUNS]`

use std::time::Instant;

/// User plus system CPU seconds of this process so far (Linux; 0 elsewhere).
fn cpu_seconds() -> f64 {
    let Ok(stat) = std::fs::read_to_string("/proc/self/stat") else {
        return 0.0;
    };
    // Fields after the command name (which is in parentheses and may hold spaces).
    let after = &stat[stat.rfind(')').map_or(0, |i| i + 2)..];
    let fields: Vec<&str> = after.split_whitespace().collect();
    let ticks = |k: usize| {
        fields
            .get(k)
            .and_then(|f| f.parse::<f64>().ok())
            .unwrap_or(0.0)
    };
    // utime and stime are fields 14 and 15 of the line, 12 and 13 after the name; the clock
    // tick is 100 Hz on Linux.
    (ticks(11) + ticks(12)) / 100.0
}

fn main() {
    let mut args = std::env::args().skip(1);
    let path = args.next().expect("usage: open_tree TREE.sahkd [RUNS]");
    let runs: usize = args
        .next()
        .map_or(3, |r| r.parse().expect("RUNS is a number"));
    for _ in 0..runs {
        let (wall, cpu) = (Instant::now(), cpu_seconds());
        let (tree, _) = sahkd::KdTree::load(path.as_ref()).unwrap_or_else(|e| panic!("{e}"));
        let wall = wall.elapsed().as_secs_f64();
        let cpu = cpu_seconds() - cpu;
        println!(
            "{} triangles, {} nodes: opened in {wall:.3} s wall, {cpu:.2} s CPU",
            tree.triangles().len(),
            tree.nodes().len()
        );
        drop(tree);
    }
}
