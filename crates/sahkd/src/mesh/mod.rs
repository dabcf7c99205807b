//! Triangle meshes: the input of every builder.
//!
//! A [`Mesh`] is an indexed triangle list. [`Mesh::load`] reads PLY and OBJ files;
//! [`Mesh::validate`] is the gate every mesh passes before a build, so that bad input is
//! reported with the offending vertex or face named instead of surfacing as a wrong tree.

mod obj;
mod ply;

use crate::geometry::{Aabb, Triangle, Vec3};
use std::fmt;
use std::path::Path;

/// An indexed triangle mesh.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Mesh {
    pub vertices: Vec<[f32; 3]>,
    pub triangles: Vec<[u32; 3]>,
}

/// What is wrong with a mesh file or a mesh.
#[derive(Debug)]
pub enum MeshError {
    Io {
        path: String,
        source: std::io::Error,
    },
    /// The file is not a PLY/OBJ we can read; the message says where and why.
    Parse {
        path: String,
        message: String,
    },
    UnknownFormat {
        path: String,
    },
    NonFiniteVertex {
        vertex: usize,
        value: [f32; 3],
    },
    IndexOutOfRange {
        face: usize,
        index: u32,
        vertices: usize,
    },
    /// A mesh read from a file failed validation: the file, and what is wrong.
    InFile {
        path: String,
        error: Box<MeshError>,
    },
}

impl fmt::Display for MeshError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            MeshError::Io { path, source } => write!(f, "cannot read {path}: {source}"),
            MeshError::Parse { path, message } => write!(f, "{path}: {message}"),
            MeshError::UnknownFormat { path } => write!(
                f,
                "{path}: unknown mesh format (expected a .ply or .obj file)"
            ),
            MeshError::NonFiniteVertex { vertex, value } => {
                write!(
                    f,
                    "vertex {vertex} has a non-finite coordinate ({}, {}, {})",
                    value[0], value[1], value[2]
                )?;
                if value.iter().any(|c| c.is_infinite()) {
                    write!(
                        f,
                        ": written as infinite, or beyond the float32 range (magnitudes up to {:e})",
                        f32::MAX
                    )?;
                }
                Ok(())
            }
            MeshError::IndexOutOfRange {
                face,
                index,
                vertices,
            } => write!(
                f,
                "face {face} refers to vertex {index}, but the mesh has only {vertices} vertices"
            ),
            MeshError::InFile { path, error } => write!(f, "{path}: {error}"),
        }
    }
}

impl std::error::Error for MeshError {}

/// What `path` is when it exists but is not a regular file: "a directory", "a character
/// device" (such as /dev/null), "a named pipe (FIFO)". `None` for regular files and for
/// paths that do not exist (reading them reports that). Every input file of meshes, trees
/// and rays is refused by this: opening a named pipe waits for a writer, forever if there
/// is none, and neither a tree (mapped) nor a .npy file (sized first) can be read from one.
pub fn not_a_file(path: &Path) -> Option<&'static str> {
    let kind = std::fs::metadata(path).ok()?.file_type();
    if kind.is_file() {
        return None;
    }
    if kind.is_dir() {
        return Some("a directory");
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if kind.is_fifo() {
            return Some("a named pipe (FIFO)");
        }
        if kind.is_char_device() {
            return Some("a character device");
        }
        if kind.is_block_device() {
            return Some("a block device");
        }
        if kind.is_socket() {
            return Some("a socket");
        }
    }
    Some("neither a file nor a directory")
}

impl Mesh {
    /// Reads a `.ply` (ASCII or binary, either byte order) or `.obj` file and validates it.
    /// Every error names the file.
    pub fn load(path: impl AsRef<Path>) -> Result<Mesh, MeshError> {
        let path = path.as_ref();
        let name = path.display().to_string();
        if let Some(what) = not_a_file(path) {
            return Err(MeshError::Parse {
                path: name,
                message: format!("is {what}, not a mesh file"),
            });
        }
        let bytes = std::fs::read(path).map_err(|source| MeshError::Io {
            path: name.clone(),
            source,
        })?;
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(|e| e.to_ascii_lowercase());
        let mesh = match ext.as_deref() {
            Some("ply") => ply::parse(&bytes),
            Some("obj") => obj::parse(&bytes),
            _ if bytes.starts_with(b"ply") => ply::parse(&bytes),
            _ => return Err(MeshError::UnknownFormat { path: name }),
        }
        .map_err(|message| MeshError::Parse {
            path: name.clone(),
            message,
        })?;
        mesh.validate().map_err(|error| MeshError::InFile {
            path: name,
            error: Box::new(error),
        })?;
        Ok(mesh)
    }

