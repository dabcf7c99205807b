//! Fuzzing of the mesh readers in CI, on stable Rust: small valid PLY files
//! (ASCII, binary little- and big-endian, every scalar type, extra properties, lists and
//! elements) and OBJ files are generated with the mesh they hold, checked to read as that
//! mesh, then mutated (truncations, byte flips, insertions, deletions, lying counts and
//! indices, swapped type names) and fed to both readers, from bytes and from files. The
//! property: the reader returns the mesh or a one-line error, never panics, stays within
//! a memory bound proportional to the input (a counting global allocator), and never hangs
//! (a watchdog per case). See `common/fuzz.rs` for the budget and how to rerun a case.
//!
//! `corpus_inputs_read_as_recorded` reads every file of `tests/corpus/`: each input that
//! once broke a reader, with its expected outcome in `tests/corpus/expected.txt`.

#[path = "common/fuzz.rs"]
mod fuzz;

use fuzz::{case_rng, check_corpus, check_outcome, measured, mutate, Counting};
use rand::rngs::StdRng;
use rand::Rng;
use sahkd::Mesh;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

#[global_allocator]
static ALLOCATOR: Counting = Counting;

// ---------------------------------------------------------------------------------------
// PLY seeds

#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum Encoding {
    Ascii,
    Little,
    Big,
}

/// (name, size, integer, signed) of the PLY scalar types, one spelling each way.
const TYPES: [(&str, &str, usize, bool, bool); 8] = [
    ("char", "int8", 1, true, true),
    ("uchar", "uint8", 1, true, false),
    ("short", "int16", 2, true, true),
    ("ushort", "uint16", 2, true, false),
    ("int", "int32", 4, true, true),
    ("uint", "uint32", 4, true, false),
    ("float", "float32", 4, false, true),
    ("double", "float64", 8, false, true),
];

const INTEGERS: [usize; 6] = [0, 1, 2, 3, 4, 5];

/// Every word a PLY header mutation may swap for another.
const PLY_WORDS: &[&str] = &[
    "char",
    "uchar",
    "short",
    "ushort",
    "int",
    "uint",
    "float",
    "double",
    "int8",
    "uint8",
    "int16",
    "uint16",
    "int32",
    "uint32",
    "float32",
    "float64",
    "list",
    "ascii",
    "binary_little_endian",
    "binary_big_endian",
    "vertex",
    "face",
    "vertex_indices",
    "element",
    "property",
    "end_header",
    "1.0",
];

enum Kind {
    Scalar(usize),
    List { count: usize, item: usize },
}

struct Property {
    name: String,
    kind: Kind,
}

/// A value written as type `t`: integers exactly, floats in their shortest form.
fn encode(out: &mut Vec<u8>, encoding: Encoding, t: usize, value: f64) {
    if encoding == Encoding::Ascii {
        if TYPES[t].3 {
            out.extend_from_slice(format!("{} ", value as i64).as_bytes());
        } else {
            out.extend_from_slice(format!("{value} ").as_bytes());
        }
        return;
    }
    let bytes: Vec<u8> = match (TYPES[t].0, encoding) {
        ("char", _) => vec![value as i8 as u8],
        ("uchar", _) => vec![value as u8],
        ("short", Encoding::Little) => (value as i16).to_le_bytes().to_vec(),
        ("short", _) => (value as i16).to_be_bytes().to_vec(),
        ("ushort", Encoding::Little) => (value as u16).to_le_bytes().to_vec(),
        ("ushort", _) => (value as u16).to_be_bytes().to_vec(),
        ("int", Encoding::Little) => (value as i32).to_le_bytes().to_vec(),
        ("int", _) => (value as i32).to_be_bytes().to_vec(),
        ("uint", Encoding::Little) => (value as u32).to_le_bytes().to_vec(),
        ("uint", _) => (value as u32).to_be_bytes().to_vec(),
        ("float", Encoding::Little) => (value as f32).to_le_bytes().to_vec(),
        ("float", _) => (value as f32).to_be_bytes().to_vec(),
        ("double", Encoding::Little) => value.to_le_bytes().to_vec(),
        (_, _) => value.to_be_bytes().to_vec(),
    };
    out.extend_from_slice(&bytes);
}

