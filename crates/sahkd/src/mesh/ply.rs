//! PLY reader: ASCII, binary little-endian and binary big-endian, version 1.0.
//!
//! Written by hand because it is the product's input path: the common scanner layout
//! (three float coordinates, faces as a uchar count and int indices) is read straight
//! from the byte slice, which is several times faster than a general PLY library. Any
//! other layout goes through a general reader that walks each record property by property.
//!
//! Only vertex positions (`x`, `y`, `z`) and the face list (`vertex_indices` or
//! `vertex_index`) are kept; every other property and element is skipped. Polygons are
//! fan-triangulated; faces with fewer than three indices are dropped. Index ranges are
//! checked later by `Mesh::validate`.

use super::Mesh;

/// The scalar types of PLY 1.0, under either of their spellings.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    fn from_name(name: &str) -> Option<Scalar> {
        Some(match name {
            "char" | "int8" => Scalar::I8,
            "uchar" | "uint8" => Scalar::U8,
            "short" | "int16" => Scalar::I16,
            "ushort" | "uint16" => Scalar::U16,
            "int" | "int32" => Scalar::I32,
            "uint" | "uint32" => Scalar::U32,
            "float" | "float32" => Scalar::F32,
            "double" | "float64" => Scalar::F64,
            _ => return None,
        })
    }

    fn name(self) -> &'static str {
        match self {
            Scalar::I8 => "char",
            Scalar::U8 => "uchar",
            Scalar::I16 => "short",
            Scalar::U16 => "ushort",
            Scalar::I32 => "int",
            Scalar::U32 => "uint",
            Scalar::F32 => "float",
            Scalar::F64 => "double",
        }
    }

    fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }

    fn is_integer(self) -> bool {
        !matches!(self, Scalar::F32 | Scalar::F64)
    }

    /// The values an integer type can hold (ASCII values outside it are rejected).
    fn range(self) -> (i64, i64) {
        match self {
            Scalar::I8 => (i8::MIN.into(), i8::MAX.into()),
            Scalar::U8 => (0, u8::MAX.into()),
            Scalar::I16 => (i16::MIN.into(), i16::MAX.into()),
            Scalar::U16 => (0, u16::MAX.into()),
            Scalar::I32 => (i32::MIN.into(), i32::MAX.into()),
            Scalar::U32 => (0, u32::MAX.into()),
            Scalar::F32 | Scalar::F64 => (i64::MIN, i64::MAX),
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Kind {
    Scalar(Scalar),
    List { count: Scalar, item: Scalar },
}

#[derive(Debug)]
struct Property {
    name: String,
    kind: Kind,
}

#[derive(Debug)]
struct Element {
    name: String,
    count: u64,
    properties: Vec<Property>,
}

impl Element {
    /// Size of one record when every property is a scalar (lists make records variable).
    fn fixed_stride(&self) -> Option<usize> {
        self.properties.iter().try_fold(0, |sum, p| match p.kind {
            Kind::Scalar(t) => Some(sum + t.size()),
            Kind::List { .. } => None,
        })
    }

    /// "vertices", "faces", or "'edge' elements", for messages.
    fn plural(&self) -> String {
        match self.name.as_str() {
            "vertex" => "vertices".into(),
            "face" => "faces".into(),
            name => format!("'{name}' elements"),
        }
    }

    fn truncated(&self, done: u64) -> String {
        format!("file ends after {done} of {} {}", self.count, self.plural())
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Encoding {
    Ascii,
    BinaryLittle,
    BinaryBig,
}

/// Where the vertex positions and the face indices are in the element list.
#[derive(Clone, Copy, Debug)]
struct Roles {
    vertex: usize,
    /// Property indices of x, y and z within the vertex element.
    xyz: [usize; 3],
    face: usize,
    /// Property index of the index list within the face element.
    indices: usize,
}

#[derive(Debug)]
struct Header {
    encoding: Encoding,
    elements: Vec<Element>,
    roles: Roles,
    /// Offset of the first byte after the `end_header` line.
    body: usize,
    /// Number of header lines (the ASCII body starts on the next line).
    lines: usize,
}

pub(super) fn parse(bytes: &[u8]) -> Result<Mesh, String> {
    let header = parse_header(bytes)?;
    let body = &bytes[header.body..];
    let mut mesh = Mesh::default();
    match header.encoding {
        Encoding::Ascii => read_ascii(&header, body, &mut mesh)?,
        Encoding::BinaryLittle => read_binary::<Little>(&header, body, &mut mesh)?,
        Encoding::BinaryBig => read_binary::<Big>(&header, body, &mut mesh)?,
    }
    Ok(mesh)
}

// ---------------------------------------------------------------------------------------
// Header

fn parse_header(bytes: &[u8]) -> Result<Header, String> {
    let Some(rest) = [&b"ply\n"[..], b"ply\r\n"]
        .iter()
        .find_map(|first| bytes.strip_prefix(*first))
    else {
        return Err("not a PLY file: it does not start with a 'ply' line".into());
    };
    let mut encoding = None;
    let mut elements: Vec<Element> = Vec::new();
    let mut pos = bytes.len() - rest.len();
    let mut number = 1;
    loop {
        let Some(len) = bytes[pos..].iter().position(|&b| b == b'\n') else {
            return Err("header: no 'end_header' line (the file is truncated or not a PLY)".into());
        };
        number += 1;
        let raw = &bytes[pos..pos + len];
        pos += len + 1;
        let raw = raw.strip_suffix(b"\r").unwrap_or(raw);
        // Comments are skipped before the text check: some writers put Latin-1 in them.
        let first_word = raw.split(u8::is_ascii_whitespace).find(|w| !w.is_empty());
        if matches!(first_word, Some(b"comment" | b"obj_info")) {
            continue;
        }
        let Ok(line) = std::str::from_utf8(raw) else {
            return Err(format!("header line {number}: not text"));
        };
        let at = |message: String| format!("header line {number}: {message}");
        let words: Vec<&str> = line.split_whitespace().collect();
        match words.as_slice() {
            [] => {}
            ["end_header"] => break,
            ["format", format, version] => {
                if encoding.is_some() {
                    return Err(at("a second 'format' line".into()));
                }
                encoding = Some(match *format {
                    "ascii" => Encoding::Ascii,
                    "binary_little_endian" => Encoding::BinaryLittle,
                    "binary_big_endian" => Encoding::BinaryBig,
                    _ => return Err(at(format!(
                        "unknown format '{format}' (expected ascii, binary_little_endian or binary_big_endian)"
                    ))),
                });
                if version.parse::<f64>() != Ok(1.0) {
                    return Err(at(format!(
                        "unsupported PLY version '{version}' (only 1.0 is supported)"
                    )));
                }
            }
            ["format", ..] => {
                return Err(at("expected 'format <kind> 1.0'".into()));
            }
            ["element", name, count] => {
                let count = count.parse::<u64>().map_err(|_| {
                    at(format!(
                        "element '{name}' count '{count}' is not a non-negative integer"
                    ))
                })?;
                if elements.iter().any(|e| e.name == *name) {
                    return Err(at(format!("element '{name}' is declared twice")));
                }
                elements.push(Element {
                    name: name.to_string(),
                    count,
                    properties: Vec::new(),
                });
            }
            ["element", ..] => return Err(at("expected 'element <name> <count>'".into())),
            ["property", rest @ ..] => {
                let Some(element) = elements.last_mut() else {
                    return Err(at("property before any element".into()));
                };
                let scalar = |name: &str| {
                    Scalar::from_name(name)
                        .ok_or_else(|| at(format!("unknown property type '{name}'")))
                };
                let (kind, name) = match rest {
                    ["list", count, item, name] => {
                        let count = scalar(count)?;
                        if !count.is_integer() {
                            return Err(at(format!(
                                "list '{name}' has count type '{}'; counts must be integers",
                                count.name()
                            )));
                        }
                        let item = scalar(item)?;
                        (Kind::List { count, item }, *name)
                    }
                    ["list", ..] => {
                        return Err(at(
                            "expected 'property list <count type> <item type> <name>'".into(),
                        ))
                    }
                    [ty, name] => (Kind::Scalar(scalar(ty)?), *name),
                    _ => return Err(at("expected 'property <type> <name>'".into())),
                };
                element.properties.push(Property {
                    name: name.to_string(),
                    kind,
                });
            }
            [keyword, ..] => return Err(at(format!("unknown keyword '{keyword}'"))),
        }
    }
    let encoding = encoding.ok_or("header: no 'format' line")?;
    let roles = find_roles(&elements)?;
    Ok(Header {
        encoding,
        elements,
        roles,
        body: pos,
        lines: number,
    })
}

fn find_roles(elements: &[Element]) -> Result<Roles, String> {
    let find = |name: &str| {
        elements
            .iter()
            .position(|e| e.name == name)
            .ok_or_else(|| format!("header: no element '{name}'"))
    };
    let vertex = find("vertex")?;
    let face = find("face")?;
    let mut xyz = [0; 3];
    for (slot, axis) in xyz.iter_mut().zip(["x", "y", "z"]) {
        let props = &elements[vertex].properties;
        *slot = props
            .iter()
            .position(|p| p.name == axis)
            .ok_or_else(|| format!("header: element 'vertex' has no property '{axis}'"))?;
        if matches!(props[*slot].kind, Kind::List { .. }) {
            return Err(format!(
                "header: vertex property '{axis}' is a list; coordinates must be scalars"
            ));
        }
    }
    let props = &elements[face].properties;
    let indices = props
        .iter()
        .position(|p| p.name == "vertex_indices" || p.name == "vertex_index")
        .ok_or("header: element 'face' has no property 'vertex_indices' (or 'vertex_index')")?;
    match props[indices].kind {
        Kind::List { item, .. } if !item.is_integer() => {
            return Err(format!(
                "header: face property '{}' has index type '{}'; indices must be integers",
                props[indices].name,
                item.name()
            ))
        }
        Kind::Scalar(_) => {
            return Err(format!(
                "header: face property '{}' is not a list",
                props[indices].name
            ))
        }
        Kind::List { .. } => {}
    }
    Ok(Roles {
        vertex,
        xyz,
        face,
        indices,
    })
}

// ---------------------------------------------------------------------------------------
// Shared by both readers

/// Appends the fan (v0, vi, vi+1) of one face; faces with fewer than 3 indices add nothing.
fn push_fan(triangles: &mut Vec<[u32; 3]>, polygon: &[u32]) {
    if let [first, rest @ ..] = polygon {
        for pair in rest.windows(2) {
            triangles.push([*first, pair[0], pair[1]]);
        }
    }
}

fn negative_index(face: u64, value: i64) -> String {
    format!("face {face}: vertex index {value} is negative")
}

/// How many records of at least `min_size` bytes `available` bytes can hold: a capacity
/// that a lying header cannot turn into a huge allocation.
fn capacity(count: u64, available: usize, min_size: usize) -> usize {
    count.min((available / min_size.max(1)) as u64) as usize
}

// ---------------------------------------------------------------------------------------
// Binary

/// Byte order of a binary body; the reads are monomorphised so the hot loops have no
/// byte-order branch.
trait ByteOrder {
    fn u16(b: [u8; 2]) -> u16;
    fn u32(b: [u8; 4]) -> u32;
    fn u64(b: [u8; 8]) -> u64;
}

struct Little;
struct Big;

impl ByteOrder for Little {
    fn u16(b: [u8; 2]) -> u16 {
        u16::from_le_bytes(b)
    }
    fn u32(b: [u8; 4]) -> u32 {
        u32::from_le_bytes(b)
    }
    fn u64(b: [u8; 8]) -> u64 {
        u64::from_le_bytes(b)
    }
}

impl ByteOrder for Big {
    fn u16(b: [u8; 2]) -> u16 {
        u16::from_be_bytes(b)
    }
    fn u32(b: [u8; 4]) -> u32 {
        u32::from_be_bytes(b)
    }
    fn u64(b: [u8; 8]) -> u64 {
        u64::from_be_bytes(b)
    }
}

/// The first N bytes of `b`; callers have checked that `b` is long enough.
fn take<const N: usize>(b: &[u8]) -> [u8; N] {
    let mut out = [0; N];
    out.copy_from_slice(&b[..N]);
    out
}

/// An integer value of type `t` at the start of `b` (a float type, which the header rules
/// out for list counts and face indices, is truncated).
fn int_at<O: ByteOrder>(b: &[u8], t: Scalar) -> i64 {
    match t {
        Scalar::I8 => b[0] as i8 as i64,
        Scalar::U8 => b[0] as i64,
        Scalar::I16 => O::u16(take(b)) as i16 as i64,
        Scalar::U16 => O::u16(take(b)) as i64,
        Scalar::I32 => O::u32(take(b)) as i32 as i64,
        Scalar::U32 => O::u32(take(b)) as i64,
        Scalar::F32 => f32::from_bits(O::u32(take(b))) as i64,
        Scalar::F64 => f64::from_bits(O::u64(take(b))) as i64,
    }
}

/// A coordinate of type `t` at the start of `b`, as f32.
fn real_at<O: ByteOrder>(b: &[u8], t: Scalar) -> f32 {
    match t {
        Scalar::F32 => f32::from_bits(O::u32(take(b))),
        Scalar::F64 => f64::from_bits(O::u64(take(b))) as f32,
        _ => int_at::<O>(b, t) as f32,
    }
}

fn read_binary<O: ByteOrder>(header: &Header, body: &[u8], mesh: &mut Mesh) -> Result<(), String> {
    let roles = header.roles;
    let mut pos = 0;
    for (index, element) in header.elements.iter().enumerate() {
        let rest = &body[pos..];
        pos += if index == roles.vertex {
            read_binary_vertices::<O>(element, roles.xyz, rest, &mut mesh.vertices)?
        } else if index == roles.face {
            read_binary_faces::<O>(element, roles.indices, rest, &mut mesh.triangles)?
        } else {
            skip_binary::<O>(element, rest)?
        };
    }
    // Bytes after the last element mean the header does not describe the file; a final
    // line break, as some writers add, is not data.
    let rest = &body[pos..];
    if !rest.trim_ascii().is_empty() {
        return Err(format!(
            "{} bytes of data after the last element: the header declares {}",
            rest.len(),
            declared(header)
        ));
    }
    Ok(())
}

/// Checks that `count` records of `stride` bytes are present and returns their bytes.
fn fixed_records<'a>(element: &Element, stride: usize, data: &'a [u8]) -> Result<&'a [u8], String> {
    let total = usize::try_from(element.count)
        .ok()
        .and_then(|n| n.checked_mul(stride));
    match total {
        Some(total) if total <= data.len() => Ok(&data[..total]),
        _ => Err(element.truncated((data.len() / stride) as u64)),
    }
}

/// Reads the vertex element; returns the number of bytes it occupies.
fn read_binary_vertices<O: ByteOrder>(
    element: &Element,
    xyz: [usize; 3],
    data: &[u8],
    vertices: &mut Vec<[f32; 3]>,
) -> Result<usize, String> {
    let types = xyz.map(|i| match element.properties[i].kind {
        Kind::Scalar(t) => t,
        Kind::List { .. } => unreachable!("the header rejects list coordinates"),
    });
    let Some(stride) = element.fixed_stride() else {
        // Lists in the vertex element: walk each record.
        let mut values = [0f32; 3];
        let mut pos = 0;
        vertices.reserve(capacity(element.count, data.len(), 1));
        for done in 0..element.count {
            pos += walk_record::<O>(element, done, &data[pos..], |prop, bytes| {
                if let Some(axis) = xyz.iter().position(|&i| i == prop) {
                    values[axis] = real_at::<O>(bytes, types[axis]);
                }
            })?;
            vertices.push(values);
        }
        return Ok(pos);
    };
    let offsets = xyz.map(|i| {
        element.properties[..i]
            .iter()
            .map(|p| match p.kind {
                Kind::Scalar(t) => t.size(),
                Kind::List { .. } => 0,
            })
            .sum::<usize>()
    });
    let records = fixed_records(element, stride, data)?;
    vertices.reserve(element.count as usize);
    if types == [Scalar::F32; 3] {
        // The common case: a fixed conversion the compiler can vectorise around.
        let [ox, oy, oz] = offsets;
        let f = |r: &[u8], o: usize| f32::from_bits(O::u32(take(&r[o..])));
        vertices.extend(
            records
                .chunks_exact(stride)
                .map(|r| [f(r, ox), f(r, oy), f(r, oz)]),
        );
    } else {
        vertices.extend(
            records
                .chunks_exact(stride)
                .map(|r| [0, 1, 2].map(|axis| real_at::<O>(&r[offsets[axis]..], types[axis]))),
        );
        if types.contains(&Scalar::F64) {
            check_doubles::<O>(element, xyz, &offsets, records, stride, vertices)?;
        }
    }
    Ok(records.len())
}

/// Fails on the first double coordinate that became infinite as f32 though it is finite:
/// run only on files with double coordinates, after the fast conversion.
fn check_doubles<O: ByteOrder>(
    element: &Element,
    xyz: [usize; 3],
    offsets: &[usize; 3],
    records: &[u8],
    stride: usize,
    vertices: &[[f32; 3]],
) -> Result<(), String> {
    let first = vertices.len() - records.len() / stride;
    for (done, vertex) in vertices[first..].iter().enumerate() {
        for axis in 0..3 {
            if vertex[axis].is_infinite() {
                let record = &records[done * stride..];
                if let Kind::Scalar(Scalar::F64) = element.properties[xyz[axis]].kind {
                    let value = f64::from_bits(O::u64(take(&record[offsets[axis]..])));
                    to_f32(value).map_err(|message| {
                        let name = &element.properties[xyz[axis]].name;
                        format!("vertex {done} coordinate '{name}' {message}")
                    })?;
                }
            }
        }
    }
    Ok(())
}

/// Reads the face element; returns the number of bytes it occupies.
fn read_binary_faces<O: ByteOrder>(
    element: &Element,
    list: usize,
    data: &[u8],
    triangles: &mut Vec<[u32; 3]>,
) -> Result<usize, String> {
    let Kind::List {
        count: count_type,
        item,
    } = element.properties[list].kind
    else {
        unreachable!("the header checked the face list");
    };
    let record_guess = count_type.size() + 3 * item.size();
    triangles.reserve(capacity(element.count, data.len(), record_guess));
    let mut pos = 0;
    let mut done = 0;
    // Fast path for the scanner layout: a uchar count of 3 and three 32-bit indices per
    // face and nothing else. It stops at the first face that does not fit, and the
    // general loop below takes over from there.
    if element.properties.len() == 1
        && count_type == Scalar::U8
        && matches!(item, Scalar::I32 | Scalar::U32)
    {
        let whole = capacity(element.count, data.len(), 13);
        let triangles_only = data[..whole * 13]
            .chunks_exact(13)
            .take_while(|record| record[0] == 3)
            .count();
        let records = &data[..triangles_only * 13];
        let first = triangles.len();
        triangles.extend(
            records
                .chunks_exact(13)
                .map(|record| [1, 5, 9].map(|o| O::u32(take(&record[o..])))),
        );
        if item == Scalar::I32 {
            let added = &triangles[first..];
            if let Some(face) = added.iter().position(|t| ((t[0] | t[1] | t[2]) as i32) < 0) {
                let bad = added[face].iter().find(|&&i| (i as i32) < 0).copied();
                return Err(negative_index(face as u64, bad.unwrap_or(0) as i32 as i64));
            }
        }
        done = triangles_only as u64;
        pos = done as usize * 13;
    }
    let mut polygon = Vec::new();
    let mut bad_index = None;
    while done < element.count {
        pos += walk_record::<O>(element, done, &data[pos..], |prop, bytes| {
            if prop != list {
                return;
            }
            polygon.clear();
            let n = int_at::<O>(bytes, count_type) as usize;
            for k in 0..n {
                let value = int_at::<O>(&bytes[count_type.size() + k * item.size()..], item);
                if value < 0 {
                    bad_index.get_or_insert(value);
                }
                polygon.push(value as u32);
            }
        })?;
        if let Some(value) = bad_index {
            return Err(negative_index(done, value));
        }
        push_fan(triangles, &polygon);
        done += 1;
    }
    Ok(pos)
}

/// Skips an element that is not read; returns the number of bytes it occupies.
fn skip_binary<O: ByteOrder>(element: &Element, data: &[u8]) -> Result<usize, String> {
    if let Some(stride) = element.fixed_stride() {
        if stride == 0 {
            return Ok(0);
        }
        return Ok(fixed_records(element, stride, data)?.len());
    }
    let mut pos = 0;
    for done in 0..element.count {
        pos += walk_record::<O>(element, done, &data[pos..], |_, _| {})?;
    }
    Ok(pos)
}

/// Walks record `done` of `element` at the start of `data`, calling
/// `visit(property index, bytes)` with the bytes of each property (a list's bytes start with
/// its count). Returns the record size.
fn walk_record<O: ByteOrder>(
    element: &Element,
    done: u64,
    data: &[u8],
    mut visit: impl FnMut(usize, &[u8]),
) -> Result<usize, String> {
    let mut pos = 0;
    for (index, property) in element.properties.iter().enumerate() {
        let size = match property.kind {
            Kind::Scalar(t) => Some(t.size()),
            Kind::List { count, item } => {
                let head = data
                    .get(pos..pos + count.size())
                    .ok_or_else(|| element.truncated(done))?;
                let n = int_at::<O>(head, count);
                if n < 0 {
                    return Err(negative_count(element, done, property, n));
                }
                (n as usize)
                    .checked_mul(item.size())
                    .and_then(|s| s.checked_add(count.size()))
            }
        };
        let bytes = size
            .and_then(|size| data.get(pos..pos.checked_add(size)?))
            .ok_or_else(|| element.truncated(done))?;
        visit(index, bytes);
        pos += bytes.len();
    }
    Ok(pos)
}

fn negative_count(element: &Element, done: u64, property: &Property, n: i64) -> String {
    let Element { name, .. } = element;
    let list = &property.name;
    format!("{name} {done}: list '{list}' has negative length {n}")
}

// ---------------------------------------------------------------------------------------
// ASCII

/// The body's non-blank lines with their numbers in the whole file: one record per line.
struct Lines<'a> {
    data: &'a [u8],
    pos: usize,
    /// Line number (in the whole file) of the line starting at `pos`.
    line: usize,
}

impl<'a> Lines<'a> {
    /// The next line that holds anything but whitespace, and its number.
    fn next(&mut self) -> Option<(&'a [u8], usize)> {
        while self.pos < self.data.len() {
            let rest = &self.data[self.pos..];
            let len = rest.iter().position(|&b| b == b'\n').unwrap_or(rest.len());
            let (text, number) = (&rest[..len], self.line);
            self.pos += (len + 1).min(rest.len());
            self.line += 1;
            if !text.trim_ascii().is_empty() {
                return Some((text, number));
            }
        }
        None
    }

    /// Whether only whitespace is left.
    fn at_end(&self) -> bool {
        self.data[self.pos..].trim_ascii().is_empty()
    }
}

/// The values of one record's line, counted so that a short or long line is named.
struct Values<'a, 'e> {
    words: std::slice::Split<'a, u8, fn(&u8) -> bool>,
    line: usize,
    element: &'e Element,
    record: u64,
    /// The line was the file's last.
    last: bool,
    read: usize,
}

impl<'a> Values<'a, '_> {
    fn next(&mut self) -> Result<&'a [u8], String> {
        match self.words.by_ref().find(|w| !w.is_empty()) {
            Some(word) => {
                self.read += 1;
                Ok(word)
            }
            None => Err(self.short()),
        }
    }

    fn short(&self) -> String {
        let mut message = format!(
            "line {}: {} {} has only {} value{}, fewer than the header declares",
            self.line,
            self.element.name,
            self.record,
            self.read,
            if self.read == 1 { "" } else { "s" }
        );
        if self.last {
            message += &format!("; {}", self.element.truncated(self.record));
        }
        message
    }

    /// Fails when the line holds more values than the record declared.
    fn finish(mut self) -> Result<(), String> {
        let extra = self.words.by_ref().filter(|w| !w.is_empty()).count();
        if extra == 0 {
            return Ok(());
        }
        Err(format!(
            "line {}: {} {} has {} values, more than the {} the header declares",
            self.line,
            self.element.name,
            self.record,
            self.read + extra,
            self.read
        ))
    }
}

