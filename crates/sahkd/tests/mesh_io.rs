//! Mesh readers: PLY in all three encodings and OBJ give the same hand-computed mesh, bad
//! input gives an error naming the problem (never a panic), and the real scenes load with
//! the statistics their README lists.

use proptest::prelude::*;
use sahkd::{Mesh, MeshError};
use std::path::PathBuf;

// ---------------------------------------------------------------------------------------
// A tiny PLY writer, used to produce the same data in ASCII, little- and big-endian.

#[derive(Clone, Copy, Debug, PartialEq)]
enum Format {
    Ascii,
    Little,
    Big,
}

const FORMATS: [Format; 3] = [Format::Ascii, Format::Little, Format::Big];

#[derive(Clone)]
enum Value {
    One(f64),
    List(Vec<f64>),
}

#[derive(Clone)]
struct Prop {
    /// `Some(count type)` for a list.
    list: Option<&'static str>,
    ty: &'static str,
    name: &'static str,
}

fn scalar(ty: &'static str, name: &'static str) -> Prop {
    Prop {
        list: None,
        ty,
        name,
    }
}

fn list(count: &'static str, ty: &'static str, name: &'static str) -> Prop {
    Prop {
        list: Some(count),
        ty,
        name,
    }
}

#[derive(Clone)]
struct Element {
    name: &'static str,
    props: Vec<Prop>,
    rows: Vec<Vec<Value>>,
}

fn encode(ty: &str, v: f64, format: Format, out: &mut Vec<u8>) {
    macro_rules! put {
        ($t:ty) => {{
            let x = v as $t;
            out.extend_from_slice(&match format {
                Format::Big => x.to_be_bytes(),
                Format::Little => x.to_le_bytes(),
                Format::Ascii => return,
            })
        }};
    }
    match ty {
        "char" | "int8" => put!(i8),
        "uchar" | "uint8" => put!(u8),
        "short" | "int16" => put!(i16),
        "ushort" | "uint16" => put!(u16),
        "int" | "int32" => put!(i32),
        "uint" | "uint32" => put!(u32),
        "float" | "float32" => put!(f32),
        "double" | "float64" => put!(f64),
        _ => panic!("test writer: unknown type {ty}"),
    }
}

fn write_ply(format: Format, elements: &[Element]) -> Vec<u8> {
    let name = match format {
        Format::Ascii => "ascii",
        Format::Little => "binary_little_endian",
        Format::Big => "binary_big_endian",
    };
    let mut out = format!("ply\nformat {name} 1.0\ncomment written by the mesh_io test\n");
    for e in elements {
        out += &format!("element {} {}\n", e.name, e.rows.len());
        for p in &e.props {
            match p.list {
                Some(count) => out += &format!("property list {count} {} {}\n", p.ty, p.name),
                None => out += &format!("property {} {}\n", p.ty, p.name),
            }
        }
    }
    out += "end_header\n";
    let mut out = out.into_bytes();
    for e in elements {
        for row in &e.rows {
            assert_eq!(row.len(), e.props.len(), "test writer: row of {}", e.name);
            let mut words = Vec::new();
            for (p, value) in e.props.iter().zip(row) {
                let (count, items) = match (value, p.list) {
                    (Value::One(v), None) => (None, std::slice::from_ref(v)),
                    (Value::List(items), Some(count)) => (Some(count), &items[..]),
                    _ => panic!("test writer: value does not match property {}", p.name),
                };
                if let Some(count) = count {
                    words.push(items.len().to_string());
                    encode(count, items.len() as f64, format, &mut out);
                }
                for v in items {
                    words.push(v.to_string());
                    encode(p.ty, *v, format, &mut out);
                }
            }
            if format == Format::Ascii {
                out.extend_from_slice(words.join(" ").as_bytes());
                out.push(b'\n');
            }
        }
    }
    out
}

fn one(v: f64) -> Value {
    Value::One(v)
}

fn many(items: &[f64]) -> Value {
    Value::List(items.to_vec())
}

// ---------------------------------------------------------------------------------------
// The reference mesh: six vertices, a triangle, a quad, a pentagon, a two-index face and an
// empty face (both dropped), and one more triangle. Polygons are fanned from their first
// vertex, by hand:
//   quad     [0, 2, 3, 4]    -> (0, 2, 3), (0, 3, 4)
//   pentagon [5, 4, 3, 2, 1] -> (5, 4, 3), (5, 3, 2), (5, 2, 1)

const POSITIONS: [[f64; 3]; 6] = [
    [0.0, 0.0, 0.0],
    [2.0, 0.0, 0.0],
    [2.0, 3.0, 0.0],
    [0.0, 3.0, 0.0],
    [-1.0, 1.0, 1.5],
    [4.0, -2.0, 0.25],
];

const FACES: [&[f64]; 6] = [
    &[0.0, 1.0, 2.0],
    &[0.0, 2.0, 3.0, 4.0],
    &[5.0, 4.0, 3.0, 2.0, 1.0],
    &[1.0, 2.0],
    &[],
    &[3.0, 4.0, 5.0],
];

fn expected() -> Mesh {
    Mesh {
        vertices: POSITIONS.iter().map(|p| p.map(|c| c as f32)).collect(),
        triangles: vec![
            [0, 1, 2],
            [0, 2, 3],
            [0, 3, 4],
            [5, 4, 3],
            [5, 3, 2],
            [5, 2, 1],
            [3, 4, 5],
        ],
    }
}