/// A random value that type `t` holds exactly, and that every coordinate type holds too
/// when `small`.
fn value_of(rng: &mut StdRng, t: usize, small: bool) -> f64 {
    let (_, _, size, integer, signed) = TYPES[t];
    if !integer {
        return rng.random_range(-400..400) as f64 / 8.0;
    }
    let (lo, hi) = match (small, signed) {
        (true, true) => (-50, 50),
        (true, false) => (0, 100),
        (false, true) => (-(1i64 << (8 * size - 1)), (1i64 << (8 * size - 1)) - 1),
        (false, false) => (0, (1i64 << (8 * size)) - 1),
    };
    rng.random_range(lo..=hi) as f64
}

/// A random valid PLY file and the mesh it holds.
fn ply_seed(rng: &mut StdRng) -> (Vec<u8>, Mesh) {
    let encoding = [Encoding::Ascii, Encoding::Little, Encoding::Big][rng.random_range(0..3)];
    let n = rng.random_range(0..6usize);
    // Vertex properties: x, y, z in random places among extras.
    let mut vertex_props: Vec<Property> = ["x", "y", "z"]
        .iter()
        .map(|axis| Property {
            name: axis.to_string(),
            kind: Kind::Scalar(rng.random_range(0..8)),
        })
        .collect();
    for k in 0..rng.random_range(0..3) {
        let kind = if rng.random_bool(0.3) {
            Kind::List {
                count: INTEGERS[rng.random_range(0..6)],
                item: rng.random_range(0..8),
            }
        } else {
            Kind::Scalar(rng.random_range(0..8))
        };
        let at = rng.random_range(0..=vertex_props.len());
        let name = format!("extra{k}");
        vertex_props.insert(at, Property { name, kind });
    }
    let mut face_props = vec![Property {
        name: if rng.random_bool(0.8) {
            "vertex_indices"
        } else {
            "vertex_index"
        }
        .into(),
        kind: Kind::List {
            count: INTEGERS[rng.random_range(0..6)],
            item: INTEGERS[rng.random_range(0..6)],
        },
    }];
    if rng.random_bool(0.3) {
        let at = rng.random_range(0..=1);
        let kind = Kind::Scalar(rng.random_range(0..8));
        face_props.insert(
            at,
            Property {
                name: "flags".into(),
                kind,
            },
        );
    }
    // Elements: vertex and face (in either order) and maybe an unread one anywhere.
    let faces = rng.random_range(0..5usize);
    let mut elements = vec![("vertex", n, vertex_props), ("face", faces, face_props)];
    if rng.random_bool(0.5) {
        elements.swap(0, 1);
    }
    if rng.random_bool(0.4) {
        let props = vec![
            Property {
                name: "a".into(),
                kind: Kind::Scalar(rng.random_range(0..8)),
            },
            Property {
                name: "b".into(),
                kind: Kind::List {
                    count: INTEGERS[rng.random_range(0..6)],
                    item: rng.random_range(0..8),
                },
            },
        ];
        let at = rng.random_range(0..=2);
        elements.insert(at, ("edge", rng.random_range(0..3), props));
    }

    let format = match encoding {
        Encoding::Ascii => "ascii",
        Encoding::Little => "binary_little_endian",
        Encoding::Big => "binary_big_endian",
    };
    let mut out = format!("ply\nformat {format} 1.0\ncomment fuzz seed\n").into_bytes();
    for (name, count, props) in &elements {
        out.extend_from_slice(format!("element {name} {count}\n").as_bytes());
        for p in props {
            let mut spell = |t: usize| {
                if rng.random_bool(0.5) {
                    TYPES[t].0
                } else {
                    TYPES[t].1
                }
            };
            let line = match p.kind {
                Kind::Scalar(t) => format!("property {} {}\n", spell(t), p.name),
                Kind::List { count, item } => {
                    format!(
                        "property list {} {} {}\n",
                        spell(count),
                        spell(item),
                        p.name
                    )
                }
            };
            out.extend_from_slice(line.as_bytes());
        }
    }
    out.extend_from_slice(b"end_header\n");

    let mut mesh = Mesh::default();
    for (name, count, props) in &elements {
        for _ in 0..*count {
            let mut position = [0f32; 3];
            for p in props {
                match p.kind {
                    Kind::Scalar(t) => {
                        let axis = ["x", "y", "z"].iter().position(|a| *a == p.name);
                        let value = value_of(rng, t, axis.is_some());
                        if let (Some(axis), true) = (axis, *name == "vertex") {
                            position[axis] = value as f32;
                        }
                        encode(&mut out, encoding, t, value);
                    }
                    Kind::List { count, item } => {
                        let indices = *name == "face" && p.name.starts_with("vertex_ind");
                        let len = rng.random_range(0..if indices { 7 } else { 3 });
                        encode(&mut out, encoding, count, len as f64);
                        let polygon: Vec<u32> = (0..len)
                            .map(|_| {
                                let value = if indices && n > 0 {
                                    rng.random_range(0..n) as f64
                                } else {
                                    value_of(rng, item, true).abs()
                                };
                                encode(&mut out, encoding, item, value);
                                value as u32
                            })
                            .collect();
                        if indices && len >= 3 {
                            for j in 1..len - 1 {
                                mesh.triangles
                                    .push([polygon[0], polygon[j], polygon[j + 1]]);
                            }
                        }
                    }
                }
            }
            if *name == "vertex" {
                mesh.vertices.push(position);
            }
            if encoding == Encoding::Ascii {
                out.pop();
                out.push(b'\n');
            }
        }
    }
    (out, mesh)
}

