//! The queries both classes answer, defined once: KdTree's on its tree and Scene's on its
//! scene tree ([`Target`]), rays in either precision and points. [`methods!`] writes both
//! classes' `#[pymethods]` (pyo3 cannot make those generic): each query is a thin method
//! that asks the class for its target and pool (`target()`) and calls one function with
//! them and its arguments: a generic one here for what both classes answer.

use numpy::PyArray1;
use pyo3::prelude::*;
use pyo3::sync::PyOnceLock;
use pyo3::types::PyType;
use rayon::ThreadPool;
use sahkd::{InsideTest, KdTree, Ray64, SceneTree, Vec3};

use crate::columns::{ClosestColumns, HitColumns};
use crate::{arrays, batch, inside_arg, is_f64, namedtuple, ray_input, traced};

/// The rays of a query, read as `precision=` asks.
pub enum Rays<'py> {
    /// float64 rows, walked in float64.
    F64(Vec<Ray64>),
    /// The checked arrays, read in float32 by each worker.
    F32(arrays::RayInput<'py>),
}

impl<'py> Rays<'py> {
    pub fn read(args: &RayArgs<'_, 'py>, precision: &str) -> PyResult<Self> {
        Ok(if is_f64(precision)? {
            Rays::F64(arrays::rays64(&args.input()?)?)
        } else {
            Rays::F32(args.input()?)
        })
    }
}

/// `impl Target` for a type with the library's query calls: what both types answer with
/// the same calls, after what the type says itself.
macro_rules! target {
    (impl Target for $t:ty { $($own:tt)* }) => {
        impl Target for $t {
            $($own)*
            fn occluded_f64(&self, rays: &[Ray64]) -> Vec<bool> {
                self.occluded_batch_f64(rays)
            }
            fn distances(&self, points: &[Vec3]) -> Vec<f64> {
                self.distance_batch(points)
            }
            fn signed_distances(&self, points: &[Vec3], test: InsideTest) -> Vec<f64> {
                self.signed_distance_batch(points, test)
            }
            fn contain(&self, points: &[Vec3], test: InsideTest) -> Vec<bool> {
                self.contains_batch(points, test)
            }
        }
    };
}

