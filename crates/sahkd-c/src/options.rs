//! The build options as one C struct, versioned by its `size` field, with the library's
//! defaults, presets, names and ranges (`sahkd::BuildOptions`).

use crate::checked::{get, get_mut, text};
use crate::{guard, invalid, sahkd_status, Result};
use sahkd::{Algorithm, Axes, BuildOptions, CostModel, Counting, Preset};
use std::ffi::c_char;
use std::mem::{offset_of, size_of};

/// `algorithm`: the default; a binned top built in parallel, then exact sweep subtrees
/// (with bins 0: the paper's level passes on top).
pub const SAHKD_ALGORITHM_HYBRID: u32 = 0;
/// `algorithm`: Wald & Havran's serial O(N log N) sweep.
pub const SAHKD_ALGORITHM_SWEEP: u32 = 1;
/// `algorithm`: Li, Tan & Liao's breadth-first level builder.
pub const SAHKD_ALGORITHM_LEVEL: u32 = 2;
/// `algorithm`: the level framework with brute-force counting.
pub const SAHKD_ALGORITHM_NAIVE: u32 = 3;
/// `algorithm`: spatial-median cuts at the top, exact SAH below.
pub const SAHKD_ALGORITHM_MEDIAN: u32 = 4;
/// `axes`: each node's longest axis only.
pub const SAHKD_AXES_LONGEST: u32 = 0;
/// `axes`: all three axes.
pub const SAHKD_AXES_ALL: u32 = 1;
/// `counting`: the paper's interval-tree walk.
pub const SAHKD_COUNTING_SPACE_TREE: u32 = 0;
/// `counting`: prefix sums over sorted events (the default).
pub const SAHKD_COUNTING_SCAN: u32 = 1;
/// `bins`: the builder's default (binned for the hybrid, exact for the others).
pub const SAHKD_BINS_DEFAULT: i32 = -1;

/// Everything that decides a build. Fill it with sahkd_build_options_default() or
/// sahkd_build_options_preset(), then change fields; `size` tells the library which fields
/// the caller knows (fields past it take their defaults), so programs compiled against an
/// older header keep working.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct sahkd_build_options {
    /// sizeof(sahkd_build_options) as the caller compiled it.
    pub size: u32,
    /// SAHKD_ALGORITHM_*.
    pub algorithm: u32,
    /// SAHKD_AXES_*.
    pub axes: u32,
    /// SAHKD_COUNTING_* (level builder).
    pub counting: u32,
    /// 1: clip straddling triangles to each child (perfect splits); 0: triangle boxes.
    pub clip: u32,
    /// Worker threads of the build; 0: every core.
    pub threads: u32,
    /// SAHKD_BINS_DEFAULT, 0 (exact SAH) or 2 to 1024 bins (sweep and hybrid builders).
    pub bins: i32,
    /// K_T, the cost of a node step (at least 0).
    pub traversal_cost: f32,
    /// K_I, the cost of a triangle test (above 0).
    pub intersection_cost: f32,
    /// Factor on a split with an empty side, in (0, 1]; 1 disables the bonus.
    pub empty_bonus: f32,
    /// Nodes with this many triangles or fewer become leaves unpriced.
    pub leaf_size: u32,
    /// Depth limit, at most 60; 0: 8 + 1.3 log2(triangles).
    pub max_depth: u32,
    /// Splitting stops once references reach this many times the triangles (at least 1).
    pub max_duplication: f32,
    /// Median builder: nodes with more triangles than this are cut by the spatial median.
    pub median_large_node: u32,
}

fn code_of<T: PartialEq + Copy>(all: &[T], v: T) -> u32 {
    all.iter().position(|&a| a == v).unwrap() as u32
}

fn value_of<T: Copy>(all: &[T], names: &[&str], code: u32, what: &str) -> Result<T> {
    match all.get(code as usize) {
        Some(&v) => Ok(v),
        None => invalid(format!(
            "{what} {code} is out of range: 0 to {} ({})",
            all.len() - 1,
            names.join(", ")
        )),
    }
}

impl From<&BuildOptions> for sahkd_build_options {
    fn from(o: &BuildOptions) -> Self {
        sahkd_build_options {
            size: size_of::<sahkd_build_options>() as u32,
            algorithm: code_of(Algorithm::ALL, o.algorithm),
            axes: code_of(Axes::ALL, o.axes),
            counting: code_of(Counting::ALL, o.counting),
            clip: o.clip as u32,
            threads: o.threads.unwrap_or(0) as u32,
            bins: o.bins.map_or(SAHKD_BINS_DEFAULT, |b| b as i32),
            traversal_cost: o.cost.traversal,
            intersection_cost: o.cost.intersection,
            empty_bonus: o.cost.empty_bonus,
            leaf_size: o.cost.leaf_size,
            max_depth: o.cost.max_depth.unwrap_or(0),
            max_duplication: o.cost.max_duplication,
            median_large_node: o.median_large_node,
        }
    }
}