/// The reference mesh among distractions: a vertex element whose x is a double and y a
/// short, between normals, colours and confidence (and, with `vertex_list`, a list
/// property); faces with a flag before the index list and texture coordinates after it; an
/// `edge` element with a list and a `material` element with scalars only.
fn rich_elements(vertex_list: bool) -> (Element, Element, Element, Element) {
    let mut vertex_props = vec![
        scalar("float", "nx"),
        scalar("double", "x"),
        scalar("uchar", "red"),
        scalar("short", "y"),
        scalar("float32", "z"),
        scalar("float", "confidence"),
    ];
    if vertex_list {
        vertex_props.insert(3, list("uint8", "int16", "neighbours"));
    }
    let vertex = Element {
        name: "vertex",
        props: vertex_props,
        rows: POSITIONS
            .iter()
            .enumerate()
            .map(|(i, p)| {
                let mut row = vec![one(0.5), one(p[0]), one(200.0), one(p[1]), one(p[2])];
                row.push(one(i as f64 * 0.25));
                if vertex_list {
                    row.insert(3, many(&vec![-7.0; i]));
                }
                row
            })
            .collect(),
    };
    let face = Element {
        name: "face",
        props: vec![
            scalar("uchar", "flags"),
            list("uchar", "int", "vertex_indices"),
            list("int", "float", "texcoord"),
        ],
        rows: FACES
            .iter()
            .map(|f| vec![one(9.0), many(f), many(&[0.5, 0.75])])
            .collect(),
    };
    let edge = Element {
        name: "edge",
        props: vec![
            scalar("int", "vertex1"),
            list("ushort", "uint", "path"),
            scalar("int", "vertex2"),
        ],
        rows: vec![
            vec![one(0.0), many(&[1.0, 2.0, 3.0]), one(1.0)],
            vec![one(2.0), many(&[]), one(3.0)],
        ],
    };
    let material = Element {
        name: "material",
        props: vec![scalar("uchar", "r"), scalar("double", "shine")],
        rows: vec![vec![one(1.0), one(2.5)]],
    };
    (vertex, face, edge, material)
}

fn parse(bytes: &[u8]) -> Result<Mesh, String> {
    Mesh::from_ply_bytes(bytes)
}

#[test]
fn ply_all_formats_give_the_same_mesh() {
    for vertex_list in [false, true] {
        let (vertex, face, edge, material) = rich_elements(vertex_list);
        let orders = [
            vec![edge.clone(), vertex.clone(), material.clone(), face.clone()],
            vec![face.clone(), edge.clone(), vertex.clone(), material.clone()],
            vec![vertex.clone(), face.clone()],
        ];
        for elements in &orders {
            for format in FORMATS {
                let bytes = write_ply(format, elements);
                let names: Vec<_> = elements.iter().map(|e| e.name).collect();
                assert_eq!(
                    parse(&bytes),
                    Ok(expected()),
                    "{format:?}, vertex list {vertex_list}, order {names:?}"
                );
            }
        }
    }
}

#[test]
fn ply_hand_written_ascii() {
    // CRLF in the header, comments, obj_info, a blank line and the vertex_index spelling.
    // Each record on its own line: a record split over lines is an error.
    let text = "ply\r\nformat ascii 1.0\r\ncomment made by hand\r\nobj_info nothing\r\n\r\n\
        element vertex 6\r\nproperty float x\r\nproperty float y\r\nproperty float z\r\n\
        property uchar red\r\n\
        element face 6\r\nproperty list uchar int vertex_index\r\nend_header\r\n\
        0 0 0 1\n2 0 0 1\n2 3 0 1\n0 3 0 1\n-1 1 1.5 1\n4 -2 0.25 1\n\
        3 0 1 2\n4 0 2 3 4\n5 5 4 3 2 1\n2 1 2\n0\n3 3 4 5\n";
    assert_eq!(parse(text.as_bytes()), Ok(expected()));
}

#[test]
fn ply_comments_need_not_be_utf8() {
    let mut bytes = write_ply(Format::Little, &scanner_layout("int", &FACES));
    let at = bytes.windows(8).position(|w| w == b"comment ").unwrap() + 8;
    bytes.splice(at..at, b"caf\xe9 ".iter().copied());
    assert_eq!(parse(&bytes), Ok(expected()));
    // Elsewhere in the header, bytes that are not text are an error.
    let at = bytes.windows(7).position(|w| w == b"element").unwrap();
    bytes[at + 1] = 0xe9;
    assert_error(&bytes, &["header line 4: not text"]);
}

#[test]
fn ply_every_scalar_type_for_coordinates_counts_and_indices() {
    let ints = ["char", "uchar", "short", "ushort", "int", "uint"];
    let aliases = ["int8", "uint8", "int16", "uint16", "int32", "uint32"];
    let reals = ["float", "double", "float32", "float64"];
    // Small integer coordinates fit every type; negative ones only signed types.
    for coordinate in ints.iter().chain(&aliases).chain(&reals) {
        let unsigned = coordinate.starts_with('u');
        let positions: Vec<[f64; 3]> = POSITIONS
            .iter()
            .map(|p| p.map(|c| if unsigned { c.abs().floor() } else { c.floor() }))
            .collect();
        for (count, index) in ints.iter().zip(aliases.iter().rev()) {
            let vertex = Element {
                name: "vertex",
                props: vec![
                    scalar(coordinate, "z"),
                    scalar(coordinate, "y"),
                    scalar(coordinate, "x"),
                ],
                rows: positions
                    .iter()
                    .map(|p| vec![one(p[2]), one(p[1]), one(p[0])])
                    .collect(),
            };
            let face = Element {
                name: "face",
                props: vec![list(count, index, "vertex_indices")],
                rows: FACES.iter().map(|f| vec![many(f)]).collect(),
            };
            let mut want = expected();
            want.vertices = positions.iter().map(|p| p.map(|c| c as f32)).collect();
            for format in FORMATS {
                let bytes = write_ply(format, &[vertex.clone(), face.clone()]);
                assert_eq!(
                    parse(&bytes),
                    Ok(want.clone()),
                    "{format:?}: coordinates {coordinate}, list {count} {index}"
                );
            }
        }
    }
}

