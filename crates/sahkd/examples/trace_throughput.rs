//! Ray throughput of the kd-tree traversal on one mesh: primary, shadow, AO and bounce rays.
//!
//! ```text
//! cargo run --release -p sahkd --example trace_throughput -- MESH [--camera front|near|auto]
//!     [--threads 1,2] [--size 1024] [--repeat 7] [--dump DIR]
//!     [--sets primary,shadow,ao,bounce] [--no-count] [--preset NAME] [--traversal-cost X]
//!     [--empty-bonus X] [--bins N] [--clip on|off] [--walk packets|single]
//! ```
//! The tree is built with the default options (or the preset named), with the cost model's
//! traversal cost and empty-space bonus, the bins and the clipping given after it.
//! Primary rays (closest hit): one per pixel centre of a size x size picture. `front` is the
//! fixed benchmark camera (bounding-box centre + (0, 0, 2 x diagonal) looking at the centre,
//! up +y, 45 degree vertical field of view; most rays miss), `near` the same at 0.75 diagonals,
//! `auto` the camera `sahkd render` picks (the mesh fills the frame; inside the building for
//! Sponza). From every primary hit, moved off the surface as `sahkd render` does: one shadow
//! ray to a point light (any hit), 8 cosine-weighted AO rays with t_max a tenth of the
//! diagonal (any hit) and one cosine-weighted bounce ray (closest hit): `sahkd::render::RaySets`,
//! the sets `sahkd bench` times too.
//!
//! Each set is traced `--repeat` times in a rayon pool of each of the `--threads` counts
//! (`KdTree::intersect_batch` / `occluded_batch`); the median and min-max Mrays/s are printed,
//! with nodes visited, leaves entered and triangles tested per ray from one counting pass.
//! `--sets` times only the sets named, `--no-count` skips the counting pass (both for
//! profiling one set's batch calls, e.g. under callgrind).
//! `--walk` picks what is timed: `packets` (default) the batch calls' packets over the kd
//! nodes, `single` the single-ray calls (`intersect`, `occluded`: the 8-wide nodes' walk) one
//! ray at a time. The counting pass counts the single-ray walk's wide nodes, leaves and
//! triangles and checks every batch answer against it.
//! `--dump DIR` writes the mesh (vertices and faces), its triangles, every set and sahkd's answers as `.npy` files for
//! `scripts/embree_throughput.py`, which traces the very same rays with Embree.

use sahkd::render::{Camera, Query, RaySet, RaySets};
use sahkd::{BuildOptions, KdTree, Mesh, Ray, TraceStats};
use std::io::Write;
use std::path::Path;
use std::time::Instant;

struct Args {
    mesh: String,
    camera: String,
    threads: Vec<usize>,
    size: u32,
    repeat: usize,
    dump: Option<String>,
    sets: Option<Vec<String>>,
    count: bool,
    options: BuildOptions,
    single: bool,
}

