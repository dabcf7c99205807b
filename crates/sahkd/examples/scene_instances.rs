//! The measurement behind `scene`'s design: one tree over every placed triangle against one
//! tree per mesh with rays carried into each instance's frame (a list of instances culled by
//! their world boxes, which is what a top tree does for a few dozen instances).
//!
//! `cargo run --release -p sahkd --example scene_instances -- [MESH] [GRID] [RAYS]`
//! (defaults `spd:sphere:20000`, 4: a 4x4x4 grid of rotated, slightly overlapping copies,
//! and 200000 rays). Both answer every ray identically up to float32 rounding; it prints the
//! build times, the triangles stored, and single-thread Mrays/s for closest hits.

use sahkd::scene::{Scene, Transform};
use sahkd::{build, Aabb, BuildOptions, Ray, Vec3};
use std::time::Instant;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let spec = args.get(1).map_or("spd:sphere:20000", |s| s.as_str());
    let grid: usize = args.get(2).map_or(4, |s| s.parse().expect("GRID"));
    let n_rays: usize = args.get(3).map_or(200_000, |s| s.parse().expect("RAYS"));
    let mesh = sahkd::scenes::generate(spec).expect("mesh");
    let b = mesh.bounds();
    let size = (0..3).map(|a| b.extent()[a]).fold(0.0f32, f32::max) as f64;
    let c = b.centre();

    // Copies on a grid a little tighter than the mesh, each turned differently.
    let mut transforms = Vec::new();
    for i in 0..grid * grid * grid {
        let (x, y, z) = (i % grid, (i / grid) % grid, i / (grid * grid));
        let angle = 0.37 * i as f64;
        let (s, co) = angle.sin_cos();
        let at = [x, y, z].map(|k| k as f64 * size * 0.9);
        let m = [[co, -s, 0.0], [s, co, 0.0], [0.0, 0.0, 1.0]];
        // Rotate about the mesh's centre, then move to the grid point.
        let centre = [c[0] as f64, c[1] as f64, c[2] as f64];
        let t =
            [0, 1, 2].map(|r| at[r] + centre[r] - (0..3).map(|k| m[r][k] * centre[k]).sum::<f64>());
        transforms.push(Transform(
            [0, 1, 2].map(|r| [m[r][0], m[r][1], m[r][2], t[r]]),
        ));
    }

    let options = BuildOptions {
        threads: Some(1),
        ..BuildOptions::default()
    };
    let start = Instant::now();
    let mut scene = Scene::new();
    let m = scene.add_mesh(&mesh).unwrap();
    // The mesh itself is placed by the first transform: add it, then instances of the rest.
    for t in &transforms[1..] {
        scene.add_instance(m, *t).unwrap();
    }
    let one = scene.build(&options).unwrap();
    let one_ms = start.elapsed().as_secs_f64() * 1e3;
    let start = Instant::now();
    let tree = build(&mesh, &options).unwrap().tree;
    let per_mesh_ms = start.elapsed().as_secs_f64() * 1e3;

    // The per-instance side: inverse transforms and world boxes.
    let mut instances = vec![(Transform::IDENTITY, b)];
    for t in &transforms[1..] {
        let inv = invert(t);
        let mut world = Aabb::EMPTY;
        for k in 0..8 {
            let p = [0, 1, 2].map(|a| if k >> a & 1 == 1 { b.hi[a] } else { b.lo[a] } as f64);
            let w = t.apply(p);
            world = world.grow(Vec3::new(w[0] as f32, w[1] as f32, w[2] as f32));
        }
        instances.push((inv, world));
    }

    // Rays from a sphere around the grid towards random points inside it.
    let span = grid as f64 * size;
    let mut state = 0x2545_F491_4F6C_DD1Du64;
    let mut rnd = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    let rays: Vec<Ray> = (0..n_rays)
        .map(|_| {
            let o = [0; 3].map(|_| (rnd() - 0.5) * 3.0 * span + span * 0.5);
            let q = [0; 3].map(|_| rnd() * span);
            let v = |p: [f64; 3]| Vec3::new(p[0] as f32, p[1] as f32, p[2] as f32);
            Ray::new(v(o), v([q[0] - o[0], q[1] - o[1], q[2] - o[2]]))
        })
        .collect();

    one.tree().prepare_trace();
    tree.prepare_trace();
    let start = Instant::now();
    let mut hits_one = 0usize;
    for r in &rays {
        hits_one += one.intersect(r).is_some() as usize;
    }
    let one_s = start.elapsed().as_secs_f64();

    let start = Instant::now();
    let mut hits_per = 0usize;
    for r in &rays {
        let mut best = r.t_max;
        let mut hit = false;
        for (inv, world) in &instances {
            if !slab(world, r, best) {
                continue;
            }
            // Affine: t is the same in both frames when the direction is carried unnormalised.
            let o = inv.apply(r.origin.0.map(f64::from));
            let mut d = inv.apply(r.direction.0.map(f64::from));
            let zero = inv.apply([0.0; 3]);
            d = [d[0] - zero[0], d[1] - zero[1], d[2] - zero[2]];
            let v = |p: [f64; 3]| Vec3::new(p[0] as f32, p[1] as f32, p[2] as f32);
            let local = Ray::new(v(o), v(d)).with_range(r.t_min, best);
            if let Some(h) = tree.intersect(&local) {
                best = h.t;
                hit = true;
            }
        }
        hits_per += hit as usize;
    }
    let per_s = start.elapsed().as_secs_f64();

    let placed = one.tree().triangles().len();
    println!(
        "{spec}, {} instances, {n_rays} rays, 1 thread",
        transforms.len()
    );
    println!(
        "one tree:       build {one_ms:8.0} ms, {placed:9} triangles stored, {:6.2} Mrays/s ({hits_one} hits)",
        n_rays as f64 / one_s / 1e6
    );
    println!(
        "tree per mesh:  build {per_mesh_ms:8.0} ms, {:9} triangles stored, {:6.2} Mrays/s ({hits_per} hits)",
        mesh.triangles.len(),
        n_rays as f64 / per_s / 1e6
    );
}