/// The layout of the real scenes (three floats; uchar count and int indices), which has a
/// fast path, with a polygon in the middle so the fast path has to hand over.
fn scanner_layout(index: &'static str, faces: &[&[f64]]) -> Vec<Element> {
    vec![
        Element {
            name: "vertex",
            props: vec![
                scalar("float", "x"),
                scalar("float", "y"),
                scalar("float", "z"),
            ],
            rows: POSITIONS
                .iter()
                .map(|p| p.iter().map(|&c| one(c)).collect())
                .collect(),
        },
        Element {
            name: "face",
            props: vec![list("uchar", index, "vertex_indices")],
            rows: faces.iter().map(|f| vec![many(f)]).collect(),
        },
    ]
}

#[test]
fn ply_scanner_layout_with_polygons() {
    for index in ["int", "uint"] {
        for format in FORMATS {
            let bytes = write_ply(format, &scanner_layout(index, &FACES));
            assert_eq!(parse(&bytes), Ok(expected()), "{format:?} {index}");
        }
    }
    // Triangles only: the fast path reads everything.
    let triangles: Vec<&[f64]> = vec![&[0.0, 1.0, 2.0], &[3.0, 4.0, 5.0]];
    let bytes = write_ply(Format::Little, &scanner_layout("int", &triangles));
    let mesh = parse(&bytes).unwrap();
    assert_eq!(mesh.triangles, vec![[0, 1, 2], [3, 4, 5]]);
    assert_eq!(mesh.vertices, expected().vertices);
}

// ---------------------------------------------------------------------------------------
// PLY errors

/// Asserts that `bytes` is rejected with a message containing every one of `parts`.
#[track_caller]
fn assert_error(bytes: &[u8], parts: &[&str]) {
    match parse(bytes) {
        Ok(mesh) => panic!("expected an error containing {parts:?}, got {mesh:?}"),
        Err(message) => {
            for part in parts {
                assert!(
                    message.contains(part),
                    "message {message:?} does not contain {part:?}"
                );
            }
        }
    }
}

fn header(body: &str) -> String {
    format!("ply\nformat ascii 1.0\n{body}")
}

const XYZ: &str = "property float x\nproperty float y\nproperty float z\n";
const INDICES: &str = "property list uchar int vertex_indices\n";

#[test]
fn ply_header_errors() {
    assert_error(b"", &["not a PLY"]);
    assert_error(b"solid cube\nfacet\n", &["not a PLY", "'ply'"]);
    assert_error(
        b"ply\nformat ascii 1.0\nelement vertex 3\n",
        &["end_header"],
    );
    let cases: Vec<(String, Vec<&str>)> = vec![
        (
            "ply\nformat binary_middle_endian 1.0\nend_header\n".into(),
            vec!["line 2", "unknown format 'binary_middle_endian'"],
        ),
        (
            "ply\nformat ascii 2.0\nend_header\n".into(),
            vec!["line 2", "version '2.0'"],
        ),
        (
            format!("ply\nelement vertex 0\n{XYZ}end_header\n"),
            vec!["no 'format' line"],
        ),
        (
            header("element vertex 1\nproperty float16 x\nend_header\n"),
            vec!["line 4", "unknown property type 'float16'"],
        ),
        (
            header("property float x\nend_header\n"),
            vec!["line 3", "property before any element"],
        ),
        (
            header("element vertex many\nend_header\n"),
            vec!["line 3", "count 'many'"],
        ),
        (
            header("element vertex -2\nend_header\n"),
            vec!["line 3", "count '-2'"],
        ),
        (
            header("element vertex 0\nproperty float\nend_header\n"),
            vec!["line 4", "property <type> <name>"],
        ),
        (
            header("element face 0\nproperty list uchar vertex_indices\nend_header\n"),
            vec!["line 4", "property list"],
        ),
        (
            header("element face 0\nproperty list float int vertex_indices\nend_header\n"),
            vec!["line 4", "count type 'float'"],
        ),
        (
            header("elements vertex 0\nend_header\n"),
            vec!["line 3", "unknown keyword 'elements'"],
        ),
        (
            header(&format!(
                "element vertex 0\n{XYZ}element vertex 0\n{XYZ}end_header\n"
            )),
            vec!["line 7", "element 'vertex' is declared twice"],
        ),
        (
            header(&format!("element face 0\n{INDICES}end_header\n")),
            vec!["no element 'vertex'"],
        ),
        (
            header(&format!("element vertex 0\n{XYZ}end_header\n")),
            vec!["no element 'face'"],
        ),
        (
            header(&format!(
                "element vertex 0\nproperty float x\nproperty float z\nelement face 0\n{INDICES}end_header\n"
            )),
            vec!["element 'vertex' has no property 'y'"],
        ),
        (
            header(&format!(
                "element vertex 0\nproperty float x\nproperty list uchar float y\nproperty float z\nelement face 0\n{INDICES}end_header\n"
            )),
            vec!["vertex property 'y' is a list"],
        ),
        (
            header(&format!(
                "element vertex 0\n{XYZ}element face 0\nproperty list uchar int corners\nend_header\n"
            )),
            vec!["element 'face' has no property 'vertex_indices'"],
        ),
        (
            header(&format!(
                "element vertex 0\n{XYZ}element face 0\nproperty int vertex_indices\nend_header\n"
            )),
            vec!["'vertex_indices' is not a list"],
        ),
        (
            header(&format!(
                "element vertex 0\n{XYZ}element face 0\nproperty list uchar float vertex_indices\nend_header\n"
            )),
            vec!["index type 'float'", "integers"],
        ),
    ];
    for (text, parts) in cases {
        assert_error(text.as_bytes(), &parts);
    }
}

