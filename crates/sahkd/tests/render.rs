//! The renderer against independent answers: every pixel of a normal-shaded picture against
//! the brute-force first hit of the camera's ray, thread-count independence, the cameras'
//! documented geometry, and ambient occlusion on a convex object.

use sahkd::render::{
    background, normal_colour, render, to_rgb8, Camera, Image, RenderOptions, RenderReport, Shading,
};
use sahkd::trace::brute;
use sahkd::{build, Aabb, BuildOptions, KdTree, Mesh, Ray, Vec3};
use std::sync::atomic::{AtomicU64, Ordering};

fn scene(spec: &str) -> (Mesh, KdTree) {
    let mesh = sahkd::scenes::generate(spec).unwrap();
    let tree = build(&mesh, &BuildOptions::default()).unwrap().tree;
    (mesh, tree)
}

fn in_pool<T: Send>(threads: usize, f: impl FnOnce() -> T + Send) -> T {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap()
        .install(f)
}

fn quiet(tree: &KdTree, options: &RenderOptions) -> (Image, RenderReport) {
    render(tree, options, &|_, _| {})
}

/// The angle between two directions, accurate for small angles too (atan2, not acos).
fn angle_degrees(a: Vec3, b: Vec3) -> f32 {
    let (a, b) = (a.normalized(), b.normalized());
    a.cross(b).length().atan2(a.dot(b)).to_degrees()
}

#[test]
fn normal_shading_shows_the_brute_force_first_hit_of_every_pixel() {
    for (spec, front) in [("spd:sphereflake:3000", false), ("spd:tetra:1000", true)] {
        let (mesh, tree) = scene(spec);
        let camera = if front {
            Camera::front(tree.bounds())
        } else {
            Camera::auto(tree.bounds())
        };
        let (w, h) = (64, 48);
        let options = RenderOptions::new(w, h, camera);
        let (image, report) = quiet(&tree, &options);
        assert_eq!(
            (image.width, image.height, image.rgb.len()),
            (w, h, 3 * 64 * 48)
        );
        let triangles = mesh.corner_triangles();
        let mut hits = 0;
        for y in 0..h {
            for x in 0..w {
                let ray = camera.primary_ray(w, h, x as f32 + 0.5, y as f32 + 0.5);
                let expected = match brute::intersect(&triangles, &ray) {
                    Some(hit) => {
                        hits += 1;
                        normal_colour(&triangles[hit.prim as usize], &ray)
                    }
                    None => background(&ray),
                };
                assert_eq!(
                    image.pixel(x, y),
                    to_rgb8(expected),
                    "{spec}: pixel ({x}, {y})"
                );
            }
        }
        // Not a picture of nothing (nor of nothing but the scene). The front camera stands
        // back two diagonals, so the scene is small in its picture.
        assert!(hits > 80 && hits < w * h, "{spec}: {hits} hits");
        assert_eq!(report.primary.rays, (w * h) as u64);
        assert_eq!(report.occlusion.rays, 0);
        assert!(report.primary.nodes_per_ray > 0.0 && report.primary.triangles_per_ray > 0.0);
    }
}

#[test]
fn normal_colour_matches_hand_computation() {
    let tri = [
        Vec3::new(0.0, 0.0, 0.0),
        Vec3::new(1.0, 0.0, 0.0),
        Vec3::new(0.0, 1.0, 0.0),
    ];
    // Normal +z; seen from +z it stays, seen from -z it is flipped to face the ray.
    let from_front = Ray::new(Vec3::new(0.2, 0.2, 5.0), Vec3::new(0.0, 0.0, -1.0));
    let from_back = Ray::new(Vec3::new(0.2, 0.2, -5.0), Vec3::new(0.0, 0.0, 1.0));
    assert_eq!(to_rgb8(normal_colour(&tri, &from_front)), [128, 128, 255]);
    assert_eq!(to_rgb8(normal_colour(&tri, &from_back)), [128, 128, 0]);
    // The background is a gradient: looking up differs from looking at the horizon.
    let up = background(&Ray::new(Vec3::splat(0.0), Vec3::new(0.0, 1.0, 0.0)));
    let level = background(&Ray::new(Vec3::splat(0.0), Vec3::new(1.0, 0.0, 0.0)));
    assert_ne!(to_rgb8(up), to_rgb8(level));
}