fn show(token: &[u8]) -> String {
    String::from_utf8_lossy(token).into_owned()
}

/// An integer token of type `t`; `what` names the value for the message (built only on
/// error, since it runs once per number).
fn ascii_int(
    token: &[u8],
    line: usize,
    t: Scalar,
    what: impl Fn() -> String,
) -> Result<i64, String> {
    let value = std::str::from_utf8(token)
        .ok()
        .and_then(|s| s.parse::<i64>().ok())
        .ok_or_else(|| {
            format!(
                "line {line}: {} '{}' is not an integer",
                what(),
                show(token)
            )
        })?;
    let (lo, hi) = t.range();
    if value < lo || value > hi {
        return Err(format!(
            "line {line}: {} {value} does not fit its type '{}'",
            what(),
            t.name()
        ));
    }
    Ok(value)
}

fn ascii_real(
    token: &[u8],
    line: usize,
    t: Scalar,
    what: impl Fn() -> String,
) -> Result<f32, String> {
    if t.is_integer() {
        return Ok(ascii_int(token, line, t, what)? as f32);
    }
    let text = std::str::from_utf8(token).ok();
    let not_a_number = || format!("line {line}: {} '{}' is not a number", what(), show(token));
    let value = match t {
        // Parsed as f32 directly: through f64 it could round twice.
        Scalar::F32 => text.and_then(|s| s.parse::<f32>().ok()),
        _ => None,
    };
    match value {
        Some(v) if v.is_finite() => Ok(v),
        // Infinite or double: the f64 value tells a written `inf` from one beyond float32.
        _ => {
            let wide = text
                .and_then(|s| s.parse::<f64>().ok())
                .ok_or_else(not_a_number)?;
            to_f32(wide).map_err(|message| format!("line {line}: {} {message}", what()))
        }
    }
}

