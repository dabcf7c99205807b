//! The MESH argument: a `.ply`/`.obj` file or a procedural scene spec such as
//! `spd:sphere:10000`.

use crate::progress::Progress;
use anyhow::{anyhow, Context, Result};
use sahkd::{scenes, Mesh};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The positional MESH argument of every command that reads a mesh.
#[derive(clap::Args, Clone, Debug)]
pub struct MeshArg {
    /// A .ply or .obj file, or a procedural scene spec such as spd:sphere:10000
    #[arg(value_name = "MESH", default_value = scenes::DEFAULT_SCENE)]
    pub mesh: String,
}

/// Where a mesh comes from.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Source {
    File(PathBuf),
    Scene(String),
}

impl Source {
    /// A file when the argument names anything that exists (a directory or a device is then
    /// refused as what it is) or ends in a mesh extension, a scene spec otherwise.
    pub fn resolve(arg: &str) -> Source {
        let path = Path::new(arg);
        let mesh_extension = path
            .extension()
            .and_then(|e| e.to_str())
            .is_some_and(|e| e.eq_ignore_ascii_case("ply") || e.eq_ignore_ascii_case("obj"));
        if mesh_extension || path.exists() {
            Source::File(path.to_path_buf())
        } else {
            Source::Scene(arg.to_string())
        }
    }

    /// How reports name the source.
    pub fn describe(&self) -> String {
        match self {
            Source::File(p) => p.display().to_string(),
            Source::Scene(s) => format!("{s} (procedural)"),
        }
    }

    pub fn name(&self) -> String {
        match self {
            Source::File(p) => p.display().to_string(),
            Source::Scene(s) => s.clone(),
        }
    }
}

/// A mesh and how getting it went.
pub struct Loaded {
    pub source: Source,
    pub mesh: Mesh,
    pub load_ms: f64,
    /// Size of the mesh file; `None` for procedural scenes.
    pub file_bytes: Option<u64>,
}

/// Reads or generates the mesh named by the MESH argument.
pub fn load(arg: &MeshArg, progress: &Progress) -> Result<Loaded> {
    let source = Source::resolve(&arg.mesh);
    let spinner = progress.spinner(format!("loading {}", source.name()));
    let start = Instant::now();
    let (mesh, file_bytes) = match &source {
        Source::File(path) => {
            let mesh = Mesh::load(path)?;
            // The file was just read, so its size is there unless it vanished meanwhile.
            let bytes = std::fs::metadata(path).map(|m| m.len()).ok();
            (mesh, bytes)
        }
        Source::Scene(spec) => {
            let mesh = scenes::generate(spec).map_err(|e| {
                if spec.contains(':') {
                    anyhow!("cannot make the scene: {e}")
                } else {
                    anyhow!("{spec}: no such mesh file, and not a scene spec ({e})")
                }
            })?;
            mesh.validate()
                .with_context(|| format!("scene {spec} is not a valid mesh"))?;
            (mesh, None)
        }
    };
    let load_ms = start.elapsed().as_secs_f64() * 1e3;
    spinner.finish_and_clear();
    Ok(Loaded {
        source,
        mesh,
        load_ms,
        file_bytes,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn arguments_resolve_to_files_or_scenes() {
        assert_eq!(
            Source::resolve("spd:sphere:100"),
            Source::Scene("spd:sphere:100".into())
        );
        // A mesh extension means a file even when it does not exist, so that the error
        // names the missing file rather than a bad scene spec.
        assert_eq!(
            Source::resolve("missing/bunny.PLY"),
            Source::File("missing/bunny.PLY".into())
        );
        assert_eq!(
            Source::resolve("missing.obj"),
            Source::File("missing.obj".into())
        );
        // Any existing file is a file, whatever its name.
        let manifest = concat!(env!("CARGO_MANIFEST_DIR"), "/Cargo.toml");
        assert_eq!(Source::resolve(manifest), Source::File(manifest.into()));
    }
}
