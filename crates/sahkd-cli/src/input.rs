//! The MESH argument: a `.ply`/`.obj` file, a procedural scene spec such as
//! `spd:sphere:10000`, or (for the commands that trace) a tree saved by `build --save`,
//! told apart by its first bytes, whatever its name.

use crate::progress::Progress;
use anyhow::{anyhow, bail, Context, Result};
use sahkd::saved::is_tree_file;
use sahkd::{scenes, KdTree, LoadError, Mesh, TreeMeta};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The positional MESH argument of every command that reads a mesh.
#[derive(clap::Args, Clone, Debug)]
pub struct MeshArg {
    /// A .ply or .obj file, or a procedural scene spec such as spd:sphere:10000 (trace,
    /// query, render and info also take a tree saved by `build --save`)
    #[arg(value_name = "MESH", default_value = scenes::DEFAULT_SCENE)]
    pub mesh: String,
}

/// Where a mesh comes from.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Source {
    File(PathBuf),
    Scene(String),
    /// A `.sahkd` file: a saved tree.
    Tree(PathBuf),
}

impl Source {
    /// A saved tree when the argument names a file that starts like one or ends in `.sahkd`;
    /// a file when it names anything else that exists (a directory or a device is then
    /// refused as what it is) or ends in a mesh extension; a scene spec otherwise.
    pub fn resolve(arg: &str) -> Source {
        let path = Path::new(arg);
        let mesh_extension = path
            .extension()
            .and_then(|e| e.to_str())
            .is_some_and(|e| e.eq_ignore_ascii_case("ply") || e.eq_ignore_ascii_case("obj"));
        let tree_extension = path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("sahkd"));
        // A `.sahkd` file that does not start like a tree (empty, cut short) is still read
        // as one, so that the error says what is wrong with it as a tree.
        if path.is_file() && (tree_extension || is_tree_file(path)) {
            Source::Tree(path.to_path_buf())
        } else if mesh_extension || path.exists() {
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
            Source::Tree(p) => format!("{} (saved tree)", p.display()),
        }
    }

    /// The file read, if any (outputs must not overwrite it).
    pub fn file(&self) -> Option<&Path> {
        match self {
            Source::File(p) | Source::Tree(p) => Some(p),
            Source::Scene(_) => None,
        }
    }

    pub fn name(&self) -> String {
        match self {
            Source::File(p) | Source::Tree(p) => p.display().to_string(),
            Source::Scene(s) => s.clone(),
        }
    }
}

/// A mesh, or a saved tree, and how getting it went.
pub struct Loaded {
    pub source: Source,
    /// Empty for a saved tree (its triangles are in the tree).
    pub mesh: Mesh,
    /// The saved tree and how it was built, for [`Source::Tree`] (taken by the command).
    pub saved: Option<(KdTree, TreeMeta)>,
    pub load_ms: f64,
    /// Size of the mesh or tree file; `None` for procedural scenes.
    pub file_bytes: Option<u64>,
}

/// Reads or generates the mesh named by the MESH argument; a saved tree is refused (the
/// command needs the mesh itself).
pub fn load(arg: &MeshArg, progress: &Progress) -> Result<Loaded> {
    if let Source::Tree(path) = Source::resolve(&arg.mesh) {
        bail!(
            "{}: is a saved tree, not a mesh (trace, query, render and info take saved trees)",
            path.display()
        );
    }
    open(arg, &[], progress)
}

/// Reads the mesh, or opens the saved tree (no build: its `saved` is set), named by the MESH
/// argument. `builder_flags` are the builder options given on the command line: they cannot
/// change a tree that is already built, so naming any with a saved tree is an error.
pub fn open(arg: &MeshArg, builder_flags: &[String], progress: &Progress) -> Result<Loaded> {
    let source = Source::resolve(&arg.mesh);
    if let (Source::Tree(path), false) = (&source, builder_flags.is_empty()) {
        bail!(
            "{}: is a saved tree, already built; the builder options {} apply only to a mesh",
            path.display(),
            builder_flags.join(", ")
        );
    }
    let spinner = progress.spinner(format!("loading {}", source.name()));
    let start = Instant::now();
    let mut saved = None;
    let (mesh, file_bytes) = match &source {
        Source::Tree(path) => {
            let opened = KdTree::load(path).map_err(|e| match e {
                LoadError::Io(e) => anyhow!("cannot read {}: {e}", path.display()),
                LoadError::Invalid(e) => anyhow!("{}: {e}", path.display()),
            })?;
            saved = Some(opened);
            (
                Mesh::default(),
                std::fs::metadata(path).map(|m| m.len()).ok(),
            )
        }
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
        saved,
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
