//! Build options from Python keyword arguments.

use std::sync::Arc;

use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use rayon::ThreadPool;
use sahkd::{Algorithm, Axes, BuildOptions, CostModel, Counting, Preset};

/// The cost-model keywords `KdTree(...)` accepts beside its named parameters.
pub const COST_KEYWORDS: [&str; 6] = [
    "traversal",
    "intersection",
    "empty_bonus",
    "leaf_size",
    "max_depth",
    "max_duplication",
];

/// A value of one of the library's named options, by the library's names.
fn choice<T: std::str::FromStr>(name: &str, value: &str, names: &[&str]) -> PyResult<T> {
    value.parse::<T>().map_err(|_| {
        let names: Vec<String> = names.iter().map(|k| format!("'{k}'")).collect();
        PyValueError::new_err(format!(
            "{name} must be one of {}, got '{value}'",
            names.join(", ")
        ))
    })
}

fn type_name(v: &Bound<'_, PyAny>) -> String {
    v.get_type()
        .name()
        .map(|n| n.to_string())
        .unwrap_or_else(|_| "?".into())
}

/// A string argument (None: absent).
pub fn str_arg(v: Option<&Bound<'_, PyAny>>, name: &str) -> PyResult<Option<String>> {
    match v {
        Some(v) if !v.is_none() => v.extract::<String>().map(Some).map_err(|_| {
            PyTypeError::new_err(format!("{name} must be a string, got {}", type_name(v)))
        }),
        _ => Ok(None),
    }
}

/// A True/False argument (numpy booleans too); None: absent.
pub fn bool_arg(v: Option<&Bound<'_, PyAny>>, name: &str) -> PyResult<Option<bool>> {
    match v {
        Some(v) if !v.is_none() => v.extract::<bool>().map(Some).map_err(|_| {
            PyTypeError::new_err(format!(
                "{name} must be True or False, got {}",
                type_name(v)
            ))
        }),
        _ => Ok(None),
    }
}

/// An integer argument or None (bools are refused: `threads=True` is a mistake).
pub fn int_arg(v: Option<&Bound<'_, PyAny>>, name: &str) -> PyResult<Option<i64>> {
    match v {
        Some(v) if !v.is_none() => {
            if v.is_instance_of::<pyo3::types::PyBool>() {
                return Err(PyTypeError::new_err(format!(
                    "{name} must be an integer or None, not a bool"
                )));
            }
            if v.is_instance_of::<pyo3::types::PyInt>() {
                // An int too large for 64 bits is a value out of range, not a wrong type.
                return v
                    .extract::<i64>()
                    .map(Some)
                    .map_err(|_| PyValueError::new_err(format!("{name} = {v} is out of range")));
            }
            v.extract::<i64>().map(Some).map_err(|_| {
                PyTypeError::new_err(format!(
                    "{name} must be an integer or None, got {}",
                    type_name(v)
                ))
            })
        }
        _ => Ok(None),
    }
}

/// The keyword arguments that choose a build, as Python gave them (`None`: not given).
pub struct BuildArgs<'a, 'py> {
    pub preset: Option<&'a Bound<'py, PyAny>>,
    pub algorithm: Option<&'a Bound<'py, PyAny>>,
    pub axes: Option<&'a Bound<'py, PyAny>>,
    pub counting: Option<&'a Bound<'py, PyAny>>,
    pub clip: Option<&'a Bound<'py, PyAny>>,
    pub threads: Option<&'a Bound<'py, PyAny>>,
    pub bins: Option<&'a Bound<'py, PyAny>>,
    /// The remaining keywords: the cost model.
    pub cost: Option<&'a Bound<'py, PyDict>>,
}

/// A build as the arguments chose it.
pub struct Building {
    /// The options as chosen, `threads` among them, for the tree's report.
    pub options: BuildOptions,
    /// The pool the build runs on, and the tree's queries after it.
    pub pool: Arc<ThreadPool>,
    /// The options the build runs with: the pool is chosen here, so the core must not start
    /// one of its own.
    pub run: BuildOptions,
}

impl BuildArgs<'_, '_> {
    /// The options ([`build_options`]) and the pool of `threads=`.
    pub fn parse(self) -> PyResult<Building> {
        let threads = crate::threads_arg(int_arg(self.threads, "threads")?)?;
        let options = build_options(&self, threads)?;
        Ok(Building {
            options,
            pool: crate::pool_of(threads)?,
            run: BuildOptions {
                threads: None,
                ..options
            },
        })
    }
}

