//! The ray queries both classes answer, KdTree's on its tree and Scene's on its scene tree,
//! in either precision: one body for intersect and one for occluded.

use numpy::PyArray1;
use pyo3::prelude::*;
use pyo3::types::PyTuple;
use rayon::ThreadPool;
use sahkd::{KdTree, Ray64, SceneTree};

use crate::columns::HitColumns;
use crate::{arrays, batch, is_f64, ray_args64, ray_input, traced};

/// The rays of a query, read as `precision=` asks.
pub enum Rays<'py> {
    /// float64 rows, walked in float64.
    F64(Vec<Ray64>),
    /// The checked arrays, read in float32 by each worker.
    F32(arrays::RayInput<'py>),
}

impl<'py> Rays<'py> {
    pub fn read(
        origins: &Bound<'py, PyAny>,
        directions: &Bound<'py, PyAny>,
        t_min: Option<&Bound<'py, PyAny>>,
        t_max: Option<&Bound<'py, PyAny>>,
        precision: &str,
    ) -> PyResult<Self> {
        Ok(if is_f64(precision)? {
            Rays::F64(ray_args64(origins, directions, t_min, t_max)?)
        } else {
            Rays::F32(ray_input(origins, directions, t_min, t_max)?)
        })
    }
}

/// What answers rays: a tree, or a scene tree, whose answers also name the geometry.
pub trait Target: Sync {
    fn tree(&self) -> &KdTree;
    /// Closest hits of float64 rays, as columns.
    fn hits_f64(&self, rays: &[Ray64]) -> HitColumns<f64>;
    /// The float32 walk's columns as this target reports them.
    fn finish(&self, columns: HitColumns<f32>) -> HitColumns<f32>;
    fn occluded_f64(&self, rays: &[Ray64]) -> Vec<bool>;
}

impl Target for KdTree {
    fn tree(&self) -> &KdTree {
        self
    }
    fn hits_f64(&self, rays: &[Ray64]) -> HitColumns<f64> {
        let found = self.intersect_batch_f64(rays);
        HitColumns::new(&found, f64::INFINITY, 0.0, |h| (h.t, h.prim, h.u, h.v))
    }
    fn finish(&self, columns: HitColumns<f32>) -> HitColumns<f32> {
        columns
    }
    fn occluded_f64(&self, rays: &[Ray64]) -> Vec<bool> {
        self.occluded_batch_f64(rays)
    }
}

impl Target for SceneTree {
    fn tree(&self) -> &KdTree {
        SceneTree::tree(self)
    }
    fn hits_f64(&self, rays: &[Ray64]) -> HitColumns<f64> {
        let found = self.intersect_batch_f64(rays);
        HitColumns::new(&found, f64::INFINITY, 0.0, |h| (h.t, h.prim, h.u, h.v))
            .and_geometry(&found, |h| h.geometry)
    }
    fn finish(&self, columns: HitColumns<f32>) -> HitColumns<f32> {
        columns.in_scene(self)
    }
    fn occluded_f64(&self, rays: &[Ray64]) -> Vec<bool> {
        self.occluded_batch_f64(rays)
    }
}

/// Closest hits as the fields of Hits (SceneHits for a scene), the interpreter released.
pub fn closest<'py>(
    py: Python<'py>,
    target: &impl Target,
    rays: &Rays<'py>,
    pool: &ThreadPool,
) -> PyResult<Bound<'py, PyTuple>> {
    match rays {
        Rays::F64(rays) => py
            .detach(|| pool.install(|| target.hits_f64(rays)))
            .into_tuple(py),
        Rays::F32(input) => traced(py, input, |rays| {
            let columns = batch::closest(target.tree(), rays, pool)?;
            Some(pool.install(|| target.finish(columns)))
        })?
        .into_tuple(py),
    }
}

/// Whether each ray hits anything, the interpreter released.
pub fn occluded<'py>(
    py: Python<'py>,
    target: &impl Target,
    rays: &Rays<'py>,
    pool: &ThreadPool,
) -> PyResult<Bound<'py, PyArray1<bool>>> {
    let hit = match rays {
        Rays::F64(rays) => py.detach(|| pool.install(|| target.occluded_f64(rays))),
        Rays::F32(input) => traced(py, input, |rays| batch::occluded(target.tree(), rays, pool))?,
    };
    Ok(PyArray1::from_vec(py, hit))
}