fn parse_args() -> Result<Args, String> {
    let mut args = Args {
        mesh: String::new(),
        camera: "front".into(),
        threads: vec![1, 2],
        size: 1024,
        repeat: 7,
        dump: None,
        sets: None,
        count: true,
        options: BuildOptions::default(),
        single: false,
    };
    let mut it = std::env::args().skip(1);
    while let Some(a) = it.next() {
        let mut value = |name: &str| it.next().ok_or(format!("{name} needs a value"));
        match a.as_str() {
            "--camera" => args.camera = value("--camera")?,
            "--threads" => {
                args.threads = value("--threads")?
                    .split(',')
                    .map(|t| t.parse().map_err(|e| format!("--threads: {e}")))
                    .collect::<Result<_, _>>()?
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
            "--sets" => args.sets = Some(value("--sets")?.split(',').map(String::from).collect()),
            "--no-count" => args.count = false,
            "--walk" => match value("--walk")?.as_str() {
                "packets" => {}
                "single" => args.single = true,
                w => return Err(format!("--walk: expected packets or single, got {w}")),
            },
            "--preset" => {
                // Options given before it are replaced by the preset's; give them after it.
                args.options = value("--preset")?
                    .parse::<sahkd::Preset>()
                    .map_err(|e| format!("--preset: {e}"))?
                    .options()
            }
            "--traversal-cost" => {
                args.options.cost.traversal = value("--traversal-cost")?
                    .parse()
                    .map_err(|e| format!("--traversal-cost: {e}"))?
            }
            "--bins" => {
                args.options.bins = Some(
                    value("--bins")?
                        .parse()
                        .map_err(|e| format!("--bins: {e}"))?,
                )
            }
            "--clip" => {
                args.options.clip = match value("--clip")?.as_str() {
                    "on" => true,
                    "off" => false,
                    v => return Err(format!("--clip: expected on or off, got {v}")),
                }
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
        return Err("usage: trace_throughput MESH [--camera front|near|auto] [--threads 1,2] [--size 1024] [--repeat 7] [--dump DIR] [--sets primary,shadow,ao,bounce] [--no-count] [--preset NAME] [--traversal-cost X] [--empty-bonus X] [--bins N] [--clip on|off] [--walk packets|single]".into());
    }
    if args.threads.contains(&0) || args.repeat == 0 || args.size == 0 {
        return Err("--threads, --repeat and --size must be at least 1".into());
    }
    Ok(args)
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

/// Answers `rays` one at a time by `f` on the current pool's threads, as a caller without
/// the batch calls would.
fn one_by_one<T: Send>(rays: &[Ray], f: impl Fn(&Ray) -> T + Sync + Send) {
    use rayon::prelude::*;
    let answers: Vec<T> = rays.par_iter().with_min_len(256).map(f).collect();
    std::hint::black_box(answers);
}

/// A little-endian float32 `.npy` file of the given shape.
fn write_npy(path: &Path, shape: &[usize], data: &[f32]) -> std::io::Result<()> {
    let bytes: Vec<[u8; 4]> = data.iter().map(|x| x.to_le_bytes()).collect();
    write_npy_words(path, "<f4", shape, &bytes)
}

/// A `.npy` file of 4-byte little-endian items of type `descr` (`<f4`, `<i4`).
fn write_npy_words(
    path: &Path,
    descr: &str,
    shape: &[usize],
    data: &[[u8; 4]],
) -> std::io::Result<()> {
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
    for x in data {
        file.write_all(x)?;
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

/// sahkd's answers to a set, as rows for the agreement check: `[t, triangle]` (inf and -1 for
/// a miss) for closest hits, `[1 or 0]` for any hit.
fn answers(tree: &KdTree, set: &RaySet) -> (Vec<f32>, usize, usize) {
    match set.query {
        Query::Closest => {
            let hits = tree.intersect_batch(&set.rays);
            let found = hits.iter().filter(|h| h.is_some()).count();
            let rows = hits
                .iter()
                .flat_map(|h| h.map_or([f32::INFINITY, -1.0], |h| [h.t, h.prim as f32]))
                .collect();
            (rows, 2, found)
        }
        Query::Any => {
            let blocked = tree.occluded_batch(&set.rays);
            let found = blocked.iter().filter(|&&b| b).count();
            (blocked.iter().map(|&b| b as u8 as f32).collect(), 1, found)
        }
    }
}

/// Writes the mesh (`vertices.npy`, float32 rows x y z, and `faces.npy`, int32 rows of corner
/// indices: face `i` is the tree's triangle `i`), the triangles' corners, and per set
/// `NAME.npy` (rays) and `NAME_answers.npy`, and `sets.txt` (one line `NAME closest|any` per
/// set) for `scripts/embree_throughput.py`, which loads Embree from the indexed mesh as its
/// users do.
fn dump(dir: &str, mesh: &Mesh, tree: &KdTree, sets: &[RaySet]) -> std::io::Result<()> {
    let dir = Path::new(dir);
    std::fs::create_dir_all(dir)?;
    let vertices: Vec<[u8; 4]> = mesh
        .vertices
        .iter()
        .flat_map(|v| v.map(f32::to_le_bytes))
        .collect();
    write_npy_words(
        &dir.join("vertices.npy"),
        "<f4",
        &[mesh.vertices.len(), 3],
        &vertices,
    )?;
    let faces: Vec<[u8; 4]> = mesh
        .triangles
        .iter()
        .flat_map(|f| f.map(|i| (i as i32).to_le_bytes()))
        .collect();
    write_npy_words(
        &dir.join("faces.npy"),
        "<i4",
        &[mesh.triangles.len(), 3],
        &faces,
    )?;
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
    let mut list = String::new();
    for set in sets {
        write_npy(
            &dir.join(format!("{}.npy", set.name)),
            &[set.rays.len(), 8],
            &ray_rows(&set.rays),
        )?;
        let (rows, width, _) = answers(tree, set);
        write_npy(
            &dir.join(format!("{}_answers.npy", set.name)),
            &[set.rays.len(), width],
            &rows,
        )?;
        list += &format!("{} {}\n", set.name, set.query.name());
    }
    std::fs::write(dir.join("sets.txt"), list)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args = parse_args()?;
    let mesh = Mesh::load(&args.mesh)?;
    let start = Instant::now();
    let tree = sahkd::build(&mesh, &args.options)?.tree;
    let build_seconds = start.elapsed().as_secs_f64();
    let bounds = tree.bounds();
    let camera = match args.camera.as_str() {
        "front" => Camera::front(bounds),
        "near" => Camera::near(bounds),
        "auto" => Camera::framing(&tree),
        other => return Err(format!("unknown camera {other:?} (front, near or auto)").into()),
    };
    let n = args.size;
    // The first query makes the tree's trace layout; timed on its own.
    let start = Instant::now();
    std::hint::black_box(tree.intersect(&camera.primary_ray(n, n, 0.5, 0.5)));
    let layout_seconds = start.elapsed().as_secs_f64();
    let RaySets {
        light,
        inside,
        sets,
        ..
    } = RaySets::new(&tree, camera, n, n);
    if let Some(dir) = &args.dump {
        dump(dir, &mesh, &tree, &sets)?;
    }

    println!(
        "{}: {} triangles, {} nodes, {} references, built in {build_seconds:.2} s, trace layout ({:.0} MB) in {:.3} s; camera {} (eye {:?}{}), light {:?}, {n}x{n}, {} repeats",
        args.mesh,
        tree.triangles().len(),
        tree.nodes().len(),
        tree.refs().len(),
        tree.trace_bytes() as f64 / 1e6,
        layout_seconds,
        args.camera,
        camera.eye.0,
        if inside { ", inside the box" } else { "" },
        light.0,
        args.repeat
    );
    for set in &sets {
        if args
            .sets
            .as_ref()
            .is_some_and(|only| !only.iter().any(|s| s == set.name))
        {
            continue;
        }
        // Nodes, leaves and triangles per ray from one counting pass of the single-ray walk;
        // the batch calls must give its answers.
        let mut stats = TraceStats::default();
        let mut found = 0usize;
        let mut differ = 0usize;
        if args.count {
            match set.query {
                Query::Closest => {
                    let batch = tree.intersect_batch(&set.rays);
                    for (r, b) in set.rays.iter().zip(&batch) {
                        let h = tree.intersect_counted(r, &mut stats);
                        found += h.is_some() as usize;
                        differ += (h != *b) as usize;
                    }
                }
                Query::Any => {
                    let batch = tree.occluded_batch(&set.rays);
                    for (r, &b) in set.rays.iter().zip(&batch) {
                        let h = tree.occluded_counted(r, &mut stats);
                        found += h as usize;
                        differ += (h != b) as usize;
                    }
                }
            }
        }
        if differ > 0 {
            println!(
                "{}: {differ} batch answers differ from the single-ray walk's",
                set.name
            );
        }
        let count = set.rays.len().max(1) as f64;
        for &threads in &args.threads {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()?;
            let rate = throughput(set.rays.len(), args.repeat, || {
                pool.install(|| match set.query {
                    Query::Closest if args.single => one_by_one(&set.rays, |r| tree.intersect(r)),
                    Query::Any if args.single => one_by_one(&set.rays, |r| tree.occluded(r)),
                    Query::Closest => {
                        std::hint::black_box(tree.intersect_batch(&set.rays));
                    }
                    Query::Any => {
                        std::hint::black_box(tree.occluded_batch(&set.rays));
                    }
                })
            });
            println!(
                "{:>7} ({}): {:>8} rays, {:5.1}% hit, {threads} thread(s), {:6.2} Mrays/s median ({:.2}-{:.2}), {:.1} nodes, {:.2} leaves, {:.2} triangles per ray",
                set.name,
                set.query.name(),
                set.rays.len(),
                100.0 * found as f64 / count,
                rate.0,
                rate.1,
                rate.2,
                stats.nodes as f64 / count,
                stats.leaves as f64 / count,
                stats.triangles as f64 / count,
            );
        }
    }
    Ok(())
}
