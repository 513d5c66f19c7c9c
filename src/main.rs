//! The `bvhc` command line: convert (default), verify, info, render. See `bvhc --help`.
#![forbid(unsafe_code)]

mod cli;

fn main() -> std::process::ExitCode {
    cli::run()
}
