//! `sahkd._sahkd`: the Python extension module behind the `sahkd` package.
//!
//! Arrays come in as numpy arrays of float32 or float64 and any integer type, are checked and
//! converted once (`arrays`), and the build and every query then run on a worker pool with
//! the interpreter released (`Python::detach`), so other Python threads go on meanwhile.
//! Results go back as numpy arrays that take over the Rust vectors without a copy.

mod arrays;
mod batch;
mod columns;
mod options;
mod pool;
mod queries;
mod scene;

use std::path::PathBuf;
use std::sync::{Arc, OnceLock};

use numpy::{PyArray1, PyArray2, PyArray3, PyArrayMethods};
use pyo3::exceptions::{PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::pybacked::PyBackedBytes;
use pyo3::sync::PyOnceLock;
use pyo3::types::{PyBytes, PyDict, PyTuple, PyType};
use rayon::ThreadPool;
use sahkd::{Hit, InsideTest, KdTree, LoadError, TreeMeta as Meta, TreeStats, Vec3};

/// A mesh's vertices and faces, as `_read_mesh` returns them.
type MeshArrays<'py> = (Bound<'py, PyArray2<f32>>, Bound<'py, PyArray2<i64>>);

/// Nodes as (N, 2) words and the references, as `_structure` returns them.
type Structure<'py> = (Bound<'py, PyArray2<u32>>, Bound<'py, PyArray1<u32>>);

/// Rays handed to one worker at a time by the all-hits queries.
/// A kd-tree over a triangle mesh, for batched ray queries from numpy.
///
/// vertices: (V, 3) float32 or float64 array; faces: (F, 3) array of any integer type,
/// every index in 0..V. Other memory layouts (slices, transposes) are read in place.
/// preset: "fast", "balanced" (the default), "quality", "paper" or "sweep": named options, by
/// how many rays the tree will trace; the arguments below, when given, override the preset's.
/// algorithm: "hybrid" (binned SAH at the top, then subtrees by the sweep, on
/// every core), "level" (the paper's parallel level-by-level builder), "sweep" (the serial reference
/// builder), "naive" or "median" (Zhou et al.'s spatial-median builder). axes: "longest" or "all"; counting: "scan" or "space-tree" (None:
/// the library defaults, shown in .stats). clip: clip straddling triangles to each child
/// ("perfect splits"). threads: worker threads for the build and for every query of this
/// tree (None: every core, or RAYON_NUM_THREADS). cost: the SAH cost model and limits,
/// traversal, intersection, empty_bonus, leaf_size, max_depth, max_duplication.
///
/// The interpreter is released during the build and every query. Trees pickle, and save
/// to files (save / sahkd.load).
#[pyclass(module = "sahkd", name = "KdTree", frozen)]
struct PyKdTree {
    tree: KdTree,
    meta: Meta,
    stats: OnceLock<TreeStats>,
}

/// Which oracle answers an all-hits query: the tree walk, or every triangle tested.
#[derive(Clone, Copy)]
enum Walk {
    Tree,
    Brute,
}

fn pool_of(threads: Option<usize>) -> PyResult<Arc<ThreadPool>> {
    pool::pool(threads).map_err(PyRuntimeError::new_err)
}

/// `threads=` as `BuildOptions::threads`, whose range `BuildOptions::validate` checks by the
/// library's rule (`sahkd::threads`); only a negative number, which is no count, is refused here.
fn threads_arg(threads: Option<i64>) -> PyResult<Option<usize>> {
    let count = |n: i64| {
        usize::try_from(n).map_err(|_| {
            PyValueError::new_err(format!(
                "threads must be at least 1 (or None for every core), got {n}"
            ))
        })
    };
    threads.map(count).transpose()
}

fn namedtuple<'py>(
    py: Python<'py>,
    cell: &'static PyOnceLock<Py<PyType>>,
    name: &str,
) -> PyResult<Bound<'py, PyType>> {
    Ok(cell.import(py, "sahkd._types", name)?.clone())
}

