//! The `sahkd` command: build, inspect and trace SAH kd-trees.

mod bench;
mod cmd;
mod format;
mod gpu;
mod input;
mod options;
mod output;
mod progress;
mod rays;
mod resident;

/// The fuzzing harness of the mesh readers, shared by the `.npy` readers' fuzz test.
#[cfg(test)]
#[path = "../../sahkd/tests/common/fuzz.rs"]
mod fuzz_harness;

use clap::error::ErrorKind;
use clap::parser::ValueSource;
use clap::{ArgMatches, CommandFactory, FromArgMatches, Parser};
use std::process::ExitCode;

/// Build SAH kd-trees for ray tracing, inspect meshes and trace rays.
#[derive(Parser, Debug)]
#[command(name = "sahkd", version, arg_required_else_help = true)]
struct Cli {
    /// No progress display and no messages on stderr
    #[arg(short, long, global = true)]
    quiet: bool,

    #[command(subcommand)]
    command: cmd::Command,
}

/// Exit status of a command-line mistake, as clap and most Unix tools use.
const USAGE: u8 = 2;
/// Exit status of a command that could not do its work.
const FAILURE: u8 = 1;

fn main() -> ExitCode {
    let matches = match Cli::command().try_get_matches() {
        Ok(m) => m,
        Err(e) => return usage_error(e),
    };
    let cli = match Cli::from_arg_matches(&matches) {
        Ok(cli) => cli,
        Err(e) => return usage_error(e),
    };
    let context = cmd::Context {
        quiet: cli.quiet,
        builder_flags: builder_flags(&matches),
    };
    match cli.command.run(&context) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::from(FAILURE)
        }
    }
}

/// The builder options (the "Builder options" heading of the help, less `--threads`) that
/// the command line gave explicitly, as `--name`: defaults do not count.
fn builder_flags(matches: &ArgMatches) -> Vec<String> {
    let Some((name, sub)) = matches.subcommand() else {
        return Vec::new();
    };
    let command = Cli::command();
    let Some(definition) = command.find_subcommand(name) else {
        return Vec::new();
    };
    definition
        .get_arguments()
        .filter(|a| a.get_help_heading() == Some("Builder options"))
        .filter(|a| a.get_id() != "threads")
        .filter(|a| sub.value_source(a.get_id().as_str()) == Some(ValueSource::CommandLine))
        .filter_map(|a| a.get_long().map(|l| format!("--{l}")))
        .collect()
}

/// Help and version go out as clap writes them; real mistakes become one `error:` line.
fn usage_error(e: clap::Error) -> ExitCode {
    match e.kind() {
        ErrorKind::DisplayHelp
        | ErrorKind::DisplayVersion
        | ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand => {
            let _ = e.print();
            if e.kind() == ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand {
                ExitCode::from(USAGE)
            } else {
                ExitCode::SUCCESS
            }
        }
        _ => {
            eprintln!("{}", one_line(&e.render().to_string()));
            ExitCode::from(USAGE)
        }
    }
}

/// Joins clap's message, its possible values and tips into one line, dropping the usage
/// and the "For more information" footer.
fn one_line(rendered: &str) -> String {
    let mut line = String::new();
    for part in rendered
        .lines()
        .map(str::trim)
        .take_while(|l| !l.starts_with("Usage:") && !l.starts_with("For more information"))
        .filter(|l| !l.is_empty())
    {
        if !line.is_empty() {
            line.push_str(if part.starts_with("tip:") { "; " } else { " " });
        }
        line.push_str(part);
    }
    line
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_command_line_definition_is_consistent() {
        use clap::CommandFactory;
        Cli::command().debug_assert();
    }

    #[test]
    fn only_builder_options_given_explicitly_are_named() {
        let m = Cli::command()
            .try_get_matches_from(["sahkd", "trace", "t", "--rays", "r.npy", "-o", "h.npz"])
            .unwrap();
        assert!(builder_flags(&m).is_empty());
        let m = Cli::command()
            .try_get_matches_from([
                "sahkd",
                "trace",
                "t",
                "--rays",
                "r.npy",
                "-o",
                "h.npz",
                "--kt",
                "1",
                "--threads",
                "2",
                "--clip",
                "on",
            ])
            .unwrap();
        assert_eq!(builder_flags(&m), ["--clip", "--kt"]);
    }

    #[test]
    fn usage_errors_fit_on_one_line() {
        let e = Cli::try_parse_from(["sahkd", "build", "--algorithm", "quick"]).unwrap_err();
        let line = one_line(&e.render().to_string());
        assert!(line.starts_with("error: "), "{line}");
        assert!(!line.contains('\n'), "{line}");
        assert!(line.contains("quick") && line.contains("level"), "{line}");
    }
}