#[test]
fn ply_body_errors_ascii() {
    let head = header(&format!(
        "element vertex 3\n{XYZ}element face 2\n{INDICES}end_header\n"
    ));
    // Line numbers: the header has 9 lines, so the body starts on line 10.
    let good_vertices = "0 0 0\n1 0 0\n0 1 0\n";
    let cases: Vec<(String, Vec<&str>)> = vec![
        (
            format!("{good_vertices}3 0 1 2\n3 0 x 2\n"),
            vec!["line 14", "face 1 vertex index 'x' is not an integer"],
        ),
        (
            format!("{good_vertices}3 0 1 2\n3 0 -1 2\n"),
            vec!["line 14", "face 1", "-1", "negative"],
        ),
        (
            format!("{good_vertices}3 0 1 2\n3 0 1 4294967296\n"),
            vec!["line 14", "face 1", "does not fit"],
        ),
        (
            format!("{good_vertices}3 0 1 2\n-3 0 1 2\n"),
            vec!["line 14", "face 1", "-3", "does not fit"],
        ),
        (
            format!("{good_vertices}3 0 1 2\n256 0 1 2\n"),
            vec!["line 14", "does not fit", "uchar"],
        ),
        (
            "0 0 0\n1 0 zero\n0 1 0\n3 0 1 2\n3 0 1 2\n".into(),
            vec!["line 11", "vertex 1 coordinate 'z' 'zero' is not a number"],
        ),
        (
            "0 0 0\n1 0 0\n".into(),
            vec!["file ends after 2 of 3 vertices"],
        ),
        (
            format!("{good_vertices}3 0 1 2\n3 0 1\n"),
            vec!["file ends after 1 of 2 faces"],
        ),
        (
            format!("{good_vertices}3 0 1 2\n"),
            vec!["file ends after 1 of 2 faces"],
        ),
    ];
    for (body, parts) in cases {
        assert_error(format!("{head}{body}").as_bytes(), &parts);
    }
    // A vertex coordinate of an integer type must be an integer.
    let short = header(&format!(
        "element vertex 1\nproperty short x\nproperty short y\nproperty short z\nelement face 0\n{INDICES}end_header\n1 2.5 3\n"
    ));
    assert_error(
        short.as_bytes(),
        &["line 10", "vertex 0 coordinate 'y' '2.5' is not an integer"],
    );
}

#[test]
fn ply_body_errors_binary() {
    for format in [Format::Little, Format::Big] {
        let faces: Vec<&[f64]> = vec![&[0.0, 1.0, 2.0], &[0.0, 1.0, 2.0, 3.0], &[4.0, 5.0, 1.0]];
        let bytes = write_ply(format, &scanner_layout("int", &faces));
        let body = bytes.len() - (6 * 12 + 13 + 17 + 13);
        // Cut inside the vertices: after 1 whole vertex and part of the next.
        assert_error(
            &bytes[..body + 12 + 5],
            &["file ends after 1 of 6 vertices"],
        );
        // Cut inside the quad (the general path) and inside the last triangle.
        assert_error(
            &bytes[..body + 72 + 13 + 10],
            &["file ends after 1 of 3 faces"],
        );
        assert_error(&bytes[..bytes.len() - 1], &["file ends after 2 of 3 faces"]);

        // Negative index on the fast path (first face) and on the general path (quad).
        let bad_fast: Vec<&[f64]> = vec![&[0.0, 1.0, 2.0], &[0.0, -4.0, 2.0]];
        let bytes = write_ply(format, &scanner_layout("int", &bad_fast));
        assert_error(&bytes, &["face 1", "-4", "negative"]);
        let bad_general: Vec<&[f64]> = vec![&[0.0, 1.0, 2.0, 3.0], &[0.0, 1.0, 2.0, -3.0]];
        let bytes = write_ply(format, &scanner_layout("int", &bad_general));
        assert_error(&bytes, &["face 1", "-3", "negative"]);

        // A negative list length in a skipped element.
        let mut elements = scanner_layout("int", &faces);
        elements.push(Element {
            name: "edge",
            props: vec![list("char", "int", "path")],
            rows: vec![vec![many(&[1.0])]],
        });
        let mut bytes = write_ply(format, &elements);
        let n = bytes.len();
        assert_error(&bytes[..n - 1], &["file ends after 0 of 1 'edge' elements"]);
        bytes[n - 5] = (-2i8) as u8;
        assert_error(&bytes, &["edge 0", "list 'path' has negative length -2"]);
    }
}

