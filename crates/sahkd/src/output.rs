//! Files written whole or not at all: every output of the command line and of the Python
//! package goes through here.
//!
//! The data goes to a hidden temporary file beside the target (same directory, so the same
//! file system), is flushed to disk (`fsync`), and only then renamed over the target; the
//! directory is synced so the rename survives a crash. A failure at any step (a full disk, a
//! killed process) leaves the old file, or none, never a half-written one; the temporary is
//! removed on error.

use std::ffi::OsString;
use std::fs::{File, OpenOptions};
use std::io;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// Writes `path` through `write`, which gets the open temporary file.
pub fn write_atomically<T>(
    path: &Path,
    write: impl FnOnce(&mut File) -> io::Result<T>,
) -> io::Result<T> {
    let (temporary, mut file) = create_temporary(path)?;
    let result = write(&mut file).and_then(|value| {
        file.sync_all()?;
        Ok(value)
    });
    drop(file);
    finish(temporary, path, result)
}

/// Writes `path` through `write`, which gets the temporary file's path (for libraries that
/// open files themselves). The temporary's name ends with the target's file name, so a
/// library that picks the format from the extension picks the same one.
pub fn write_atomically_at<T, E>(
    path: &Path,
    write: impl FnOnce(&Path) -> Result<T, E>,
) -> Result<T, AtomicError<E>> {
    let (temporary, file) = create_temporary(path).map_err(AtomicError::Io)?;
    drop(file);
    let value = match write(&temporary) {
        Ok(value) => value,
        Err(e) => {
            let _ = std::fs::remove_file(&temporary);
            return Err(AtomicError::Write(e));
        }
    };
    let synced = File::open(&temporary).and_then(|f| f.sync_all());
    finish(temporary, path, synced.map(|()| value)).map_err(AtomicError::Io)
}

/// Why [`write_atomically_at`] failed: the caller's writer, or the file system around it.
#[derive(Debug)]
pub enum AtomicError<E> {
    Write(E),
    Io(io::Error),
}

impl<E: std::fmt::Display> std::fmt::Display for AtomicError<E> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            AtomicError::Write(e) => e.fmt(f),
            AtomicError::Io(e) => e.fmt(f),
        }
    }
}

impl<E: std::fmt::Debug + std::fmt::Display> std::error::Error for AtomicError<E> {}

/// Checks that a file can be created in `path`'s directory (by creating and removing a
/// temporary there), so that a long computation is not lost to an unwritable output.
pub fn check_writable(path: &Path) -> io::Result<()> {
    let (temporary, file) = create_temporary(path)?;
    drop(file);
    std::fs::remove_file(temporary)
}

fn directory_of(path: &Path) -> &Path {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    }
}

/// A new, empty, hidden file beside `path`: `.sahkd-PID-N-NAME`.
fn create_temporary(path: &Path) -> io::Result<(PathBuf, File)> {
    static NEXT: AtomicU64 = AtomicU64::new(0);
    let name = path
        .file_name()
        .ok_or_else(|| io::Error::new(io::ErrorKind::InvalidInput, "the path names no file"))?;
    let directory = directory_of(path);
    loop {
        let n = NEXT.fetch_add(1, Ordering::Relaxed);
        let mut temporary_name = OsString::from(format!(".sahkd-{}-{n}-", std::process::id()));
        temporary_name.push(name);
        let temporary = directory.join(temporary_name);
        match OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(&temporary)
        {
            Ok(file) => return Ok((temporary, file)),
            Err(e) if e.kind() == io::ErrorKind::AlreadyExists => continue,
            Err(e) => return Err(e),
        }
    }
}

/// Renames the synced temporary over `path` when `result` is Ok; removes it otherwise.
fn finish<T>(temporary: PathBuf, path: &Path, result: io::Result<T>) -> io::Result<T> {
    let value = match result.and_then(|v| std::fs::rename(&temporary, path).map(|()| v)) {
        Ok(value) => value,
        Err(e) => {
            let _ = std::fs::remove_file(&temporary);
            return Err(e);
        }
    };
    sync_directory(directory_of(path))?;
    Ok(value)
}

/// Makes a rename in `directory` durable (Unix; elsewhere the rename is all there is).
fn sync_directory(directory: &Path) -> io::Result<()> {
    #[cfg(unix)]
    File::open(directory)?.sync_all()?;
    #[cfg(not(unix))]
    let _ = directory;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("sahkd-output-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    fn entries(dir: &Path) -> Vec<String> {
        let mut names: Vec<String> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        names
    }

    #[test]
    fn a_complete_write_replaces_the_file() {
        let dir = scratch("complete");
        let path = dir.join("out.bin");
        std::fs::write(&path, b"old").unwrap();
        write_atomically(&path, |f| io::Write::write_all(f, b"new contents")).unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"new contents");
        assert_eq!(entries(&dir), ["out.bin"]);
        std::fs::remove_dir_all(dir).unwrap();
    }

    #[test]
    fn a_failed_write_keeps_the_old_file_and_leaves_no_temporary() {
        let dir = scratch("failed");
        let path = dir.join("out.bin");
        std::fs::write(&path, b"old").unwrap();
        let e = write_atomically(&path, |f| {
            io::Write::write_all(f, b"half")?;
            Err::<(), _>(io::Error::other("disk full"))
        })
        .unwrap_err();
        assert_eq!(e.to_string(), "disk full");
        assert_eq!(std::fs::read(&path).unwrap(), b"old");
        assert_eq!(entries(&dir), ["out.bin"]);

        let e = write_atomically_at(&path, |p: &Path| {
            assert!(p.to_string_lossy().ends_with("out.bin"), "{}", p.display());
            std::fs::write(p, b"half").unwrap();
            Err::<(), _>("encoder failed")
        })
        .unwrap_err();
        assert_eq!(e.to_string(), "encoder failed");
        assert_eq!(std::fs::read(&path).unwrap(), b"old");
        assert_eq!(entries(&dir), ["out.bin"]);
        std::fs::remove_dir_all(dir).unwrap();
    }

    #[test]
    fn writes_through_a_path_land_whole() {
        let dir = scratch("at");
        let path = dir.join("chart.png");
        write_atomically_at(&path, |p: &Path| std::fs::write(p, b"picture")).unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"picture");
        check_writable(&path).unwrap();
        assert_eq!(entries(&dir), ["chart.png"]);
        assert!(check_writable(&dir.join("missing").join("x")).is_err());
        std::fs::remove_dir_all(dir).unwrap();
    }
}
