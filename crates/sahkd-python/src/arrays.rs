//! numpy arrays in: checks of shape, dtype and values, and conversion to the core's types.
//!
//! Arrays are read where they lie, through their strides: a C-contiguous array is read as one
//! slice, any other layout row by row, so slices and transposes are accepted without a copy.
//! Only arrays numpy cannot hand over as a plain view (misaligned, or in the other byte order)
//! are first copied by numpy into a normal array. Every value is checked on the way in, so a
//! bad input is a Python exception naming the offending row, never a wrong answer or a crash.

use numpy::ndarray::{ArrayView1, ArrayView2};
use numpy::prelude::*;
use numpy::{Element, PyArray1, PyArray2, PyUntypedArray};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use rayon::prelude::*;
use rayon::ThreadPool;
use sahkd::{Ray, Ray64, RayPart, Triangle, Vec3};

/// Any numpy array (array-likes go through `numpy.asarray`), in native byte order and aligned.
fn ndarray<'py>(obj: &Bound<'py, PyAny>, name: &str) -> PyResult<Bound<'py, PyUntypedArray>> {
    let py = obj.py();
    let numpy = py.import("numpy")?;
    let arr = match obj.cast::<PyUntypedArray>() {
        Ok(a) => a.clone(),
        Err(_) => numpy
            .call_method1("asarray", (obj,))
            .map_err(|e| {
                PyTypeError::new_err(format!("{name} must be a numpy array or array-like: {e}"))
            })?
            .cast_into::<PyUntypedArray>()
            .map_err(|_| PyTypeError::new_err(format!("{name} must be a numpy array")))?,
    };
    let dtype = arr.dtype();
    if dtype.has_fields() || dtype.has_subarray() {
        return Err(PyTypeError::new_err(format!(
            "{name} must be a plain numeric array, not a structured one (dtype {})",
            dtype_name(&arr)
        )));
    }
    if arr.is_aligned() && dtype.is_native_byteorder() != Some(false) {
        return Ok(arr);
    }
    let native = dtype.call_method1("newbyteorder", ("=",))?;
    Ok(numpy
        .call_method1("ascontiguousarray", (&arr, native))?
        .cast_into::<PyUntypedArray>()?)
}

fn dtype_name(arr: &Bound<'_, PyUntypedArray>) -> String {
    arr.dtype()
        .str()
        .map(|s| s.to_string())
        .unwrap_or_else(|_| "?".into())
}

fn shape_text(shape: &[usize]) -> String {
    match shape {
        [n] => format!("({n},)"),
        _ => format!(
            "({})",
            shape
                .iter()
                .map(|d| d.to_string())
                .collect::<Vec<_>>()
                .join(", ")
        ),
    }
}

/// Checks that `arr` is `(n, 3)`, naming the expected shape as `what`.
fn check_rows_of_3(arr: &Bound<'_, PyUntypedArray>, name: &str, what: &str) -> PyResult<usize> {
    let shape = arr.shape();
    if shape.len() != 2 || shape[1] != 3 {
        return Err(PyValueError::new_err(format!(
            "{name} must have shape {what}, got {}",
            shape_text(shape)
        )));
    }
    Ok(shape[0])
}

/// Calls `f(row_index, row)` for each row of an `(n, 3)` view, in order.
fn for_each_row<T: Copy, E>(
    view: ArrayView2<'_, T>,
    mut f: impl FnMut(usize, [T; 3]) -> Result<(), E>,
) -> Result<(), E> {
    if let Some(flat) = view.as_slice() {
        for (i, r) in flat.chunks_exact(3).enumerate() {
            f(i, [r[0], r[1], r[2]])?;
        }
    } else {
        for (i, r) in view.outer_iter().enumerate() {
            f(i, [r[0], r[1], r[2]])?;
        }
    }
    Ok(())
}

/// Rows per task of the parallel readers below.
const ROWS_PER_TASK: usize = 4096;

