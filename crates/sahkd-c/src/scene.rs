//! Scenes: several meshes, each placed as given and again by instances, built into one tree.

use crate::checked::{clear_out, free, get, get_mut, give, put, slice};
use crate::mesh::{build_error, sahkd_mesh};
use crate::options::{build_options, sahkd_build_options};
use crate::{guard, sahkd_status};
use sahkd::{Scene, SceneTree, Transform};

/// Meshes and instances being gathered (not thread-safe while it changes).
pub struct sahkd_scene {
    scene: Scene,
}

/// A built scene: one tree over every placed triangle, every answer with its geometry id.
/// Immutable: any number of threads may query it at once.
pub struct sahkd_scene_tree {
    pub(crate) scene: SceneTree,
}

fn scene_error(e: sahkd::SceneError) -> crate::Error {
    build_error(e)
}

/// A new, empty scene.
#[no_mangle]
pub unsafe extern "C" fn sahkd_scene_new(scene: *mut *mut sahkd_scene) -> sahkd_status {
    guard(|| {
        clear_out(scene, "scene")?;
        give(
            scene,
            sahkd_scene {
                scene: Scene::new(),
            },
        );
        Ok(())
    })
}

/// Frees a scene (NULL: nothing). Scene trees built from it do not need it.
#[no_mangle]
pub unsafe extern "C" fn sahkd_scene_free(scene: *mut sahkd_scene) {
    free(scene)
}

/// Adds a copy of a mesh, placed as given; `*geometry` receives its geometry id (ids count
/// from 0 over meshes and instances).
#[no_mangle]
pub unsafe extern "C" fn sahkd_scene_add_mesh(
    scene: *mut sahkd_scene,
    mesh: *const sahkd_mesh,
    geometry: *mut u32,
) -> sahkd_status {
    guard(|| {
        let s = get_mut(scene, "scene")?;
        let m = &get(mesh, "mesh")?.mesh;
        get(geometry, "geometry")?;
        let id = s.scene.add_mesh(m).map_err(scene_error)?;
        put(geometry, id, "geometry")
    })
}

/// Places the mesh with geometry id `mesh_geometry` (from sahkd_scene_add_mesh) again,
/// transformed by an affine 3x4 matrix (12 doubles, row by row: the top three rows of the
/// 4x4), finite and not singular; `*geometry` receives the instance's id.
#[no_mangle]
pub unsafe extern "C" fn sahkd_scene_add_instance(
    scene: *mut sahkd_scene,
    mesh_geometry: u32,
    transform: *const f64,
    geometry: *mut u32,
) -> sahkd_status {
    guard(|| {
        let s = get_mut(scene, "scene")?;
        let m = slice(transform.cast::<[f64; 4]>(), 3, "transform")?;
        get(geometry, "geometry")?;
        let t = Transform([m[0], m[1], m[2]]);
        let id = s
            .scene
            .add_instance(mesh_geometry, t)
            .map_err(|e| crate::Error {
                status: sahkd_status::SAHKD_ERROR_INVALID_ARGUMENT,
                message: e.to_string(),
            })?;
        put(geometry, id, "geometry")
    })
}

/// The number of geometries (meshes and instances).
#[no_mangle]
pub unsafe extern "C" fn sahkd_scene_count(
    scene: *const sahkd_scene,
    count: *mut usize,
) -> sahkd_status {
    guard(|| put(count, get(scene, "scene")?.scene.len(), "count"))
}

/// Builds one tree over every placed triangle; `options` NULL uses the library's defaults.
#[no_mangle]
pub unsafe extern "C" fn sahkd_scene_build(
    scene: *const sahkd_scene,
    options: *const sahkd_build_options,
    tree: *mut *mut sahkd_scene_tree,
) -> sahkd_status {
    guard(|| {
        clear_out(tree, "tree")?;
        let s = &get(scene, "scene")?.scene;
        let options = build_options(options)?;
        let built = s.build(&options).map_err(scene_error)?;
        give(tree, sahkd_scene_tree { scene: built });
        Ok(())
    })
}

/// Frees a scene tree (NULL: nothing).
#[no_mangle]
pub unsafe extern "C" fn sahkd_scene_tree_free(tree: *mut sahkd_scene_tree) {
    free(tree)
}