/// What answers queries: a tree, or a scene tree, whose answers also name the geometry.
pub trait Target: Sync {
    fn tree(&self) -> &KdTree;
    /// The named tuple of closest hits (`Hits` or `SceneHits`).
    fn hits_type(py: Python<'_>) -> PyResult<Bound<'_, PyType>>;
    /// The named tuple of closest points (`Closest` or `SceneClosest`).
    fn closest_type(py: Python<'_>) -> PyResult<Bound<'_, PyType>>;
    fn closest_columns(&self, points: &[Vec3]) -> ClosestColumns;
    fn distances(&self, points: &[Vec3]) -> Vec<f64>;
    fn signed_distances(&self, points: &[Vec3], test: InsideTest) -> Vec<f64>;
    fn contain(&self, points: &[Vec3], test: InsideTest) -> Vec<bool>;
    /// Closest hits of float64 rays, as columns.
    fn hits_f64(&self, rays: &[Ray64]) -> HitColumns<f64>;
    /// The float32 walk's columns as this target reports them.
    fn finish(&self, columns: HitColumns<f32>) -> HitColumns<f32>;
    fn occluded_f64(&self, rays: &[Ray64]) -> Vec<bool>;
}

static HITS: PyOnceLock<Py<PyType>> = PyOnceLock::new();
static CLOSEST: PyOnceLock<Py<PyType>> = PyOnceLock::new();
static SCENE_HITS: PyOnceLock<Py<PyType>> = PyOnceLock::new();
static SCENE_CLOSEST: PyOnceLock<Py<PyType>> = PyOnceLock::new();

target! {
impl Target for KdTree {
    fn tree(&self) -> &KdTree {
        self
    }
    fn hits_type(py: Python<'_>) -> PyResult<Bound<'_, PyType>> {
        namedtuple(py, &HITS, "Hits")
    }
    fn closest_type(py: Python<'_>) -> PyResult<Bound<'_, PyType>> {
        namedtuple(py, &CLOSEST, "Closest")
    }
    fn closest_columns(&self, points: &[Vec3]) -> ClosestColumns {
        let found = self.closest_point_batch(points);
        ClosestColumns::new(&found, |c| (c.point, c.distance, c.prim))
    }
    fn hits_f64(&self, rays: &[Ray64]) -> HitColumns<f64> {
        let found = self.intersect_batch_f64(rays);
        HitColumns::new(&found, f64::INFINITY, 0.0, |h| (h.t, h.prim, h.u, h.v))
    }
    fn finish(&self, columns: HitColumns<f32>) -> HitColumns<f32> {
        columns
    }
}
}

target! {
impl Target for SceneTree {
    fn tree(&self) -> &KdTree {
        SceneTree::tree(self)
    }
    fn hits_type(py: Python<'_>) -> PyResult<Bound<'_, PyType>> {
        namedtuple(py, &SCENE_HITS, "SceneHits")
    }
    fn closest_type(py: Python<'_>) -> PyResult<Bound<'_, PyType>> {
        namedtuple(py, &SCENE_CLOSEST, "SceneClosest")
    }
    fn closest_columns(&self, points: &[Vec3]) -> ClosestColumns {
        let found = self.closest_point_batch(points);
        ClosestColumns::new(&found, |c| (c.point, c.distance, c.prim))
            .and_geometry(&found, |c| c.geometry)
    }
    fn hits_f64(&self, rays: &[Ray64]) -> HitColumns<f64> {
        let found = self.intersect_batch_f64(rays);
        HitColumns::new(&found, f64::INFINITY, 0.0, |h| (h.t, h.prim, h.u, h.v))
            .and_geometry(&found, |h| h.geometry)
    }
    fn finish(&self, columns: HitColumns<f32>) -> HitColumns<f32> {
        columns.in_scene(self)
    }
}
}

/// Closest hits as Hits (SceneHits for a scene), the interpreter released.
fn closest<'py, T: Target>(
    py: Python<'py>,
    target: &T,
    rays: &Rays<'py>,
    pool: &ThreadPool,
) -> PyResult<Bound<'py, PyAny>> {
    let columns = match rays {
        Rays::F64(rays) => py
            .detach(|| pool.install(|| target.hits_f64(rays)))
            .into_tuple(py)?,
        Rays::F32(input) => traced(py, input, |rays| {
            let columns = batch::closest(target.tree(), rays, pool)?;
            Some(pool.install(|| target.finish(columns)))
        })?
        .into_tuple(py)?,
    };
    T::hits_type(py)?.call1(columns)
}

/// Whether each ray hits anything, the interpreter released.
fn any_hit<'py>(
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

/// The closest point of the mesh to each point as Closest (SceneClosest for a scene).
pub fn closest_point<'py, T: Target>(
    py: Python<'py>,
    target: &T,
    pool: &ThreadPool,
    points: &[Vec3],
) -> PyResult<Bound<'py, PyAny>> {
    let columns = py.detach(|| pool.install(|| target.closest_columns(points)));
    T::closest_type(py)?.call1(columns.into_tuple(py)?)
}

/// `answer` of the points on the pool, the interpreter released, as a numpy array.
pub fn per_point<'py, E: numpy::Element + Send>(
    py: Python<'py>,
    pool: &ThreadPool,
    answer: impl FnOnce() -> Vec<E> + Send,
) -> PyResult<Bound<'py, PyArray1<E>>> {
    Ok(PyArray1::from_vec(py, py.detach(|| pool.install(answer))))
}

pub fn distance<'py>(
    py: Python<'py>,
    target: &impl Target,
    pool: &ThreadPool,
    points: &[Vec3],
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    per_point(py, pool, || target.distances(points))
}

pub fn signed_distance<'py>(
    py: Python<'py>,
    target: &impl Target,
    pool: &ThreadPool,
    points: &[Vec3],
    inside: &str,
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    let test = inside_arg(inside)?;
    per_point(py, pool, || target.signed_distances(points, test))
}

pub fn contains<'py>(
    py: Python<'py>,
    target: &impl Target,
    pool: &ThreadPool,
    points: &[Vec3],
    inside: &str,
) -> PyResult<Bound<'py, PyArray1<bool>>> {
    let test = inside_arg(inside)?;
    per_point(py, pool, || target.contain(points, test))
}

/// The arguments every ray query takes, as given.
pub struct RayArgs<'a, 'py> {
    pub origins: &'a Bound<'py, PyAny>,
    pub directions: &'a Bound<'py, PyAny>,
    pub t_min: Option<&'a Bound<'py, PyAny>>,
    pub t_max: Option<&'a Bound<'py, PyAny>>,
}

impl<'py> RayArgs<'_, 'py> {
    /// The checked arrays, with the default bounds [0, inf).
    pub fn input(&self) -> PyResult<arrays::RayInput<'py>> {
        ray_input(self.origins, self.directions, self.t_min, self.t_max)
    }
}

/// `intersect`: the closest hits as Hits (SceneHits for a scene).
pub fn intersect<'py, T: Target>(
    py: Python<'py>,
    target: &T,
    pool: &ThreadPool,
    args: RayArgs<'_, 'py>,
    precision: &str,
) -> PyResult<Bound<'py, PyAny>> {
    let rays = Rays::read(&args, precision)?;
    closest(py, target, &rays, pool)
}