// ---------------------------------------------------------------------------------------
// OBJ seeds

const OBJ_WORDS: &[&str] = &["v ", "f ", "vt ", "vn ", "o ", "#", "/", "//", "\\", "-"];

/// A random valid OBJ file and the mesh it holds: every face form, absolute and relative
/// indices, and the statements that are read past.
fn obj_seed(rng: &mut StdRng) -> (Vec<u8>, Mesh) {
    let n = rng.random_range(0..8usize);
    let mut mesh = Mesh::default();
    let mut text = String::new();
    let mut defined = 0;
    let mut faces = rng.random_range(0..5);
    while defined < n || faces > 0 {
        match rng.random_range(0..7) {
            0..=2 if defined < n => {
                let p = [0; 3].map(|_| rng.random_range(-400..400) as f32 / 8.0);
                mesh.vertices.push(p);
                text += &format!("v {} {} {}\n", p[0], p[1], p[2]);
                defined += 1;
            }
            3 if defined > 0 && faces > 0 => {
                faces -= 1;
                let k = rng.random_range(3..7);
                let polygon: Vec<usize> = (0..k).map(|_| rng.random_range(0..defined)).collect();
                text += "f";
                for &i in &polygon {
                    let index = if rng.random_bool(0.3) {
                        format!("-{}", defined - i)
                    } else {
                        (i + 1).to_string()
                    };
                    text += &[" {}", " {}/1", " {}//2", " {}/3/4", " \\\n{}"]
                        [rng.random_range(0..5)]
                    .replace("{}", &index);
                }
                text += "\n";
                for j in 1..k - 1 {
                    mesh.triangles
                        .push([polygon[0], polygon[j], polygon[j + 1]].map(|i| i as u32));
                }
            }
            3 if defined == 0 => faces = 0,
            4 => text += "o thing\ng part\ns 1\nusemtl stone\n",
            5 => text += "vt 0.5 0.25\nvn 0 0 1\nl 1 2\n",
            _ => text += "# a comment\n\n",
        }
    }
    (text.into_bytes(), mesh)
}

// ---------------------------------------------------------------------------------------
// Cases

