//! `sahkd.Scene`: several meshes and their instances in one tree (`sahkd::scene`), with the
//! geometry id beside the primitive in every answer.
//!
//! The queries follow `KdTree`'s: the same argument checks (`arrays`), names, dtypes and miss
//! values, the same `threads` rule, the interpreter released while they run. The scene is
//! changed under a lock and queried through a shared handle to the last build, so a query
//! never holds the lock while it runs and a build never waits for one.

use std::sync::{Arc, Mutex, MutexGuard};

use numpy::{PyArray1, PyArrayMethods, PyUntypedArray, PyUntypedArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use rayon::ThreadPool;
use sahkd::scene::{Scene, SceneTree, Transform};

use crate::{arrays, options, pool_of, queries};

/// Several meshes, each placed as given and again by instances, in one kd-tree.
///
/// add_mesh(vertices, faces) -> geometry id: a mesh (arrays as for KdTree), placed as given.
/// add_instance(mesh_id, transform) -> geometry id: that mesh placed again, transformed by an
/// affine 4x4 (last row 0, 0, 0, 1) or 3x4 matrix, finite and not singular; mirrors keep the
/// mesh's inside and outside. Ids count from 0 over both calls. build(**options) builds the
/// tree over every placed triangle with KdTree's options; the queries then answer like
/// KdTree's, each with geometry_id (int64, -1 where prim is -1) beside prim (the face index
/// in that geometry's mesh). contains is the union: inside any geometry. Changing the scene
/// after build() needs another build() before the next query.
#[pyclass(module = "sahkd", name = "Scene", frozen)]
pub struct PyScene {
    state: Mutex<State>,
}

#[derive(Default)]
struct State {
    scene: Scene,
    /// The last build's tree and its `threads=`.
    built: Option<(Arc<SceneTree>, Option<usize>)>,
    /// Changed since the last build.
    stale: bool,
}

impl PyScene {
    fn lock(&self) -> MutexGuard<'_, State> {
        // A panic cannot leave the state half changed (each change is one push), so a
        // poisoned lock is still good.
        self.state.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// The last build's tree and its pool, for the shared queries (`queries::methods!`).
    fn target(&self) -> PyResult<(Arc<SceneTree>, Arc<ThreadPool>)> {
        let (tree, threads) = {
            let state = self.lock();
            match &state.built {
                None => Err(PyValueError::new_err(
                    "the scene is not built: call build() after adding meshes and instances",
                )),
                Some(_) if state.stale => Err(PyValueError::new_err(
                    "the scene changed since build(): call build() again",
                )),
                Some((tree, threads)) => Ok((tree.clone(), *threads)),
            }?
        };
        Ok((tree, pool_of(threads)?))
    }
}

/// `build(**options)`: the tree over every placed triangle, on the pool the options
/// chose.
fn build_scene(scene: &PyScene, py: Python<'_>, building: options::Building) -> PyResult<()> {
    let options::Building { options, pool, run } = building;
    // A snapshot (the meshes are shared, not copied): the scene may change meanwhile,
    // and then this build is already stale.
    let (snapshot, len) = {
        let state = scene.lock();
        (state.scene.clone(), state.scene.len())
    };
    let tree = py
        .detach(|| pool.install(|| snapshot.build(&run)))
        .map_err(|e| PyValueError::new_err(e.to_string()))?;
    let mut state = scene.lock();
    state.stale = state.scene.len() != len;
    state.built = Some((Arc::new(tree), options.threads));
    Ok(())
}

/// `transform=`: a 4x4 or 3x4 array of finite numbers.
fn transform_arg(obj: &Bound<'_, PyAny>) -> PyResult<Transform> {
    let py = obj.py();
    let bad = |why: String| PyValueError::new_err(format!("transform: {why}"));
    let arr = py
        .import("numpy")?
        .call_method1("asarray", (obj, "float64"))
        .map_err(|e| bad(format!("must be a 4x4 or 3x4 array of numbers ({e})")))?;
    let shape = arr.cast::<PyUntypedArray>()?.shape().to_vec();
    if shape != [4, 4] && shape != [3, 4] {
        return Err(bad(format!(
            "must be a 4x4 or 3x4 array, got shape {shape:?}"
        )));
    }
    let arr = arr.cast_into::<numpy::PyArray2<f64>>()?;
    let m = arr.try_readonly()?;
    let m = m.as_array();
    let row = |i: usize| [m[[i, 0]], m[[i, 1]], m[[i, 2]], m[[i, 3]]];
    let t = if shape[0] == 4 {
        Transform::from_4x4([row(0), row(1), row(2), row(3)])
    } else {
        Ok(Transform([row(0), row(1), row(2)]))
    };
    let t = t.and_then(|t| t.validate().map(|_| t));
    t.map_err(|e| {
        bad(e
            .to_string()
            .trim_start_matches("bad transform: ")
            .to_string())
    })
}

queries::methods! {
impl PyScene {
    #[new]
    fn new() -> Self {
        PyScene {
            state: Mutex::new(State::default()),
        }
    }

    /// Number of geometries (meshes and instances).
    fn __len__(&self) -> usize {
        self.lock().scene.len()
    }

    fn __repr__(&self) -> String {
        let state = self.lock();
        let built = match (&state.built, state.stale) {
            (None, _) => "not built".to_string(),
            (Some(_), true) => "changed since build".to_string(),
            (Some((tree, _)), false) => format!("{} placed triangles", tree.tree().triangles().len()),
        };
        format!("<sahkd.Scene: {} geometries, {built}>", state.scene.len())
    }

    /// Adds a mesh, placed as given: vertices (V, 3) float32 or float64, faces (F, 3) of any
    /// integer type. Returns its geometry id, which add_instance takes.
    #[pyo3(text_signature = "(self, vertices, faces)")]
    fn add_mesh(&self, vertices: &Bound<'_, PyAny>, faces: &Bound<'_, PyAny>) -> PyResult<i64> {
        let triangles = arrays::triangles_then(vertices, faces, &*pool_of(None)?, |t| t)?;
        let mut state = self.lock();
        let id = state
            .scene
            .add_triangles(triangles)
            .map_err(|e| PyValueError::new_err(e.to_string()))?;
        state.stale = true;
        Ok(id as i64)
    }

    /// Places the mesh with geometry id mesh_id (from add_mesh) again, transformed by a 4x4
    /// or 3x4 affine matrix. Returns the instance's geometry id.
    #[pyo3(text_signature = "(self, mesh_id, transform)")]
    fn add_instance(
        &self,
        mesh_id: &Bound<'_, PyAny>,
        transform: &Bound<'_, PyAny>,
    ) -> PyResult<i64> {
        let id = options::int_arg(Some(mesh_id), "mesh_id")?
            .ok_or_else(|| PyValueError::new_err("mesh_id must be an integer, got None"))?;
        let transform = transform_arg(transform)?;
        let mut state = self.lock();
        let id = u32::try_from(id).map_err(|_| {
            PyValueError::new_err(format!(
                "no mesh with id {id}: ids are the non-negative numbers add_mesh returned"
            ))
        })?;
        let id = state
            .scene
            .add_instance(id, transform)
            .map_err(|e| PyValueError::new_err(e.to_string()))?;
        state.stale = true;
        Ok(id as i64)
    }
}
build {
    /// Builds the tree over every placed triangle; options as for KdTree.
    build(&self, py: Python<'_>) -> ()
        = build_scene(self, py), [],
        "(self, preset=None, algorithm=None, axes=None, counting=None, clip=None, threads=None, bins=None, **cost)";
}
rays {
    /// SceneHits(t, prim, u, v, geometry_id): KdTree.intersect's answer (same arguments,
    /// dtypes and miss values; prim is the face in the geometry's mesh, u, v its
    /// barycentrics), and geometry_id (int64, -1 on a miss). Ties in t go to the lower
    /// geometry id, then the lower face.
    intersect(precision: &str = "f32") -> PyAny = queries::intersect, "(self, origins, directions, t_min=0.0, t_max=math.inf, precision='f32')";
    /// Whether each ray hits any geometry with t_min <= t <= t_max, as a bool array;
    /// arguments as for intersect.
    occluded(precision: &str = "f32") -> PyArray1<bool> = queries::occluded, "(self, origins, directions, t_min=0.0, t_max=math.inf, precision='f32')";
}
points {
    /// SceneClosest(point, distance, prim, geometry_id): KdTree.closest_point's answer over
    /// every geometry (ties to the lower geometry id, then face), and the geometry (int64).
    /// An empty scene gives NaN points, infinite distances, prim and geometry_id -1.
    closest_point() -> PyAny = queries::closest_point, "(self, points)";
    /// Distance from each point to the nearest geometry, (N,) float64 (inf on an empty scene).
    distance() -> PyArray1<f64> = queries::distance, "(self, points)";
    /// The distance, negative inside any geometry, (N,) float64; inside as for KdTree
    /// ("parity" or "winding"), each geometry judged alone.
    signed_distance(inside: &str = "parity") -> PyArray1<f64> = queries::signed_distance, "(self, points, inside='parity')";
    /// Whether each point is inside any geometry, (N,) bool; inside as for signed_distance.
    contains(inside: &str = "parity") -> PyArray1<bool> = queries::contains, "(self, points, inside='parity')";
}
}
