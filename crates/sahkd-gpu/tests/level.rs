//! The GPU level builder against the CPU level builder: the same tree (same split planes, same
//! leaf references, compared by `KdTree::first_difference`) for the same options.

mod common;

use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use sahkd::{Axes, BuildOptions, CostModel, Counting, Triangle, Vec3};
use sahkd_gpu::Gpu;

fn cpu_and_gpu_agree(gpu: &Gpu, name: &str, triangles: &[Triangle], options: &BuildOptions) {
    // The GPU runs the level builder: compare with the CPU's (the library's default is hybrid).
    let options = &BuildOptions {
        algorithm: sahkd::Algorithm::Level,
        ..*options
    };
    let cpu = sahkd::build_triangles(triangles.to_vec(), options).unwrap();
    let built = sahkd_gpu::build(gpu, triangles.to_vec(), options)
        .unwrap_or_else(|e| panic!("{name}: {e}"));
    built
        .tree
        .validate()
        .unwrap_or_else(|e| panic!("{name}: {e}"));
    if let Some(d) = cpu.tree.first_difference(&built.tree) {
        panic!("{name} ({options:?}): GPU tree differs from the CPU's at {d}");
    }
    assert_eq!(
        built.report.levels,
        cpu.report.levels.len(),
        "{name}: levels"
    );
    // One read per level: the decision's totals (the candidate layout stays on the device).
    assert_eq!(built.report.round_trips, built.report.levels);
    assert!(
        cpu.tree.nodes().len() > 1 || triangles.len() <= 1,
        "{name}: a real tree"
    );
}

/// Random triangles on a coarse grid, a third of them flat on some axis: many equal
/// positions, planar references and ties between candidates.
fn grid_triangles(seed: u64, n: usize) -> Vec<Triangle> {
    let mut rng = StdRng::seed_from_u64(seed);
    (0..n)
        .map(|_| {
            let c: [f32; 3] = std::array::from_fn(|_| rng.random_range(0..16) as f32 - 8.0);
            let flat = rng.random_range(0..6);
            let corner = |rng: &mut StdRng| {
                let mut v = c;
                for (a, x) in v.iter_mut().enumerate() {
                    if a != flat {
                        *x += rng.random_range(0..4) as f32 * 0.5;
                    }
                }
                Vec3(v)
            };
            [corner(&mut rng), corner(&mut rng), corner(&mut rng)]
        })
        .collect()
}

fn option_sets() -> Vec<BuildOptions> {
    let paper = BuildOptions::paper();
    vec![
        paper,
        BuildOptions {
            axes: Axes::All,
            ..paper
        },
        BuildOptions {
            counting: Counting::SpaceTree,
            ..paper
        },
        BuildOptions {
            cost: CostModel {
                leaf_size: 4,
                max_depth: Some(7),
                traversal: 3.0,
                empty_bonus: 1.0,
                ..CostModel::default()
            },
            ..paper
        },
        // A reference budget that runs out: whole levels become leaves.
        BuildOptions {
            axes: Axes::All,
            cost: CostModel {
                max_duplication: 1.0,
                ..CostModel::default()
            },
            ..paper
        },
        // The default, and perfect splits: straddlers clipped to the children.
        BuildOptions::default(),
        BuildOptions {
            clip: true,
            ..BuildOptions::default()
        },
        BuildOptions::quality(),
        BuildOptions {
            clip: true,
            counting: Counting::SpaceTree,
            cost: CostModel {
                max_duplication: 1.5,
                ..CostModel::default()
            },
            ..paper
        },
    ]
}

#[test]
fn generated_scenes_give_the_cpu_tree() {
    let Some(gpu) = common::gpu() else { return };
    let mut scenes: Vec<(String, Vec<Triangle>)> = vec![
        ("grid 1".into(), grid_triangles(1, 1)),
        ("grid 40".into(), grid_triangles(2, 40)),
        ("grid 3000".into(), grid_triangles(3, 3000)),
    ];
    for spec in ["spd:toys:5000", "spd:sphereflake:3000", "spd:tetra:2000"] {
        let mesh = sahkd::scenes::generate(spec).unwrap();
        scenes.push((spec.into(), mesh.corner_triangles()));
    }
    for (name, triangles) in &scenes {
        for options in option_sets() {
            cpu_and_gpu_agree(&gpu, name, triangles, &options);
        }
    }
}

/// Every scene with perfect splits (`--device gpu --clip on`, the GPU's most work); the
/// smaller ones also with the defaults (triangle boxes) and the paper's setting, and one with
/// all axes.
#[test]
fn real_meshes_give_the_cpu_tree() {
    let Some(gpu) = common::gpu() else { return };
    let paper = BuildOptions::paper();
    for file in [
        "dragon_res4.ply",
        "dragon_res3.ply",
        "bunny.ply",
        "buddha_res3.ply",
        "sponza_dabrovic.ply",
        "dragon_res2.ply",
        "dragon.ply",
    ] {
        let Some(mesh) = common::scene(file) else {
            continue;
        };
        let triangles = mesh.corner_triangles();
        let clipped = BuildOptions {
            clip: true,
            ..BuildOptions::default()
        };
        cpu_and_gpu_agree(&gpu, file, &triangles, &clipped);
        if triangles.len() < 100_000 {
            cpu_and_gpu_agree(&gpu, file, &triangles, &BuildOptions::default());
            cpu_and_gpu_agree(&gpu, file, &triangles, &paper);
        }
        if file == "dragon_res4.ply" {
            let space_tree = BuildOptions {
                counting: Counting::SpaceTree,
                ..clipped
            };
            let all = BuildOptions {
                axes: Axes::All,
                ..paper
            };
            for options in [BuildOptions::quality(), all, space_tree] {
                cpu_and_gpu_agree(&gpu, file, &triangles, &options);
            }
        }
    }
}

#[test]
fn unsupported_options_and_empty_input() {
    let Some(gpu) = common::gpu() else { return };
    let sweep = BuildOptions::sweep();
    let err = sahkd_gpu::build(&gpu, grid_triangles(4, 10), &sweep)
        .err()
        .unwrap();
    assert!(err.to_string().contains("level builder only"), "{err}");
    let empty = sahkd_gpu::build(&gpu, Vec::new(), &BuildOptions::paper()).unwrap();
    assert_eq!(empty.tree.nodes().len(), 1);
}
