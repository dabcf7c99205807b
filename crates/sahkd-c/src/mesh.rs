//! Meshes and trees: load or copy a mesh, build its tree, save and load trees.

use crate::checked::{clear_out, free, get, give, path, put, slice};
use crate::options::{build_options, sahkd_build_options};
use crate::{error, guard, sahkd_status};
use sahkd::{KdTree, LoadError, Mesh, MeshError, TreeMeta};

/// A triangle mesh: vertices and indexed triangles.
pub struct sahkd_mesh {
    pub(crate) mesh: Mesh,
}

/// A built kd-tree over a mesh's triangles, with its build options. Immutable: any number of
/// threads may query it at once.
pub struct sahkd_tree {
    pub(crate) tree: KdTree,
    pub(crate) meta: TreeMeta,
}

fn mesh_error(e: MeshError) -> crate::Error {
    let status = match e {
        MeshError::Io { .. } => sahkd_status::SAHKD_ERROR_IO,
        _ => sahkd_status::SAHKD_ERROR_INVALID_MESH,
    };
    crate::Error {
        status,
        message: e.to_string(),
    }
}

fn load_error(e: LoadError, what: &str) -> crate::Error {
    let status = match e {
        LoadError::Io(_) => sahkd_status::SAHKD_ERROR_IO,
        LoadError::Invalid(_) => sahkd_status::SAHKD_ERROR_INVALID_TREE,
    };
    crate::Error {
        status,
        message: format!("{what}: {e}"),
    }
}

/// Reads a mesh from a PLY (ASCII or binary) or OBJ file.
#[no_mangle]
pub unsafe extern "C" fn sahkd_mesh_load(
    path_utf8: *const std::ffi::c_char,
    mesh: *mut *mut sahkd_mesh,
) -> sahkd_status {
    guard(|| {
        clear_out(mesh, "mesh")?;
        let loaded = Mesh::load(path(path_utf8, "path")?).map_err(mesh_error)?;
        give(mesh, sahkd_mesh { mesh: loaded });
        Ok(())
    })
}

/// Copies a mesh from arrays: `vertices` holds 3 floats per vertex, `indices` 3 vertex
/// indices per triangle. Every vertex must be finite and every index below `vertex_count`.
#[no_mangle]
pub unsafe extern "C" fn sahkd_mesh_new(
    vertices: *const f32,
    vertex_count: usize,
    indices: *const u32,
    triangle_count: usize,
    mesh: *mut *mut sahkd_mesh,
) -> sahkd_status {
    guard(|| {
        clear_out(mesh, "mesh")?;
        let v = slice(vertices.cast::<[f32; 3]>(), vertex_count, "vertices")?;
        let t = slice(indices.cast::<[u32; 3]>(), triangle_count, "indices")?;
        let m = Mesh {
            vertices: v.to_vec(),
            triangles: t.to_vec(),
        };
        m.validate().map_err(mesh_error)?;
        give(mesh, sahkd_mesh { mesh: m });
        Ok(())
    })
}

/// Frees a mesh (NULL: nothing). Trees built from it do not need it.
#[no_mangle]
pub unsafe extern "C" fn sahkd_mesh_free(mesh: *mut sahkd_mesh) {
    free(mesh)
}

/// The mesh's vertex and triangle counts (either output may be NULL).
#[no_mangle]
pub unsafe extern "C" fn sahkd_mesh_counts(
    mesh: *const sahkd_mesh,
    vertex_count: *mut usize,
    triangle_count: *mut usize,
) -> sahkd_status {
    guard(|| {
        let m = &get(mesh, "mesh")?.mesh;
        if !vertex_count.is_null() {
            put(vertex_count, m.vertices.len(), "vertex_count")?;
        }
        if !triangle_count.is_null() {
            put(triangle_count, m.triangles.len(), "triangle_count")?;
        }
        Ok(())
    })
}

pub(crate) fn build_error(e: impl std::fmt::Display) -> crate::Error {
    let message = e.to_string();
    let status = if message.starts_with("invalid mesh") {
        sahkd_status::SAHKD_ERROR_INVALID_MESH
    } else {
        sahkd_status::SAHKD_ERROR_INVALID_ARGUMENT
    };
    crate::Error { status, message }
}

pub(crate) fn meta(options: sahkd::BuildOptions, report: &sahkd::BuildReport) -> TreeMeta {
    let threads = options.threads.unwrap_or_else(rayon::current_num_threads);
    TreeMeta::new(options, report, threads)
}

/// Builds the kd-tree of a mesh; `options` NULL uses the library's defaults.
#[no_mangle]
pub unsafe extern "C" fn sahkd_tree_build(
    mesh: *const sahkd_mesh,
    options: *const sahkd_build_options,
    tree: *mut *mut sahkd_tree,
) -> sahkd_status {
    guard(|| {
        clear_out(tree, "tree")?;
        let m = &get(mesh, "mesh")?.mesh;
        let options = build_options(options)?;
        let built = sahkd::build(m, &options).map_err(build_error)?;
        let meta = meta(options, &built.report);
        give(
            tree,
            sahkd_tree {
                tree: built.tree,
                meta,
            },
        );
        Ok(())
    })
}

