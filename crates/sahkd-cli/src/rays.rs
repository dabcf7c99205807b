//! Rays and query points from `.npy` files: float32 rows of origin xyz, direction xyz, and
//! optionally t_min, t_max; or of point xyz.

use anyhow::{anyhow, bail, Context, Result};
use npyz::{DType, NpyFile, Order, TypeChar};
use sahkd::{Ray, Vec3};
use std::fs::File;
use std::io::{BufRead, BufReader};
use std::path::Path;

/// Reads an (R, 6) or (R, 8) float32 array. Rows of 6 get the range [0, inf).
/// A ray the library's input rule refuses (`RayPart::problem`) is an error naming its row.
pub fn read(path: &Path) -> Result<Vec<Ray>> {
    let rows = read_rows(path, &[6, 8], "(R, 6) or (R, 8)", "rays")?;
    (0..rows.rows)
        .map(|r| {
            let at = |col| rows.at(r, col);
            let ray = Ray::new(
                Vec3::new(at(0), at(1), at(2)),
                Vec3::new(at(3), at(4), at(5)),
            );
            let ray = if rows.width == 8 {
                ray.with_range(at(6), at(7))
            } else {
                ray
            };
            match ray.input_problem() {
                Some((part, why)) => {
                    bail!("{}: ray {r}: its {} is {why}", path.display(), part.name())
                }
                None => Ok(ray),
            }
        })
        .collect()
}

/// Reads query points: an (N, 3) float32 array.
pub fn read_points(path: &Path) -> Result<Vec<Vec3>> {
    let rows = read_rows(path, &[3], "(N, 3)", "points")?;
    Ok((0..rows.rows)
        .map(|r| Vec3::new(rows.at(r, 0), rows.at(r, 1), rows.at(r, 2)))
        .collect())
}

/// A 2-D float32 array as read, in either memory order.
struct Rows {
    values: Vec<f32>,
    rows: usize,
    width: usize,
    order: Order,
}

impl Rows {
    /// Fortran order stores column by column; C order row by row.
    fn at(&self, row: usize, col: usize) -> f32 {
        match self.order {
            Order::C => self.values[row * self.width + col],
            Order::Fortran => self.values[col * self.rows + row],
        }
    }
}