fn invert(t: &Transform) -> Transform {
    let m = t.0;
    let a = |r: usize, c: usize| m[r][c];
    let det = t.determinant();
    // The inverse's entries are the cofactors, transposed, over the determinant.
    let cof = |r: usize, c: usize| {
        let (r1, r2) = ((r + 1) % 3, (r + 2) % 3);
        let (c1, c2) = ((c + 1) % 3, (c + 2) % 3);
        a(r1, c1) * a(r2, c2) - a(r1, c2) * a(r2, c1)
    };
    let inv = [0, 1, 2].map(|r| [0, 1, 2].map(|c| cof(c, r) / det));
    let tr = [m[0][3], m[1][3], m[2][3]];
    let mt = [0, 1, 2].map(|r| -(0..3).map(|k| inv[r][k] * tr[k]).sum::<f64>());
    Transform([0, 1, 2].map(|r| [inv[r][0], inv[r][1], inv[r][2], mt[r]]))
}

/// Whether the ray meets the box within `[t_min, limit]`.
fn slab(b: &Aabb, r: &Ray, limit: f32) -> bool {
    let (mut t0, mut t1) = (r.t_min, limit);
    for a in 0..3 {
        let inv = 1.0 / r.direction[a];
        let (mut n, mut f) = ((b.lo[a] - r.origin[a]) * inv, (b.hi[a] - r.origin[a]) * inv);
        if n > f {
            std::mem::swap(&mut n, &mut f);
        }
        t0 = if n > t0 { n } else { t0 };
        t1 = if f < t1 { f } else { t1 };
    }
    t0 <= t1
}
