//! What every entry point of the C API shares: the status codes and their names, the open file, the per-thread
//! last error, and the guard that turns errors and panics into status codes at the boundary.

use std::cell::RefCell;
use std::ffi::{CStr, CString, c_char, c_int};
use std::panic::{AssertUnwindSafe, catch_unwind};

use bvhc_loader::{BvhView, TracedFile, Tracer};

/// Status codes (`bvhc_status` in the header).
pub const BVHC_OK: c_int = 0;
/// A file could not be read.
pub const BVHC_ERROR_IO: c_int = 1;
/// The bytes break a validity rule of the format.
pub const BVHC_ERROR_INVALID: c_int = 2;
/// A null pointer, a bad length or index, a path that is not UTF-8, or a hit that is not the file's.
pub const BVHC_ERROR_ARGUMENT: c_int = 3;
/// The system refused memory.
pub const BVHC_ERROR_MEMORY: c_int = 4;
/// A bug inside the library was caught at the boundary.
pub const BVHC_ERROR_PANIC: c_int = 5;
/// The file lacks an optional section the call needs (the source vertices of format 1.2, the metadata).
pub const BVHC_ERROR_NOT_IN_FILE: c_int = 6;
/// A ray breaks the ray contract (the message names the ray and the rule).
pub const BVHC_ERROR_RAY: c_int = 7;

/// Each status code's name, as the header spells it.
const STATUS_NAMES: [&CStr; 8] = [
    c"BVHC_OK",
    c"BVHC_ERROR_IO",
    c"BVHC_ERROR_INVALID",
    c"BVHC_ERROR_ARGUMENT",
    c"BVHC_ERROR_MEMORY",
    c"BVHC_ERROR_PANIC",
    c"BVHC_ERROR_NOT_IN_FILE",
    c"BVHC_ERROR_RAY",
];

/// An open file (`bvhc_file`, opaque to C), with its tracer made once at open, so a call traces at once. The
/// tracer trusts its rays: the entry points check them first, to report a status rather than panic.
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

/// A thread's error messages: the last failed call's (`pending`, numbered), and the text
/// [`bvhc_last_error_message`] last handed out (`shown`, with the number it had), which stays allocated until the
/// thread asks again after a newer failure. So a pointer it returned outlives later failing calls: a C argument
/// list that calls both in either order prints some message of this thread, never freed memory.
#[derive(Default)]
struct Messages {
    pending: (u64, CString),
    shown: (u64, CString),
}

thread_local! {
    static MESSAGES: RefCell<Messages> = RefCell::new(Messages::default());
}

fn set_error(message: &str) {
    let message = CString::new(message.replace('\0', " ")).unwrap_or_default();
    MESSAGES.with(|m| {
        let mut m = m.borrow_mut();
        m.pending = (m.pending.0 + 1, message);
    });
}

/// Runs `body`, turning an error into its status (with its message as the thread's last error) and a panic
/// into `BVHC_ERROR_PANIC`.
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
        // Positions or transforms that do not fit the file, or a file a refit cannot take.
        bvhc_loader::Error::Refit(_) => BVHC_ERROR_ARGUMENT,
        _ => BVHC_ERROR_INVALID,
    }
}

pub(crate) fn argument(message: &str) -> (c_int, String) {
    (BVHC_ERROR_ARGUMENT, message.to_string())
}

/// The file behind `file`, or an argument error naming `call`.
///
/// # Safety
///
/// `file` is null or a pointer `bvhc_open` returned and `bvhc_close` has not freed.
pub(crate) unsafe fn file_ref<'f>(call: &str, file: *const BvhcFile) -> Result<&'f BvhcFile, (c_int, String)> {
    // SAFETY: by the contract `file` is null or live; `as_ref` checks null.
    unsafe { file.as_ref() }.ok_or_else(|| argument(&format!("{call}: file is null")))
}

/// The message of the last failed call on this thread (empty when none), NUL-terminated. The pointer stays
/// valid, and its text the same, until this thread calls `bvhc_last_error_message` again after another call has
/// failed: later failures do not free it (calls that succeed change nothing). [`bvhc_error_message`] copies the
/// message instead.
#[unsafe(no_mangle)]
pub extern "C" fn bvhc_last_error_message() -> *const c_char {
    MESSAGES.with(|m| {
        let mut m = m.borrow_mut();
        if m.shown.0 != m.pending.0 {
            m.shown = m.pending.clone();
        }
        m.shown.1.as_ptr()
    })
}

