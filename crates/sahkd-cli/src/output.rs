//! Every file a command writes: checked before the long steps (a file in an existing,
//! writable folder, and none of the command's inputs), then written whole or not at all
//! through `sahkd::output` (temporary beside it, fsync, rename).

use anyhow::{bail, Context, Result};
use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::path::Path;

/// Fails early when `path` cannot be written, or would overwrite one of `inputs`, so that a
/// long build is not lost and no input is clobbered.
pub fn check(path: &Path, inputs: &[&Path]) -> Result<()> {
    let name = path.display();
    if path.is_dir() {
        bail!("{name}: is a directory, not a file to write");
    }
    if let Some(input) = inputs.iter().find(|input| same_file(path, input)) {
        bail!(
            "{name}: is the input {}; writing the output there would destroy it",
            input.display()
        );
    }
    let parent = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    if !parent.is_dir() {
        bail!(
            "cannot write {name}: the directory {} does not exist",
            parent.display()
        );
    }
    sahkd::output::check_writable(path).with_context(|| format!("cannot write {name}"))
}

/// Writes `path` whole or not at all through a buffered writer.
pub fn write(path: &Path, write: impl FnOnce(&mut dyn Write) -> io::Result<()>) -> Result<()> {
    sahkd::output::write_atomically(path, |file| {
        let mut buffered = BufWriter::new(file);
        write(&mut buffered)?;
        buffered.flush()
    })
    .with_context(|| format!("cannot write {}", path.display()))
}

/// Writes `path` whole or not at all through the open file (for writers that seek).
pub fn write_file(path: &Path, write: impl FnOnce(&mut File) -> io::Result<()>) -> Result<()> {
    sahkd::output::write_atomically(path, write)
        .with_context(|| format!("cannot write {}", path.display()))
}

/// Whether two paths name the same existing file (also through links).
pub fn same_file(a: &Path, b: &Path) -> bool {
    let (Ok(ma), Ok(mb)) = (std::fs::metadata(a), std::fs::metadata(b)) else {
        return false;
    };
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        ma.dev() == mb.dev() && ma.ino() == mb.ino()
    }
    #[cfg(not(unix))]
    {
        let _ = (ma, mb);
        matches!((a.canonicalize(), b.canonicalize()), (Ok(x), Ok(y)) if x == y)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_same_file_is_recognised_under_another_name() {
        let dir = tempfile::tempdir().unwrap();
        let a = dir.path().join("a.ply");
        std::fs::write(&a, "x").unwrap();
        let b = dir.path().join("b.ply");
        std::fs::write(&b, "x").unwrap();
        assert!(same_file(&a, &dir.path().join(".").join("a.ply")));
        assert!(!same_file(&a, &b));
        assert!(!same_file(&a, &dir.path().join("missing.ply")));
        let e = check(&a, &[&b, &a]).unwrap_err().to_string();
        assert!(e.contains("is the input"), "{e}");
        check(&dir.path().join("c.npz"), &[&a, &b]).unwrap();
    }
}