#[test]
fn pictures_do_not_depend_on_the_thread_count() {
    let (_, tree) = scene("spd:toys:600");
    for shading in Shading::ALL {
        let options = RenderOptions {
            shading,
            spp: 2,
            ao_samples: 3,
            ..RenderOptions::new(40, 30, Camera::auto(tree.bounds()))
        };
        let (one, r1) = in_pool(1, || quiet(&tree, &options));
        let (four, r4) = in_pool(4, || quiet(&tree, &options));
        assert!(
            one == four,
            "{shading:?}: pictures differ between 1 and 4 threads"
        );
        assert_eq!(r1.primary.rays, r4.primary.rays);
        assert_eq!(r1.occlusion.rays, r4.occlusion.rays);
        assert_eq!(r1.primary.nodes_per_ray, r4.primary.nodes_per_ray);
        assert_eq!(
            r1.occlusion.triangles_per_ray,
            r4.occlusion.triangles_per_ray
        );
        if shading != Shading::Normal {
            assert!(
                r1.occlusion.rays > 0,
                "{shading:?} traced no occlusion rays"
            );
        }
    }
}

#[test]
fn front_camera_follows_its_definition() {
    let bounds = Aabb::new(Vec3::new(-1.0, 2.0, 3.0), Vec3::new(5.0, 4.0, 4.0));
    let c = Camera::front(bounds);
    let diagonal = (36.0f32 + 4.0 + 1.0).sqrt();
    let centre = Vec3::new(2.0, 3.0, 3.5);
    assert_eq!(c.look_at, centre);
    assert_eq!(c.eye, centre + Vec3::new(0.0, 0.0, 2.0 * diagonal));
    assert_eq!(c.up, Vec3::new(0.0, 1.0, 0.0));
    assert_eq!(c.fov_y_degrees, 45.0);

    // Pinhole geometry: the centre of the picture looks at the target, the top edge 22.5
    // degrees above it, the left edge atan(tan 22.5 * aspect) to the left; y grows down.
    let (w, h) = (200, 100);
    let forward = c.look_at - c.eye;
    let mid = c.primary_ray(w, h, 100.0, 50.0);
    assert_eq!(mid.origin, c.eye);
    assert!(angle_degrees(mid.direction, forward) < 1e-3);
    assert!((mid.direction.length() - 1.0).abs() < 1e-6);
    let top = c.primary_ray(w, h, 100.0, 0.0);
    assert!((angle_degrees(top.direction, forward) - 22.5).abs() < 1e-3);
    assert!(top.direction[1] > 0.0);
    let left = c.primary_ray(w, h, 0.0, 50.0);
    let expected = (22.5f32.to_radians().tan() * 2.0).atan().to_degrees();
    assert!((angle_degrees(left.direction, forward) - expected).abs() < 1e-3);
    assert!(left.direction[0] < 0.0);
}

#[test]
fn auto_camera_frames_the_whole_box_tightly() {
    for bounds in [
        Aabb::new(Vec3::new(-1.0, 0.0, -1.0), Vec3::new(1.0, 0.2, 1.0)),
        Aabb::new(Vec3::new(10.0, -3.0, 0.0), Vec3::new(11.0, 30.0, 2.0)),
        Aabb::new(Vec3::splat(-2.0), Vec3::splat(2.0)),
    ] {
        let c = Camera::auto(bounds);
        let forward = (c.look_at - c.eye).normalized();
        let right = forward.cross(c.up).normalized();
        let up = right.cross(forward);
        let tan = (0.5 * c.fov_y_degrees).to_radians().tan();
        assert!(forward[1] < 0.0, "looks down on the scene");
        let mut widest = 0.0f32;
        for k in 0..8 {
            let p = Vec3::new(
                if k & 1 == 0 {
                    bounds.lo[0]
                } else {
                    bounds.hi[0]
                },
                if k & 2 == 0 {
                    bounds.lo[1]
                } else {
                    bounds.hi[1]
                },
                if k & 4 == 0 {
                    bounds.lo[2]
                } else {
                    bounds.hi[2]
                },
            );
            let q = p - c.eye;
            let depth = q.dot(forward);
            assert!(depth > 0.0, "corner {p:?} behind the camera");
            // Screen coordinates in [-1, 1] of a 4:3 picture.
            let x = q.dot(right) / depth / (tan * 4.0 / 3.0);
            let y = q.dot(up) / depth / tan;
            assert!(
                x.abs() <= 1.0001 && y.abs() <= 1.0001,
                "corner {p:?} at ({x}, {y})"
            );
            widest = widest.max(x.abs()).max(y.abs());
        }
        assert!(
            widest > 0.999,
            "{bounds:?}: the box only fills {widest} of the frame"
        );
    }
}