/// A coordinate as f32, or why it has none: a finite value beyond float32's range becomes
/// infinite, which is an error in its own words rather than a later "non-finite vertex".
fn to_f32(value: f64) -> Result<f32, String> {
    let narrow = value as f32;
    if narrow.is_infinite() && value.is_finite() {
        return Err(format!(
            "{value:e} is beyond the float32 range (magnitudes up to {:e})",
            f32::MAX
        ));
    }
    Ok(narrow)
}

/// Reads the ASCII body one line per record, each line holding exactly the values the
/// header declares for it, and nothing after the last element.
fn read_ascii(header: &Header, body: &[u8], mesh: &mut Mesh) -> Result<(), String> {
    let mut lines = Lines {
        data: body,
        pos: 0,
        line: header.lines + 1,
    };
    let roles = header.roles;
    let mut polygon = Vec::new();
    for (index, element) in header.elements.iter().enumerate() {
        let is_vertex = index == roles.vertex;
        let is_face = index == roles.face;
        if is_vertex {
            mesh.vertices
                .reserve(capacity(element.count, body.len(), 6));
        } else if is_face {
            mesh.triangles
                .reserve(capacity(element.count, body.len(), 8));
        }
        if element.properties.is_empty() {
            continue;
        }
        for done in 0..element.count {
            let (text, line) = lines.next().ok_or_else(|| element.truncated(done))?;
            let is_space: fn(&u8) -> bool = u8::is_ascii_whitespace;
            let mut values = Values {
                words: text.split(is_space),
                line,
                element,
                record: done,
                last: lines.at_end(),
                read: 0,
            };
            let mut position = [0f32; 3];
            for (prop, property) in element.properties.iter().enumerate() {
                let token = values.next()?;
                match property.kind {
                    Kind::Scalar(t) => {
                        if !is_vertex {
                            continue;
                        }
                        if let Some(axis) = roles.xyz.iter().position(|&i| i == prop) {
                            let what = || format!("vertex {done} coordinate '{}'", property.name);
                            position[axis] = ascii_real(token, line, t, what)?;
                        }
                    }
                    Kind::List { count, item } => {
                        let name = &element.name;
                        let list = &property.name;
                        let what = || format!("{name} {done} list '{list}' length");
                        let n = ascii_int(token, line, count, what)?;
                        if n < 0 {
                            let message = negative_count(element, done, property, n);
                            return Err(format!("line {line}: {message}"));
                        }
                        let read = is_face && prop == roles.indices;
                        polygon.clear();
                        for _ in 0..n {
                            let token = values.next()?;
                            if read {
                                let value = ascii_int(token, line, item, || {
                                    format!("face {done} vertex index")
                                })?;
                                if value < 0 {
                                    let message = negative_index(done, value);
                                    return Err(format!("line {line}: {message}"));
                                }
                                polygon.push(value as u32);
                            }
                        }
                        if read {
                            push_fan(&mut mesh.triangles, &polygon);
                        }
                    }
                }
            }
            values.finish()?;
            if is_vertex {
                mesh.vertices.push(position);
            }
        }
    }
    if let Some((text, line)) = lines.next() {
        return Err(format!(
            "line {line}: data after the last element ('{}'): the header declares {}",
            shorten(text),
            declared(header)
        ));
    }
    Ok(())
}

