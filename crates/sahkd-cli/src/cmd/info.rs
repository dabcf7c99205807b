//! `sahkd info`: what a mesh holds, and what in it a builder will find odd; or what a saved
//! tree holds and how it was built.

use super::Context;
use crate::format::{self, Table};
use crate::input::{self, Loaded, MeshArg, Source};
use crate::options::OptionsReport;
use crate::progress::Progress;
use anyhow::Result;
use sahkd::{KdTree, Mesh, TreeMeta};
use serde::Serialize;

#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    pub mesh: MeshArg,

    /// Print one JSON object on stdout instead of text
    #[arg(long)]
    pub json: bool,
}

#[derive(Serialize)]
struct Bounds {
    lo: [f32; 3],
    hi: [f32; 3],
}

impl Bounds {
    /// `None` for the empty box of a mesh without triangles.
    fn of(b: &sahkd::Aabb) -> Option<Self> {
        (!b.is_empty()).then_some(Bounds {
            lo: b.lo.0,
            hi: b.hi.0,
        })
    }

    fn text(bounds: &Option<Self>) -> String {
        match bounds {
            Some(b) => format!("{} - {}", point(b.lo), point(b.hi)),
            None => "empty".to_string(),
        }
    }
}

/// The rows every `info` table starts with: what was read and its size on disk.
fn source_rows(t: &mut Table, what: &str, loaded: &Loaded) {
    t.row(what, loaded.source.describe());
    if let Some(bytes) = loaded.file_bytes {
        t.row(
            "file size",
            format!("{} ({} bytes)", format::bytes(bytes), format::count(bytes)),
        );
    }
}

#[derive(Serialize)]
struct Report {
    source: String,
    /// "file" or "scene".
    kind: &'static str,
    /// `null` for a procedural scene.
    file_bytes: Option<u64>,
    load_ms: f64,
    vertices: usize,
    triangles: usize,
    /// Of the referenced vertices; `null` for a mesh without triangles.
    bounds: Option<Bounds>,
    zero_area_triangles: usize,
    unreferenced_vertices: usize,
}

/// The JSON report on a saved tree.
#[derive(Serialize)]
struct TreeReport {
    source: String,
    /// "tree".
    kind: &'static str,
    file_bytes: Option<u64>,
    /// Opening the file (map, checks), no build.
    load_ms: f64,
    triangles: usize,
    bounds: Option<Bounds>,
    nodes: usize,
    leaves: usize,
    references: usize,
    max_depth: u32,
    sah_cost: f64,
    #[serde(flatten)]
    options: OptionsReport,
    /// How the saved tree's build went.
    build_ms: f64,
    presort_ms: f64,
    build_threads: usize,
}

pub fn run(args: Args, context: &Context) -> Result<()> {
    let progress = Progress::new(context.quiet, args.json);
    let mut loaded = input::open(&args.mesh, &[], &progress)?;
    if let Some((tree, meta)) = loaded.saved.take() {
        return tree_info(&loaded, &tree, &meta, args.json);
    }
    let mesh = &loaded.mesh;
    let bounds = mesh.bounds();
    let report = Report {
        source: loaded.source.name(),
        kind: match loaded.source {
            Source::File(_) => "file",
            Source::Scene(_) => "scene",
            Source::Tree(_) => "tree",
        },
        file_bytes: loaded.file_bytes,
        load_ms: loaded.load_ms,
        vertices: mesh.vertices.len(),
        triangles: mesh.triangles.len(),
        bounds: Bounds::of(&bounds),
        zero_area_triangles: mesh.zero_area_triangles(),
        unreferenced_vertices: unreferenced_vertices(mesh),
    };
    if args.json {
        return format::print_json(&report);
    }
    let mut t = Table::default();
    source_rows(&mut t, "mesh", &loaded);
    t.row("load time", format::ms(report.load_ms))
        .row("vertices", format::count(report.vertices as u64))
        .row("triangles", format::count(report.triangles as u64))
        .row("bounds", Bounds::text(&report.bounds))
        .row(
            "zero-area triangles",
            format::count(report.zero_area_triangles as u64),
        )
        .row(
            "unreferenced vertices",
            format::count(report.unreferenced_vertices as u64),
        );
    format::print_text(&t.render())
}

fn tree_info(loaded: &Loaded, tree: &KdTree, meta: &TreeMeta, json: bool) -> Result<()> {
    let o = &meta.options;
    let stats = tree.stats(&o.cost);
    let b = tree.bounds();
    let report = TreeReport {
        source: loaded.source.name(),
        kind: "tree",
        file_bytes: loaded.file_bytes,
        load_ms: loaded.load_ms,
        triangles: tree.triangles().len(),
        bounds: Bounds::of(&b),
        nodes: stats.nodes,
        leaves: stats.leaves,
        references: stats.references,
        max_depth: stats.max_depth,
        sah_cost: stats.sah_cost,
        options: OptionsReport::of(o),
        build_ms: meta.build_ms,
        presort_ms: meta.presort_ms,
        build_threads: meta.build_threads,
    };
    if json {
        return format::print_json(&report);
    }
    let mut t = Table::default();
    source_rows(&mut t, "tree", loaded);
    t.row("open time", format::ms(report.load_ms))
        .row("triangles", format::count(report.triangles as u64))
        .row("bounds", Bounds::text(&report.bounds))
        .row("nodes", format::count(report.nodes as u64))
        .row("leaves", format::count(report.leaves as u64))
        .row("references", format::count(report.references as u64))
        .row("max depth", report.max_depth.to_string())
        .row("SAH cost", format!("{:.3}", report.sah_cost))
        .row(
            "built by",
            format!(
                "{}{}, {} axes, {} counting, clip {}{}, {} threads, in {}",
                report
                    .options
                    .preset
                    .map_or(String::new(), |p| format!("preset {p}: ")),
                report.options.algorithm,
                report.options.axes,
                report.options.counting,
                if report.options.clip { "on" } else { "off" },
                match report.options.bins {
                    0 => String::new(),
                    n => format!(", {n} bins"),
                },
                report.build_threads,
                format::ms(report.build_ms)
            ),
        );
    format::print_text(&t.render())
}

fn point(p: [f32; 3]) -> String {
    format!("({}, {}, {})", p[0], p[1], p[2])
}

/// Vertices no triangle uses (indices are in range: the mesh was validated on loading).
fn unreferenced_vertices(mesh: &Mesh) -> usize {
    let mut used = vec![false; mesh.vertices.len()];
    for &i in mesh.triangles.iter().flatten() {
        used[i as usize] = true;
    }
    used.iter().filter(|&&u| !u).count()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unreferenced_vertices_are_counted() {
        let mesh = Mesh {
            vertices: vec![[0.0; 3]; 6],
            triangles: vec![[0, 2, 3], [3, 2, 0]],
        };
        assert_eq!(unreferenced_vertices(&mesh), 3);
    }
}
