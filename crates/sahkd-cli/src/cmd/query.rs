//! `sahkd query`: closest points (and with --signed, signed distances and the inside test)
//! of points from a `.npy` file against a mesh, written to `.npz`. Same input, output and
//! error rules as `trace`.

use super::common::{self, write_array, RunReport};
use super::Context;
use crate::format;
use crate::input::MeshArg;
use crate::options::BuilderArgs;
use crate::progress::Progress;
use crate::rays;
use crate::resident::PeakResident;
use anyhow::Result;
use sahkd::{ClosestPoint, InsideTest, KdTree, Vec3};
use serde::Serialize;
use std::path::{Path, PathBuf};

#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    pub mesh: MeshArg,

    /// Query points: float32 array of shape (N, 3)
    #[arg(long, value_name = "POINTS.npy")]
    pub points: PathBuf,

    /// Where to write the answers: `point` (float64, (N, 3), the closest point on the mesh),
    /// `distance` (float64) and `prim` (int64, the triangle); with --signed also
    /// `signed_distance` (float64, negative inside) and `inside` (bool). A point with a
    /// non-finite coordinate gets prim -1 and NaN values; on a mesh without triangles,
    /// prim -1, NaN points and infinite distances
    #[arg(long, short, value_name = "ANSWERS.npz")]
    pub output: PathBuf,

    /// Also decide inside/outside and write signed distances
    #[arg(long)]
    pub signed: bool,

    /// The inside test of --signed: `parity` (one ray's crossing count, three voting where it
    /// passes near an edge; fast, for closed meshes) or `winding` (generalized winding number over every triangle;
    /// robust for meshes with holes, but O(triangles) per point)
    #[arg(long, value_name = "TEST", default_value = "parity")]
    pub inside_test: InsideTest,

    /// Print one JSON object on stdout instead of the summary on stderr
    #[arg(long)]
    pub json: bool,

    // Last: the heading of its flattened options would carry over to any argument after it.
    #[command(flatten)]
    pub builder: BuilderArgs,
}

#[derive(Serialize)]
struct Report {
    #[serde(flatten)]
    run: RunReport,
    points: usize,
    signed: bool,
    inside_test: Option<&'static str>,
    query_ms: f64,
    mpoints_per_s: f64,
    /// Points inside the mesh (with --signed).
    inside: Option<usize>,
    /// The process's peak resident memory: mesh, build, tree, walk layout, points, answers.
    #[serde(flatten)]
    resident: PeakResident,
}

/// One point's answer: the closest point and, with --signed, whether it is inside.
type Answer = (Option<ClosestPoint>, Option<bool>);

pub fn run(args: Args, context: &Context) -> Result<()> {
    let progress = Progress::new(context.quiet, args.json);
    let inputs = common::Inputs {
        mesh: &args.mesh,
        builder: &args.builder,
        data: &args.points,
        output: &args.output,
    };
    let test = args.signed.then_some(args.inside_test);
    let ran = common::run(
        inputs,
        context,
        &progress,
        rays::read_points,
        |tree, points, progress| query(tree, points, test, progress),
        |output, points, answers| write_answers(output, points, answers, args.signed),
    )?;
    let (points, answers) = (&ran.prepared.data, &ran.answers);
    let report = Report {
        run: ran.report(),
        points: points.len(),
        signed: args.signed,
        inside_test: test.map(|t| match t {
            InsideTest::Parity => "parity",
            InsideTest::Winding => "winding",
        }),
        query_ms: ran.work_ms,
        mpoints_per_s: ran.rate(points.len()),
        inside: args
            .signed
            .then(|| answers.iter().filter(|a| a.1 == Some(true)).count()),
        resident: PeakResident::now(ran.prepared.built.tree.triangles().len()),
    };
    if args.json {
        format::print_json(&report)?;
    } else if !context.quiet {
        let inside = match report.inside {
            Some(n) => format!(", {} inside", format::count(n as u64)),
            None => String::new(),
        };
        eprintln!(
            "{} points on {} triangles of {}{inside}; build {}, layout {}, query {}, {:.2} Mpoints/s on {} threads; wrote {}",
            format::count(report.points as u64),
            format::count(report.run.triangles as u64),
            report.run.source,
            format::ms(report.run.build_ms),
            format::ms(report.run.layout_ms),
            format::ms(report.query_ms),
            report.mpoints_per_s,
            report.run.threads,
            args.output.display()
        );
    }
    Ok(())
}

/// Answers in one batch, or in slices when a progress bar is shown so that it can move.
fn query(
    tree: &KdTree,
    points: &[Vec3],
    test: Option<InsideTest>,
    progress: &Progress,
) -> Vec<Answer> {
    let slice = if progress.enabled() {
        (points.len() / 100).max(1 << 14)
    } else {
        points.len().max(1)
    };
    let bar = progress.bar(points.len() as u64, "querying");
    // Slices of the points in spatial order, as one batch would walk them; the answers go
    // back to the input's order at the end.
    let order = sahkd::query::spatial_order(points);
    let sorted: Vec<Vec3> = order.iter().map(|&i| points[i as usize]).collect();
    let mut out = Vec::with_capacity(points.len());
    for chunk in sorted.chunks(slice) {
        match test {
            Some(test) => out.extend(
                tree.closest_point_signed_batch(chunk, test)
                    .into_iter()
                    .map(|(c, inside)| (c, Some(inside))),
            ),
            None => out.extend(
                tree.closest_point_batch(chunk)
                    .into_iter()
                    .map(|c| (c, None)),
            ),
        }
        bar.inc(chunk.len() as u64);
    }
    bar.finish_and_clear();
    let mut answers = vec![(None, None); points.len()];
    for (&i, answer) in order.iter().zip(out) {
        answers[i as usize] = answer;
    }
    answers
}

/// The distance written for a point without an answer: NaN for a non-finite point,
/// infinite when the mesh has no triangles.
fn no_distance(p: &Vec3) -> f64 {
    if p.is_finite() {
        f64::INFINITY
    } else {
        f64::NAN
    }
}

fn write_answers(path: &Path, points: &[Vec3], answers: &[Answer], signed: bool) -> Result<()> {
    common::write_npz(path, |npz| {
        let n = answers.len();
        let point = answers
            .iter()
            .flat_map(|a| a.0.map_or([f64::NAN; 3], |c| c.point));
        let distance = answers
            .iter()
            .zip(points)
            .map(|(a, p)| a.0.map_or_else(|| no_distance(p), |c| c.distance));
        let prim = answers
            .iter()
            .map(|a| a.0.map_or(-1, |c| i64::from(c.prim)));
        write_array(npz, "point", &[n as u64, 3], point)?;
        write_array(npz, "distance", &[n as u64], distance)?;
        write_array(npz, "prim", &[n as u64], prim)?;
        if signed {
            let inside = answers.iter().map(|a| a.1 == Some(true));
            let signed = answers.iter().zip(points).map(|(a, p)| match a.0 {
                Some(c) if a.1 == Some(true) && c.distance > 0.0 => -c.distance,
                Some(c) => c.distance,
                None => no_distance(p),
            });
            write_array(npz, "signed_distance", &[n as u64], signed)?;
            write_array(npz, "inside", &[n as u64], inside)?;
        }
        Ok(())
    })
}
