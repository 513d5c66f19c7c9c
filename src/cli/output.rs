//! Standard output and error without panics: a full disk (`> /dev/full`) or a closed pipe (`| head`) must not
//! crash the tool. Results are gathered in a `String` with [`outln!`] and written once by [`print`].
//!
//! Rules: a closed pipe on stdout ends the command quietly with its own exit code (as `cat` and ripgrep do: the
//! reader has what it wanted); any other write error on stdout is exit 3 with a message on stderr; errors
//! writing stderr itself are ignored (there is nowhere left to report them), the exit code still tells.

use std::io::{ErrorKind, Write};

use super::Exit;

/// Appends one line to a `String` report (writing to a `String` cannot fail).
macro_rules! outln {
    ($out:expr, $($arg:tt)*) => {{
        use std::fmt::Write as _;
        let _ = writeln!($out, $($arg)*);
    }};
}
pub(crate) use outln;

/// Writes `text` to stdout and returns `exit`, or the exit code of the write error (see the module doc).
pub fn print(text: &str, exit: Exit) -> Exit {
    let mut stdout = std::io::stdout().lock();
    match stdout.write_all(text.as_bytes()).and_then(|()| stdout.flush()) {
        Ok(()) => exit,
        Err(error) if error.kind() == ErrorKind::BrokenPipe => exit,
        Err(error) => error_line(Exit::Io, format_args!("cannot write to standard output: {error}")),
    }
}

/// Writes `bvhc: error: <message>` to stderr (ignoring a failure to do so) and returns `exit`.
pub fn error_line(exit: Exit, message: std::fmt::Arguments<'_>) -> Exit {
    let _ = writeln!(std::io::stderr().lock(), "bvhc: error: {message}");
    exit
}
