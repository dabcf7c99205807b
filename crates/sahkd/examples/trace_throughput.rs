//! Ray throughput of the kd-tree traversal on one mesh: primary and occlusion rays.
//!
//! ```text
//! cargo run --release -p sahkd --example trace_throughput -- MESH [--camera front|auto]
//!     [--threads N] [--size 1024] [--repeat 7] [--dump DIR]
//!     [--traversal-cost X] [--empty-bonus X]
//! ```
//! The tree is built with the default options, or the cost model's traversal cost and
//! empty-space bonus given.
//! Primary rays: one per pixel centre of a size x size picture. `front` is the fixed benchmark
//! camera (bounding-box centre + (0, 0, 2 x diagonal) looking at the centre, up +y, 45 degree
//! vertical field of view; most rays miss), `auto` the camera `sahkd render` picks (the mesh
//! fills the frame). Occlusion rays: for every primary hit, the shadow ray towards the
//! renderer's sun, from the hit point moved off the surface exactly as `sahkd render` does.
//!
//! Each batch is traced `--repeat` times in a rayon pool of `--threads` workers
//! (`KdTree::intersect_batch` / `occluded_batch`); the median and min-max Mrays/s are printed,
//! with nodes visited and triangles tested per ray from one counting pass. `--dump DIR` writes
//! the triangles and both ray sets as `.npy` files for `scripts/embree_throughput.py`, which
//! traces the very same rays with Embree.

use sahkd::render::{facing_normal, Camera, SUN_DIRECTION};
use sahkd::{BuildOptions, Hit, KdTree, Mesh, Ray, TraceStats};
use std::io::Write;
use std::path::Path;
use std::time::Instant;

struct Args {
    mesh: String,
    camera: String,
    threads: usize,
    size: u32,
    repeat: usize,
    dump: Option<String>,
    options: BuildOptions,
}

fn parse_args() -> Result<Args, String> {
    let mut args = Args {
        mesh: String::new(),
        camera: "front".into(),
        threads: 1,
        size: 1024,
        repeat: 7,
        dump: None,
        options: BuildOptions::default(),
    };
    let mut it = std::env::args().skip(1);
    while let Some(a) = it.next() {
        let mut value = |name: &str| it.next().ok_or(format!("{name} needs a value"));
        match a.as_str() {
            "--camera" => args.camera = value("--camera")?,
            "--threads" => {
                args.threads = value("--threads")?
                    .parse()
                    .map_err(|e| format!("--threads: {e}"))?
            }
            "--size" => {
                args.size = value("--size")?
                    .parse()
                    .map_err(|e| format!("--size: {e}"))?
            }
            "--repeat" => {
                args.repeat = value("--repeat")?
                    .parse()
                    .map_err(|e| format!("--repeat: {e}"))?
            }
            "--dump" => args.dump = Some(value("--dump")?),
            "--traversal-cost" => {
                args.options.cost.traversal = value("--traversal-cost")?
                    .parse()
                    .map_err(|e| format!("--traversal-cost: {e}"))?
            }
            "--empty-bonus" => {
                args.options.cost.empty_bonus = value("--empty-bonus")?
                    .parse()
                    .map_err(|e| format!("--empty-bonus: {e}"))?
            }
            _ if a.starts_with("--") => return Err(format!("unknown option {a}")),
            _ => args.mesh = a,
        }
    }
    if args.mesh.is_empty() {
        return Err("usage: trace_throughput MESH [--camera front|auto] [--threads N] [--size 1024] [--repeat 7] [--dump DIR] [--traversal-cost X] [--empty-bonus X]".into());
    }
    if args.threads == 0 || args.repeat == 0 || args.size == 0 {
        return Err("--threads, --repeat and --size must be at least 1".into());
    }
    Ok(args)
}

/// The shadow ray towards the sun of a hit, placed off the surface as `sahkd render` does.
fn shadow_ray(tree: &KdTree, ray: &Ray, hit: &Hit) -> Ray {
    let tri = &tree.triangles()[hit.prim as usize];
    let normal = facing_normal(tri, ray);
    let p = tri[0] * (1.0 - hit.u - hit.v) + tri[1] * hit.u + tri[2] * hit.v;
    let magnitude = p[0].abs().max(p[1].abs()).max(p[2].abs());
    let offset =
        sahkd::render::OFFSET_SCALE * tree.bounds().diagonal() + 8.0 * f32::EPSILON * magnitude;
    Ray::new(p + normal * offset, SUN_DIRECTION)
}

/// Median, min and max of Mrays/s over the repeats of `f`.
fn throughput(rays: usize, repeat: usize, mut f: impl FnMut()) -> (f64, f64, f64) {
    let mut rates: Vec<f64> = (0..repeat)
        .map(|_| {
            let start = Instant::now();
            f();
            rays as f64 / start.elapsed().as_secs_f64() / 1e6
        })
        .collect();
    rates.sort_by(f64::total_cmp);
    (rates[rates.len() / 2], rates[0], rates[rates.len() - 1])
}