#[test]
fn ply_huge_counts_are_errors_not_allocations() {
    let huge = u64::MAX;
    for format in ["ascii", "binary_little_endian"] {
        let text = format!(
            "ply\nformat {format} 1.0\nelement vertex {huge}\n{XYZ}element face 0\n{INDICES}end_header\n0 0 0\n"
        );
        assert_error(
            text.as_bytes(),
            &["file ends after", "of 18446744073709551615 vertices"],
        );
        let text = format!(
            "ply\nformat {format} 1.0\nelement vertex 0\n{XYZ}element face {huge}\n{INDICES}end_header\n"
        );
        assert_error(
            text.as_bytes(),
            &["file ends after 0 of 18446744073709551615 faces"],
        );
    }
    // An element without properties takes no bytes, however many it claims.
    let text = format!(
        "ply\nformat binary_big_endian 1.0\nelement nothing {huge}\nelement vertex 0\n{XYZ}element face 0\n{INDICES}end_header\n"
    );
    assert_eq!(parse(text.as_bytes()), Ok(Mesh::default()));
}

/// Every prefix of a valid file is an error or a mesh, never a panic; binary prefixes that
/// cut the data are always errors.
#[test]
fn ply_truncations_never_panic() {
    let (vertex, face, edge, material) = rich_elements(true);
    let rich = vec![edge, vertex, material, face];
    for elements in [rich, scanner_layout("int", &FACES)] {
        for format in FORMATS {
            let bytes = write_ply(format, &elements);
            for end in 0..bytes.len() {
                let result = parse(&bytes[..end]);
                if format != Format::Ascii {
                    assert!(result.is_err(), "{format:?} prefix of {end} bytes parsed");
                }
            }
            assert_eq!(parse(&bytes), Ok(expected()));
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]

    /// Corrupting bytes anywhere (header or body) gives an error or a mesh, never a panic.
    #[test]
    fn ply_corruption_never_panics(
        format in 0..3usize,
        edits in prop::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 1..6),
    ) {
        let (vertex, face, edge, material) = rich_elements(true);
        let mut bytes = write_ply(FORMATS[format], &[edge, vertex, material, face]);
        for (at, byte) in edits {
            let i = at.index(bytes.len());
            bytes[i] = byte;
        }
        let _ = parse(&bytes);
    }
}

// ---------------------------------------------------------------------------------------
// OBJ

fn corners(mesh: &Mesh) -> Vec<[[f32; 3]; 3]> {
    mesh.corner_triangles()
        .iter()
        .map(|t| t.map(|v| v.0))
        .collect()
}

#[test]
fn obj_gives_the_same_triangles_as_ply() {
    // The reference mesh with texture coordinates, normals, every index form, a point and
    // a line (ignored), and the pentagon written with relative indices.
    let text = "# reference mesh\nmtllib missing.mtl\n\
        v 0 0 0\nv 2 0 0\nv 2 3 0\nv 0 3 0\nv -1 1 1.5\nv 4 -2 0.25\n\
        vt 0 0\nvt 1 0\nvn 0 0 1\n\
        usemtl stone\n\
        f 1/1 2/2 3/1\n\
        f 1//1 3//1 4//1 5//1\n\
        f -1/-1/-1 -2 -3 -4 -5\n\
        l 1 2\n\
        p 3\n\
        f 4 5 6\n";
    let mesh = Mesh::from_obj_bytes(text.as_bytes()).unwrap();
    assert_eq!(corners(&mesh), corners(&expected()));
    mesh.validate().unwrap();
}

#[test]
fn obj_objects_and_groups_are_merged() {
    // Three objects sharing one vertex list: indices are the file's, whatever the object.
    let text = "v 0 0 0\nv 2 0 0\nv 2 3 0\nv 0 3 0\nv -1 1 1.5\nv 4 -2 0.25\n\
        o first\nf 1 2 3\n\
        o second\nf 1 3 4 5\n\
        g third\nf 6 5 4 3 2\nf 4 5 6\n";
    let mesh = Mesh::from_obj_bytes(text.as_bytes()).unwrap();
    assert_eq!(corners(&mesh), corners(&expected()));
    mesh.validate().unwrap();
    // Vertices shared across objects are the file's, not one copy per object.
    assert_eq!(mesh.vertices.len(), 6);
}

#[test]
fn obj_quad_and_polygon() {
    let text = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv -1 0.5 0\nf 1 2 3 4\nf 1 2 3 4 5\n";
    let mesh = Mesh::from_obj_bytes(text.as_bytes()).unwrap();
    let v = |i: usize| mesh.vertices[i];
    assert_eq!(mesh.vertices.len(), 5);
    let expect = [[0, 1, 2], [0, 2, 3], [0, 1, 2], [0, 2, 3], [0, 3, 4]];
    let want: Vec<_> = expect.iter().map(|t| t.map(v)).collect();
    assert_eq!(corners(&mesh), want);
}

