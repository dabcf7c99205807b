//! Build options from Python keyword arguments.

use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use sahkd::cost::MAX_DEPTH_CAP;
use sahkd::{Algorithm, Axes, BuildOptions, CostModel, Counting};

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

/// A True/False argument (numpy booleans too).
pub fn bool_arg(v: Option<&Bound<'_, PyAny>>, name: &str, default: bool) -> PyResult<bool> {
    match v {
        None => Ok(default),
        Some(v) => v.extract::<bool>().map_err(|_| {
            PyTypeError::new_err(format!(
                "{name} must be True or False, got {}",
                type_name(v)
            ))
        }),
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

fn positive(name: &str, v: f32) -> PyResult<f32> {
    if v.is_finite() && v > 0.0 {
        Ok(v)
    } else {
        Err(PyValueError::new_err(format!(
            "{name} must be a positive finite number, got {v}"
        )))
    }
}

/// Options from the constructor's arguments; `cost` holds the remaining keywords.
pub fn build_options(
    algorithm: &str,
    axes: Option<&str>,
    counting: Option<&str>,
    clip: bool,
    threads: Option<usize>,
    bins: Option<i64>,
    cost: Option<&Bound<'_, PyDict>>,
) -> PyResult<BuildOptions> {
    let mut o = BuildOptions {
        clip,
        threads,
        ..BuildOptions::default()
    };
    o.algorithm = choice("algorithm", algorithm, Algorithm::NAMES)?;
    if let Some(a) = axes {
        o.axes = choice("axes", a, Axes::NAMES)?;
    }
    if let Some(c) = counting {
        o.counting = choice("counting", c, Counting::NAMES)?;
    }
    if threads == Some(0) {
        return Err(PyValueError::new_err(
            "threads must be at least 1 (or None for every core)",
        ));
    }
    if let Some(kw) = cost {
        o.cost = cost_model(kw)?;
    }
    if let Some(b) = bins {
        o.bins = Some(u32::try_from(b).map_err(|_| {
            PyValueError::new_err(format!(
                "bins must be 0 (exact SAH) or from 2 to {}, got {b}",
                sahkd::MAX_BINS
            ))
        })?);
    }
    // The library's own rules (bins' range, and which builders take bins), named as it names them.
    o.validate().map_err(|e| match e {
        sahkd::builders::BuildError::InvalidOptions(m) => PyValueError::new_err(m),
        e => PyValueError::new_err(e.to_string()),
    })?;
    Ok(o)
}

fn cost_model(kw: &Bound<'_, PyDict>) -> PyResult<CostModel> {
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
    let mut c = CostModel::default();
    let get = |k: &str| kw.get_item(k);
    let float = |k: &str, v: &Bound<'_, PyAny>| -> PyResult<f32> {
        v.extract::<f64>()
            .map(|x| x as f32)
            .map_err(|_| PyTypeError::new_err(format!("{k} must be a number")))
    };
    let int = |k: &str, v: &Bound<'_, PyAny>, max: u32| -> PyResult<u32> {
        if v.is_instance_of::<pyo3::types::PyBool>() {
            return Err(PyTypeError::new_err(format!(
                "{k} must be an integer, not a bool"
            )));
        }
        let x: i64 = v
            .extract()
            .map_err(|_| PyTypeError::new_err(format!("{k} must be an integer")))?;
        u32::try_from(x)
            .ok()
            .filter(|&x| x <= max)
            .ok_or_else(|| PyValueError::new_err(format!("{k} must be in 0..={max}, got {x}")))
    };
    if let Some(v) = get("traversal")? {
        c.traversal = positive("traversal", float("traversal", &v)?)?;
    }
    if let Some(v) = get("intersection")? {
        c.intersection = positive("intersection", float("intersection", &v)?)?;
    }
    if let Some(v) = get("empty_bonus")? {
        let b = float("empty_bonus", &v)?;
        if !(b > 0.0 && b <= 1.0) {
            return Err(PyValueError::new_err(format!(
                "empty_bonus must be in (0, 1] (1 disables the bonus), got {b}"
            )));
        }
        c.empty_bonus = b;
    }
    if let Some(v) = get("leaf_size")? {
        c.leaf_size = int("leaf_size", &v, u32::MAX)?;
    }
    if let Some(v) = get("max_depth")? {
        c.max_depth = if v.is_none() {
            None
        } else {
            Some(int("max_depth", &v, MAX_DEPTH_CAP)?)
        };
    }
    if let Some(v) = get("max_duplication")? {
        let m = float("max_duplication", &v)?;
        if !(m.is_finite() && m >= 1.0) {
            return Err(PyValueError::new_err(format!(
                "max_duplication must be a finite number of at least 1, got {m}"
            )));
        }
        c.max_duplication = m;
    }
    Ok(c)
}