/// Frees a tree (NULL: nothing).
#[no_mangle]
pub unsafe extern "C" fn sahkd_tree_free(tree: *mut sahkd_tree) {
    free(tree)
}

/// The number of triangles in the tree.
#[no_mangle]
pub unsafe extern "C" fn sahkd_tree_triangle_count(
    tree: *const sahkd_tree,
    count: *mut usize,
) -> sahkd_status {
    guard(|| put(count, get(tree, "tree")?.tree.triangles().len(), "count"))
}

/// The scene box: `lo` and `hi` receive 3 floats each.
#[no_mangle]
pub unsafe extern "C" fn sahkd_tree_bounds(
    tree: *const sahkd_tree,
    lo: *mut f32,
    hi: *mut f32,
) -> sahkd_status {
    guard(|| {
        let b = get(tree, "tree")?.tree.bounds();
        put(lo.cast::<[f32; 3]>(), b.lo.0, "lo")?;
        put(hi.cast::<[f32; 3]>(), b.hi.0, "hi")
    })
}

/// The tree's build options (as given to the build, or as saved in its file).
#[no_mangle]
pub unsafe extern "C" fn sahkd_tree_options(
    tree: *const sahkd_tree,
    options: *mut sahkd_build_options,
) -> sahkd_status {
    guard(|| {
        put(
            options,
            (&get(tree, "tree")?.meta.options).into(),
            "options",
        )
    })
}

/// Checks the tree's whole structure; SAHKD_ERROR_INVALID_TREE names what is broken.
#[no_mangle]
pub unsafe extern "C" fn sahkd_tree_validate(tree: *const sahkd_tree) -> sahkd_status {
    guard(|| {
        get(tree, "tree")?
            .tree
            .validate()
            .or_else(|e| error(sahkd_status::SAHKD_ERROR_INVALID_TREE, e))
    })
}

/// Writes the tree to a file (the .sahkd format the command line and Python read), whole or
/// not at all.
#[no_mangle]
pub unsafe extern "C" fn sahkd_tree_save(
    tree: *const sahkd_tree,
    path_utf8: *const std::ffi::c_char,
) -> sahkd_status {
    guard(|| {
        let t = get(tree, "tree")?;
        let p = path(path_utf8, "path")?;
        t.tree.save(&p, &t.meta).or_else(|e| {
            error(
                sahkd_status::SAHKD_ERROR_IO,
                format!("{}: {e}", p.display()),
            )
        })
    })
}

/// Opens a tree saved by sahkd_tree_save (or `sahkd build --save`, or Python's save).
#[no_mangle]
pub unsafe extern "C" fn sahkd_tree_load(
    path_utf8: *const std::ffi::c_char,
    tree: *mut *mut sahkd_tree,
) -> sahkd_status {
    guard(|| {
        clear_out(tree, "tree")?;
        let p = path(path_utf8, "path")?;
        let (t, meta) = KdTree::load(&p).map_err(|e| load_error(e, &p.display().to_string()))?;
        give(tree, sahkd_tree { tree: t, meta });
        Ok(())
    })
}

/// The tree as bytes of the .sahkd format, in a buffer owned by sahkd: free it with
/// sahkd_bytes_free(*data, *size).
#[no_mangle]
pub unsafe extern "C" fn sahkd_tree_to_bytes(
    tree: *const sahkd_tree,
    data: *mut *mut u8,
    size: *mut usize,
) -> sahkd_status {
    guard(|| {
        clear_out(data, "data")?;
        put(size, 0, "size")?;
        let t = get(tree, "tree")?;
        let bytes = t.tree.to_bytes(&t.meta).into_boxed_slice();
        *size = bytes.len();
        *data = Box::into_raw(bytes).cast::<u8>();
        Ok(())
    })
}

/// Frees bytes from sahkd_tree_to_bytes (NULL: nothing); `size` must be the size it gave.
#[no_mangle]
pub unsafe extern "C" fn sahkd_bytes_free(data: *mut u8, size: usize) {
    if !data.is_null() {
        drop(Box::from_raw(std::ptr::slice_from_raw_parts_mut(
            data, size,
        )));
    }
}

/// Reads a tree from bytes of the .sahkd format (checked as a file is).
#[no_mangle]
pub unsafe extern "C" fn sahkd_tree_from_bytes(
    data: *const u8,
    size: usize,
    tree: *mut *mut sahkd_tree,
) -> sahkd_status {
    guard(|| {
        clear_out(tree, "tree")?;
        let bytes = slice(data, size, "data")?;
        let (t, meta) = KdTree::from_bytes(bytes).map_err(|e| load_error(e, "bytes"))?;
        give(tree, sahkd_tree { tree: t, meta });
        Ok(())
    })
}