/// "3 vertices, 1 face": what the header declares, for messages about extra data.
fn declared(header: &Header) -> String {
    let parts: Vec<String> = header
        .elements
        .iter()
        .map(|e| format!("{} {}", e.count, e.plural()))
        .collect();
    parts.join(", ")
}

/// A line of the file, cut to a length that fits a message.
fn shorten(text: &[u8]) -> String {
    let text = String::from_utf8_lossy(text);
    let text = text.trim();
    match text.char_indices().nth(40) {
        Some((cut, _)) => format!("{}...", &text[..cut]),
        None => text.to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const HEAD: &str = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n\
                        property float y\nproperty float z\nelement face 1\n\
                        property list uchar int vertex_indices\nend_header\n";

    fn error(body: &str) -> String {
        parse(format!("{HEAD}{body}").as_bytes()).unwrap_err()
    }

    #[test]
    fn ascii_records_are_read_one_per_line() {
        // Records split or joined across lines would shift every later value.
        let mesh = parse(format!("{HEAD}0 0 0\n\n1 0 0\r\n0 1 0\n3 0 1 2\n\n").as_bytes());
        assert_eq!(mesh.unwrap().triangles, vec![[0, 1, 2]]);
        let e = error("0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
        assert!(e.starts_with("line 10: vertex 0 has only 2 values"), "{e}");
        let e = error("0 0 0 1\n1 0 0\n0 1 0\n3 0 1 2\n");
        assert!(
            e.starts_with("line 10: vertex 0 has 4 values, more than the 3"),
            "{e}"
        );
        let e = error("0 0 0\n1 0 0\n0 1 0\n3 0 1\n");
        assert!(e.contains("line 13: face 0 has only 3 values"), "{e}");
        assert!(e.contains("file ends after 0 of 1 faces"), "{e}");
        let e = error("0 0 0\n1 0 0\n0 1 0\n3 0 1 2 5\n");
        assert!(
            e.contains("line 13: face 0 has 5 values, more than the 4"),
            "{e}"
        );
    }

    #[test]
    fn data_after_the_last_element_is_an_error() {
        let e = error("0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n3 0 1 2\n");
        assert!(
            e.contains("line 14: data after the last element ('3 0 1 2')")
                && e.contains("3 vertices, 1 faces"),
            "{e}"
        );
        let binary = "ply\nformat binary_little_endian 1.0\nelement vertex 1\nproperty float x\n\
                      property float y\nproperty float z\nelement face 0\n\
                      property list uchar int vertex_indices\nend_header\n";
        let mut bytes = binary.as_bytes().to_vec();
        bytes.extend_from_slice(&[0; 12]);
        assert!(parse(&bytes).is_ok());
        bytes.push(b'\n');
        assert!(parse(&bytes).is_ok(), "a final line break is not data");
        bytes.extend_from_slice(&[7; 5]);
        let e = parse(&bytes).unwrap_err();
        assert!(
            e.starts_with("6 bytes of data after the last element"),
            "{e}"
        );
    }

    #[test]
    fn values_beyond_float32_say_so() {
        let e = error("0 0 0\n1 -4e38 0\n0 1 0\n3 0 1 2\n");
        assert!(
            e.starts_with("line 11: vertex 1 coordinate 'y' -4e38 is beyond the float32 range"),
            "{e}"
        );
        // A written infinity is read as one (and refused later by validation, as such).
        let mesh = parse(format!("{HEAD}0 0 0\n1 inf 0\n0 1 0\n3 0 1 2\n").as_bytes());
        assert!(mesh.unwrap().vertices[1][1].is_infinite());
        // Binary doubles too.
        let mut bytes = b"ply\nformat binary_big_endian 1.0\nelement vertex 1\nproperty double x\n\
                          property double y\nproperty double z\nelement face 0\n\
                          property list uchar int vertex_indices\nend_header\n"
            .to_vec();
        for v in [1.0f64, 2.0, 1e300] {
            bytes.extend_from_slice(&v.to_be_bytes());
        }
        let e = parse(&bytes).unwrap_err();
        assert!(
            e.starts_with("vertex 0 coordinate 'z' 1e300 is beyond"),
            "{e}"
        );
    }
}
