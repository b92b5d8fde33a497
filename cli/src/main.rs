//! The `radiosity` binary: parses the command line ([`args`]), runs one command
//! ([`commands`]) on the library, prints the summary, and maps failures to messages and exit
//! statuses ([`failure`]): 0 success, 1 internal failure, 2 bad input or usage, 3 the solver
//! stopped at --max-iterations without converging (the output is written). Progress bars and
//! verbose notes are drawn by [`progress_bars`].

mod args;
mod commands;
mod failure;
mod progress_bars;

use std::process::ExitCode;

use clap::Parser;

use args::{Cli, Command};
use failure::{Failure, EXIT_USAGE};

fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => {
            // clap prints help/version to stdout (exit 0) and usage errors to stderr (exit 2).
            let _ = e.print();
            return ExitCode::from(if e.use_stderr() { EXIT_USAGE } else { 0 });
        }
    };
    if let Some(n) = cli.threads {
        if n == 0 {
            return fail(&Failure::usage("--threads", "must be at least 1"));
        }
        if let Err(e) = rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build_global()
        {
            eprintln!("error: cannot start {n} threads: {e}");
            return ExitCode::from(1);
        }
    }
    progress_bars::install(cli.quiet, cli.verbose);
    let result = match &cli.command {
        Command::Bake(args) => commands::bake(args, cli.quiet),
        Command::Verify(args) => commands::verify(args, cli.quiet),
        Command::Generate(args) => commands::generate(args),
        Command::Render(args) => commands::render(args, cli.quiet),
        Command::Info(args) => commands::info(args),
    };
    match result {
        Ok(code) => ExitCode::from(code),
        Err(failure) => fail(&failure),
    }
}

/// Prints `failure` with its causes on stderr and returns its exit status.
fn fail(failure: &Failure) -> ExitCode {
    eprintln!("error: {failure}");
    for cause in failure.causes() {
        eprintln!("  caused by: {cause}");
    }
    ExitCode::from(failure.exit_code())
}