static ALL_HITS: PyOnceLock<Py<PyType>> = PyOnceLock::new();

/// `inside=`: the name of an inside test.
fn inside_arg(inside: &str) -> PyResult<InsideTest> {
    inside
        .parse()
        .map_err(|e: String| PyValueError::new_err(format!("inside: {e}")))
}

impl PyKdTree {
    fn from_tree(tree: KdTree, meta: Meta) -> Self {
        PyKdTree {
            tree,
            meta,
            stats: OnceLock::new(),
        }
    }

    fn pool(&self) -> PyResult<Arc<ThreadPool>> {
        pool_of(self.meta.options.threads)
    }

    /// What the shared queries (`queries::methods!`) run on.
    fn target(&self) -> PyResult<(&KdTree, Arc<ThreadPool>)> {
        Ok((&self.tree, self.pool()?))
    }

    fn tree_stats(&self) -> &TreeStats {
        self.stats
            .get_or_init(|| self.tree.stats(&self.meta.options.cost))
    }
}

/// Every hit of every ray as flat arrays plus offsets, nearest first within a ray.
fn all_hits<'py>(
    py: Python<'py>,
    tree: &KdTree,
    pool: &ThreadPool,
    input: &arrays::RayInput<'py>,
    max_hits: Option<usize>,
    walk: Walk,
) -> PyResult<Bound<'py, PyAny>> {
    let rows = input.len;
    let (flat, counts) = traced(py, input, |rays| {
        let blocks = batch::per_block(rays, pool, |block| {
            let (mut flat, mut counts, mut buf) = (Vec::new(), Vec::new(), Vec::new());
            for r in block {
                match walk {
                    Walk::Tree => tree.all_hits_into(r, &mut buf),
                    Walk::Brute => tree.brute_all_hits_into(r, &mut buf),
                }
                buf.truncate(max_hits.unwrap_or(usize::MAX));
                counts.push(buf.len() as u32);
                flat.extend_from_slice(&buf);
            }
            (flat, counts)
        })?;
        let total = blocks.iter().map(|(f, _)| f.len()).sum();
        let mut flat: Vec<Hit> = Vec::with_capacity(total);
        let mut counts = Vec::with_capacity(rows);
        for (f, c) in blocks {
            flat.extend(f);
            counts.extend(c);
        }
        Some((flat, counts))
    })?;
    let mut offsets = Vec::with_capacity(counts.len() + 1);
    offsets.push(0i64);
    let mut at = 0i64;
    for c in counts {
        at += c as i64;
        offsets.push(at);
    }
    let t: Vec<f32> = flat.iter().map(|h| h.t).collect();
    let prim: Vec<i64> = flat.iter().map(|h| h.prim as i64).collect();
    let u: Vec<f32> = flat.iter().map(|h| h.u).collect();
    let v: Vec<f32> = flat.iter().map(|h| h.v).collect();
    namedtuple(py, &ALL_HITS, "AllHits")?.call1((
        PyArray1::from_vec(py, t),
        PyArray1::from_vec(py, prim),
        PyArray1::from_vec(py, u),
        PyArray1::from_vec(py, v),
        PyArray1::from_vec(py, offsets),
    ))
}

/// `count_hits`: how many faces each ray hits.
fn count_hits<'py>(
    py: Python<'py>,
    tree: &KdTree,
    pool: &ThreadPool,
    args: queries::RayArgs<'_, 'py>,
) -> PyResult<Bound<'py, PyArray1<i64>>> {
    let input = args.input()?;
    let counts = traced(py, &input, |rays| batch::count_hits(tree, rays, pool))?;
    Ok(PyArray1::from_vec(py, counts))
}