/// `occluded`: whether each ray hits anything.
pub fn occluded<'py>(
    py: Python<'py>,
    target: &impl Target,
    pool: &ThreadPool,
    args: RayArgs<'_, 'py>,
    precision: &str,
) -> PyResult<Bound<'py, PyArray1<bool>>> {
    let rays = Rays::read(&args, precision)?;
    any_hit(py, target, &rays, pool)
}

/// The `#[pymethods]` of a class: its own methods (given as `impl Class { ... }`), then
/// its queries, each as a thin method that asks the class for its target and pool (the
/// class's `fn target(&self) -> PyResult<(H, Arc<ThreadPool>)>`, `&*H` what the function
/// takes) and calls one function with them, its arguments and its extra ones. The ray
/// queries take (origins, directions, t_min=None, t_max=None, extra...), the point queries
/// (points, extra...); each is given as `/// docstring` then
/// `name(extra: Type = default, ...) -> Answer = function, "text signature";`. The build
/// (KdTree's constructor, Scene's build) takes the class's own arguments, then the build
/// options of `options::BuildArgs`.
macro_rules! methods {
    (
        impl $class:ident { $($own:tt)* }
        build {
            $(#[$build_attr:meta])*
            $build:ident($($build_head:tt)*) -> $build_ret:ty
                = $build_fn:ident($($build_call:expr),*), [$($build_sig:ident),*], $build_text:literal;
        }
        rays {
            $(
                $(#[$ray_doc:meta])*
                $ray:ident($($ray_arg:ident: $ray_ty:ty = $ray_default:expr),*) -> $ray_ret:ty
                    = $ray_fn:path, $ray_text:literal;
            )*
        }
        points {
            $(
                $(#[$point_doc:meta])*
                $point:ident($($point_arg:ident: $point_ty:ty = $point_default:expr),*) -> $point_ret:ty
                    = $point_fn:path, $point_text:literal;
            )*
        }
    ) => {
        #[pymethods]
        impl $class {
            $($own)*

            $(#[$build_attr])*
            #[pyo3(
                signature = ($($build_sig,)* preset=None, algorithm=None, axes=None, counting=None, clip=None, threads=None, bins=None, **cost),
                text_signature = $build_text
            )]
            #[allow(clippy::too_many_arguments)]
            fn $build(
                $($build_head)*,
                preset: Option<&Bound<'_, PyAny>>,
                algorithm: Option<&Bound<'_, PyAny>>,
                axes: Option<&Bound<'_, PyAny>>,
                counting: Option<&Bound<'_, PyAny>>,
                clip: Option<&Bound<'_, PyAny>>,
                threads: Option<&Bound<'_, PyAny>>,
                bins: Option<&Bound<'_, PyAny>>,
                cost: Option<&Bound<'_, pyo3::types::PyDict>>,
            ) -> PyResult<$build_ret> {
                let args = $crate::options::BuildArgs {
                    preset,
                    algorithm,
                    axes,
                    counting,
                    clip,
                    threads,
                    bins,
                    cost,
                };
                $build_fn($($build_call,)* args.parse()?)
            }

            $(
                $(#[$ray_doc])*
                #[pyo3(
                    signature = (origins, directions, t_min=None, t_max=None $(, $ray_arg = $ray_default)*),
                    text_signature = $ray_text
                )]
                fn $ray<'py>(
                    &self,
                    py: Python<'py>,
                    origins: &Bound<'py, PyAny>,
                    directions: &Bound<'py, PyAny>,
                    t_min: Option<&Bound<'py, PyAny>>,
                    t_max: Option<&Bound<'py, PyAny>>,
                    $($ray_arg: $ray_ty,)*
                ) -> PyResult<Bound<'py, $ray_ret>> {
                    let args = $crate::queries::RayArgs { origins, directions, t_min, t_max };
                    let (target, pool) = self.target()?;
                    $ray_fn(py, &*target, &pool, args $(, $ray_arg)*)
                }
            )*

            $(
                $(#[$point_doc])*
                #[pyo3(signature = (points $(, $point_arg = $point_default)*), text_signature = $point_text)]
                fn $point<'py>(
                    &self,
                    py: Python<'py>,
                    points: &Bound<'py, PyAny>,
                    $($point_arg: $point_ty,)*
                ) -> PyResult<Bound<'py, $point_ret>> {
                    let points = $crate::arrays::query_points(points)?;
                    let (target, pool) = self.target()?;
                    $point_fn(py, &*target, &pool, &points $(, $point_arg)*)
                }
            )*
        }
    };
}
pub(crate) use methods;