impl sahkd_build_options {
    /// The library's options from the caller's struct, every field checked.
    #[allow(clippy::field_reassign_with_default)]
    pub(crate) fn resolve(&self) -> Result<BuildOptions> {
        let full = size_of::<sahkd_build_options>();
        let known = self.size as usize;
        // Every field is 4 bytes, so a size from any version of the header is a multiple of 4.
        if known < offset_of!(sahkd_build_options, algorithm) || known > full || known % 4 != 0 {
            return invalid(format!(
                "options.size is {known}: set it with sahkd_build_options_default() \
                 (this library's sahkd_build_options has {full} bytes)"
            ));
        }
        // Fields the caller's header did not have take the defaults.
        let mut o = sahkd_build_options::from(&BuildOptions::default());
        unsafe {
            std::ptr::copy_nonoverlapping(
                (self as *const Self).cast::<u8>(),
                (&mut o as *mut Self).cast::<u8>(),
                known,
            );
        }
        let clip = match o.clip {
            0 => false,
            1 => true,
            c => return invalid(format!("options.clip must be 0 or 1, got {c}")),
        };
        // 0 is every core; any other count is checked by `validate`, the library's rule.
        let threads = (o.threads != 0).then_some(o.threads as usize);
        let bins = match o.bins {
            SAHKD_BINS_DEFAULT => None,
            b if b < 0 => {
                return invalid(format!(
                    "options.bins must be SAHKD_BINS_DEFAULT (-1), 0 or 2 to {}, got {b}",
                    sahkd::MAX_BINS
                ))
            }
            b => Some(b as u32),
        };
        // Field by field over the defaults, so that options the library adds later keep
        // their defaults here until this struct grows a field for them.
        let mut options = BuildOptions::default();
        options.algorithm = value_of(
            Algorithm::ALL,
            Algorithm::NAMES,
            o.algorithm,
            "options.algorithm",
        )?;
        options.axes = value_of(Axes::ALL, Axes::NAMES, o.axes, "options.axes")?;
        options.counting = value_of(
            Counting::ALL,
            Counting::NAMES,
            o.counting,
            "options.counting",
        )?;
        options.clip = clip;
        options.threads = threads;
        options.bins = bins;
        options.median_large_node = o.median_large_node;
        options.cost = CostModel {
            traversal: o.traversal_cost,
            intersection: o.intersection_cost,
            empty_bonus: o.empty_bonus,
            leaf_size: o.leaf_size,
            max_depth: (o.max_depth != 0).then_some(o.max_depth),
            max_duplication: o.max_duplication,
        };
        // The struct does not say which preset filled it.
        options.preset = None;
        options.validate().or_else(|e| invalid(e.to_string()))?;
        Ok(options)
    }
}

/// The options of a build: the library's defaults when `options` is NULL.
pub(crate) unsafe fn build_options(options: *const sahkd_build_options) -> Result<BuildOptions> {
    if options.is_null() {
        Ok(BuildOptions::default())
    } else {
        get(options, "options")?.resolve()
    }
}

/// The library's preset of that name (`sahkd::Preset`'s names); "default" is `balanced`.
fn preset(name: &str) -> Result<BuildOptions> {
    if name.trim().eq_ignore_ascii_case("default") {
        return Ok(BuildOptions::default());
    }
    match name.parse::<Preset>() {
        Ok(p) => Ok(p.options()),
        Err(e) => invalid(format!("{e} (or default)")),
    }
}

/// Fills `options` with the library's defaults (and `size`).
#[no_mangle]
pub unsafe extern "C" fn sahkd_build_options_default(
    options: *mut sahkd_build_options,
) -> sahkd_status {
    guard(|| {
        *get_mut(options, "options")? = (&BuildOptions::default()).into();
        Ok(())
    })
}

/// Fills `options` with a named configuration of the library: "fast", "balanced" (also
/// "default"), "quality", "paper", "sweep".
#[no_mangle]
pub unsafe extern "C" fn sahkd_build_options_preset(
    name: *const c_char,
    options: *mut sahkd_build_options,
) -> sahkd_status {
    guard(|| {
        let out = get_mut(options, "options")?;
        *out = (&preset(text(name, "name")?)?).into();
        Ok(())
    })
}

/// Sets one option by the names the command line and Python use: `key` is "algorithm",
/// "axes" or "counting", `value` one of its names (such as "sweep", "all", "space-tree").
#[no_mangle]
pub unsafe extern "C" fn sahkd_build_options_set(
    options: *mut sahkd_build_options,
    key: *const c_char,
    value: *const c_char,
) -> sahkd_status {
    guard(|| {
        let out = get_mut(options, "options")?;
        let (key, value) = (text(key, "key")?, text(value, "value")?);
        let parsed = |e: String| crate::Error {
            status: sahkd_status::SAHKD_ERROR_INVALID_ARGUMENT,
            message: e,
        };
        match key {
            "algorithm" => out.algorithm = code_of(Algorithm::ALL, value.parse().map_err(parsed)?),
            "axes" => out.axes = code_of(Axes::ALL, value.parse().map_err(parsed)?),
            "counting" => out.counting = code_of(Counting::ALL, value.parse().map_err(parsed)?),
            _ => {
                return invalid(format!(
                    "unknown option `{key}`: expected algorithm, axes or counting"
                ))
            }
        }
        Ok(())
    })
}

/// Checks every field as a build would, without building.
#[no_mangle]
pub unsafe extern "C" fn sahkd_build_options_validate(
    options: *const sahkd_build_options,
) -> sahkd_status {
    guard(|| get(options, "options")?.resolve().map(|_| ()))
}