/// Screen coordinates in [-1, 1] of a 4:3 picture of point `p`, and its depth.
fn project(c: &Camera, p: Vec3) -> (f32, f32, f32) {
    let forward = (c.look_at - c.eye).normalized();
    let right = forward.cross(c.up).normalized();
    let up = right.cross(forward);
    let tan = (0.5 * c.fov_y_degrees).to_radians().tan();
    let q = p - c.eye;
    let depth = q.dot(forward);
    (
        q.dot(right) / depth / (tan * 4.0 / 3.0),
        q.dot(up) / depth / tan,
        depth,
    )
}

#[test]
fn framing_fits_every_vertex_into_the_picture_with_a_small_margin() {
    for spec in ["spd:tetra:1000", "spd:sphereflake:3000", "spd:toys:600"] {
        let (mesh, tree) = scene(spec);
        let c = Camera::framing(&tree);
        assert!(c.eye[1] > c.look_at[1], "{spec}: looks down on the scene");
        let (mut lo, mut hi) = ([f32::INFINITY; 2], [f32::NEG_INFINITY; 2]);
        for &v in &mesh.vertices {
            let (x, y, depth) = project(&c, Vec3::new(v[0], v[1], v[2]));
            assert!(depth > 0.0, "{spec}: vertex {v:?} behind the camera");
            assert!(
                x.abs() <= 0.95 && y.abs() <= 0.95,
                "{spec}: vertex {v:?} at ({x}, {y}), outside the margin"
            );
            lo = [lo[0].min(x), lo[1].min(y)];
            hi = [hi[0].max(x), hi[1].max(y)];
        }
        // Tight along one axis and centred along both: the model is neither small nor
        // off to one side (as it was when the 8 corners of the box were fitted).
        let fill = (hi[0] - lo[0]).max(hi[1] - lo[1]);
        assert!(fill > 1.8, "{spec}: the model fills only {fill} of 2");
        for a in 0..2 {
            assert!(
                (hi[a] + lo[a]).abs() < 0.01,
                "{spec}: off-centre on axis {a}: {} .. {}",
                lo[a],
                hi[a]
            );
        }
    }
}

/// The 12 triangles of a box's faces, facing inwards (a room) or outwards (a solid).
fn cube(inwards: bool) -> Mesh {
    let vertices = (0..8)
        .map(|k| {
            [
                if k & 1 == 0 { -2.0 } else { 2.0 },
                if k & 2 == 0 { 0.0 } else { 3.0 },
                if k & 4 == 0 { -1.0 } else { 1.0 },
            ]
        })
        .collect();
    // Counter-clockwise seen from outside: outward normals.
    let quads = [
        [0, 2, 3, 1],
        [4, 5, 7, 6],
        [0, 1, 5, 4],
        [2, 6, 7, 3],
        [0, 4, 6, 2],
        [1, 3, 7, 5],
    ];
    let triangles = quads
        .iter()
        .flat_map(|&[a, b, c, d]| [[a, b, c], [a, c, d]])
        .map(|[a, b, c]| if inwards { [a, c, b] } else { [a, b, c] })
        .collect();
    Mesh {
        vertices,
        triangles,
    }
}

