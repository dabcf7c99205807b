//! Loads a mesh file several times and prints its size and the load times.
//!
//! Usage: `cargo run --release -p sahkd --example load_mesh -- <file.ply|file.obj> [runs]`
//!
//! The first load warms the page cache and is not counted; the median of the next `runs`
//! loads (default 5) is the warm load time of `Mesh::load` (read, parse, validate).

use sahkd::Mesh;
use std::time::Instant;

fn main() {
    let mut args = std::env::args().skip(1);
    let Some(path) = args.next() else {
        eprintln!("usage: load_mesh <file.ply|file.obj> [runs]");
        std::process::exit(2);
    };
    let runs: usize = match args.next().map(|r| r.parse()) {
        None => 5,
        Some(Ok(r)) if r > 0 => r,
        Some(_) => {
            eprintln!("runs must be a positive integer");
            std::process::exit(2);
        }
    };
    let load = || {
        Mesh::load(&path).unwrap_or_else(|e| {
            eprintln!("{e}");
            std::process::exit(1);
        })
    };
    let mesh = load();
    let mut times: Vec<f64> = (0..runs)
        .map(|_| {
            let start = Instant::now();
            let mesh = load();
            let seconds = start.elapsed().as_secs_f64();
            drop(mesh);
            seconds
        })
        .collect();
    println!(
        "{path}: {} triangles, {} vertices",
        mesh.triangles.len(),
        mesh.vertices.len()
    );
    let list: Vec<String> = times.iter().map(|t| format!("{:.1}", t * 1e3)).collect();
    println!("warm loads (ms): {}", list.join(" "));
    times.sort_by(f64::total_cmp);
    println!("median warm load: {:.1} ms", times[times.len() / 2] * 1e3);
}
