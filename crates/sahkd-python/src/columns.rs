//! Query answers as the numpy columns the Python API returns, with the miss values in one
//! place: a ray that hits nothing has t = inf, prim (and geometry) -1, u = v = 0; a point
//! with no closest point (an empty mesh) has a NaN point, an infinite distance, prim -1.

use numpy::{Element, PyArray1, PyArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyTuple;

use rayon::prelude::*;
use sahkd::scene::SceneTree;
use sahkd::Hit;

/// The columns of a batch of closest hits: (t, prim, u, v), plus geometry_id for scenes.
pub struct HitColumns<F> {
    t: Vec<F>,
    prim: Vec<i64>,
    u: Vec<F>,
    v: Vec<F>,
    geometry: Option<Vec<i64>>,
}

impl HitColumns<f32> {
    /// The columns of a scene's tree ([`SceneTree::tree`]) as the scene names its hits
    /// ([`SceneTree::scene_hit`]: geometry, primitive within it, barycentrics in its corner
    /// order), with the geometry_id column; misses keep -1. On the current rayon pool.
    pub fn in_scene(mut self, scene: &SceneTree) -> Self {
        let mut geometry = vec![-1i64; self.prim.len()];
        self.prim
            .par_iter_mut()
            .zip(self.u.par_iter_mut())
            .zip(self.v.par_iter_mut())
            .zip(geometry.par_iter_mut())
            .with_min_len(1024)
            .for_each(|(((prim, u), v), g)| {
                if let Ok(index) = u32::try_from(*prim) {
                    let h = scene.scene_hit(Hit {
                        t: 0.0,
                        prim: index,
                        u: *u,
                        v: *v,
                    });
                    (*prim, *u, *v, *g) = (h.prim as i64, h.u, h.v, h.geometry as i64);
                }
            });
        self.geometry = Some(geometry);
        self
    }
}

impl<F: Element + Copy> HitColumns<F> {
    /// `row` gives a hit's (t, prim, u, v); `miss` is the t of a ray that hits nothing
    /// (infinity), `zero` its u and v.
    pub fn new<H>(
        hits: &[Option<H>],
        miss: F,
        zero: F,
        row: impl Fn(&H) -> (F, u32, F, F),
    ) -> Self {
        let n = hits.len();
        let mut c = HitColumns {
            t: Vec::with_capacity(n),
            prim: Vec::with_capacity(n),
            u: Vec::with_capacity(n),
            v: Vec::with_capacity(n),
            geometry: None,
        };
        for h in hits {
            let (t, prim, u, v) = match h {
                Some(h) => {
                    let (t, prim, u, v) = row(h);
                    (t, prim as i64, u, v)
                }
                None => (miss, -1, zero, zero),
            };
            c.t.push(t);
            c.prim.push(prim);
            c.u.push(u);
            c.v.push(v);
        }
        c
    }

    /// Columns made elsewhere (`batch`), with the miss values above.
    pub fn from_columns(t: Vec<F>, prim: Vec<i64>, u: Vec<F>, v: Vec<F>) -> Self {
        HitColumns {
            t,
            prim,
            u,
            v,
            geometry: None,
        }
    }

    /// Adds the geometry_id column of a scene's hits (-1 on a miss).
    pub fn and_geometry<H>(mut self, hits: &[Option<H>], geometry: impl Fn(&H) -> u32) -> Self {
        self.geometry = Some(
            hits.iter()
                .map(|h| h.as_ref().map_or(-1, |h| geometry(h) as i64))
                .collect(),
        );
        self
    }

    /// The columns as a tuple of numpy arrays, taking over the vectors.
    pub fn into_tuple(self, py: Python<'_>) -> PyResult<Bound<'_, PyTuple>> {
        let mut items: Vec<Bound<'_, PyAny>> = vec![
            PyArray1::from_vec(py, self.t).into_any(),
            PyArray1::from_vec(py, self.prim).into_any(),
            PyArray1::from_vec(py, self.u).into_any(),
            PyArray1::from_vec(py, self.v).into_any(),
        ];
        if let Some(g) = self.geometry {
            items.push(PyArray1::from_vec(py, g).into_any());
        }
        PyTuple::new(py, items)
    }
}

/// The columns of a batch of closest points: point (N, 3), distance, prim, plus geometry_id
/// for scenes.
pub struct ClosestColumns {
    point: Vec<f64>,
    distance: Vec<f64>,
    prim: Vec<i64>,
    geometry: Option<Vec<i64>>,
}

impl ClosestColumns {
    /// `row` gives a closest point's (point, distance, prim).
    pub fn new<C>(found: &[Option<C>], row: impl Fn(&C) -> ([f64; 3], f64, u32)) -> Self {
        let n = found.len();
        let mut c = ClosestColumns {
            point: Vec::with_capacity(3 * n),
            distance: Vec::with_capacity(n),
            prim: Vec::with_capacity(n),
            geometry: None,
        };
        for f in found {
            let (point, distance, prim) = match f {
                Some(f) => {
                    let (point, distance, prim) = row(f);
                    (point, distance, prim as i64)
                }
                None => ([f64::NAN; 3], f64::INFINITY, -1),
            };
            c.point.extend(point);
            c.distance.push(distance);
            c.prim.push(prim);
        }
        c
    }

    /// Adds the geometry_id column of a scene's answers (-1 where there is none).
    pub fn and_geometry<C>(mut self, found: &[Option<C>], geometry: impl Fn(&C) -> u32) -> Self {
        self.geometry = Some(
            found
                .iter()
                .map(|f| f.as_ref().map_or(-1, |f| geometry(f) as i64))
                .collect(),
        );
        self
    }

    /// The columns as a tuple of numpy arrays; the points as an (N, 3) array.
    pub fn into_tuple(self, py: Python<'_>) -> PyResult<Bound<'_, PyTuple>> {
        let n = self.distance.len();
        let mut items: Vec<Bound<'_, PyAny>> = vec![
            PyArray1::from_vec(py, self.point)
                .reshape([n, 3])?
                .into_any(),
            PyArray1::from_vec(py, self.distance).into_any(),
            PyArray1::from_vec(py, self.prim).into_any(),
        ];
        if let Some(g) = self.geometry {
            items.push(PyArray1::from_vec(py, g).into_any());
        }
        PyTuple::new(py, items)
    }
}
