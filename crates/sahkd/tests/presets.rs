//! Build presets (`Preset`, `BuildOptions::fast()` and the others): names the library owns,
//! options that validate, options given beside a preset overriding it, and for every preset a
//! tree that answers rays as brute force does and is the same on any number of threads.

mod common;

use common::*;
use sahkd::{build, build_triangles, Algorithm, Axes, BuildOptions, Preset};

fn on_threads(preset: Preset, threads: usize) -> BuildOptions {
    BuildOptions {
        threads: Some(threads),
        ..preset.options()
    }
}

#[test]
fn names_read_back_and_a_bad_name_lists_the_good_ones() {
    assert_eq!(
        Preset::NAMES,
        ["fast", "balanced", "quality", "paper", "sweep"]
    );
    for &p in Preset::ALL {
        assert_eq!(p.to_string().parse::<Preset>(), Ok(p));
        assert_eq!(p.options().preset, Some(p));
        p.options().validate().unwrap();
    }
    assert_eq!("QUALITY".parse::<Preset>(), Ok(Preset::Quality));
    let err = "fastest".parse::<Preset>().unwrap_err();
    assert!(
        err.contains("fastest") && err.contains("fast, balanced, quality, paper, sweep"),
        "{err}"
    );
}

#[test]
fn the_constructors_are_the_presets_and_balanced_is_the_default() {
    assert_eq!(BuildOptions::default(), Preset::Balanced.options());
    assert_eq!(BuildOptions::balanced(), BuildOptions::default());
    assert_eq!(BuildOptions::fast(), Preset::Fast.options());
    assert_eq!(BuildOptions::quality(), Preset::Quality.options());
    assert_eq!(BuildOptions::paper(), Preset::Paper.options());
    assert_eq!(BuildOptions::sweep(), Preset::Sweep.options());
    // What each stands for, by the options that define it.
    let q = BuildOptions::quality();
    assert_eq!((q.axes, q.clip, q.resolved_bins()), (Axes::All, true, 0));
    let p = BuildOptions::paper();
    assert_eq!(
        (p.algorithm, p.axes, p.clip),
        (Algorithm::Level, Axes::Longest, false)
    );
    let s = BuildOptions::sweep();
    assert_eq!((s.algorithm, s.resolved_bins()), (Algorithm::Sweep, 0));
}

#[test]
fn options_beside_a_preset_override_it() {
    let tris = random_triangles(&mut rng(3), 3000);
    let fast = BuildOptions::fast();
    let overridden = BuildOptions {
        clip: !fast.clip,
        ..fast
    };
    let a = build_triangles(tris.clone(), &overridden).unwrap().tree;
    let b = build_triangles(
        tris,
        &BuildOptions {
            preset: None,
            ..overridden
        },
    )
    .unwrap()
    .tree;
    // The label decides nothing: the options build the tree.
    assert_eq!(fingerprint(&a), fingerprint(&b));
    assert_eq!(overridden.preset, Some(Preset::Fast));
}

#[test]
fn every_preset_answers_rays_as_brute_force_does() {
    let mut r = rng(29);
    for &preset in Preset::ALL {
        for n in [1, 40, 700, 4000] {
            let tris = random_triangles(&mut r, n);
            let tree = build_triangles(tris, &on_threads(preset, 2)).unwrap().tree;
            tree.validate().unwrap();
            let rays = random_rays(&mut r, &tree.bounds(), 300);
            if let Err(e) = check_oracle(&tree, &rays) {
                panic!("{preset} on {n} triangles: {e}");
            }
        }
    }
}

#[test]
fn every_preset_builds_one_tree_on_any_number_of_threads() {
    // Big enough for binned nodes under every preset's bins.
    let tris = random_triangles(&mut rng(41), 20_000);
    for &preset in Preset::ALL {
        let one = build_triangles(tris.clone(), &on_threads(preset, 1))
            .unwrap()
            .tree;
        for threads in [2, 3, 5] {
            let many = build_triangles(tris.clone(), &on_threads(preset, threads))
                .unwrap()
                .tree;
            assert_eq!(
                fingerprint(&one),
                fingerprint(&many),
                "{preset}: 1 and {threads} threads built different trees"
            );
        }
    }
}

#[test]
fn every_preset_builds_one_tree_of_a_real_mesh_on_one_and_two_threads() {
    let Some(mesh) = load_scene("bunny.ply") else {
        eprintln!("skipped: no scenes folder (SAHKD_SCENES or ../shared/scenes)");
        return;
    };
    for &preset in Preset::ALL {
        let one = build(&mesh, &on_threads(preset, 1)).unwrap().tree;
        let two = build(&mesh, &on_threads(preset, 2)).unwrap().tree;
        assert_eq!(fingerprint(&one), fingerprint(&two), "{preset} on bunny");
    }
}