    /// Parses PLY data from memory (no validation).
    pub fn from_ply_bytes(bytes: &[u8]) -> Result<Mesh, String> {
        ply::parse(bytes)
    }

    /// Parses OBJ data from memory (no validation).
    pub fn from_obj_bytes(bytes: &[u8]) -> Result<Mesh, String> {
        obj::parse(bytes)
    }

    /// Every vertex finite and every index in range. Zero-area triangles are allowed: they
    /// are kept, built into the tree like any other, and never hit by a ray.
    pub fn validate(&self) -> Result<(), MeshError> {
        if let Some((vertex, v)) = self
            .vertices
            .iter()
            .enumerate()
            .find(|(_, v)| !v.iter().all(|c| c.is_finite()))
        {
            return Err(MeshError::NonFiniteVertex { vertex, value: *v });
        }
        let n = self.vertices.len();
        for (face, t) in self.triangles.iter().enumerate() {
            if let Some(&index) = t.iter().find(|&&i| i as usize >= n) {
                return Err(MeshError::IndexOutOfRange {
                    face,
                    index,
                    vertices: n,
                });
            }
        }
        Ok(())
    }

    pub fn triangle(&self, i: usize) -> Triangle {
        let [a, b, c] = self.triangles[i];
        [
            Vec3(self.vertices[a as usize]),
            Vec3(self.vertices[b as usize]),
            Vec3(self.vertices[c as usize]),
        ]
    }

    /// The triangles as corner triples, the form the builders and the traversal use.
    pub fn corner_triangles(&self) -> Vec<Triangle> {
        (0..self.triangles.len())
            .map(|i| self.triangle(i))
            .collect()
    }

    /// Bounds of the referenced vertices (empty for an empty mesh).
    pub fn bounds(&self) -> Aabb {
        self.triangles
            .iter()
            .flatten()
            .fold(Aabb::EMPTY, |b, &i| b.grow(Vec3(self.vertices[i as usize])))
    }

    /// Number of triangles whose cross product is exactly zero (computed in f64).
    pub fn zero_area_triangles(&self) -> usize {
        self.triangles
            .iter()
            .filter(|t| {
                let p = |k: usize| self.vertices[t[k] as usize].map(|c| c as f64);
                let (a, b, c) = (p(0), p(1), p(2));
                let e1 = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
                let e2 = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
                let n = [
                    e1[1] * e2[2] - e1[2] * e2[1],
                    e1[2] * e2[0] - e1[0] * e2[2],
                    e1[0] * e2[1] - e1[1] * e2[0],
                ];
                n == [0.0, 0.0, 0.0]
            })
            .count()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(name: &str, contents: &str) -> std::path::PathBuf {
        let path = std::env::temp_dir().join(format!("sahkd-mesh-{}-{name}", std::process::id()));
        std::fs::write(&path, contents).unwrap();
        path
    }

    #[test]
    fn errors_about_a_files_contents_name_the_file() {
        let path = scratch("nan.obj", "v 0 0 0\nv 1 nan 0\nv 0 1 0\nf 1 2 3\n");
        let e = Mesh::load(&path).unwrap_err().to_string();
        std::fs::remove_file(&path).unwrap();
        assert!(
            e.starts_with(&format!("{}: vertex 1", path.display())),
            "{e}"
        );
        let path = scratch("big.obj", "v 0 0 0\nv 1 1e39 0\nv 0 1 0\nf 1 2 3\n");
        let e = Mesh::load(&path).unwrap_err().to_string();
        std::fs::remove_file(&path).unwrap();
        assert!(
            e.starts_with(&format!("{}: vertex 1", path.display())),
            "{e}"
        );
        assert!(e.contains("beyond the float32 range"), "{e}");
    }

    #[test]
    fn directories_and_devices_are_not_mesh_files() {
        let dir = std::env::temp_dir();
        let e = Mesh::load(&dir).unwrap_err().to_string();
        assert!(e.ends_with("is a directory, not a mesh file"), "{e}");
        if Path::new("/dev/null").exists() {
            let e = Mesh::load("/dev/null").unwrap_err().to_string();
            assert_eq!(e, "/dev/null: is a character device, not a mesh file");
        }
    }
}