/// A little-endian float32 `.npy` file of the given shape.
fn write_npy(path: &Path, shape: &[usize], data: &[f32]) -> std::io::Result<()> {
    let dims: Vec<String> = shape.iter().map(|d| d.to_string()).collect();
    let mut header = format!(
        "{{'descr': '<f4', 'fortran_order': False, 'shape': ({},), }}",
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
    for x in data {
        file.write_all(&x.to_le_bytes())?;
    }
    file.flush()
}

/// Rays as rows `ox oy oz dx dy dz t_min t_max`.
fn ray_rows(rays: &[Ray]) -> Vec<f32> {
    rays.iter()
        .flat_map(|r| {
            let (o, d) = (r.origin, r.direction);
            [o[0], o[1], o[2], d[0], d[1], d[2], r.t_min, r.t_max]
        })
        .collect()
}

fn dump(
    dir: &str,
    tree: &KdTree,
    primary: &[Ray],
    hits: &[Option<Hit>],
    occlusion: &[Ray],
) -> std::io::Result<()> {
    let dir = Path::new(dir);
    std::fs::create_dir_all(dir)?;
    let corners: Vec<f32> = tree
        .triangles()
        .iter()
        .flat_map(|t| t.iter().flat_map(|v| v.0))
        .collect();
    write_npy(
        &dir.join("triangles.npy"),
        &[tree.triangles().len(), 3, 3],
        &corners,
    )?;
    write_npy(
        &dir.join("primary.npy"),
        &[primary.len(), 8],
        &ray_rows(primary),
    )?;
    write_npy(
        &dir.join("occlusion.npy"),
        &[occlusion.len(), 8],
        &ray_rows(occlusion),
    )?;
    // sahkd's answers, for the agreement check: hit distance (inf for a miss) and triangle.
    let answers: Vec<f32> = hits
        .iter()
        .flat_map(|h| h.map_or([f32::INFINITY, -1.0], |h| [h.t, h.prim as f32]))
        .collect();
    write_npy(&dir.join("primary_hits.npy"), &[hits.len(), 2], &answers)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args = parse_args()?;
    let mesh = Mesh::load(&args.mesh)?;
    let start = Instant::now();
    let tree = sahkd::build(&mesh, &args.options)?.tree;
    let build_seconds = start.elapsed().as_secs_f64();
    let camera = match args.camera.as_str() {
        "front" => Camera::front(tree.bounds()),
        "auto" => Camera::framing(&tree),
        other => return Err(format!("unknown camera {other:?} (front or auto)").into()),
    };
    let n = args.size;
    let primary: Vec<Ray> = (0..n)
        .flat_map(|y| (0..n).map(move |x| (x, y)))
        .map(|(x, y)| camera.primary_ray(n, n, x as f32 + 0.5, y as f32 + 0.5))
        .collect();
    // The first query makes the tree's trace layout; timed on its own.
    let start = Instant::now();
    std::hint::black_box(tree.intersect(&primary[0]));
    let layout_seconds = start.elapsed().as_secs_f64();
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(args.threads)
        .build()?;
    let hits = pool.install(|| tree.intersect_batch(&primary));
    let occlusion: Vec<Ray> = primary
        .iter()
        .zip(&hits)
        .filter_map(|(r, h)| h.as_ref().map(|h| shadow_ray(&tree, r, h)))
        .collect();
    if let Some(dir) = &args.dump {
        dump(dir, &tree, &primary, &hits, &occlusion)?;
    }

    let mut primary_stats = TraceStats::default();
    for r in &primary {
        tree.intersect_counted(r, &mut primary_stats);
    }
    let mut occlusion_stats = TraceStats::default();
    let mut blocked = 0usize;
    for r in &occlusion {
        blocked += tree.occluded_counted(r, &mut occlusion_stats) as usize;
    }

    let primary_rate = throughput(primary.len(), args.repeat, || {
        std::hint::black_box(pool.install(|| tree.intersect_batch(&primary)));
    });
    let occlusion_rate = throughput(occlusion.len(), args.repeat, || {
        std::hint::black_box(pool.install(|| tree.occluded_batch(&occlusion)));
    });

    println!(
        "{}: {} triangles, {} nodes, {} references, built in {build_seconds:.2} s, trace layout ({:.0} MB) in {:.3} s; camera {}, {n}x{n}, {} thread(s), {} repeats",
        args.mesh,
        tree.triangles().len(),
        tree.nodes().len(),
        tree.refs().len(),
        // 8-byte nodes and a 40-byte record per reference.
        (8 * tree.nodes().len() + 40 * tree.refs().len()) as f64 / 1e6,
        layout_seconds,
        args.camera,
        args.threads,
        args.repeat
    );
    let per_ray = |s: &TraceStats, rays: usize| {
        let rays = rays.max(1) as f64;
        (s.nodes as f64 / rays, s.triangles as f64 / rays)
    };
    let hit_count = hits.iter().filter(|h| h.is_some()).count();
    for (name, rays, rate, stats, answered) in [
        (
            "primary",
            primary.len(),
            primary_rate,
            primary_stats,
            hit_count,
        ),
        (
            "occlusion",
            occlusion.len(),
            occlusion_rate,
            occlusion_stats,
            blocked,
        ),
    ] {
        let (nodes, tris) = per_ray(&stats, rays);
        println!(
            "{name:>9}: {rays:>8} rays, {:5.1}% hit, {:6.2} Mrays/s median ({:.2}-{:.2}), {nodes:.1} nodes and {tris:.2} triangles per ray",
            100.0 * answered as f64 / rays.max(1) as f64,
            rate.0,
            rate.1,
            rate.2
        );
    }
    Ok(())
}