/// Reads a float32 array of shape (rows, w) with w one of `widths`; `expected` describes the
/// shape and `noun` the rows in error messages.
fn read_rows(path: &Path, widths: &[u64], expected: &str, noun: &str) -> Result<Rows> {
    let name = path.display();
    if let Some(what) = sahkd::mesh::not_a_file(path) {
        bail!("{name}: is {what}, not a .npy file");
    }
    let file = File::open(path).with_context(|| format!("cannot read {name}"))?;
    let file_bytes = file
        .metadata()
        .with_context(|| format!("cannot read {name}"))?
        .len();
    let mut reader = BufReader::new(file);
    if let Ok(head) = reader.fill_buf() {
        if let Some(rest) = head.strip_prefix(b"\x93NUMPY") {
            if let [major, minor, ..] = rest {
                if !(1..=3).contains(major) {
                    bail!(
                        "{name}: .npy format version {major}.{minor}, which this reader does not \
                         know (it reads versions 1, 2 and 3)"
                    );
                }
            }
        }
    }
    // npyz allocates the header's declared length before reading it: a lying length field
    // (up to 4 GiB in versions 2 and 3) must not become an allocation.
    if let Some((length, prefix)) = reader.fill_buf().ok().and_then(header_length) {
        if (prefix + length) as u64 > file_bytes {
            bail!(
                "{name}: the header declares a header of {length} bytes, more than the file's \
                 {file_bytes} bytes hold"
            );
        }
    }
    // npyz multiplies the header's dimensions unchecked (a panic on overflow in debug builds,
    // a wrong count otherwise), so a shape no file could hold is refused before it looks.
    if let Some((shape, descr, data_start)) = declared_shape(&mut reader) {
        // Another dtype is refused as such, before its size is judged as float32's.
        if let Some(other) = descr.as_deref().filter(|d| !is_float32_descr(d)) {
            bail!(
                "{name}: expected dtype float32, found {}",
                describe_descr(other)
            );
        }
        let data_bytes = file_bytes.saturating_sub(data_start);
        let fits = shape
            .iter()
            .try_fold(4u64, |bytes, &d| bytes.checked_mul(d))
            .is_some_and(|n| n <= data_bytes);
        if !fits {
            bail!(
                "{name}: the header declares shape {} of float32, more than the file's \
                 {data_bytes} bytes of data hold",
                describe_shape(&shape)
            );
        }
    }
    let npy = NpyFile::new(reader).map_err(|e| {
        anyhow!(
            "{name}: not a readable .npy file: {}",
            one_line(&e.to_string())
        )
    })?;
    let dtype = npy.dtype();
    if !is_float32(&dtype) {
        bail!(
            "{name}: expected dtype float32, found {}",
            describe_dtype(&dtype)
        );
    }
    let shape = npy.shape().to_vec();
    let width = match shape[..] {
        [_, w] if widths.contains(&w) => w as usize,
        _ => bail!(
            "{name}: expected shape {expected}, found {}",
            describe_shape(&shape)
        ),
    };
    // Checked again on npyz's reading of the shape, in case the pre-check could not read it.
    if shape[0]
        .checked_mul(width as u64 * 4)
        .is_none_or(|n| n > file_bytes)
    {
        bail!(
            "{name}: the header declares {} {noun}, more than the file holds",
            shape[0]
        );
    }
    let rows = usize::try_from(shape[0]).with_context(|| format!("too many {noun}"))?;
    let order = npy.order();
    let values: Vec<f32> = npy.into_vec().map_err(|e| {
        let what = &noun[..noun.len() - 1];
        anyhow!(
            "{name}: cannot read the {what} data: {}",
            one_line(&e.to_string())
        )
    })?;
    Ok(Rows {
        values,
        rows,
        width,
        order,
    })
}

/// The length of a .npy header as its prefix declares it, and the size of that prefix;
/// `None` when the file does not start like a .npy file (npyz then reports what is wrong).
fn header_length(head: &[u8]) -> Option<(usize, usize)> {
    let rest = head.strip_prefix(b"\x93NUMPY")?;
    // Version 1 has a 2-byte header length, later versions 4 bytes.
    match rest.first()? {
        1 => Some((
            u16::from_le_bytes([*rest.get(2)?, *rest.get(3)?]) as usize,
            10,
        )),
        _ => Some((
            u32::from_le_bytes(rest.get(2..6)?.try_into().ok()?) as usize,
            12,
        )),
    }
}

/// The `shape` of a .npy header, its `descr` when that is a plain type string, and where its
/// data starts, read without consuming it; `None` when the header is not one this can read
/// (npyz then reports what is wrong).
fn declared_shape(reader: &mut BufReader<File>) -> Option<(Vec<u64>, Option<String>, u64)> {
    let head = reader.fill_buf().ok()?;
    let (length, prefix) = header_length(head)?;
    let text = head.get(prefix..)?;
    let header = std::str::from_utf8(text.get(..length.min(text.len()))?).ok()?;
    let key = header
        .find("'shape'")
        .or_else(|| header.find("\"shape\""))?;
    let after = &header[key + "'shape'".len()..];
    let tuple = after
        .trim_start()
        .strip_prefix(':')?
        .trim_start()
        .strip_prefix('(')?;
    let tuple = &tuple[..tuple.find(')')?];
    let shape = tuple
        .split(',')
        .map(str::trim)
        .filter(|d| !d.is_empty())
        .map(|d| d.trim_end_matches('L').parse::<u64>().ok())
        .collect::<Option<Vec<u64>>>()?;
    let descr = ["'descr'", "\"descr\""].iter().find_map(|key| {
        let after = header[header.find(key)? + key.len()..]
            .trim_start()
            .strip_prefix(':')?
            .trim_start();
        let quote = after.chars().next().filter(|c| *c == '\'' || *c == '"')?;
        let value = &after[1..];
        Some(value[..value.find(quote)?].to_string())
    });
    Some((shape, descr, (prefix + length) as u64))
}