/// Where a case writes its input to read it through `Mesh::load`.
fn scratch(name: &str) -> PathBuf {
    // In memory where the system offers it: writes to a disk slow the cases down.
    let shm = Path::new("/dev/shm");
    let base = if shm.is_dir() {
        shm
    } else {
        Path::new(env!("CARGO_TARGET_TMPDIR"))
    };
    let dir = base.join(format!("sahkd-mesh-fuzz-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

/// Mutated inputs their own reader still read as a mesh, per target: a check that the
/// mutations reach past the header, reported with the number of cases.
static READ_OK: [AtomicU64; 2] = [AtomicU64::new(0), AtomicU64::new(0)];

/// Removes a target's scratch file, and the folder once both targets are done with it.
fn remove_scratch(name: &str) {
    let path = scratch(name);
    let _ = std::fs::remove_file(&path);
    let _ = std::fs::remove_dir(path.parent().unwrap());
}

/// Both readers on `bytes`, from memory; every 4th case also `Mesh::load` from a file.
fn read_every_way(case: u64, bytes: &[u8], ext: &str) -> Result<(), String> {
    let (ply, usage) = measured(|| Mesh::from_ply_bytes(bytes));
    let own_ok = if ext == "ply" {
        ply.is_ok()
    } else {
        Mesh::from_obj_bytes(bytes).is_ok()
    };
    READ_OK[(ext == "obj") as usize].fetch_add(own_ok as u64, Ordering::Relaxed);
    check_outcome(bytes.len(), &ply, usage).map_err(|e| format!("PLY reader: {e}"))?;
    let (obj, usage) = measured(|| Mesh::from_obj_bytes(bytes));
    check_outcome(bytes.len(), &obj, usage).map_err(|e| format!("OBJ reader: {e}"))?;
    if case % 4 == 0 {
        let path = scratch(&format!("case.{ext}"));
        std::fs::write(&path, bytes).unwrap();
        let (loaded, usage) = measured(|| Mesh::load(&path).map_err(|e| e.to_string()));
        check_outcome(bytes.len(), &loaded, usage).map_err(|e| format!("Mesh::load: {e}"))?;
        if let Err(e) = &loaded {
            if !e.starts_with(&path.display().to_string()) {
                return Err(format!("Mesh::load's error does not name the file: {e}"));
            }
        }
    }
    Ok(())
}

fn seed_reads_as_written(
    read: Result<Mesh, String>,
    mesh: &Mesh,
    bytes: &[u8],
) -> Result<(), String> {
    match read {
        Ok(read) if read == *mesh => Ok(()),
        other => Err(format!(
            "the seed {:?} reads as {other:?}, not {mesh:?}",
            String::from_utf8_lossy(bytes)
        )),
    }
}

fn ply_case(case: u64) -> Result<(), String> {
    let mut rng = case_rng("ply", case);
    let (mut bytes, mesh) = ply_seed(&mut rng);
    seed_reads_as_written(Mesh::from_ply_bytes(&bytes), &mesh, &bytes)?;
    mutate(&mut rng, &mut bytes, PLY_WORDS);
    read_every_way(case, &bytes, "ply")
}

fn obj_case(case: u64) -> Result<(), String> {
    let mut rng = case_rng("obj", case);
    let (mut bytes, mesh) = obj_seed(&mut rng);
    seed_reads_as_written(Mesh::from_obj_bytes(&bytes), &mesh, &bytes)?;
    mutate(&mut rng, &mut bytes, OBJ_WORDS);
    read_every_way(case, &bytes, "obj")
}

#[test]
fn fuzz_ply() {
    let cases = fuzz::run("ply", ply_case);
    remove_scratch("case.ply");
    let ok = READ_OK[0].load(Ordering::Relaxed);
    eprintln!("fuzz ply: {ok} of {cases} mutated inputs still read as a mesh");
    assert!(cases > 0);
}

#[test]
fn fuzz_obj() {
    let cases = fuzz::run("obj", obj_case);
    remove_scratch("case.obj");
    let ok = READ_OK[1].load(Ordering::Relaxed);
    eprintln!("fuzz obj: {ok} of {cases} mutated inputs still read as a mesh");
    assert!(cases > 0);
}

/// The harness itself: the watchdog, the panic catcher and the allocation bound each turn a
/// bad reader into a failing case.
#[test]
fn the_harness_catches_what_it_should() {
    let over = |_: u64| -> Result<(), String> {
        let (v, usage) = measured(|| vec![0u8; 10 << 20]);
        check_outcome(10, &Ok::<_, String>(v.len()), usage)
    };
    let e = std::panic::catch_unwind(|| fuzz::run("over", over)).unwrap_err();
    let e = e.downcast_ref::<String>().unwrap();
    assert!(
        e.contains("case 0 fails") && e.contains("allocation"),
        "{e}"
    );
    let panics = |_: u64| -> Result<(), String> { panic!("a reader bug") };
    let e = std::panic::catch_unwind(|| fuzz::run("panics", panics)).unwrap_err();
    let e = e.downcast_ref::<String>().unwrap();
    assert!(e.contains("panicked: a reader bug"), "{e}");
}

// ---------------------------------------------------------------------------------------
// Corpus

/// Every file of `tests/corpus/` read by `Mesh::load`, with the outcome `expected.txt`
/// records for it: `name: ok V vertices T triangles` or `name: error: <part of the message>`.
#[test]
fn corpus_inputs_read_as_recorded() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/corpus");
    check_corpus(&dir, |path, size, _| {
        let (read, usage) = measured(|| Mesh::load(path).map_err(|e| e.to_string()));
        check_outcome(size, &read, usage).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        read.map(|mesh| {
            format!(
                "ok {} vertices {} triangles",
                mesh.vertices.len(),
                mesh.triangles.len()
            )
        })
    });
}