/// `f` of every row of an `(n, 3)` view, in order, computed on the current rayon pool's
/// workers, or `None` when `ok` refuses a row (the serial readers then name it). The rows are
/// checked first and mapped after, each worker taking [`ROWS_PER_TASK`] rows at a time in a
/// plain loop: a task per row cost more than the reads, and so did carrying the refusal
/// through the map (an `Option` per row).
fn map_rows<T: Copy + Sync, R: Copy + Default + Send>(
    view: ArrayView2<'_, T>,
    ok: impl Fn([T; 3]) -> bool + Sync,
    f: impl Fn([T; 3]) -> R + Sync,
) -> Option<Vec<R>> {
    let n = view.nrows();
    let flat = view.as_slice();
    let row = |i: usize| match flat {
        Some(f) => [f[3 * i], f[3 * i + 1], f[3 * i + 2]],
        None => [view[[i, 0]], view[[i, 1]], view[[i, 2]]],
    };
    let task = |t: usize| t * ROWS_PER_TASK..n.min((t + 1) * ROWS_PER_TASK);
    let tasks = n.div_ceil(ROWS_PER_TASK);
    if !(0..tasks)
        .into_par_iter()
        .all(|t| task(t).all(|i| ok(row(i))))
    {
        return None;
    }
    let mut rows = vec![R::default(); n];
    rows.par_chunks_mut(ROWS_PER_TASK)
        .enumerate()
        .for_each(|(t, out)| {
            for (o, i) in out.iter_mut().zip(task(t)) {
                *o = f(row(i));
            }
        });
    Some(rows)
}

/// A float32 or float64 `(n, 3)` array, borrowed read-only.
pub enum Points<'py> {
    F32(numpy::PyReadonlyArray2<'py, f32>),
    F64(numpy::PyReadonlyArray2<'py, f64>),
}

/// A [`Points`]' values, readable from any thread.
#[derive(Clone, Copy)]
enum PointsView<'a> {
    F32(ArrayView2<'a, f32>),
    F64(ArrayView2<'a, f64>),
}

impl Points<'_> {
    fn view(&self) -> PointsView<'_> {
        match self {
            Points::F32(a) => PointsView::F32(a.as_array()),
            Points::F64(a) => PointsView::F64(a.as_array()),
        }
    }
}

impl PointsView<'_> {
    /// The points in single precision, read on the current pool's workers, or `None` when one
    /// is not finite in float32 (`visit_points` names it).
    fn single_rows(self) -> Option<Vec<[f32; 3]>> {
        let finite = |p: [f32; 3]| p.iter().all(|c| c.is_finite());
        let single = |p: [f64; 3]| p.map(|c| c as f32);
        match self {
            PointsView::F32(a) => map_rows(a, finite, |p| p),
            PointsView::F64(a) => map_rows(a, |p| finite(single(p)), single),
        }
    }
}

fn points<'py>(obj: &Bound<'py, PyAny>, name: &str, what: &str) -> PyResult<(Points<'py>, usize)> {
    let arr = ndarray(obj, name)?;
    let dtype = arr.dtype();
    let (kind, size) = (dtype.kind(), dtype.itemsize());
    let pts = match (kind, size) {
        (b'f', 4) => Points::F32(arr.cast::<PyArray2<f32>>().map_err(|_| shape_err(&arr, name, what))?.try_readonly()?),
        (b'f', 8) => Points::F64(arr.cast::<PyArray2<f64>>().map_err(|_| shape_err(&arr, name, what))?.try_readonly()?),
        _ => {
            return Err(PyTypeError::new_err(format!(
                "{name} must be a float32 or float64 array, got dtype {} (convert with .astype(numpy.float32))",
                dtype_name(&arr)
            )))
        }
    };
    let n = check_rows_of_3(&arr, name, what)?;
    Ok((pts, n))
}

fn shape_err(arr: &Bound<'_, PyUntypedArray>, name: &str, what: &str) -> PyErr {
    PyValueError::new_err(format!(
        "{name} must have shape {what}, got {}",
        shape_text(arr.shape())
    ))
}

/// Calls `f(row, point)` for every row in single precision, rejecting values that are not
/// finite (or overflow float32) with the row named.
fn visit_points(pts: &Points<'_>, name: &str, mut f: impl FnMut(usize, [f32; 3])) -> PyResult<()> {
    visit_points_f64(pts, name, "float32", |i, p| {
        let q = p.map(|c| c as f32);
        q.iter().all(|c| c.is_finite()).then(|| f(i, q)).is_some()
    })
}

