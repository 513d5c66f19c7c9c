//! What every entry point of the C API shares: the status codes, the open file, the per-thread last error,
//! and the guard that turns errors and panics into status codes at the boundary.

use std::cell::RefCell;
use std::ffi::{CString, c_char, c_int};
use std::panic::{AssertUnwindSafe, catch_unwind};

use bvhc_loader::{BvhView, TracedFile, Tracer};

/// Status codes (`bvhc_status` in the header).
pub const BVHC_OK: c_int = 0;
/// A file could not be read.
pub const BVHC_ERROR_IO: c_int = 1;
/// The bytes break a validity rule of the format.
pub const BVHC_ERROR_INVALID: c_int = 2;
/// A null pointer, a bad length, or a path that is not UTF-8.
pub const BVHC_ERROR_ARGUMENT: c_int = 3;
/// The system refused memory.
pub const BVHC_ERROR_MEMORY: c_int = 4;
/// A bug inside the library was caught at the boundary.
pub const BVHC_ERROR_PANIC: c_int = 5;
/// The file lacks an optional section the call needs (the source vertices of format 1.2).
pub const BVHC_ERROR_NOT_IN_FILE: c_int = 6;

/// An open file (`bvhc_file`, opaque to C), with its tracer made once at open, so a call traces at once.
pub struct BvhcFile {
    /// The file's bytes, structurally checked, and the fastest tracer over them.
    pub(crate) traced: TracedFile,
}

impl BvhcFile {
    /// The file's fastest tracer (borrowed: copying it costs more than a call's other work).
    pub(crate) fn tracer(&self) -> &Tracer<'_> {
        self.traced.tracer()
    }

    /// A view of the file.
    pub(crate) fn view(&self) -> BvhView<'_> {
        self.traced.view()
    }
}

thread_local! {
    static LAST_ERROR: RefCell<CString> = RefCell::new(CString::default());
}

fn set_error(message: &str) {
    let message = CString::new(message.replace('\0', " ")).unwrap_or_default();
    LAST_ERROR.with(|last| *last.borrow_mut() = message);
}

/// Runs `body`, turning a panic into `BVHC_ERROR_PANIC` with its message.
pub(crate) fn guarded(body: impl FnOnce() -> Result<c_int, (c_int, String)>) -> c_int {
    match catch_unwind(AssertUnwindSafe(body)) {
        Ok(Ok(status)) => status,
        Ok(Err((status, message))) => {
            set_error(&message);
            status
        }
        Err(_) => {
            set_error("internal error (a panic was caught at the C boundary); please report it");
            BVHC_ERROR_PANIC
        }
    }
}

pub(crate) fn status_of(error: &bvhc_loader::Error) -> c_int {
    match error {
        bvhc_loader::Error::Io { .. } => BVHC_ERROR_IO,
        bvhc_loader::Error::OutOfMemory { .. } => BVHC_ERROR_MEMORY,
        _ => BVHC_ERROR_INVALID,
    }
}

pub(crate) fn argument(message: &str) -> (c_int, String) {
    (BVHC_ERROR_ARGUMENT, message.to_string())
}

/// The message of the last error on this thread (empty when none), valid until the next call on this thread.
#[unsafe(no_mangle)]
pub extern "C" fn bvhc_last_error_message() -> *const c_char {
    LAST_ERROR.with(|last| last.borrow().as_ptr())
}