#[test]
fn framing_looks_at_a_room_from_inside_and_at_a_solid_from_outside() {
    let room = build(&cube(true), &BuildOptions::default()).unwrap().tree;
    let solid = build(&cube(false), &BuildOptions::default()).unwrap().tree;
    // The normals of the room face its centre.
    let centre = room.bounds().centre();
    for t in room.triangles() {
        let n = (t[1] - t[0]).cross(t[2] - t[0]);
        assert!(n.dot(centre - t[0]) > 0.0);
    }
    let inside = |p: Vec3| (0..3).all(|a| p[a] > room.bounds().lo[a] && p[a] < room.bounds().hi[a]);
    let c = Camera::framing(&room);
    assert!(inside(c.eye), "room: eye {:?} outside", c.eye);
    // Backed away along the long (x) axis, looking across the centre.
    assert!(c.eye[0] < centre[0] - 0.5, "{:?}", c.eye);
    assert_eq!(c.look_at, centre);
    // Every pixel of the room picture is wall.
    let (image, _) = quiet(&room, &RenderOptions::new(32, 24, c));
    for y in 0..24 {
        for x in 0..32 {
            let ray = c.primary_ray(32, 24, x as f32 + 0.5, y as f32 + 0.5);
            assert_ne!(image.pixel(x, y), to_rgb8(background(&ray)), "({x}, {y})");
        }
    }
    let c = Camera::framing(&solid);
    assert!(!inside(c.eye), "solid: eye {:?} inside", c.eye);
}

#[test]
fn ambient_occlusion_leaves_a_convex_object_unoccluded() {
    // A sphere cannot shadow itself: every AO ray escapes, so every hit pixel is equally
    // bright. Then a sphereflake, whose children do occlude the root sphere.
    let (mesh, tree) = scene("spd:sphere:500");
    let options = RenderOptions {
        shading: Shading::Ao,
        ao_samples: 8,
        ao_distance: Some(10.0),
        ..RenderOptions::new(48, 36, Camera::front(tree.bounds()))
    };
    let (image, report) = quiet(&tree, &options);
    let triangles = mesh.corner_triangles();
    let mut lit = std::collections::BTreeSet::new();
    let mut hits = 0;
    for y in 0..36 {
        for x in 0..48 {
            let ray = options
                .camera
                .primary_ray(48, 36, x as f32 + 0.5, y as f32 + 0.5);
            if brute::intersect(&triangles, &ray).is_some() {
                hits += 1;
                lit.insert(image.pixel(x, y));
            } else {
                assert_eq!(image.pixel(x, y), to_rgb8(background(&ray)));
            }
        }
    }
    assert!(hits > 50);
    assert_eq!(lit.len(), 1, "a convex sphere has occluded pixels: {lit:?}");
    assert_eq!(report.occlusion.rays, 8 * hits);

    let (mesh, flake) = scene("spd:sphereflake:4000");
    let options = RenderOptions {
        camera: Camera::auto(flake.bounds()),
        ..options
    };
    let (image, _) = quiet(&flake, &options);
    let triangles = mesh.corner_triangles();
    let mut shades = std::collections::BTreeSet::new();
    for y in 0..36 {
        for x in 0..48 {
            let ray = options
                .camera
                .primary_ray(48, 36, x as f32 + 0.5, y as f32 + 0.5);
            if brute::intersect(&triangles, &ray).is_some() {
                shades.insert(image.pixel(x, y));
            }
        }
    }
    assert!(
        shades.len() > 3,
        "no occlusion seen on the sphereflake: {shades:?}"
    );
}

#[test]
fn progress_reaches_every_pixel() {
    let (_, tree) = scene("spd:sphere:200");
    let options = RenderOptions::new(37, 21, Camera::auto(tree.bounds()));
    let (calls, most) = (AtomicU64::new(0), AtomicU64::new(0));
    render(&tree, &options, &|done, total| {
        assert_eq!(total, 37 * 21);
        assert!(done <= total);
        calls.fetch_add(1, Ordering::Relaxed);
        most.fetch_max(done, Ordering::Relaxed);
    });
    // 3 x 2 tiles of 16 x 16.
    assert_eq!(calls.load(Ordering::Relaxed), 6);
    assert_eq!(most.load(Ordering::Relaxed), 37 * 21);
}