/// Calls `f(row, point)` for every row in double precision; a row that is not finite, or for
/// which `f` returns false (not finite in `precision`), is an error naming the row.
fn visit_points_f64(
    pts: &Points<'_>,
    name: &str,
    precision: &str,
    mut f: impl FnMut(usize, [f64; 3]) -> bool,
) -> PyResult<()> {
    let mut visit = |i: usize, p: [f64; 3]| -> PyResult<()> {
        if !(p.iter().all(|c| c.is_finite()) && f(i, p)) {
            return Err(PyValueError::new_err(format!(
                "{name}[{i}] = ({}, {}, {}) is not finite in {precision}",
                p[0], p[1], p[2]
            )));
        }
        Ok(())
    };
    match pts {
        Points::F32(a) => for_each_row(a.as_array(), |i, r| visit(i, r.map(f64::from))),
        Points::F64(a) => for_each_row(a.as_array(), visit),
    }
}

/// An `(n, 3)` float array in single precision.
fn read_points(obj: &Bound<'_, PyAny>, name: &str, what: &str) -> PyResult<Vec<[f32; 3]>> {
    let (pts, n) = points(obj, name, what)?;
    let mut out = Vec::with_capacity(n);
    visit_points(&pts, name, |_, p| out.push(p))?;
    Ok(out)
}

/// Query points: an `(N, 3)` float32 or float64 array, rounded to float32 (the precision of
/// the mesh); a non-finite point is an error.
pub fn query_points(obj: &Bound<'_, PyAny>) -> PyResult<Vec<Vec3>> {
    Ok(read_points(obj, "points", "(N, 3)")?
        .into_iter()
        .map(Vec3)
        .collect())
}

/// Integer dtypes accepted for face indices.
trait Index: Element + Copy {
    fn wide(self) -> i128;
}
macro_rules! index_types {
    ($($t:ty),*) => { $(impl Index for $t { fn wide(self) -> i128 { self as i128 } })* };
}
index_types!(i8, i16, i32, i64, u8, u16, u32, u64);

/// What the parallel reader refused: a vertex not finite, or a face's index beyond the
/// vertices (how many there are); the serial readers then name the row.
enum Refused {
    Vertex,
    Face(usize),
}

/// `then` of the triangles of `vertices` (the array `points` was read from) and the faces
/// `arr`, read on `pool`'s workers with the interpreter released, in the same call as `then`
/// (a build): each call wakes the workers and puts the caller to sleep, which on one core
/// took longer than the reads.
fn faces_of<T: Index + Sync, R: Send>(
    vertices: &Bound<'_, PyAny>,
    points: &Points<'_>,
    arr: &Bound<'_, PyUntypedArray>,
    pool: &ThreadPool,
    then: impl FnOnce(Vec<Triangle>) -> R + Send,
) -> PyResult<R> {
    let faces = arr
        .cast::<PyArray2<T>>()
        .map_err(|_| shape_err(arr, "faces", "(F, 3)"))?
        .try_readonly()?;
    let view = faces.as_array();
    let points = points.view();
    let read = arr.py().detach(|| {
        pool.install(|| {
            let corners = points.single_rows().ok_or(Refused::Vertex)?;
            let n = corners.len() as u128;
            // A negative index, widened, is beyond every count.
            let ok = |r: [T; 3]| r.iter().all(|k| (k.wide() as u128) < n);
            let at = |k: T| Vec3(corners[k.wide() as usize]);
            let triangles =
                map_rows(view, ok, |r| r.map(at)).ok_or(Refused::Face(corners.len()))?;
            // Freed before the build, whose peak it would add to.
            drop(corners);
            Ok(then(triangles))
        })
    });
    let n = match read {
        Ok(done) => return Ok(done),
        Err(Refused::Vertex) => {
            read_points(vertices, "vertices", "(V, 3)")?;
            unreachable!("a vertex refused by the parallel reader is named by the serial one")
        }
        Err(Refused::Face(n)) => n as i128,
    };
    for_each_row(view, |i, r| {
        match r.iter().map(|k| k.wide()).find(|w| !(0..n).contains(w)) {
            None => Ok(()),
            Some(w) => {
                let valid = match n {
                    0 => "there are no vertices".to_string(),
                    1 => "the only vertex is 0".to_string(),
                    _ => format!("valid indices are 0 to {}", n - 1),
                };
                Err(PyValueError::new_err(format!(
                    "faces[{i}] refers to vertex {w}, but there are only {n} vertices ({valid})"
                )))
            }
        }
    })?;
    unreachable!("a face refused by the parallel reader is named by the serial one")
}

