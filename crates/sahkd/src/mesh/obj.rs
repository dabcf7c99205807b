//! OBJ reader on top of `tobj`: positions and faces only, every object and group merged
//! into one mesh, polygons fan-triangulated, relative (negative) indices resolved.
//!
//! `tobj` reports errors without a place, so the input goes through [`Lines`], which
//! counts the lines handed to it; an error is then reported at the line being read.

use super::Mesh;
use std::io::{BufRead, Read};

/// The statements of the OBJ format (geometry, grouping, display and free-form); a file with
/// text but none of them is not an OBJ file. `tobj` skips unknown lines without a word.
const STATEMENTS: &[&str] = &[
    "v",
    "vt",
    "vn",
    "vp",
    "f",
    "l",
    "p",
    "o",
    "g",
    "s",
    "mg",
    "usemtl",
    "mtllib",
    "cstype",
    "deg",
    "bmat",
    "step",
    "curv",
    "curv2",
    "surf",
    "parm",
    "trim",
    "hole",
    "scrv",
    "sp",
    "end",
    "con",
    "lod",
    "maplib",
    "usemap",
    "bevel",
    "c_interp",
    "d_interp",
    "shadow_obj",
    "trace_obj",
    "ctech",
    "stech",
    "call",
    "csh",
];

/// Fails for text with no OBJ statement (comments and blank lines alone are an empty mesh),
/// naming its first line.
fn check_is_obj(bytes: &[u8]) -> Result<(), String> {
    let mut first = None;
    for (number, line) in bytes.split(|&b| b == b'\n').enumerate() {
        let text = line.trim_ascii();
        if text.is_empty() || text.starts_with(b"#") {
            continue;
        }
        let keyword = text.split(u8::is_ascii_whitespace).next().unwrap_or(text);
        if STATEMENTS.iter().any(|s| s.as_bytes() == keyword) {
            return Ok(());
        }
        first.get_or_insert((number + 1, text));
    }
    match first {
        None => Ok(()),
        Some((number, text)) => {
            let text = String::from_utf8_lossy(text);
            let shown: String = text.chars().take(40).collect();
            let more = if shown.len() < text.len() { "..." } else { "" };
            Err(format!(
                "not an OBJ file: no OBJ statement (v, f, o, g, ...) in it; line {number} reads '{shown}{more}'"
            ))
        }
    }
}

pub(super) fn parse(bytes: &[u8]) -> Result<Mesh, String> {
    check_is_obj(bytes)?;
    // The update keeps this compiling when optional tobj features add fields.
    #[allow(clippy::needless_update)]
    let options = tobj::LoadOptions {
        triangulate: true,
        single_index: false,
        ignore_points: true,
        ignore_lines: true,
        ..Default::default()
    };
    let mut lines = Lines::new(bytes);
    // Material libraries are never opened: only geometry is read.
    let no_materials = |_: &std::path::Path| Err(tobj::LoadError::OpenFileFailed);
    let (models, _) = tobj::load_obj_buf(&mut lines, &options, no_materials)
        .map_err(|error| describe(error, bytes, &lines))?;

    let mut mesh = Mesh::default();
    for model in &models {
        let positions = &model.mesh.positions;
        let offset = mesh.vertices.len() as u32;
        mesh.vertices
            .extend(positions.chunks_exact(3).map(|p| [p[0], p[1], p[2]]));
        mesh.triangles.extend(
            model
                .mesh
                .indices
                .chunks_exact(3)
                .map(|t| [t[0] + offset, t[1] + offset, t[2] + offset]),
        );
    }
    Ok(mesh)
}

/// A clear message for a `tobj` error raised while `lines` was at its current line.
fn describe(error: tobj::LoadError, bytes: &[u8], lines: &Lines) -> String {
    use tobj::LoadError as E;
    let line = lines.current();
    let text = lines.current_text();
    match error {
        E::PositionParseError => format!("line {line}: vertex '{text}' needs three numbers x y z"),
        E::ScalingByZeroError => format!("line {line}: vertex '{text}' has weight w = 0"),
        E::ColorParseError => format!(
            "line {line}: vertex '{text}' has the wrong number of values (expected x y z, x y z w or x y z r g b)"
        ),
        E::FaceParseError => format!(
            "line {line}: face '{text}' has an index that is not an integer (expected v, v/vt, v//vn or v/vt/vn)"
        ),
        E::MaterialParseError => format!("line {line}: 'usemtl' without a material name"),
        E::ReadError => format!("line {line}: not UTF-8 text"),
        E::FaceVertexOutOfBounds => match first_missing_vertex(bytes) {
            Some((line, index, defined)) => format!(
                "line {line}: face refers to vertex {index}, but {defined} vertices are defined"
            ),
            None => format!(
                "a face before line {line} refers to a vertex that is not defined before its object ends"
            ),
        },
        other => format!("line {line}: {other}"),
    }
}