#[test]
fn obj_errors() {
    let vertices = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";
    let cases: Vec<(String, Vec<&str>)> = vec![
        (
            format!("{vertices}f 1 x 3\n"),
            vec!["line 4", "'f 1 x 3'", "not an integer"],
        ),
        (
            format!("{vertices}f 1 2 9\n"),
            vec!["line 4", "vertex 9", "3 vertices"],
        ),
        (format!("{vertices}f 1 2 0\n"), vec!["line 4", "vertex 0"]),
        (format!("{vertices}f -4 1 2\n"), vec!["line 4", "vertex -4"]),
        (
            format!("{vertices}o a\nf 1 2 3\no b\nf 2 3 7\n"),
            vec!["line 7", "vertex 7"],
        ),
        (
            format!("v 0 0\n{vertices}"),
            vec!["line 1", "'v 0 0'", "three numbers"],
        ),
        (format!("{vertices}v 1 2 3 0\n"), vec!["line 4", "w = 0"]),
        (
            format!("{vertices}v 1 2 3 4 5\n"),
            vec!["line 4", "wrong number of values"],
        ),
        (format!("{vertices}usemtl\n"), vec!["line 4", "usemtl"]),
    ];
    for (text, parts) in cases {
        match Mesh::from_obj_bytes(text.as_bytes()) {
            Ok(mesh) => panic!("{text:?}: expected an error, got {mesh:?}"),
            Err(message) => {
                for part in parts {
                    assert!(
                        message.contains(part),
                        "{text:?}: {message:?} lacks {part:?}"
                    );
                }
            }
        }
    }
    let mut bytes = format!("{vertices}f 1 2 3\n").into_bytes();
    bytes.extend_from_slice(b"g \xff\xfe\n");
    let message = Mesh::from_obj_bytes(&bytes).unwrap_err();
    assert!(
        message.contains("line 5") && message.contains("UTF-8"),
        "{message}"
    );
}

/// Texture and normal indices are not used, so bad ones are not errors (and must not reach
/// index arithmetic, which could overflow on them); a bad position index is.
#[test]
fn obj_bad_texture_and_normal_indices_are_ignored_not_a_panic() {
    let text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvn 0 0 1\n\
        f 1/0/0 2/0/0 3/0/0\nf 1/-5/-5 2/-5/-5 3/-5/-5\nf 1/9/9 2/9/9 3/9/9\n";
    let mesh = Mesh::from_obj_bytes(text.as_bytes()).unwrap();
    assert_eq!(mesh.triangles.len(), 3);
    assert_eq!(
        corners(&mesh),
        vec![[[0., 0., 0.], [1., 0., 0.], [0., 1., 0.]]; 3]
    );
    let message = Mesh::from_obj_bytes(format!("{text}f 0/1 1/1 2/1\n").as_bytes()).unwrap_err();
    assert!(
        message.contains("line 9") && message.contains("vertex 0"),
        "{message}"
    );
}