/// `then` of the triangles of an indexed mesh, `(V, 3)` float vertices and `(F, 3)` integer
/// faces, gathered on `pool`'s workers; `then` runs there too, with the interpreter released.
pub fn triangles_then<R: Send>(
    vertices: &Bound<'_, PyAny>,
    faces: &Bound<'_, PyAny>,
    pool: &ThreadPool,
    then: impl FnOnce(Vec<Triangle>) -> R + Send,
) -> PyResult<R> {
    let (points, _) = points(vertices, "vertices", "(V, 3)")?;
    let arr = ndarray(faces, "faces")?;
    check_rows_of_3(&arr, "faces", "(F, 3)")?;
    let dtype = arr.dtype();
    macro_rules! read {
        ($index:ty) => {
            faces_of::<$index, R>(vertices, &points, &arr, pool, then)
        };
    }
    match (dtype.kind(), dtype.itemsize()) {
        (b'i', 1) => read!(i8),
        (b'i', 2) => read!(i16),
        (b'i', 4) => read!(i32),
        (b'i', 8) => read!(i64),
        (b'u', 1) => read!(u8),
        (b'u', 2) => read!(u16),
        (b'u', 4) => read!(u32),
        (b'u', 8) => read!(u64),
        _ => Err(PyTypeError::new_err(format!(
            "faces must be an integer array, got dtype {}",
            dtype_name(&arr)
        ))),
    }
}

/// A ray parameter bound: one value for every ray, or one per ray. float32 and float64
/// arrays are borrowed as they lie (a 1M-ray call used to spend a tenth of its time casting
/// them to float64 and copying them, serially, with the interpreter held); other numeric
/// dtypes are converted to float64 by numpy first.
pub enum Bound1<'py> {
    All(f64),
    F32(numpy::PyReadonlyArray1<'py, f32>),
    F64(numpy::PyReadonlyArray1<'py, f64>),
}

impl Bound1<'_> {
    /// The values, readable from any thread.
    pub fn view(&self) -> BoundView<'_> {
        match self {
            Bound1::All(v) => BoundView::All(*v),
            Bound1::F32(a) => BoundView::F32(a.as_array()),
            Bound1::F64(a) => BoundView::F64(a.as_array()),
        }
    }
}

/// A [`Bound1`]'s values.
#[derive(Clone, Copy)]
pub enum BoundView<'a> {
    All(f64),
    F32(ArrayView1<'a, f32>),
    F64(ArrayView1<'a, f64>),
}

impl BoundView<'_> {
    #[inline(always)]
    pub fn get(&self, i: usize) -> f64 {
        match self {
            BoundView::All(v) => *v,
            BoundView::F32(a) => a[i] as f64,
            BoundView::F64(a) => a[i],
        }
    }

    /// The first index whose value fails `ok`, if any. A contiguous array is first checked
    /// whole without stopping early, which the compiler vectorizes.
    fn first_bad(&self, ok: impl Fn(f64) -> bool) -> Option<usize> {
        fn first<T: Copy>(a: &ArrayView1<'_, T>, ok: impl Fn(T) -> bool) -> Option<usize> {
            if let Some(s) = a.as_slice() {
                if s.iter().fold(true, |all, &v| all & ok(v)) {
                    return None;
                }
            }
            a.iter().position(|&v| !ok(v))
        }
        match self {
            BoundView::All(v) => (!ok(*v)).then_some(0),
            BoundView::F32(a) => first(a, |v| ok(v as f64)),
            BoundView::F64(a) => first(a, ok),
        }
    }
}

