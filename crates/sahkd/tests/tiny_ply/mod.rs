//! A test-only reader for the exact binary PLY layout of the shared scenes (see
//! `shared/scenes/README.md`): little-endian float x y z vertices, then faces of a count byte
//! (always 3) and three int32 indices. Anything else is refused with a message.

#![allow(dead_code)]

use sahkd::Mesh;
use std::path::{Path, PathBuf};

/// The shared scenes folder: `SAHKD_SCENES`, else `../shared/scenes` beside the workspace.
pub fn scenes_dir() -> Option<PathBuf> {
    let dir = std::env::var_os("SAHKD_SCENES")
        .map(PathBuf::from)
        .unwrap_or_else(|| {
            PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/scenes")
        });
    dir.is_dir().then_some(dir)
}

/// Reads one of the shared scenes, or explains on stderr why it is skipped.
pub fn scene(file: &str) -> Option<Mesh> {
    let Some(dir) = scenes_dir() else {
        eprintln!("SKIPPED: no scenes folder (set SAHKD_SCENES); {file} not tested");
        return None;
    };
    let path = dir.join(file);
    if !path.is_file() {
        eprintln!("SKIPPED: {} is missing", path.display());
        return None;
    }
    Some(read(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display())))
}

pub fn read(path: &Path) -> Result<Mesh, String> {
    let bytes = std::fs::read(path).map_err(|e| e.to_string())?;
    let end = bytes
        .windows(11)
        .position(|w| w == b"end_header\n")
        .ok_or("no end_header line")?;
    let header = std::str::from_utf8(&bytes[..end]).map_err(|e| e.to_string())?;
    let expected_rest = "property float x\nproperty float y\nproperty float z\n";
    let count = |element: &str| -> Result<usize, String> {
        header
            .lines()
            .find_map(|l| l.strip_prefix(&format!("element {element} ")))
            .ok_or(format!("no element {element}"))?
            .trim()
            .parse()
            .map_err(|e| format!("element {element}: {e}"))
    };
    if !header.starts_with("ply\nformat binary_little_endian 1.0\n")
        || !header.contains(expected_rest)
    {
        return Err("not the binary little-endian layout of the shared scenes".into());
    }
    let (nv, nf) = (count("vertex")?, count("face")?);
    let body = &bytes[end + 11..];
    if body.len() != 12 * nv + 13 * nf {
        return Err(format!(
            "{} body bytes for {nv} vertices and {nf} faces",
            body.len()
        ));
    }
    let f32_at = |o: usize| f32::from_le_bytes(body[o..o + 4].try_into().unwrap());
    let vertices = (0..nv)
        .map(|i| [f32_at(12 * i), f32_at(12 * i + 4), f32_at(12 * i + 8)])
        .collect();
    let faces = &body[12 * nv..];
    let triangles = (0..nf)
        .map(|i| {
            let f = &faces[13 * i..13 * i + 13];
            if f[0] != 3 {
                return Err(format!("face {i} has {} corners", f[0]));
            }
            let idx = |k: usize| u32::from_le_bytes(f[1 + 4 * k..5 + 4 * k].try_into().unwrap());
            Ok([idx(0), idx(1), idx(2)])
        })
        .collect::<Result<_, String>>()?;
    let mesh = Mesh {
        vertices,
        triangles,
    };
    mesh.validate().map_err(|e| e.to_string())?;
    Ok(mesh)
}