#[test]
fn bad_options_are_explained_and_an_empty_picture_is_empty() {
    let (_, tree) = scene("spd:sphere:100");
    let good = RenderOptions::new(8, 8, Camera::auto(tree.bounds()));
    assert_eq!(good.validate(), Ok(()));
    let cases = [
        (RenderOptions { width: 0, ..good }, "no pixels"),
        (RenderOptions { spp: 0, ..good }, "samples per pixel"),
        (
            RenderOptions {
                shading: Shading::Ao,
                ao_samples: 0,
                ..good
            },
            "at least 1 sample",
        ),
        (
            RenderOptions {
                ao_distance: Some(-1.0),
                ..good
            },
            "AO distance",
        ),
        (
            RenderOptions {
                camera: Camera {
                    fov_y_degrees: 180.0,
                    ..good.camera
                },
                ..good
            },
            "field of view",
        ),
        (
            RenderOptions {
                camera: Camera {
                    look_at: good.camera.eye,
                    ..good.camera
                },
                ..good
            },
            "own position",
        ),
        (
            RenderOptions {
                camera: Camera {
                    up: good.camera.look_at - good.camera.eye,
                    ..good.camera
                },
                ..good
            },
            "parallel",
        ),
    ];
    for (options, why) in cases {
        let e = options.validate().expect_err(why);
        assert!(e.contains(why), "{why}: {e}");
    }
    let (image, report) = quiet(&tree, &RenderOptions { width: 0, ..good });
    assert!(image.rgb.is_empty());
    assert_eq!(report.primary.rays, 0);
    assert_eq!("ao".parse::<Shading>(), Ok(Shading::Ao));
    assert!("phong"
        .parse::<Shading>()
        .unwrap_err()
        .contains("normal, ao or diffuse"));
}

fn scenes_dir() -> Option<std::path::PathBuf> {
    let dir = match std::env::var_os("SAHKD_SCENES") {
        Some(dir) => std::path::PathBuf::from(dir),
        None => std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/scenes"),
    };
    if dir.join("README.md").is_file() {
        Some(dir)
    } else {
        println!(
            "skipping: no scenes at {} (set SAHKD_SCENES)",
            dir.display()
        );
        None
    }
}

#[test]
fn pictures_of_real_meshes_have_no_holes_or_speckles() {
    // Every camera ray of the framing camera (outside view of the dragon, inside view of
    // Sponza) hits exactly when brute force says it does, at the same distance. Colours are
    // not compared: on an edge shared by two triangles either may be reported.
    let Some(dir) = scenes_dir() else { return };
    for (file, w, h) in [("dragon_res4.ply", 96, 72), ("sponza_dabrovic.ply", 48, 36)] {
        let mesh = Mesh::load(dir.join(file)).unwrap();
        let tree = build(&mesh, &BuildOptions::default()).unwrap().tree;
        let triangles = mesh.corner_triangles();
        let camera = Camera::framing(&tree);
        let (image, _) = quiet(&tree, &RenderOptions::new(w, h, camera));
        let mut hits = 0;
        for y in 0..h {
            for x in 0..w {
                let ray = camera.primary_ray(w, h, x as f32 + 0.5, y as f32 + 0.5);
                let expected = brute::intersect(&triangles, &ray);
                let got = tree.intersect(&ray);
                match (expected, got) {
                    (Some(e), Some(g)) => {
                        hits += 1;
                        assert!(
                            (e.t - g.t).abs() <= 1e-5 * e.t.max(1.0),
                            "{file}: pixel ({x}, {y}) at t {} instead of {}",
                            g.t,
                            e.t
                        );
                        assert_ne!(image.pixel(x, y), to_rgb8(background(&ray)));
                    }
                    (None, None) => {
                        assert_eq!(image.pixel(x, y), to_rgb8(background(&ray)));
                    }
                    _ => panic!("{file}: pixel ({x}, {y}): {got:?} instead of {expected:?}"),
                }
            }
        }
        // The dragon fills a good part of its picture; from inside Sponza every ray hits
        // a wall, except towards the open sky.
        let least = if file.starts_with("sponza") {
            w * h * 3 / 4
        } else {
            w * h / 4
        };
        assert!(hits > least, "{file}: {hits} hits of {}", w * h);
    }
}