/// `intersect_all`: every hit of every ray, the nearest `max_hits` of each.
fn intersect_all<'py>(
    py: Python<'py>,
    tree: &KdTree,
    pool: &ThreadPool,
    args: queries::RayArgs<'_, 'py>,
    max_hits: Option<&Bound<'_, PyAny>>,
) -> PyResult<Bound<'py, PyAny>> {
    let max_hits = match options::int_arg(max_hits, "max_hits")? {
        None => None,
        Some(m) if m >= 0 => Some(m as usize),
        Some(m) => {
            return Err(PyValueError::new_err(format!(
                "max_hits must be at least 0 (or None for all), got {m}"
            )))
        }
    };
    all_hits(py, tree, pool, &args.input()?, max_hits, Walk::Tree)
}

/// `_brute_force_all`: intersect_all's answer by testing every face of every ray.
fn brute_force_all<'py>(
    py: Python<'py>,
    tree: &KdTree,
    pool: &ThreadPool,
    args: queries::RayArgs<'_, 'py>,
) -> PyResult<Bound<'py, PyAny>> {
    all_hits(py, tree, pool, &args.input()?, None, Walk::Brute)
}

/// `winding_number`: the generalized winding number around each point.
fn winding_number<'py>(
    py: Python<'py>,
    tree: &KdTree,
    pool: &ThreadPool,
    points: &[Vec3],
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    queries::per_point(py, pool, || tree.winding_number_batch(points))
}

/// `KdTree(vertices, faces, **options)`: the tree built on the pool the options chose.
fn build_tree(
    _py: Python<'_>,
    vertices: &Bound<'_, PyAny>,
    faces: &Bound<'_, PyAny>,
    building: options::Building,
) -> PyResult<PyKdTree> {
    let options::Building { options, pool, run } = building;
    let built = arrays::triangles_then(vertices, faces, &pool, |triangles| {
        sahkd::build_triangles(triangles, &run)
    })?
    .map_err(|e| PyValueError::new_err(e.to_string()))?;
    let meta = Meta::new(options, &built.report, pool.current_num_threads());
    Ok(PyKdTree::from_tree(built.tree, meta))
}

/// The checked arrays of a ray batch, with the default bounds [0, inf).
fn ray_input<'py>(
    origins: &Bound<'py, PyAny>,
    directions: &Bound<'py, PyAny>,
    t_min: Option<&Bound<'py, PyAny>>,
    t_max: Option<&Bound<'py, PyAny>>,
) -> PyResult<arrays::RayInput<'py>> {
    let py = origins.py();
    let zero = 0.0f64.into_pyobject(py)?.into_any();
    let inf = f64::INFINITY.into_pyobject(py)?.into_any();
    arrays::ray_input(
        origins,
        directions,
        t_min.unwrap_or(&zero),
        t_max.unwrap_or(&inf),
    )
}

