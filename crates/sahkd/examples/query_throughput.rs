//! Point-query throughput on one mesh: closest point, signed distance and occupancy.
//!
//! ```text
//! cargo run --release -p sahkd --example query_throughput -- MESH [--points 1000000]
//!     [--threads 1,2] [--repeat 3] [--check 200] [--dump DIR]
//! ```
//! The points (fixed seed) are a mix: a third within 1 % of the bounding-box
//! diagonal of the surface (a random point of a random triangle moved by up to that much in
//! a random direction), a third in the bounding box grown by 20 % about its centre, a third in
//! a box three times the bounding box's size. Each query runs `--repeat` times in a rayon pool
//! of each `--threads` count (`closest_point_batch`, `signed_distance_batch` and
//! `contains_batch` with the default parity test); the median and min-max Mpoints/s are
//! printed. `--check K` compares K of the points' closest points, single and batched, with
//! the brute force first.
//! `--dump DIR` writes the mesh as read (`vertices.npy` (V, 3) float32 and `faces.npy` (F, 3)
//! int32: face `i` is the tree's triangle `i`), `triangles.npy` (F, 3, 3) and `points.npy`
//! (N, 3) as float32, and sahkd's answers (`distance.npy`, `signed.npy` float64, `inside.npy` as float32 0/1), for
//! `scripts/query_compare.py`.

use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use sahkd::query::brute;
use sahkd::{BuildOptions, InsideTest, KdTree, Mesh, Vec3};
use std::io::Write;
use std::path::Path;
use std::time::Instant;

struct Args {
    mesh: String,
    points: usize,
    threads: Vec<usize>,
    repeat: usize,
    check: usize,
    dump: Option<String>,
}

fn parse_args() -> Result<Args, String> {
    let mut args = Args {
        mesh: String::new(),
        points: 1_000_000,
        threads: vec![1, 2],
        repeat: 3,
        check: 200,
        dump: None,
    };
    let mut it = std::env::args().skip(1);
    while let Some(a) = it.next() {
        let mut value = |name: &str| it.next().ok_or(format!("{name} needs a value"));
        let number = |s: String, name: &str| {
            s.parse::<usize>()
                .map_err(|_| format!("{name}: '{s}' is not a whole number"))
        };
        match a.as_str() {
            "--points" => args.points = number(value("--points")?, "--points")?,
            "--repeat" => args.repeat = number(value("--repeat")?, "--repeat")?.max(1),
            "--check" => args.check = number(value("--check")?, "--check")?,
            "--dump" => args.dump = Some(value("--dump")?),
            "--threads" => {
                args.threads = value("--threads")?
                    .split(',')
                    .map(|t| number(t.to_string(), "--threads"))
                    .collect::<Result<_, _>>()?
            }
            _ if a.starts_with("--") => return Err(format!("unknown option {a}")),
            _ => args.mesh = a,
        }
    }
    if args.mesh.is_empty() {
        return Err("usage: query_throughput MESH [--points N] [--threads 1,2] [--repeat 3] [--check K] [--dump DIR]".into());
    }
    Ok(args)
}

/// The mix of query points (see the module documentation).
fn make_points(tree: &KdTree, n: usize) -> Vec<Vec3> {
    let mut rng = StdRng::seed_from_u64(16);
    let b = tree.bounds();
    let (centre, ext) = (b.centre(), b.extent());
    let diag = b.diagonal();
    let tris = tree.triangles();
    let in_box = |rng: &mut StdRng, half: f32| {
        Vec3(std::array::from_fn(|a| {
            centre[a] + rng.random_range(-half..=half) * ext[a]
        }))
    };
    (0..n)
        .map(|i| match i % 3 {
            0 => {
                let t = tris[rng.random_range(0..tris.len())];
                let (mut u, mut v): (f32, f32) = (rng.random(), rng.random());
                if u + v > 1.0 {
                    (u, v) = (1.0 - u, 1.0 - v);
                }
                let on = t[0] + (t[1] - t[0]) * u + (t[2] - t[0]) * v;
                let dir = loop {
                    let d = Vec3(std::array::from_fn(|_| rng.random_range(-1.0f32..=1.0)));
                    let l = d.length();
                    if l > 1e-3 && l <= 1.0 {
                        break d * (1.0 / l);
                    }
                };
                on + dir * (rng.random_range(0.0..=0.01f32) * diag)
            }
            1 => in_box(&mut rng, 0.6),
            _ => in_box(&mut rng, 1.5),
        })
        .collect()
}

/// One timed batch call.
type Query<'a> = Box<dyn Fn() + Sync + 'a>;

fn time_median(repeat: usize, mut f: impl FnMut()) -> (f64, f64, f64) {
    let mut times: Vec<f64> = (0..repeat)
        .map(|_| {
            let start = Instant::now();
            f();
            start.elapsed().as_secs_f64()
        })
        .collect();
    times.sort_by(f64::total_cmp);
    (times[times.len() / 2], times[0], times[times.len() - 1])
}

fn write_npy(path: &Path, descr: &str, shape: &[usize], bytes: &[u8]) -> std::io::Result<()> {
    let dims: Vec<String> = shape.iter().map(|d| d.to_string()).collect();
    let mut header = format!(
        "{{'descr': '{descr}', 'fortran_order': False, 'shape': ({},), }}",
        dims.join(", ")
    );
    while (10 + header.len() + 1) % 64 != 0 {
        header.push(' ');
    }
    header.push('\n');
    let mut file = std::io::BufWriter::new(std::fs::File::create(path)?);
    file.write_all(b"\x93NUMPY\x01\x00")?;
    file.write_all(&(header.len() as u16).to_le_bytes())?;
    file.write_all(header.as_bytes())?;
    file.write_all(bytes)?;
    file.flush()
}

