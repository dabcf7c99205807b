//! What `trace` and `query` share: the steps before their own work ([`prepare`]), in one
//! order so that everything a user can get wrong is refused before the long steps (the output
//! checked against the inputs, the options, the array file read, then the mesh loaded and its
//! tree built, or a saved tree opened, and its trace layout made, timed apart), and the
//! `.npz` arrays they write.

use super::Context;
use crate::format;
use crate::input::{self, Loaded, MeshArg};
use crate::options::{Builder, BuilderArgs};
use crate::output;
use crate::progress::Progress;
use anyhow::Result;
use npyz::npz::NpzWriter;
use npyz::WriterBuilder;
use sahkd::builders::BuildReport;
use sahkd::{Build, KdTree};
use serde::Serialize;
use std::path::Path;
use std::time::Instant;

pub struct Prepared<T> {
    pub builder: Builder,
    /// What `read` made of the array file.
    pub data: T,
    pub loaded: Loaded,
    pub built: Build,
    /// Making the tree's trace layout (not part of the command's own timing).
    pub layout_ms: f64,
}

fn prepare<T>(
    mesh: &MeshArg,
    builder: &BuilderArgs,
    data: &Path,
    output: &Path,
    context: &Context,
    progress: &Progress,
    read: impl FnOnce(&Path) -> Result<T>,
) -> Result<Prepared<T>> {
    let source = input::Source::resolve(&mesh.mesh);
    let inputs: Vec<&Path> = [Some(data), source.file()].into_iter().flatten().collect();
    output::check(output, &inputs)?;
    let mut builder = builder.builder()?;
    let spinner = progress.spinner(format!("reading {}", data.display()));
    let data = read(data);
    spinner.finish_and_clear();
    let data = data?;
    let mut loaded = builder.install(|| input::open(mesh, &context.builder_flags, progress))?;

    let built = match saved(&mut builder, &mut loaded) {
        Some(built) => built,
        None => {
            let spinner = progress.spinner(format!(
                "building {} triangles",
                format::count(loaded.mesh.triangles.len() as u64)
            ));
            let built = builder.build_taking(&mut loaded.mesh);
            spinner.finish_and_clear();
            built?
        }
    };

    let start = Instant::now();
    // On the pool, like the build and the work: the layout is made in parallel.
    builder.install(|| built.tree.prepare_trace());
    let layout_ms = start.elapsed().as_secs_f64() * 1e3;
    Ok(Prepared {
        builder,
        data,
        loaded,
        built,
        layout_ms,
    })
}

/// The files and options of a `trace` or `query` call.
pub struct Inputs<'a> {
    pub mesh: &'a MeshArg,
    pub builder: &'a BuilderArgs,
    /// The array file read.
    pub data: &'a Path,
    pub output: &'a Path,
}

/// What [`run`] did: the prepared inputs, the answers and how long they took.
pub struct Ran<T, A> {
    pub prepared: Prepared<T>,
    pub answers: A,
    pub work_ms: f64,
}

impl<T, A> Ran<T, A> {
    /// The part of the JSON report every such command has.
    pub fn report(&self) -> RunReport {
        let Prepared {
            builder,
            loaded,
            built,
            layout_ms,
            ..
        } = &self.prepared;
        RunReport {
            source: loaded.source.name(),
            triangles: built.tree.triangles().len(),
            threads: builder.threads(),
            load_ms: loaded.load_ms,
            build_ms: built.report.build_ms,
            layout_ms: *layout_ms,
        }
    }

    /// Millions of `items` per second of the work.
    pub fn rate(&self, items: usize) -> f64 {
        if self.work_ms > 0.0 {
            items as f64 / (self.work_ms * 1e3)
        } else {
            0.0
        }
    }
}

/// The fields [`Ran::report`] fills, flattened into each command's report.
#[derive(Serialize)]
pub struct RunReport {
    pub source: String,
    pub triangles: usize,
    pub threads: usize,
    pub load_ms: f64,
    pub build_ms: f64,
    /// Making the tree's walk layout, done once before the work (not part of its time).
    pub layout_ms: f64,
}

/// [`prepare`], then `work` on the data in the builder's pool, timed, then the answers
/// written to the output by `write`, behind a spinner.
pub fn run<T: Sync, A: Send>(
    inputs: Inputs<'_>,
    context: &Context,
    progress: &Progress,
    read: impl FnOnce(&Path) -> Result<T>,
    work: impl FnOnce(&KdTree, &T, &Progress) -> A + Send,
    write: impl FnOnce(&Path, &T, &A) -> Result<()>,
) -> Result<Ran<T, A>> {
    let Inputs {
        mesh,
        builder,
        data,
        output,
    } = inputs;
    let prepared = prepare(mesh, builder, data, output, context, progress, read)?;
    let start = Instant::now();
    let answers = prepared
        .builder
        .install(|| work(&prepared.built.tree, &prepared.data, progress));
    let work_ms = start.elapsed().as_secs_f64() * 1e3;

    let spinner = progress.spinner(format!("writing {}", output.display()));
    let written = write(output, &prepared.data, &answers);
    spinner.finish_and_clear();
    written?;
    Ok(Ran {
        prepared,
        answers,
        work_ms,
    })
}

/// The saved tree `loaded` holds, if any, as a build that took no time; the builder takes
/// over the options it was built with, so that reports show them.
pub fn saved(builder: &mut Builder, loaded: &mut Loaded) -> Option<Build> {
    let (tree, meta) = loaded.saved.take()?;
    builder.adopt(&meta.options);
    Some(Build {
        tree,
        report: BuildReport::default(),
    })
}

/// The archive [`write_npz`] hands its caller.
pub type Npz<'a> = NpzWriter<std::io::BufWriter<&'a mut std::fs::File>>;

/// Writes `path` as an .npz archive, whole or not at all; `arrays` adds the arrays. The
/// archive is finished here so that an error doing so is reported. After any error the zip
/// writer is forgotten rather than dropped: dropped, it would try to finish the archive
/// again, fail again and print its own message beside the error (`write_file` removes the
/// temporary file, and the process ends with the error).
pub fn write_npz(
    path: &std::path::Path,
    arrays: impl FnOnce(&mut Npz) -> std::io::Result<()>,
) -> anyhow::Result<()> {
    crate::output::write_file(path, |file| {
        let mut npz = NpzWriter::new(std::io::BufWriter::new(file));
        let finished = arrays(&mut npz).and_then(|()| {
            npz.zip_writer()
                .finish()
                .map_err(std::io::Error::other)
                .and_then(|mut file| std::io::Write::flush(&mut file))
        });
        if finished.is_err() {
            std::mem::forget(npz);
        }
        finished
    })
}

/// One array of the given shape, stored uncompressed as `np.savez` does.
pub fn write_array<T, W>(
    npz: &mut NpzWriter<W>,
    name: &str,
    shape: &[u64],
    items: impl Iterator<Item = T>,
) -> std::io::Result<()>
where
    T: npyz::AutoSerialize,
    W: std::io::Write + std::io::Seek,
{
    let bytes = shape.iter().product::<u64>() * std::mem::size_of::<T>() as u64;
    let options = npyz::zip::write::FileOptions::default()
        .compression_method(npyz::zip::CompressionMethod::Stored)
        .large_file(bytes >= u32::MAX as u64);
    let mut writer = npz
        .array::<T>(name, options)?
        .default_dtype()
        .shape(shape)
        .begin_nd()?;
    writer.extend(items)?;
    writer.finish()
}