/// `batch::closest`, `batch::occluded` or `batch::count_hits` on the rays of `input` with the interpreter
/// released; a row that is not finite is reported by the serial reader, which names it.
fn traced<T: Send>(
    py: Python<'_>,
    input: &arrays::RayInput<'_>,
    trace: impl FnOnce(&batch::RayArrays<'_>) -> Option<T> + Send,
) -> PyResult<T> {
    let arrays = batch::RayArrays {
        origins: batch::PointView::of(&input.origins),
        directions: batch::PointView::of(&input.directions),
        t_min: input.t_min.view(),
        t_max: input.t_max.view(),
        len: input.len,
    };
    match py.detach(|| trace(&arrays)) {
        Some(answers) => Ok(answers),
        None => {
            arrays::rays(input)?;
            Err(PyRuntimeError::new_err(
                "a ray was refused in the batch but not by the ray reader",
            ))
        }
    }
}

/// The `precision=` argument of the ray queries: "f32" (the default) or "f64".
fn is_f64(precision: &str) -> PyResult<bool> {
    match precision {
        "f32" => Ok(false),
        "f64" => Ok(true),
        other => Err(PyValueError::new_err(format!(
            "precision must be 'f32' or 'f64', got {other:?}"
        ))),
    }
}

queries::methods! {
impl PyKdTree {
    /// Number of triangles.
    fn __len__(&self) -> usize {
        self.tree.triangles().len()
    }

    fn __repr__(&self) -> String {
        let s = self.tree_stats();
        format!(
            "<sahkd.KdTree: {} triangles, {} nodes, {} leaves, algorithm={}>",
            s.triangles,
            s.nodes,
            s.leaves,
            self.meta.options.algorithm.name()
        )
    }

    /// Size, shape and cost of the tree and how it was built, as a dict with the keys of
    /// `sahkd build --json`.
    #[getter]
    fn stats<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let s = self.tree_stats();
        let o = &self.meta.options;
        let d = PyDict::new(py);
        d.set_item("triangles", s.triangles)?;
        d.set_item("nodes", s.nodes)?;
        d.set_item("leaves", s.leaves)?;
        d.set_item("empty_leaves", s.empty_leaves)?;
        d.set_item("references", s.references)?;
        d.set_item("duplication", s.duplication)?;
        d.set_item("max_depth", s.max_depth)?;
        d.set_item("mean_leaf_size", s.mean_leaf_size)?;
        d.set_item("sah_cost", s.sah_cost)?;
        d.set_item("bytes", s.bytes)?;
        d.set_item("build_ms", self.meta.build_ms)?;
        d.set_item("presort_ms", self.meta.presort_ms)?;
        d.set_item("binned_ms", self.meta.binned_ms)?;
        d.set_item("subtrees_ms", self.meta.subtrees_ms)?;
        d.set_item("layout_ms", self.meta.layout_ms)?;
        d.set_item("preset", o.preset.map(|p| p.name()))?;
        d.set_item("algorithm", o.algorithm.name())?;
        d.set_item("axes", o.axes.name())?;
        d.set_item("counting", o.counting.name())?;
        d.set_item("clip", o.clip)?;
        d.set_item("bins", o.resolved_bins())?;
        d.set_item("threads", self.meta.build_threads)?;
        Ok(d)
    }

    /// The scene box as a (2, 3) float32 array: lo, hi.
    #[getter]
    fn bounds<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f32>>> {
        let b = self.tree.bounds();
        Ok(PyArray2::from_vec2(
            py,
            &[b.lo.0.to_vec(), b.hi.0.to_vec()],
        )?)
    }

    /// The triangles as stored (float32), a (F, 3, 3) array: triangle, corner, axis.
    #[getter]
    fn triangles<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray3<f32>>> {
        let flat: Vec<f32> = self
            .tree
            .triangles()
            .iter()
            .flat_map(|t| t.iter().flat_map(|v| v.0))
            .collect();
        let n = self.tree.triangles().len();
        PyArray1::from_vec(py, flat).reshape([n, 3, 3])
    }

    /// The raw structure: nodes as a (N, 2) uint32 array of their two words (see the
    /// `sahkd::tree` docs) and the leaves' references as a uint32 array.
    fn _structure<'py>(&self, py: Python<'py>) -> PyResult<Structure<'py>> {
        let words: Vec<u32> = self.tree.nodes().iter().flat_map(|n| n.words()).collect();
        let n = self.tree.nodes().len();
        Ok((
            PyArray1::from_vec(py, words).reshape([n, 2])?,
            PyArray1::from_vec(py, self.tree.refs().to_vec()),
        ))
    }

    /// Checks the tree's structure and completeness; raises ValueError if it is broken.
    fn validate(&self, py: Python<'_>) -> PyResult<()> {
        py.detach(|| self.tree.validate())
            .map_err(PyValueError::new_err)
    }

    /// The tree, its build options and timings as bytes (the .sahkd file format).
    fn to_bytes<'py>(&self, py: Python<'py>) -> Bound<'py, PyBytes> {
        let bytes = py.detach(|| self.tree.to_bytes(&self.meta));
        PyBytes::new(py, &bytes)
    }

    /// Writes the tree to a file, to be read back by sahkd.load. The file is written whole
    /// or not at all (a temporary beside it, synced, renamed over it).
    fn save(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        py.detach(|| self.tree.save(&path, &self.meta))?;
        Ok(())
    }

    /// Pickling: the tree travels as its bytes and is checked again when unpickled.
    fn __reduce__<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyTuple>> {
        let load = py.import("sahkd")?.getattr("from_bytes")?;
        let bytes = self.to_bytes(py);
        PyTuple::new(py, [load, PyTuple::new(py, [bytes])?.into_any()])
    }
}
build {
    #[new]
    new(py: Python<'_>, vertices: &Bound<'_, PyAny>, faces: &Bound<'_, PyAny>) -> Self
        = build_tree(py, vertices, faces), [vertices, faces],
        "(vertices, faces, preset=None, algorithm=None, axes=None, counting=None, clip=None, threads=None, bins=None, **cost)";
}
rays {
    /// The closest hit of each ray origin + t * direction with t_min <= t <= t_max, as
    /// Hits(t, prim, u, v).
    /// origins, directions: (R, 3) float32 or float64; t_min, t_max: scalars or (R,) arrays.
    /// Returns float32 t (inf on a miss), int64 prim (the face index, -1 on a miss), and
    /// float32 barycentrics u, v of corners 1 and 2 (0 on a miss). Ties in t go to the lower
    /// face index. A ray with a zero direction or t_min > t_max hits nothing.
    /// precision="f64" walks the same tree with the rays (float64 input kept as given), the
    /// plane distances and the triangle tests in float64, for scenes beyond float32 (tiny
    /// triangles far from the origin), and returns float64 t, u, v; about 3x slower.
    intersect(precision: &str = "f32") -> PyAny = queries::intersect, "(self, origins, directions, t_min=0.0, t_max=math.inf, precision='f32')";
    /// Whether each ray hits anything with t_min <= t <= t_max, as a bool array (each ray
    /// stops at the first hit found). precision as in intersect.
    occluded(precision: &str = "f32") -> PyArray1<bool> = queries::occluded, "(self, origins, directions, t_min=0.0, t_max=math.inf, precision='f32')";
    /// How many faces each ray hits with t_min <= t <= t_max (int64), each face once. A ray
    /// through an edge or vertex shared by several faces may count more than one of them.
    count_hits() -> PyArray1<i64> = count_hits, "(self, origins, directions, t_min=0.0, t_max=math.inf)";
    /// Every face each ray hits with t_min <= t <= t_max, each face once, as
    /// AllHits(t, prim, u, v, offsets). The hits of ray i
    /// are t[offsets[i]:offsets[i+1]] (and the same slice of prim, u, v), nearest first, ties
    /// by face index; offsets has R + 1 entries. max_hits keeps only the nearest that many of
    /// each ray. AllHits.ray gives the ray index of each hit.
    intersect_all(max_hits: Option<&Bound<'_, PyAny>> = None) -> PyAny = intersect_all, "(self, origins, directions, t_min=0.0, t_max=math.inf, max_hits=None)";
    /// The brute-force oracle for tests: intersect_all's answer computed by testing every
    /// face of every ray, without the tree.
    _brute_force_all() -> PyAny = brute_force_all, "(self, origins, directions, t_min=0.0, t_max=math.inf)";
}
points {
    /// The closest point of the mesh to each point, as Closest(point, distance, prim):
    /// point (N, 3) float64 on the mesh, distance (N,) float64, prim (N,) int64 (the face;
    /// the lowest index among equally near ones). points: (N, 3) float32 or float64, rounded
    /// to float32 like the mesh; the answer is then exact up to float64 rounding. On a mesh
    /// without faces: NaN points, infinite distances, prim -1.
    closest_point() -> PyAny = queries::closest_point, "(self, points)";
    /// Distance from each point to the mesh, (N,) float64 (inf on a mesh without faces).
    distance() -> PyArray1<f64> = queries::distance, "(self, points)";
    /// Distance from each point to the mesh, negative inside, (N,) float64; 0 on the surface.
    /// inside: "parity" (default: one ray's crossing parity, three voting where it passes near
    /// an edge; fast, for closed meshes) or "winding" (generalized winding number over every face; robust for meshes
    /// with holes, but O(faces) per point).
    signed_distance(inside: &str = "parity") -> PyArray1<f64> = queries::signed_distance, "(self, points, inside='parity')";
    /// Whether each point is inside the mesh, (N,) bool; inside as for signed_distance.
    /// Points on the surface may go either way.
    contains(inside: &str = "parity") -> PyArray1<bool> = queries::contains, "(self, points, inside='parity')";
    /// The generalized winding number of the mesh around each point, (N,) float64: 1 inside
    /// and 0 outside a closed mesh wound outwards (-1 inside one wound inwards), fractional
    /// near holes. Exact sum over every face, O(faces) per point.
    winding_number() -> PyArray1<f64> = winding_number, "(self, points)";
}
}

/// Reads a tree written by KdTree.to_bytes (or pickled); raises ValueError if the data is
/// not a valid tree.
#[pyfunction]
fn from_bytes(py: Python<'_>, data: PyBackedBytes) -> PyResult<PyKdTree> {
    // On this module's pools: rayon's global one is dead in a forked child that unpickles.
    let pool = pool_of(None)?;
    let (tree, meta) = py
        .detach(|| pool.install(|| KdTree::from_bytes(&data)))
        .map_err(|e| PyValueError::new_err(format!("cannot read sahkd tree: {e}")))?;
    Ok(PyKdTree::from_tree(tree, meta))
}

/// Reads a tree saved by KdTree.save; raises OSError if the file cannot be read and
/// ValueError if it is not a valid tree file.
#[pyfunction]
fn load(py: Python<'_>, path: PathBuf) -> PyResult<PyKdTree> {
    let pool = pool_of(None)?;
    let opened = py.detach(|| pool.install(|| KdTree::load(&path)));
    let (tree, meta) = opened.map_err(|e| match e {
        LoadError::Io(e) => PyErr::from(e),
        LoadError::Invalid(e) => PyValueError::new_err(format!("{}: {e}", path.display())),
    })?;
    Ok(PyKdTree::from_tree(tree, meta))
}

/// The vertices ((V, 3) float32) and faces ((F, 3) int64) of a mesh file, as the library
/// reads it for the CLI (`sahkd::Mesh::load`: PLY, ASCII or binary, and OBJ; polygons split
/// into fans); raises OSError if the file cannot be read and ValueError, naming the file,
/// if it is not a mesh it can read.
#[pyfunction]
fn _read_mesh(py: Python<'_>, path: PathBuf) -> PyResult<MeshArrays<'_>> {
    let mesh = py
        .detach(|| sahkd::Mesh::load(&path))
        .map_err(|e| match e {
            sahkd::MeshError::Io { path, source } => PyErr::from(std::io::Error::new(
                source.kind(),
                format!("{path}: {source}"),
            )),
            e => PyValueError::new_err(e.to_string()),
        })?;
    let (v, f) = (mesh.vertices.len(), mesh.triangles.len());
    let vertices: Vec<f32> = mesh.vertices.into_iter().flatten().collect();
    let faces: Vec<i64> = mesh
        .triangles
        .into_iter()
        .flatten()
        .map(i64::from)
        .collect();
    Ok((
        PyArray1::from_vec(py, vertices).reshape([v, 3])?,
        PyArray1::from_vec(py, faces).reshape([f, 3])?,
    ))
}

/// SAH kd-trees for ray casting (the Rust core of the sahkd package).
#[pymodule]
fn _sahkd(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyKdTree>()?;
    m.add_class::<scene::PyScene>()?;
    m.add_function(wrap_pyfunction!(from_bytes, m)?)?;
    m.add_function(wrap_pyfunction!(load, m)?)?;
    m.add_function(wrap_pyfunction!(_read_mesh, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
