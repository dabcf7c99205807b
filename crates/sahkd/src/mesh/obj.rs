//! OBJ reader, written by hand: positions and faces only, every object and group merged
//! into one mesh, polygons fan-triangulated, relative (negative) indices resolved.
//!
//! Hand-written rather than a library so that the mesh is the file's: every `v` is one
//! vertex in file order (a general OBJ library splits the file into objects, dropping the
//! vertices an object does not use and repeating those several objects share, so `info`
//! counted vertices the file does not have), and every error names its line.
//!
//! Only `v` and `f` are read. The other statements (texture coordinates, normals, grouping,
//! materials, points, lines, free-form geometry) are accepted and ignored, as are lines of
//! text that are no OBJ statement, as long as the file has at least one statement: text with
//! none at all is not a mesh. Positive indices may refer to vertices defined later in the
//! file (they are checked against the whole file); negative ones count back from the
//! vertices defined so far.

use super::Mesh;

/// The statements of the OBJ format (geometry, grouping, display and free-form); a file with
/// text but none of them is not an OBJ file.
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

/// The logical lines of the file: a line ending in a backslash continues on the next one.
/// Yields the line's text (the pieces joined by a space) and the number of its first line.
struct Statements<'a> {
    data: &'a [u8],
    pos: usize,
    /// Number of the physical line starting at `pos`.
    line: usize,
    joined: Vec<u8>,
}

impl<'a> Statements<'a> {
    fn new(data: &'a [u8]) -> Self {
        Statements {
            data,
            pos: 0,
            line: 1,
            joined: Vec::new(),
        }
    }

    /// The next physical line without its line break.
    fn physical(&mut self) -> Option<&'a [u8]> {
        if self.pos >= self.data.len() {
            return None;
        }
        let rest = &self.data[self.pos..];
        let len = rest.iter().position(|&b| b == b'\n').unwrap_or(rest.len());
        self.pos += (len + 1).min(rest.len());
        self.line += 1;
        let text = &rest[..len];
        Some(text.strip_suffix(b"\r").unwrap_or(text))
    }

    /// The next logical line and its (first) line number.
    fn next(&mut self) -> Option<(&[u8], usize)> {
        let number = self.line;
        let first = self.physical()?;
        let Some(head) = first.trim_ascii_end().strip_suffix(b"\\") else {
            return Some((first, number));
        };
        // Continued: join the pieces (rare, so only these lines are copied).
        self.joined.clear();
        self.joined.extend_from_slice(head);
        while let Some(next) = self.physical() {
            self.joined.push(b' ');
            match next.trim_ascii_end().strip_suffix(b"\\") {
                Some(head) => self.joined.extend_from_slice(head),
                None => {
                    self.joined.extend_from_slice(next);
                    break;
                }
            }
        }
        Some((&self.joined, number))
    }
}

/// A statement shortened for a message.
fn shorten(text: &str) -> String {
    let text = text.trim();
    match text.char_indices().nth(60) {
        Some((cut, _)) => format!("{}...", &text[..cut]),
        None => text.to_string(),
    }
}

