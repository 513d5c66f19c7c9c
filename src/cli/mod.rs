//! Argument parsing (clap derive) and dispatch. Results go to stdout (`--json` for machines), diagnostics and
//! progress to stderr, progress bars only when stderr is a terminal.
//!
//! Exit codes: 0 success (including "up to date"); 1 invalid input (a scene that cannot be imported, a `.bvh`
//! file that breaks a validity rule); 2 usage error; 3 input/output error (a file that cannot be read or
//! written); 4 internal error.

mod args;
mod batch;
mod camera;
mod convert;
mod info;
mod legend;
mod option_flags;
mod options;
mod output;
mod refit;
mod render;
mod signals;
mod stage_info;
mod trace;
mod view;

use std::process::ExitCode;

use clap::Parser;

use args::{Cli, Command};

/// The documented exit codes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Exit {
    /// 0.
    Success = 0,
    /// 1: the input is invalid.
    InvalidInput = 1,
    /// 2: the command line is wrong.
    Usage = 2,
    /// 3: a file could not be read or written.
    Io = 3,
    /// 4: a bug was caught.
    Internal = 4,
}

impl From<Exit> for ExitCode {
    fn from(exit: Exit) -> ExitCode {
        ExitCode::from(exit as u8)
    }
}

/// Prints an error to stderr and returns its exit code.
pub fn fail(exit: Exit, message: impl std::fmt::Display) -> Exit {
    output::error_line(exit, format_args!("{message}"))
}

/// The exit code of a loader error.
pub fn loader_exit(error: &bvhc::loader::Error) -> Exit {
    match error {
        bvhc::loader::Error::Invalid(_) => Exit::InvalidInput,
        bvhc::loader::Error::Io { .. } => Exit::Io,
        _ => Exit::InvalidInput,
    }
}

/// Parses the arguments and runs the command.
pub fn run() -> ExitCode {
    let cli = Cli::parse();
    if let Some(threads) = cli.threads
        && let Err(error) = rayon::ThreadPoolBuilder::new().num_threads(usize::from(threads)).build_global()
    {
        return fail(Exit::Internal, format!("cannot start {threads} threads: {error}")).into();
    }
    let output = match &cli.command {
        Some(Command::Render(args)) => Some(args.output.clone()),
        Some(Command::Trace(args)) => args.output.clone(),
        Some(Command::Refit(args)) => Some(args.output.clone()),
        Some(_) => None,
        None => cli.convert.output.clone(),
    };
    if let Some(output) = output {
        signals::clean_up_on_signal(&output);
    }
    let exit = match cli.command {
        Some(Command::Verify { file }) => info::verify(&file),
        Some(Command::Info { file, json }) => info::info(&file, json),
        Some(Command::Render(args)) => render::render(&args),
        Some(Command::Trace(args)) => trace::trace(&args),
        Some(Command::Options(args)) => options::options(&args),
        Some(Command::Refit(args)) => refit::refit(&args, cli.threads),
        Some(Command::Batch(args)) => batch::batch(&args, cli.threads),
        None => convert::convert(&cli.convert),
    };
    exit.into()
}
