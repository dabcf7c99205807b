//! How the sweep builder's time grows with the scene: O(N log N) means each doubling of the
//! triangle count costs a little over 2x.
//!
//! `cargo run --release -p sahkd --example sweep_scaling -- [--base 100000] [--runs 3]
//! [--clip on|off] [--axes all|longest]`
//!
//! Two procedural scenes at N, 2N, 4N and 8N triangles: a UV sphere, and a soup of random
//! triangles whose size shrinks as N^(-1/3) so that the overlap per triangle stays the same.

use sahkd::{build_triangles, Algorithm, Axes, BuildOptions, Triangle, Vec3};

/// A UV sphere of radius 1 with about `n` triangles.
fn sphere(n: usize) -> Vec<Triangle> {
    let k = ((n / 2) as f64).sqrt().round().max(3.0) as usize;
    let vertex = |i: usize, j: usize| {
        let theta = std::f32::consts::PI * i as f32 / k as f32;
        let phi = 2.0 * std::f32::consts::PI * (j % k) as f32 / k as f32;
        Vec3::new(
            theta.sin() * phi.cos(),
            theta.cos(),
            theta.sin() * phi.sin(),
        )
    };
    let mut tris = Vec::with_capacity(2 * k * k);
    for i in 0..k {
        for j in 0..k {
            let (a, b) = (vertex(i, j), vertex(i, j + 1));
            let (c, d) = (vertex(i + 1, j), vertex(i + 1, j + 1));
            tris.push([a, c, b]);
            tris.push([b, c, d]);
        }
    }
    tris
}

/// `n` random triangles in the unit cube, edges about 2 / cbrt(n) long.
fn soup(n: usize) -> Vec<Triangle> {
    let mut seed = 0x2545_f491_4f6c_dd1du64;
    let mut unit = move || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        (seed >> 40) as f32 / (1u64 << 24) as f32
    };
    let size = 2.0 / (n as f32).cbrt();
    (0..n)
        .map(|_| {
            let c = Vec3::new(unit(), unit(), unit());
            let mut corner = || c + Vec3::new(unit() - 0.5, unit() - 0.5, unit() - 0.5) * size;
            [corner(), corner(), corner()]
        })
        .collect()
}

/// CPU time of this thread in milliseconds (Linux; 0 elsewhere).
fn thread_cpu_ms() -> f64 {
    std::fs::read_to_string("/proc/thread-self/schedstat")
        .ok()
        .and_then(|s| s.split_whitespace().next()?.parse::<f64>().ok())
        .map_or(0.0, |ns| ns / 1e6)
}

fn main() {
    let mut base = 100_000;
    let mut runs = 3;
    let mut options = BuildOptions {
        algorithm: Algorithm::Sweep,
        axes: Axes::All,
        clip: true,
        threads: None,
        ..BuildOptions::default()
    };
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        let value = args.next().unwrap_or_default();
        match a.as_str() {
            "--base" => base = value.parse().expect("--base N"),
            "--runs" => runs = value.parse().expect("--runs N"),
            "--clip" => options.clip = value == "on",
            "--axes" => {
                options.axes = if value == "all" {
                    Axes::All
                } else {
                    Axes::Longest
                }
            }
            _ => panic!("unknown argument {a}"),
        }
    }
    println!(
        "axes {:?}, clip {}; medians of {runs} runs",
        options.axes, options.clip
    );
    println!("scene\ttriangles\tcpu ms\twall ms\tcpu ratio to previous\treferences\tnodes");
    for (name, make) in [
        ("sphere", sphere as fn(usize) -> Vec<Triangle>),
        ("soup", soup),
    ] {
        let mut previous = None;
        for scale in [1, 2, 4, 8] {
            let tris = make(base * scale);
            let (mut cpu, mut wall) = (Vec::new(), Vec::new());
            let mut last = None;
            for _ in 0..runs {
                let input = tris.clone();
                let start = thread_cpu_ms();
                let b = build_triangles(input, &options).expect("build");
                cpu.push(thread_cpu_ms() - start);
                wall.push(b.report.build_ms);
                last = Some(b);
            }
            cpu.sort_by(f64::total_cmp);
            wall.sort_by(f64::total_cmp);
            let (cpu, wall) = (cpu[runs / 2], wall[runs / 2]);
            let stats = last.unwrap().tree.stats(&options.cost);
            let ratio = previous.map_or(String::from("-"), |p: f64| format!("{:.2}", cpu / p));
            println!(
                "{name}\t{}\t{cpu:.0}\t{wall:.0}\t{ratio}\t{}\t{}",
                tris.len(),
                stats.references,
                stats.nodes
            );
            previous = Some(cpu);
        }
    }
}