/// Each face form and relative indices, against hand-resolved triangles.
#[test]
fn obj_face_forms_and_relative_indices() {
    let vertices = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nvt 0 0\nvt 1 1\nvn 0 0 1\n";
    let cases: [(&str, &[[u32; 3]]); 7] = [
        ("f 1 2 3", &[[0, 1, 2]]),
        ("f 1/1 2/2 3/1", &[[0, 1, 2]]),
        ("f 2//1 4//1 3//1", &[[1, 3, 2]]),
        ("f 4/2/1 3/1/1 1/1/1", &[[3, 2, 0]]),
        ("f -4 -3 -2", &[[0, 1, 2]]),
        ("f -1/-1/-1 -2//-1 -3/-2", &[[3, 2, 1]]),
        ("f 1 2 -1 -2", &[[0, 1, 3], [0, 3, 2]]),
    ];
    for (face, want) in cases {
        let mesh = Mesh::from_obj_bytes(format!("{vertices}{face}\n").as_bytes()).unwrap();
        assert_eq!(mesh.triangles, want, "{face}");
        assert_eq!(mesh.vertices.len(), 4, "{face}");
    }
    // A relative index counts back from the vertices defined so far, not the file's.
    let mesh =
        Mesh::from_obj_bytes(b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf -3 -2 -1\nv 9 9 9\nf -1 -2 -3\n")
            .unwrap();
    assert_eq!(mesh.triangles, vec![[0, 1, 2], [3, 2, 1]]);
    // Positive indices may refer forward, to vertices defined later.
    let mesh = Mesh::from_obj_bytes(b"f 1 2 3\nv 0 0 0\nv 1 0 0\nv 0 1 0\n").unwrap();
    assert_eq!(mesh.triangles, vec![[0, 1, 2]]);
    // w divides, comments after a statement, CRLF, tabs and continued lines.
    let mesh = Mesh::from_obj_bytes(
        b"v 2 4 6 2 # homogeneous\r\nv\t1 0 0\r\nv 0 1 \\\r\n 0\r\nf 1 2 \\\n 3 # end\n",
    )
    .unwrap();
    assert_eq!(
        mesh.vertices,
        vec![[1., 2., 3.], [1., 0., 0.], [0., 1., 0.]]
    );
    assert_eq!(mesh.triangles, vec![[0, 1, 2]]);
}

/// Every error names its line and says what is wrong.
#[test]
fn obj_errors_name_their_line() {
    let v = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";
    let cases: Vec<(Vec<u8>, &str, &str)> = vec![
        (
            format!("{v}f 1 2 4\n").into(),
            "line 4:",
            "vertex 4, but 3 vertices",
        ),
        (format!("{v}f 1 2 0\n").into(), "line 4:", "vertex 0"),
        (
            format!("{v}f 1 -4 2\n").into(),
            "line 4:",
            "vertex -4, but only 3",
        ),
        (
            format!("{v}f 1 2\n").into(),
            "line 4:",
            "has 2 vertices; a face needs at least 3",
        ),
        (format!("{v}f\n").into(), "line 4:", "has 0 vertices"),
        (
            format!("{v}f 1 2 3.5\n").into(),
            "line 4:",
            "'3.5' has an index that is not an integer",
        ),
        (
            format!("{v}f 1 2 3/x\n").into(),
            "line 4:",
            "'3/x' has an index that is not an integer",
        ),
        (
            format!("{v}f 1 2 3/1/1/1\n").into(),
            "line 4:",
            "more than three parts",
        ),
        (
            format!("{v}f 1 2 99999999999999999999\n").into(),
            "line 4:",
            "too large",
        ),
        (
            format!("{v}f 1 2 4294967297\n").into(),
            "line 4:",
            "4294967297",
        ),
        (
            format!("v 0 0 0\nv 1 zero 0\n{v}").into(),
            "line 2:",
            "'zero' is not a number",
        ),
        (format!("{v}v 1 2\n").into(), "line 4:", "three numbers"),
        (
            format!("{v}v 1 2 3 4 5\n").into(),
            "line 4:",
            "wrong number of values",
        ),
        (format!("{v}v 1 2 3 0\n").into(), "line 4:", "w = 0"),
        (
            b"v 0 0 0\nv 1 0 0\n# \xff ok\nv 0 \xe9 0\n".to_vec(),
            "line 4:",
            "not UTF-8",
        ),
        // The first bad forward reference is reported, not the largest.
        (
            format!("f 1 2 5\nf 1 2 9\n{v}").into(),
            "line 1:",
            "vertex 5",
        ),
        // A continued line is reported at its first line.
        (
            format!("{v}\nf 1 \\\n 2 \\\n 7\n").into(),
            "line 5:",
            "vertex 7",
        ),
    ];
    for (text, line, what) in cases {
        let shown = String::from_utf8_lossy(&text).into_owned();
        match Mesh::from_obj_bytes(&text) {
            Ok(mesh) => panic!("{shown:?}: expected an error, got {mesh:?}"),
            Err(e) => assert!(
                e.starts_with(line) && e.contains(what),
                "{shown:?}: {e:?} is not '{line} ... {what} ...'"
            ),
        }
    }
}

/// Random meshes written as OBJ in every face form, with absolute and relative indices,
/// objects, groups, texture coordinates, normals, comments and continued lines, read back:
/// the writer knows the mesh, so it is the oracle.
#[test]
fn obj_random_files_read_as_written() {
    use rand::{Rng, SeedableRng};
    for seed in 0..200u64 {
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
        let n = rng.random_range(3..40usize);
        let vertices: Vec<[f32; 3]> = (0..n)
            .map(|_| [0; 3].map(|_| rng.random_range(-1000..1000) as f32 / 8.0))
            .collect();
        let mut text = String::new();
        let mut triangles = Vec::new();
        let mut defined = 0;
        while defined < n || rng.random_bool(0.5) {
            match rng.random_range(0..8) {
                0..=2 if defined < n => {
                    let [x, y, z] = vertices[defined];
                    text += &format!("v {x} {y} {z}\n");
                    defined += 1;
                }
                3 if defined >= 3 => {
                    let k = rng.random_range(3..7);
                    let polygon: Vec<usize> =
                        (0..k).map(|_| rng.random_range(0..defined)).collect();
                    text += "f";
                    for &i in &polygon {
                        let index = if rng.random_bool(0.3) {
                            format!("-{}", defined - i)
                        } else {
                            (i + 1).to_string()
                        };
                        text += &match rng.random_range(0..4) {
                            0 => format!(" {index}"),
                            1 => format!(" {index}/1"),
                            2 => format!(" {index}//1"),
                            _ => format!(" {index}/1/1"),
                        };
                        if rng.random_bool(0.1) {
                            text += " \\\n";
                        }
                    }
                    text += "\n";
                    for j in 1..k - 1 {
                        triangles.push([polygon[0], polygon[j], polygon[j + 1]].map(|i| i as u32));
                    }
                }
                4 => text += &format!("o part{}\n", rng.random_range(0..9)),
                5 => text += "g a b\ns off\nusemtl m\n",
                6 => text += "vt 0.5 0.5\nvn 0 0 1\n",
                _ => text += "# comment\n\n",
            }
        }
        let mesh = Mesh::from_obj_bytes(text.as_bytes()).unwrap_or_else(|e| panic!("{e}\n{text}"));
        assert_eq!(mesh.vertices, vertices, "seed {seed}:\n{text}");
        assert_eq!(mesh.triangles, triangles, "seed {seed}:\n{text}");
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    #[test]
    fn obj_corruption_never_panics(
        edits in prop::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 1..6),
    ) {
        let mut bytes = b"v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvn 0 0 1\no a\nf 1/1/1 2/1/1 3/1/1\nf -3 -2 -1 1\n".to_vec();
        for (at, byte) in edits {
            let i = at.index(bytes.len());
            bytes[i] = byte;
        }
        let _ = Mesh::from_obj_bytes(&bytes);
    }
}

// ---------------------------------------------------------------------------------------
// Mesh::load on files

#[test]
fn load_picks_the_reader_and_names_the_file() {
    let dir = std::env::temp_dir().join(format!("sahkd-mesh-io-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let ply = dir.join("mesh.PLY");
    std::fs::write(
        &ply,
        write_ply(Format::Big, &scanner_layout("uint", &FACES)),
    )
    .unwrap();
    assert_eq!(Mesh::load(&ply).unwrap(), expected());

    let obj = dir.join("mesh.obj");
    std::fs::write(&obj, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
    assert_eq!(Mesh::load(&obj).unwrap().triangles, vec![[0, 1, 2]]);

    // An index past the vertices passes the reader and is caught by validation.
    let out_of_range = dir.join("range.ply");
    let faces: Vec<&[f64]> = vec![&[0.0, 1.0, 6.0]];
    std::fs::write(
        &out_of_range,
        write_ply(Format::Little, &scanner_layout("int", &faces)),
    )
    .unwrap();
    match Mesh::load(&out_of_range) {
        Err(MeshError::InFile { path, error }) => {
            assert!(path.ends_with("range.ply"), "{path}");
            assert!(matches!(
                *error,
                MeshError::IndexOutOfRange {
                    face: 0,
                    index: 6,
                    vertices: 6
                }
            ));
        }
        other => panic!("expected the file and the index out of range, got {other:?}"),
    }

    let broken = dir.join("broken.ply");
    std::fs::write(&broken, b"ply\nformat ascii 1.0\n").unwrap();
    let message = Mesh::load(&broken).unwrap_err().to_string();
    assert!(
        message.contains("broken.ply") && message.contains("end_header"),
        "{message}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

// ---------------------------------------------------------------------------------------
// Real scenes

fn scenes_dir() -> Option<PathBuf> {
    let dir = match std::env::var_os("SAHKD_SCENES") {
        Some(dir) => PathBuf::from(dir),
        None => PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/scenes"),
    };
    if dir.join("README.md").is_file() {
        Some(dir)
    } else {
        println!(
            "skipping: no scenes at {} (set SAHKD_SCENES)",
            dir.display()
        );
        None
    }
}

/// One row of the README's summary table.
struct SceneRow {
    file: String,
    triangles: usize,
    vertices: usize,
    lo: [f64; 3],
    hi: [f64; 3],
    zero_area: usize,
    unreferenced: usize,
    bytes: u64,
}

fn readme_rows(readme: &str) -> Vec<SceneRow> {
    let number = |s: &str| s.trim().replace(',', "").parse::<u64>().unwrap();
    let point = |s: &str| -> [f64; 3] {
        let inner = s.trim().trim_start_matches('(').trim_end_matches(')');
        let v: Vec<f64> = inner
            .split(',')
            .map(|c| c.trim().parse().unwrap())
            .collect();
        [v[0], v[1], v[2]]
    };
    readme
        .lines()
        .filter(|l| l.starts_with("| `") && l.contains(".ply`"))
        .filter_map(|line| {
            let cells: Vec<&str> = line.trim_matches('|').split('|').collect();
            if cells.len() != 7 {
                return None; // a per-scene table, not the summary
            }
            let (lo, hi) = cells[3].split_once('–').unwrap();
            Some(SceneRow {
                file: cells[0].trim().trim_matches('`').to_string(),
                triangles: number(cells[1]) as usize,
                vertices: number(cells[2]) as usize,
                lo: point(lo),
                hi: point(hi),
                zero_area: number(cells[4]) as usize,
                unreferenced: number(cells[5]) as usize,
                bytes: number(cells[6]),
            })
        })
        .collect()
}

#[test]
fn scenes_match_their_readme() {
    let Some(dir) = scenes_dir() else { return };
    let rows = readme_rows(&std::fs::read_to_string(dir.join("README.md")).unwrap());
    assert!(
        rows.len() >= 7,
        "README summary table has {} rows",
        rows.len()
    );
    for row in rows {
        let path = dir.join(&row.file);
        let mesh = Mesh::load(&path).unwrap_or_else(|e| panic!("{e}"));
        let name = &row.file;
        assert_eq!(mesh.triangles.len(), row.triangles, "{name} triangles");
        assert_eq!(mesh.vertices.len(), row.vertices, "{name} vertices");
        assert_eq!(
            mesh.zero_area_triangles(),
            row.zero_area,
            "{name} zero-area"
        );
        let mut used = vec![false; mesh.vertices.len()];
        mesh.triangles
            .iter()
            .flatten()
            .for_each(|&i| used[i as usize] = true);
        let unused = used.iter().filter(|u| !**u).count();
        assert_eq!(unused, row.unreferenced, "{name} unreferenced vertices");
        assert_eq!(
            std::fs::metadata(&path).unwrap().len(),
            row.bytes,
            "{name} bytes"
        );
        // The README prints six significant digits.
        let bounds = mesh.bounds();
        for axis in 0..3 {
            for (got, want) in [
                (bounds.lo.0[axis], row.lo[axis]),
                (bounds.hi.0[axis], row.hi[axis]),
            ] {
                let tolerance = want.abs() * 1e-5 + 1e-9;
                assert!(
                    (got as f64 - want).abs() <= tolerance,
                    "{name} bounds {got} vs {want}"
                );
            }
        }
    }
}

/// The scenes take the fast path; rewriting two of them big-endian and as ASCII sends the
/// same data through the general paths, which must agree exactly.
#[test]
fn scenes_read_the_same_through_every_path() {
    let Some(dir) = scenes_dir() else { return };
    for file in ["dragon_res4.ply", "bunny.ply"] {
        let mesh = Mesh::load(dir.join(file)).unwrap();
        let elements = vec![
            Element {
                name: "vertex",
                props: vec![
                    scalar("float", "x"),
                    scalar("float", "y"),
                    scalar("float", "z"),
                ],
                rows: mesh
                    .vertices
                    .iter()
                    .map(|v| v.iter().map(|&c| one(c as f64)).collect())
                    .collect(),
            },
            Element {
                name: "face",
                props: vec![list("uchar", "int", "vertex_indices")],
                rows: mesh
                    .triangles
                    .iter()
                    .map(|t| vec![many(&t.map(|i| i as f64))])
                    .collect(),
            },
        ];
        for format in [Format::Big, Format::Ascii] {
            let again = parse(&write_ply(format, &elements)).unwrap();
            assert!(again == mesh, "{file} read as {format:?} differs");
        }
    }
}