fn f32_bytes(x: impl Iterator<Item = f32>) -> Vec<u8> {
    x.flat_map(f32::to_le_bytes).collect()
}
fn f64_bytes(x: impl Iterator<Item = f64>) -> Vec<u8> {
    x.flat_map(f64::to_le_bytes).collect()
}

fn dump(dir: &str, mesh: &Mesh, tree: &KdTree, points: &[Vec3]) -> std::io::Result<()> {
    let dir = Path::new(dir);
    std::fs::create_dir_all(dir)?;
    write_npy(
        &dir.join("vertices.npy"),
        "<f4",
        &[mesh.vertices.len(), 3],
        &f32_bytes(mesh.vertices.iter().flatten().copied()),
    )?;
    let faces = mesh.triangles.iter().flatten().map(|&i| i as i32);
    write_npy(
        &dir.join("faces.npy"),
        "<i4",
        &[mesh.triangles.len(), 3],
        &faces.flat_map(i32::to_le_bytes).collect::<Vec<u8>>(),
    )?;
    let tris = tree.triangles();
    let corners = tris.iter().flat_map(|t| t.iter().flat_map(|v| v.0));
    write_npy(
        &dir.join("triangles.npy"),
        "<f4",
        &[tris.len(), 3, 3],
        &f32_bytes(corners),
    )?;
    let pts = points.iter().flat_map(|p| p.0);
    write_npy(
        &dir.join("points.npy"),
        "<f4",
        &[points.len(), 3],
        &f32_bytes(pts),
    )?;
    let distance = tree.distance_batch(points);
    write_npy(
        &dir.join("distance.npy"),
        "<f8",
        &[points.len()],
        &f64_bytes(distance.into_iter()),
    )?;
    let signed = tree.signed_distance_batch(points, InsideTest::Parity);
    write_npy(
        &dir.join("signed.npy"),
        "<f8",
        &[points.len()],
        &f64_bytes(signed.into_iter()),
    )?;
    let inside = tree.contains_batch(points, InsideTest::Parity);
    let inside = inside.into_iter().map(|b| b as u8 as f32);
    write_npy(
        &dir.join("inside.npy"),
        "<f4",
        &[points.len()],
        &f32_bytes(inside),
    )
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args = parse_args()?;
    let mesh = Mesh::load(&args.mesh)?;
    let start = Instant::now();
    let tree = sahkd::build(&mesh, &BuildOptions::default())?.tree;
    tree.prepare_trace();
    println!(
        "{}: {} triangles, built in {:.0} ms; {} points",
        args.mesh,
        tree.triangles().len(),
        start.elapsed().as_secs_f64() * 1e3,
        args.points
    );
    let points = make_points(&tree, args.points);
    if let Some(step) = points.len().checked_div(args.check) {
        let step = step.max(1);
        let batch = tree.closest_point_batch(&points);
        for (i, &p) in points.iter().enumerate().step_by(step) {
            let want = brute::closest_point(tree.triangles(), p);
            for (how, got) in [("single", tree.closest_point(p)), ("batch", batch[i])] {
                if got != want {
                    let e = format!("point {i} {p:?}: tree ({how}) {got:?}, brute force {want:?}");
                    return Err(e.into());
                }
            }
        }
        println!(
            "checked {} points against the brute force: identical",
            points.len().div_ceil(step)
        );
    }
    if let Some(dir) = &args.dump {
        dump(dir, &mesh, &tree, &points)?;
        println!("wrote {dir}");
    }
    // Closest points and occupancy per class of the mix, one thread: where the time goes.
    let one = rayon::ThreadPoolBuilder::new().num_threads(1).build()?;
    for (class, name) in ["near the surface", "in the box grown 20 %", "in the box x3"]
        .iter()
        .enumerate()
    {
        let some: Vec<Vec3> = points.iter().skip(class).step_by(3).copied().collect();
        let (closest, _, _) = time_median(args.repeat, || {
            one.install(|| drop(tree.closest_point_batch(&some)))
        });
        let (inside, _, _) = time_median(args.repeat, || {
            one.install(|| drop(tree.contains_batch(&some, InsideTest::Parity)))
        });
        println!(
            "1 thread   {name:22} closest point {:7.3}, occupancy {:7.3} Mpoints/s",
            some.len() as f64 / closest / 1e6,
            some.len() as f64 / inside / 1e6
        );
    }
    for &threads in &args.threads {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()?;
        pool.install(|| {
            let queries: [(&str, Query); 3] = [
                (
                    "closest point",
                    Box::new(|| drop(tree.closest_point_batch(&points))),
                ),
                (
                    "signed distance",
                    Box::new(|| drop(tree.signed_distance_batch(&points, InsideTest::Parity))),
                ),
                (
                    "occupancy",
                    Box::new(|| drop(tree.contains_batch(&points, InsideTest::Parity))),
                ),
            ];
            for (name, run) in &queries {
                let (med, lo, hi) = time_median(args.repeat, run);
                let rate = |s: f64| points.len() as f64 / s / 1e6;
                println!(
                    "{threads} threads  {name:16} {:7.3} Mpoints/s (min-max {:.3}-{:.3}), {:.0} ms",
                    rate(med),
                    rate(hi),
                    rate(lo),
                    med * 1e3
                );
            }
        });
    }
    Ok(())
}
