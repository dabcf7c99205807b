//! One module per subcommand. To add one: write `cmd/NAME.rs` with an `Args` struct and a
//! `run(args, &Context)`, then add a variant to [`Command`] and an arm to [`Command::run`].

pub mod bench;
pub mod build;
mod common;
pub mod info;
pub mod query;
pub mod render;
pub mod trace;

use anyhow::Result;
use clap::Subcommand;

/// What every command gets besides its own arguments.
#[derive(Clone, Debug, Default)]
pub struct Context {
    /// `--quiet`: no progress display and no messages on stderr.
    pub quiet: bool,
    /// The builder options given on the command line (`--kt`, ...; not `--threads`, which
    /// also sets the threads of the queries), as written: refused with a saved tree.
    pub builder_flags: Vec<String>,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// Build the kd-tree of a mesh and print its statistics
    Build(build::Args),
    /// Trace rays from a .npy file and write their hits to a .npz file
    Trace(trace::Args),
    /// Closest points, distances and (with --signed) signed distances and inside tests of
    /// points from a .npy file, written to a .npz file
    Query(query::Args),
    /// Build the kd-tree of a mesh, render a picture through it and report the ray throughput
    Render(render::Args),
    /// Reproduce the paper's experiments: Table 1, Fig. 1 and Fig. 2, with tree quality and
    /// ray throughput, written to a folder as JSON, Markdown and PNG charts
    Bench(bench::Args),
    /// Describe a mesh: counts, bounds, degenerate triangles, unused vertices
    Info(info::Args),
}

impl Command {
    pub fn run(self, context: &Context) -> Result<()> {
        match self {
            Command::Build(args) => build::run(args, context),
            Command::Trace(args) => trace::run(args, context),
            Command::Query(args) => query::run(args, context),
            Command::Info(args) => info::run(args, context),
            Command::Render(args) => render::run(args, context),
            Command::Bench(args) => bench::run(args, context),
        }
    }
}