pub(super) fn parse(bytes: &[u8]) -> Result<Mesh, String> {
    let mut mesh = Mesh::default();
    let mut statements = Statements::new(bytes);
    // Whether the file has an OBJ statement, and its first line of other text.
    let mut is_obj = false;
    let mut first_other: Option<(usize, String)> = None;
    // Positive indices beyond the vertices defined so far, kept while they grow: the first
    // of them beyond the file's vertex count is the first bad forward reference.
    let mut forward: Vec<(usize, u64)> = Vec::new();
    let mut polygon: Vec<u32> = Vec::new();
    while let Some((raw, line)) = statements.next() {
        let raw = raw.trim_ascii_start();
        if raw.is_empty() || raw.starts_with(b"#") {
            continue;
        }
        let Ok(text) = std::str::from_utf8(raw) else {
            return Err(format!("line {line}: not UTF-8 text"));
        };
        // A comment may follow a statement.
        let text = text.split('#').next().unwrap_or("");
        let mut words = text.split_ascii_whitespace();
        let keyword = words.next().unwrap_or("");
        let at = |message: String| format!("line {line}: {message}");
        match keyword {
            "v" => {
                is_obj = true;
                // x y z, x y z w, or x y z r g b (vertex colours, a common extension).
                let mut numbers = [0f32; 4];
                let mut count = 0;
                for word in words {
                    if let Some(slot) = numbers.get_mut(count) {
                        *slot = word.parse::<f32>().map_err(|_| {
                            at(format!(
                                "vertex '{}': '{word}' is not a number",
                                shorten(text)
                            ))
                        })?;
                    } else if word.parse::<f32>().is_err() {
                        return Err(at(format!(
                            "vertex '{}': '{word}' is not a number",
                            shorten(text)
                        )));
                    }
                    count += 1;
                }
                if count < 3 {
                    return Err(at(format!(
                        "vertex '{}' needs three numbers x y z",
                        shorten(text)
                    )));
                }
                if !matches!(count, 3 | 4 | 6) {
                    return Err(at(format!(
                        "vertex '{}' has the wrong number of values (expected x y z, x y z w or x y z r g b)",
                        shorten(text)
                    )));
                }
                let mut position = [numbers[0], numbers[1], numbers[2]];
                // A weight w makes the position homogeneous (x/w, y/w, z/w).
                if count == 4 {
                    let w = numbers[3];
                    if w == 0.0 {
                        return Err(at(format!("vertex '{}' has weight w = 0", shorten(text))));
                    }
                    position = position.map(|c| c / w);
                }
                if mesh.vertices.len() > u32::MAX as usize {
                    return Err(at("more vertices than 32-bit indices can address".into()));
                }
                mesh.vertices.push(position);
            }
            "f" => {
                is_obj = true;
                polygon.clear();
                let defined = mesh.vertices.len() as u64;
                for word in words {
                    let index = face_index(word)
                        .map_err(|why| at(format!("face '{}': '{word}' {why}", shorten(text))))?;
                    let resolved = match index {
                        0 => {
                            return Err(at(format!(
                                "face '{}' refers to vertex 0; OBJ indices start at 1",
                                shorten(text)
                            )))
                        }
                        i if i < 0 => {
                            if i.unsigned_abs() > defined {
                                return Err(at(format!(
                                    "face refers to vertex {i}, but only {defined} vertices are defined before it"
                                )));
                            }
                            defined - i.unsigned_abs()
                        }
                        i => {
                            let i = i as u64;
                            if i > defined && forward.last().is_none_or(|&(_, m)| i > m) {
                                forward.push((line, i));
                            }
                            i - 1
                        }
                    };
                    let Ok(resolved) = u32::try_from(resolved) else {
                        return Err(at(format!(
                            "face refers to vertex {index}, beyond what 32-bit indices can address"
                        )));
                    };
                    polygon.push(resolved);
                }
                if polygon.len() < 3 {
                    return Err(at(format!(
                        "face '{}' has {} vert{}; a face needs at least 3",
                        shorten(text),
                        polygon.len(),
                        if polygon.len() == 1 { "ex" } else { "ices" }
                    )));
                }
                let first = polygon[0];
                mesh.triangles
                    .extend(polygon[1..].windows(2).map(|p| [first, p[0], p[1]]));
            }
            "usemtl" | "mtllib" if words.next().is_none() => {
                return Err(at(format!("'{keyword}' without a material name")));
            }
            keyword if STATEMENTS.contains(&keyword) => is_obj = true,
            _ => {
                if first_other.is_none() {
                    first_other = Some((line, text.trim().to_string()));
                }
            }
        }
    }
    let total = mesh.vertices.len() as u64;
    if let Some(&(line, index)) = forward.iter().find(|&&(_, i)| i > total) {
        return Err(format!(
            "line {line}: face refers to vertex {index}, but {total} vertices are defined"
        ));
    }
    if let (false, Some((number, text))) = (is_obj, first_other) {
        let shown: String = text.chars().take(40).collect();
        let more = if shown.len() < text.len() { "..." } else { "" };
        return Err(format!(
            "not an OBJ file: no OBJ statement (v, f, o, g, ...) in it; line {number} reads '{shown}{more}'"
        ));
    }
    Ok(mesh)
}

/// The position index of a face corner `v`, `v/vt`, `v//vn` or `v/vt/vn`, or what is wrong
/// with it. Texture and normal indices are checked to be integers but not resolved: only
/// positions are read.
fn face_index(word: &str) -> Result<i64, &'static str> {
    let mut parts = word.split('/');
    let position = parts.next().unwrap_or("");
    let rest: Vec<&str> = parts.collect();
    if rest.len() > 2 {
        return Err("has more than three parts (expected v, v/vt, v//vn or v/vt/vn)");
    }
    let integer = |s: &str| s.parse::<i64>().is_ok();
    if rest.iter().any(|s| !s.is_empty() && !integer(s)) {
        return Err("has an index that is not an integer (expected v, v/vt, v//vn or v/vt/vn)");
    }
    match position.parse::<i64>() {
        Ok(i) => Ok(i),
        Err(e)
            if matches!(
                e.kind(),
                std::num::IntErrorKind::PosOverflow | std::num::IntErrorKind::NegOverflow
            ) =>
        {
            Err("is an index too large for any mesh")
        }
        Err(_) => Err("has an index that is not an integer (expected v, v/vt, v//vn or v/vt/vn)"),
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

    #[test]
    fn continued_lines_keep_the_number_of_their_first_line() {
        let mesh = parse(b"v 0 \\\n 0 0\nv 1 0 0\nv 0 1 0\nf 1 \\\n2 \\\n3\n").unwrap();
        assert_eq!(
            mesh.vertices,
            vec![[0., 0., 0.], [1., 0., 0.], [0., 1., 0.]]
        );
        assert_eq!(mesh.triangles, vec![[0, 1, 2]]);
        let e = parse(b"v 0 0 0\nv 1 0 0\nf 1 \\\n2 \\\n3\nv 0 1 0\nf 1 \\\n 2 9\n").unwrap_err();
        assert!(e.starts_with("line 7: face refers to vertex 9"), "{e}");
    }
}