/// The first face corner (line, index as written, vertices defined) naming a vertex that
/// does not exist: a positive index beyond the file's vertex count, 0, or a negative index
/// reaching before the first vertex. Only run after `tobj` reports such a face.
fn first_missing_vertex(bytes: &[u8]) -> Option<(usize, i64, usize)> {
    let total = bytes
        .split(|&b| b == b'\n')
        .filter(|l| l.trim_ascii_start().starts_with(b"v "))
        .count();
    let mut defined = 0;
    for (number, line) in bytes.split(|&b| b == b'\n').enumerate() {
        let text = String::from_utf8_lossy(line);
        let mut words = text.split_whitespace();
        match words.next() {
            Some("v") => defined += 1,
            Some("f") => {
                for word in words {
                    let Some(Ok(index)) = word.split('/').next().map(str::parse::<i64>) else {
                        continue;
                    };
                    let missing = if index < 0 {
                        index.unsigned_abs() as usize > defined
                    } else {
                        index == 0 || index as usize > total
                    };
                    if missing {
                        let known = if index < 0 { defined } else { total };
                        return Some((number + 1, index, known));
                    }
                }
            }
            _ => {}
        }
    }
    None
}

/// The OBJ text as a `BufRead` that hands out one line at a time, counting them, and
/// blanks `vt` and `vn` lines. Only positions are used, and with no texture coordinates or
/// normals `tobj` never does arithmetic on their indices, which overflows (a panic in
/// debug builds) on a relative index reaching before the first one, as in `f 1/-5 2/-5 3/-5`.
struct Lines<'a> {
    data: &'a [u8],
    /// Start of the line being handed out.
    start: usize,
    /// Bytes of that line already consumed.
    consumed: usize,
    /// Number of lines started so far (the current line's number, 1-based).
    number: usize,
    /// The line at `start` has been counted (and `blank` set for it).
    counted: bool,
    blank: bool,
}

impl<'a> Lines<'a> {
    fn new(data: &'a [u8]) -> Self {
        Lines {
            data,
            start: 0,
            consumed: 0,
            number: 0,
            counted: false,
            blank: false,
        }
    }

    /// End of the line starting at `start`, including its '\n'.
    fn line_end(&self) -> usize {
        self.data[self.start..]
            .iter()
            .position(|&b| b == b'\n')
            .map_or(self.data.len(), |i| self.start + i + 1)
    }

    /// Number of the line read last (the one an error was found on).
    fn current(&self) -> usize {
        self.number.max(1)
    }

    /// The line read last, shortened for a message.
    fn current_text(&self) -> String {
        let mut begin = self.start;
        if self.consumed == 0 && begin > 0 {
            // The line was read completely: step back to its start.
            begin = self.data[..begin - 1]
                .iter()
                .rposition(|&b| b == b'\n')
                .map_or(0, |i| i + 1);
        }
        let end = self.data[begin..]
            .iter()
            .position(|&b| b == b'\n')
            .map_or(self.data.len(), |i| begin + i);
        let text = String::from_utf8_lossy(&self.data[begin..end]);
        let text = text.trim();
        match text.char_indices().nth(60) {
            Some((cut, _)) => format!("{}...", &text[..cut]),
            None => text.to_string(),
        }
    }
}

impl Read for Lines<'_> {
    fn read(&mut self, out: &mut [u8]) -> std::io::Result<usize> {
        let available = self.fill_buf()?;
        let n = available.len().min(out.len());
        out[..n].copy_from_slice(&available[..n]);
        self.consume(n);
        Ok(n)
    }
}

impl BufRead for Lines<'_> {
    fn fill_buf(&mut self) -> std::io::Result<&[u8]> {
        if self.start >= self.data.len() {
            return Ok(&[]);
        }
        let end = self.line_end();
        if !self.counted {
            self.counted = true;
            self.number += 1;
            let words = self.data[self.start..end].trim_ascii_start();
            self.blank = words.starts_with(b"vt") || words.starts_with(b"vn");
            self.blank &= words.get(2).is_none_or(|b| b.is_ascii_whitespace());
        }
        if self.blank {
            return Ok(b"\n");
        }
        Ok(&self.data[self.start + self.consumed..end])
    }

    fn consume(&mut self, amount: usize) {
        let end = self.line_end();
        if self.blank || self.start + self.consumed + amount >= end {
            self.start = end;
            self.consumed = 0;
            self.counted = false;
        } else {
            self.consumed += amount;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn text_without_an_obj_statement_is_not_a_mesh() {
        let e = parse(b"hello world\nthis is not a mesh\n").unwrap_err();
        assert!(
            e.starts_with("not an OBJ file") && e.contains("line 1 reads 'hello world'"),
            "{e}"
        );
        // Empty files and comments alone are an empty mesh; a statement among junk is OBJ.
        assert_eq!(parse(b"").unwrap(), Mesh::default());
        assert_eq!(parse(b"# nothing\n\n").unwrap(), Mesh::default());
        let mesh = parse(b"junk\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
        assert_eq!(mesh.triangles.len(), 1);
    }
}