/// Copies the message of the last failed call on this thread into `buffer` (`capacity` bytes, NUL-terminated,
/// cut short when it does not fit, as `snprintf` does) and returns its full length without the NUL, so a
/// return value `>= capacity` says it was cut. `buffer` may be null when `capacity` is 0 (to ask the length).
///
/// # Safety
///
/// `buffer` is null or points to `capacity` writable bytes.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn bvhc_error_message(buffer: *mut c_char, capacity: usize) -> usize {
    MESSAGES.with(|m| {
        let m = m.borrow();
        // SAFETY: the caller's contract is this function's.
        unsafe { copy_text(m.pending.1.as_bytes(), buffer, capacity) }
    })
}

/// Writes `text` into `buffer` as `snprintf` would (at most `capacity - 1` bytes and a NUL; nothing when
/// `buffer` is null or `capacity` 0) and returns `text`'s length.
///
/// # Safety
///
/// `buffer` is null or points to `capacity` writable bytes.
pub(crate) unsafe fn copy_text(text: &[u8], buffer: *mut c_char, capacity: usize) -> usize {
    if !buffer.is_null() && capacity > 0 {
        let kept = text.len().min(capacity - 1);
        // SAFETY: `buffer` points to `capacity > kept` writable bytes, which cannot overlap `text` (the library's
        // own memory).
        unsafe {
            std::ptr::copy_nonoverlapping(text.as_ptr(), buffer.cast::<u8>(), kept);
            *buffer.add(kept) = 0;
        }
    }
    text.len()
}

/// The name of a status code as the header spells it (`"BVHC_ERROR_RAY"`), or `"unknown bvhc_status"`; a
/// static string.
#[unsafe(no_mangle)]
pub extern "C" fn bvhc_status_name(status: c_int) -> *const c_char {
    let name = usize::try_from(status).ok().and_then(|s| STATUS_NAMES.get(s)).copied();
    name.unwrap_or(c"unknown bvhc_status").as_ptr()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_status_is_named_and_unknown_ones_say_so() {
        // SAFETY: `bvhc_status_name` returns a static NUL-terminated string.
        let name = |s| unsafe { CStr::from_ptr(bvhc_status_name(s)) }.to_str().unwrap();
        for (status, expected) in [(BVHC_OK, "BVHC_OK"), (BVHC_ERROR_NOT_IN_FILE, "BVHC_ERROR_NOT_IN_FILE")] {
            assert_eq!(name(status), expected);
        }
        assert_eq!(name(BVHC_ERROR_RAY), "BVHC_ERROR_RAY");
        assert_eq!(name(-1), "unknown bvhc_status");
        assert_eq!(name(8), "unknown bvhc_status");
    }

    #[test]
    fn a_returned_message_outlives_later_failures_until_asked_again() {
        let text = |p: *const c_char| {
            // SAFETY: the pointer is one `bvhc_last_error_message` returned and the test asks again only after.
            unsafe { CStr::from_ptr(p) }.to_str().unwrap().to_string()
        };
        set_error("first");
        let first = bvhc_last_error_message();
        assert_eq!(bvhc_last_error_message(), first, "asking again without a new failure: the same text");
        set_error("second");
        set_error("third");
        assert_eq!(text(first), "first", "later failures leave the returned text alone");
        let third = bvhc_last_error_message();
        assert_eq!(text(third), "third");
        let mut buffer = [0 as c_char; 16];
        set_error("fourth");
        // SAFETY: `buffer` has 16 writable bytes.
        assert_eq!(unsafe { bvhc_error_message(buffer.as_mut_ptr(), 16) }, 6, "the copy is the newest message");
        assert_eq!(text(third), "third");
    }

    #[test]
    fn a_copied_message_is_cut_as_snprintf_cuts() {
        let mut buffer = [0x55 as c_char; 6];
        // SAFETY: `buffer` has 6 writable bytes.
        assert_eq!(unsafe { copy_text(b"hello world", buffer.as_mut_ptr(), 6) }, 11);
        // SAFETY: `copy_text` wrote a NUL within the buffer.
        assert_eq!(unsafe { CStr::from_ptr(buffer.as_ptr()) }.to_str().unwrap(), "hello");
        // SAFETY: a null buffer with capacity 0 is allowed.
        assert_eq!(unsafe { copy_text(b"hello world", std::ptr::null_mut(), 0) }, 11);
        // SAFETY: `buffer` has at least 1 writable byte.
        assert_eq!(unsafe { copy_text(b"", buffer.as_mut_ptr(), 1) }, 0);
        assert_eq!(buffer[0], 0);
    }
}
