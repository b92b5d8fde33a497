//! The `radiosity` binary: parses the command line ([`args`]), runs one command
//! ([`commands`]) on the library, prints the summary, and maps failures to messages and exit
//! statuses ([`failure`]): 0 success, 1 internal failure, 2 bad input or usage, 3 the solver
//! stopped at --max-iterations without converging (the output is written). Progress bars and
//! verbose notes are drawn by [`progress_bars`].

mod args;
mod commands;
mod failure;
mod progress_bars;
#[cfg(feature = "mpi")]
mod ranks;

use std::process::ExitCode;

use clap::Parser;
use radiosity::distributed::{Exchange, Solo};

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
    // With the `mpi` feature a bake is one rank of the MPI world (`mpirun -n N`; one rank
    // of one when started alone).
    #[cfg(feature = "mpi")]
    let mpi = match &cli.command {
        Command::Bake(_) => match ranks::Mpi::start() {
            Ok(mpi) => Some(mpi),
            Err(e) => {
                eprintln!("error: cannot start MPI: {e}");
                return ExitCode::from(1);
            }
        },
        _ => None,
    };
    #[cfg(feature = "mpi")]
    let comm: &dyn Exchange = match &mpi {
        Some(mpi) => mpi,
        None => &Solo,
    };
    #[cfg(not(feature = "mpi"))]
    let comm: &dyn Exchange = &Solo;
    // The ranks on one machine share its cores, unless --threads says otherwise.
    #[cfg(feature = "mpi")]
    let shared_cores = (comm.size() > 1).then(|| {
        let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
        (cores / ranks::Mpi::local_ranks().max(1)).max(1)
    });
    #[cfg(not(feature = "mpi"))]
    let shared_cores = None;
    if let Some(n) = cli.threads.or(shared_cores) {
        if n == 0 {
            return fail(&Failure::usage("--threads", "must be at least 1"), comm);
        }
        if let Err(e) = rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build_global()
        {
            eprintln!("error: cannot start {n} threads: {e}");
            return ExitCode::from(1);
        }
    }
    // Only rank 0 speaks (the others' progress and warnings are rank 0's).
    if comm.rank() == 0 {
        progress_bars::install(cli.quiet, cli.verbose);
    }
    let result = match &cli.command {
        Command::Bake(args) => commands::bake(args, cli.quiet, comm),
        Command::Verify(args) => commands::verify(args, cli.quiet),
        Command::Generate(args) => commands::generate(args),
        Command::Render(args) => commands::render(args, cli.quiet),
        Command::Info(args) => commands::info(args),
    };
    match result {
        Ok(code) => ExitCode::from(code),
        Err(failure) => {
            let code = fail(&failure, comm);
            // A rank that fails ends them all: the others would wait for it forever.
            #[cfg(feature = "mpi")]
            if let Some(mpi) = mpi.as_ref().filter(|m| m.size() > 1) {
                mpi.abort(failure.exit_code());
            }
            code
        }
    }
}

/// Prints `failure` with its causes on stderr (naming the rank in a bake of several) and
/// returns its exit status.
fn fail(failure: &Failure, comm: &dyn Exchange) -> ExitCode {
    let rank = match comm.size() {
        1 => String::new(),
        n => format!(" (rank {} of {n})", comm.rank()),
    };
    eprintln!("error{rank}: {failure}");
    for cause in failure.causes() {
        eprintln!("  caused by: {cause}");
    }
    ExitCode::from(failure.exit_code())
}