/// Options from the build arguments: the preset's (`balanced` when none is named),
/// with every argument given beside it in its place, and `cost` the remaining keywords.
/// Ranges are the library's rules (`BuildOptions::validate`), in its words.
fn build_options(args: &BuildArgs<'_, '_>, threads: Option<usize>) -> PyResult<BuildOptions> {
    let preset: Preset = match str_arg(args.preset, "preset")? {
        Some(p) => choice("preset", &p, Preset::NAMES)?,
        None => Preset::default(),
    };
    let mut o = preset.options();
    if let Some(a) = str_arg(args.algorithm, "algorithm")? {
        o.algorithm = choice("algorithm", &a, Algorithm::NAMES)?;
    }
    if let Some(a) = str_arg(args.axes, "axes")? {
        o.axes = choice("axes", &a, Axes::NAMES)?;
    }
    if let Some(c) = str_arg(args.counting, "counting")? {
        o.counting = choice("counting", &c, Counting::NAMES)?;
    }
    if let Some(clip) = bool_arg(args.clip, "clip")? {
        o.clip = clip;
    }
    o.threads = threads;
    if let Some(kw) = args.cost {
        o.cost = cost_model(kw, o.cost)?;
    }
    if let Some(b) = int_arg(args.bins, "bins")? {
        o.bins = Some(
            u32::try_from(b)
                .map_err(|_| PyValueError::new_err(BuildOptions::bins_out_of_range(b)))?,
        );
    }
    o.validate().map_err(|e| match e {
        sahkd::builders::BuildError::InvalidOptions(m) => PyValueError::new_err(m),
        e => PyValueError::new_err(e.to_string()),
    })?;
    Ok(o)
}

/// `base` with the cost keywords given in `kw` in place (types checked here, ranges by the
/// library's `validate`).
fn cost_model(kw: &Bound<'_, PyDict>, base: CostModel) -> PyResult<CostModel> {
    let unknown: Vec<String> = kw
        .keys()
        .iter()
        .map(|k| k.str().map(|s| s.to_string()))
        .collect::<PyResult<Vec<_>>>()?
        .into_iter()
        .filter(|k| !COST_KEYWORDS.contains(&k.as_str()))
        .collect();
    if !unknown.is_empty() {
        let quoted: Vec<String> = unknown.iter().map(|k| format!("'{k}'")).collect();
        return Err(PyTypeError::new_err(format!(
            "KdTree() got unexpected keyword argument(s) {}; the cost options are {}",
            quoted.join(", "),
            COST_KEYWORDS.join(", ")
        )));
    }
    let mut c = base;
    let get = |k: &str| kw.get_item(k);
    let float = |k: &str, v: &Bound<'_, PyAny>| -> PyResult<f32> {
        v.extract::<f64>()
            .map(|x| x as f32)
            .map_err(|_| PyTypeError::new_err(format!("{k} must be a number")))
    };
    let int = |k: &str, v: &Bound<'_, PyAny>| -> PyResult<u32> {
        if v.is_instance_of::<pyo3::types::PyBool>() {
            return Err(PyTypeError::new_err(format!(
                "{k} must be an integer, not a bool"
            )));
        }
        let x: i64 = v
            .extract()
            .map_err(|_| PyTypeError::new_err(format!("{k} must be an integer")))?;
        u32::try_from(x)
            .map_err(|_| PyValueError::new_err(format!("{k} must be in 0..={}, got {x}", u32::MAX)))
    };
    if let Some(v) = get("traversal")? {
        c.traversal = float("traversal", &v)?;
    }
    if let Some(v) = get("intersection")? {
        c.intersection = float("intersection", &v)?;
    }
    if let Some(v) = get("empty_bonus")? {
        c.empty_bonus = float("empty_bonus", &v)?;
    }
    if let Some(v) = get("leaf_size")? {
        c.leaf_size = int("leaf_size", &v)?;
    }
    if let Some(v) = get("max_depth")? {
        c.max_depth = if v.is_none() {
            None
        } else {
            Some(int("max_depth", &v)?)
        };
    }
    if let Some(v) = get("max_duplication")? {
        c.max_duplication = float("max_duplication", &v)?;
    }
    Ok(c)
}