fn ray_bound<'py>(obj: &Bound<'py, PyAny>, part: RayPart, rays: usize) -> PyResult<Bound1<'py>> {
    let name = part.name();
    let ok = |v: f64| part.problem(v).is_none();
    if obj.cast::<PyUntypedArray>().is_err() {
        if let Ok(v) = obj.extract::<f64>() {
            if let Some(why) = part.problem(v) {
                return Err(PyValueError::new_err(format!("{name} is {why}")));
            }
            return Ok(Bound1::All(v));
        }
    }
    let arr = ndarray(obj, name)?;
    let dtype = arr.dtype();
    let (kind, size) = (dtype.kind(), dtype.itemsize());
    if !matches!(kind, b'f' | b'i' | b'u') {
        return Err(PyTypeError::new_err(format!(
            "{name} must be a number or an array of numbers, got dtype {}",
            dtype_name(&arr)
        )));
    }
    let shape = arr.shape().to_vec();
    let bound = match (shape.len(), kind, size) {
        (1, _, _) if shape[0] != rays => None,
        (1, b'f', 4) => Some(Bound1::F32(
            arr.cast_into::<PyArray1<f32>>()?.try_readonly()?,
        )),
        (1, b'f', 8) => Some(Bound1::F64(
            arr.cast_into::<PyArray1<f64>>()?.try_readonly()?,
        )),
        (0 | 1, _, _) => {
            let floats = obj
                .py()
                .import("numpy")?
                .call_method1("asarray", (&arr, "float64"))?;
            Some(if shape.is_empty() {
                Bound1::All(floats.extract::<f64>()?)
            } else {
                Bound1::F64(floats.cast_into::<PyArray1<f64>>()?.try_readonly()?)
            })
        }
        _ => None,
    };
    let Some(bound) = bound else {
        return Err(PyValueError::new_err(format!(
            "{name} must be a scalar or have shape ({rays},) like the rays, got {}",
            shape_text(&shape)
        )));
    };
    if let Some(i) = bound.view().first_bad(ok) {
        let at = if shape.is_empty() {
            String::new()
        } else {
            format!("[{i}]")
        };
        let why = part.problem(bound.view().get(i)).unwrap_or("refused");
        return Err(PyValueError::new_err(format!("{name}{at} is {why}")));
    }
    Ok(bound)
}

/// [`rays`] in double precision, for the f64 queries: float64 input is kept as given.
pub fn rays64(input: &RayInput<'_>) -> PyResult<Vec<Ray64>> {
    let (lo, hi) = (input.t_min.view(), input.t_max.view());
    let (o, d, n) = (&input.origins, &input.directions, input.len);
    let mut rays = Vec::with_capacity(n);
    visit_points_f64(o, "origins", "float64", |i, p| {
        rays.push(Ray64::new(p, [0.0; 3]).with_range(lo.get(i), hi.get(i)));
        true
    })?;
    visit_points_f64(d, "directions", "float64", |i, p| {
        rays[i].direction = p;
        true
    })?;
    Ok(rays)
}

/// The rays of a call as columns: `len` origins and directions (`P`), and their bounds (`B`).
pub struct RayColumns<P, B> {
    pub origins: P,
    pub directions: P,
    pub t_min: B,
    pub t_max: B,
    pub len: usize,
}

/// The arrays of a ray batch with their shapes and bounds checked (rows are checked where
/// they are read): `(R, 3)` origins and directions, scalar or `(R,)` bounds.
pub type RayInput<'py> = RayColumns<Points<'py>, Bound1<'py>>;

pub fn ray_input<'py>(
    origins: &Bound<'py, PyAny>,
    directions: &Bound<'py, PyAny>,
    t_min: &Bound<'py, PyAny>,
    t_max: &Bound<'py, PyAny>,
) -> PyResult<RayInput<'py>> {
    let (origins, n) = points(origins, "origins", "(R, 3)")?;
    let (directions, m) = points(directions, "directions", "(R, 3)")?;
    if n != m {
        return Err(PyValueError::new_err(format!(
            "origins and directions must have the same number of rays, got {n} and {m}"
        )));
    }
    Ok(RayInput {
        origins,
        directions,
        t_min: ray_bound(t_min, RayPart::TMin, n)?,
        t_max: ray_bound(t_max, RayPart::TMax, n)?,
        len: n,
    })
}

/// The rays of `input`. Non-finite origins, directions or bounds are errors naming the first
/// bad row; a zero direction or an empty range is a ray that hits nothing.
pub fn rays(input: &RayInput<'_>) -> PyResult<Vec<Ray>> {
    let (lo, hi) = (input.t_min.view(), input.t_max.view());
    // Straight into the rays, without a copy of either array on the way.
    let mut rays = Vec::with_capacity(input.len);
    visit_points(&input.origins, "origins", |i, p| {
        rays.push(
            Ray::new(Vec3(p), Vec3::splat(0.0)).with_range(lo.get(i) as f32, hi.get(i) as f32),
        )
    })?;
    visit_points(&input.directions, "directions", |i, p| {
        rays[i].direction = Vec3(p)
    })?;
    Ok(rays)
}
