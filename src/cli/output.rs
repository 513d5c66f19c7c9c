//! Standard output and error without panics: a full disk (`> /dev/full`) or a closed pipe (`| head`) must not
//! crash the tool. Results are gathered in a `String` with [`outln!`] and written once by [`print`].
//!
//! Rules: a closed pipe on stdout ends the command quietly with its own exit code (as `cat` and ripgrep do: the
//! reader has what it wanted); any other write error on stdout is exit 3 with a message on stderr; errors
//! writing stderr itself are ignored (there is nowhere left to report them), the exit code still tells.

use std::io::{ErrorKind, Write};
use std::path::Path;

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

/// Writes an output file of `trace` or `render`: a character device or FIFO that exists already (`-o /dev/null`,
/// a pipe made by `mkfifo`) is written directly, since it holds no previous file to keep and a reader of a stream
/// expects the bytes there; any other path is written atomically ([`bvhc::loader::write::write_atomic`]), which refuses
/// a directory. The error names the path.
pub fn write_output(path: &Path, bytes: &[u8]) -> Result<(), String> {
    if is_stream(path) {
        let written = std::fs::OpenOptions::new().write(true).open(path).and_then(|mut file| file.write_all(bytes));
        return written.map_err(|error| format!("{}: {error}", path.display()));
    }
    bvhc::loader::write::write_atomic(path, bytes).map_err(|error| error.to_string())
}

/// Whether `path` is a character device or a FIFO (following links, as `/dev/stdout` is one).
fn is_stream(path: &Path) -> bool {
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        std::fs::metadata(path).is_ok_and(|m| m.file_type().is_char_device() || m.file_type().is_fifo())
    }
    #[cfg(not(unix))]
    {
        let _ = path;
        false
    }
}