/// A plain .npy type string of float32: `<f4`, `>f4`, `=f4` (`|f4` never occurs).
fn is_float32_descr(descr: &str) -> bool {
    matches!(descr, "<f4" | ">f4" | "=f4" | "f4")
}

/// A type string as numpy names its dtype, with the string: `float16 ('<f2')`.
fn describe_descr(descr: &str) -> String {
    let code = descr.trim_start_matches(['<', '>', '=', '|']);
    let mut chars = code.chars();
    let kind = chars.next().map(String::from).unwrap_or_default();
    let size = chars.as_str();
    let bits = size.parse::<u32>().ok().and_then(|n| n.checked_mul(8));
    let numpy = bits.and_then(|bits| match kind.as_str() {
        "b" if bits == 8 => Some("bool".to_string()),
        "i" => Some(format!("int{bits}")),
        "u" => Some(format!("uint{bits}")),
        "f" => Some(format!("float{bits}")),
        "c" => Some(format!("complex{bits}")),
        _ => None,
    });
    let descr = descr.escape_debug();
    match numpy {
        Some(n) => format!("{n} ('{descr}')"),
        None => format!("'{descr}'"),
    }
}

/// An error of npyz in one line: a header it cannot parse comes as a multi-line parser
/// report (position, the header with a caret under it, what was expected), which would
/// break the CLI's one `error:` line. Keeps the first line, the position and the notes.
fn one_line(message: &str) -> String {
    let mut lines = message.lines().map(str::trim).filter(|l| !l.is_empty());
    let first = lines.next().unwrap_or("");
    let mut out = match first.split_once("-->") {
        Some((head, at)) => format!(
            "{} at line:column {} of the header",
            head.trim_end().trim_end_matches(':'),
            at.trim()
        ),
        None => first.to_string(),
    };
    for note in lines.filter_map(|l| l.strip_prefix("= ")) {
        out += &format!(" ({note})");
    }
    out
}

fn is_float32(dtype: &DType) -> bool {
    matches!(dtype, DType::Plain(t) if t.type_char() == TypeChar::Float && t.size_field() == 4)
}

/// A dtype as numpy names it, with its type string: `float64 ('<f8')`.
fn describe_dtype(dtype: &DType) -> String {
    match dtype {
        DType::Plain(t) => {
            let bits = t.size_field() * 8;
            let numpy = match t.type_char() {
                TypeChar::Bool => Some("bool".to_string()),
                TypeChar::Int => Some(format!("int{bits}")),
                TypeChar::Uint => Some(format!("uint{bits}")),
                TypeChar::Float => Some(format!("float{bits}")),
                TypeChar::Complex => Some(format!("complex{bits}")),
                _ => None,
            };
            match numpy {
                Some(n) => format!("{n} ('{t}')"),
                None => format!("'{t}'"),
            }
        }
        DType::Array(..) | DType::Record(_) => format!("the structured dtype {}", dtype.descr()),
    }
}

/// A shape as numpy prints it: `(3, 5)`, `(7,)`, `()`.
fn describe_shape(shape: &[u64]) -> String {
    match shape {
        [n] => format!("({n},)"),
        _ => {
            let dims: Vec<String> = shape.iter().map(u64::to_string).collect();
            format!("({})", dims.join(", "))
        }
    }
}

#[cfg(test)]
mod fuzz;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn npyz_parse_errors_become_one_line() {
        let report = "could not parse Python expression: syntax error:  --> 1:113\n  |\n\
                      1 | {'descr': '<f4', } $\n  |   ^---\n  |\n  = expected EOI";
        assert_eq!(
            one_line(report),
            "could not parse Python expression: syntax error at line:column 1:113 of the header \
             (expected EOI)"
        );
        assert_eq!(one_line("plain message"), "plain message");
    }

    #[test]
    fn shapes_print_like_numpy() {
        assert_eq!(describe_shape(&[]), "()");
        assert_eq!(describe_shape(&[7]), "(7,)");
        assert_eq!(describe_shape(&[3, 5]), "(3, 5)");
    }
}
