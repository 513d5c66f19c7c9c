//! Opening, verifying and closing a file: `bvhc_open`, `bvhc_open_memory`, `bvhc_verify`, `bvhc_close`.

use std::ffi::{CStr, c_char, c_int};

use bvhc_loader::{BvhFile, TracedFile};

use crate::boundary::{BVHC_ERROR_INVALID, BVHC_OK, BvhcFile, argument, file_ref, guarded, status_of};

fn opened(result: Result<BvhFile, bvhc_loader::Error>, out: *mut *mut BvhcFile) -> Result<c_int, (c_int, String)> {
    let file = result.map_err(|e| (status_of(&e), e.to_string()))?;
    let boxed = Box::into_raw(Box::new(BvhcFile { traced: TracedFile::new(file).trusting_rays() }));
    // SAFETY: the callers checked that `out` is not null; the C contract is that it points to writable
    // storage for one pointer.
    unsafe { *out = boxed };
    Ok(BVHC_OK)
}

/// Opens the `.bvh` file at the NUL-terminated UTF-8 `path` (structural rules V1-V10) into `*out`.
///
/// # Safety
///
/// `path` is null or a NUL-terminated string; `out` is null or points to writable storage for a pointer.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn bvhc_open(path: *const c_char, out: *mut *mut BvhcFile) -> c_int {
    guarded(|| {
        if path.is_null() || out.is_null() {
            return Err(argument("bvhc_open: path and out must not be null"));
        }
        // SAFETY: `path` is not null and, by this function's contract, NUL-terminated.
        let path = unsafe { CStr::from_ptr(path) };
        let path = path.to_str().map_err(|_| argument("bvhc_open: the path is not UTF-8"))?;
        opened(BvhFile::read(path), out)
    })
}

/// Copies the `len` bytes at `bytes` and opens them (structural rules V1-V10) into `*out`.
///
/// # Safety
///
/// `bytes` is null or points to `len` readable bytes; `out` is null or points to writable storage for a
/// pointer.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn bvhc_open_memory(bytes: *const u8, len: usize, out: *mut *mut BvhcFile) -> c_int {
    guarded(|| {
        if bytes.is_null() || out.is_null() {
            return Err(argument("bvhc_open_memory: bytes and out must not be null"));
        }
        // SAFETY: `bytes` is not null and, by this function's contract, points to `len` readable bytes that
        // stay unchanged during the call (they are copied).
        let slice = unsafe { std::slice::from_raw_parts(bytes, len) };
        opened(BvhFile::from_bytes(slice), out)
    })
}

/// Checks every validity rule: `BVHC_OK`, or `BVHC_ERROR_INVALID` with the broken rule in the last error
/// message.
///
/// # Safety
///
/// `file` is null or a pointer `bvhc_open` returned and `bvhc_close` has not freed.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn bvhc_verify(file: *const BvhcFile) -> c_int {
    guarded(|| {
        // SAFETY: the caller's contract is `file_ref`'s.
        let file = unsafe { file_ref("bvhc_verify", file) }?;
        file.view().verify().map_err(|v| (BVHC_ERROR_INVALID, format!("invalid .bvh file: {v}")))?;
        Ok(BVHC_OK)
    })
}

/// Frees a file (null is accepted and ignored).
///
/// # Safety
///
/// `file` is null or a pointer `bvhc_open` returned, not freed before and not used by another thread now.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn bvhc_close(file: *mut BvhcFile) {
    if !file.is_null() {
        // SAFETY: by the contract, `file` came from `Box::into_raw` in `opened` and is freed once.
        drop(unsafe { Box::from_raw(file) });
    }
}
