//! The C API of `bvhc-loader` (`include/bvhc.h`): open a `.bvh` file from a path or from memory, verify it,
//! and trace closest-hit and any-hit rays, one at a time or in batches, with the same hit records as Rust.
//!
//! Contract at the boundary: no Rust panic crosses it (every entry point runs under `catch_unwind` and reports
//! `BVHC_ERROR_PANIC`); null pointers and unequal batch sizes are argument errors, never crashes; the message
//! of the last error is per thread (`bvhc_last_error_message`). A `bvhc_file` is immutable once opened, so any
//! number of threads may trace through one at the same time; only `bvhc_close` must not race with them.

use std::ffi::{CStr, c_char, c_int};

use bvhc_loader::{BvhFile, TracedFile};

mod batch;
mod boundary;
mod records;

pub use batch::{bvhc_any_hits, bvhc_any_hits_coherent, bvhc_closest_hits, bvhc_closest_hits_coherent};
pub use boundary::{
    BVHC_ERROR_ARGUMENT, BVHC_ERROR_INVALID, BVHC_ERROR_IO, BVHC_ERROR_MEMORY, BVHC_ERROR_NOT_IN_FILE,
    BVHC_ERROR_PANIC, BVHC_OK, BvhcFile, bvhc_last_error_message,
};
use boundary::{argument, guarded, status_of};
pub use records::{BvhcHit, BvhcRay, BvhcSourceCorners};

fn opened(result: Result<BvhFile, bvhc_loader::Error>, out: *mut *mut BvhcFile) -> Result<c_int, (c_int, String)> {
    let file = result.map_err(|e| (status_of(&e), e.to_string()))?;
    let boxed = Box::into_raw(Box::new(BvhcFile { traced: TracedFile::new(file) }));
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

/// Checks every validity rule (V11-V40): `BVHC_OK`, or `BVHC_ERROR_INVALID` with the broken rule in the last
/// error message.
///
/// # Safety
///
/// `file` is null or a pointer `bvhc_open` returned and `bvhc_close` has not freed.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn bvhc_verify(file: *const BvhcFile) -> c_int {
    guarded(|| {
        // SAFETY: by the contract, `file` is null or a live `BvhcFile`.
        let file = unsafe { file.as_ref() }.ok_or_else(|| argument("bvhc_verify: file is null"))?;
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

/// The closest hit of `*ray` into `*hit`: 1 when it hit, 0 on a miss (`*hit` untouched), -1 on an argument
/// error.
///
/// # Safety
///
/// `file` is null or a live file; `ray` is null or points to a `bvhc_ray`; `hit` is null or points to
/// writable storage for a `bvhc_hit`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn bvhc_closest_hit(file: *const BvhcFile, ray: *const BvhcRay, hit: *mut BvhcHit) -> c_int {
    let status = guarded(|| {
        // SAFETY: by the contract each pointer is null or valid for its type; `as_ref`/`as_mut` check null.
        let (file, ray, out) = unsafe { (file.as_ref(), ray.as_ref(), hit.as_mut()) };
        let (Some(file), Some(ray), Some(out)) = (file, ray, out) else {
            return Err(argument("bvhc_closest_hit: file, ray and hit must not be null"));
        };
        match file.tracer().closest_hit(ray) {
            Some(found) => {
                *out = BvhcHit::from(&found);
                Ok(1)
            }
            None => Ok(0),
        }
    });
    if status > 1 { -1 } else { status }
}

/// Whether anything is hit along `*ray`: 1 or 0, -1 on an argument error.
///
/// # Safety
///
/// `file` is null or a live file; `ray` is null or points to a `bvhc_ray`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn bvhc_any_hit(file: *const BvhcFile, ray: *const BvhcRay) -> c_int {
    let status = guarded(|| {
        // SAFETY: by the contract each pointer is null or valid for its type.
        let (Some(file), Some(ray)) = (unsafe { file.as_ref() }, unsafe { ray.as_ref() }) else {
            return Err(argument("bvhc_any_hit: file and ray must not be null"));
        };
        Ok(c_int::from(file.tracer().any_hit(ray)))
    });
    if status > 1 { -1 } else { status }
}

/// A ray leaving the surface of `*hit` along `direction` with `t_min = 0` that does not meet the triangle it
/// leaves (`SurfacePoint::spawn`), into `*out`.
///
/// # Safety
///
/// `file` is null or a live file; `hit` null or a `bvhc_hit` this file's tracing returned; `direction` null or
/// three floats; `out` null or writable storage for a `bvhc_ray`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn bvhc_spawn_ray(
    file: *const BvhcFile,
    hit: *const BvhcHit,
    direction: *const f32,
    out: *mut BvhcRay,
) -> c_int {
    guarded(|| {
        if direction.is_null() {
            return Err(argument("bvhc_spawn_ray: direction must not be null"));
        }
        // SAFETY: by the contract each pointer is null (checked) or valid; `direction` points to three floats.
        let (file, hit, out, direction) =
            unsafe { (file.as_ref(), hit.as_ref(), out.as_mut(), *(direction as *const [f32; 3])) };
        let (Some(file), Some(hit), Some(out)) = (file, hit, out) else {
            return Err(argument("bvhc_spawn_ray: file, hit and out must not be null"));
        };
        let ray = file.tracer().surface(&hit.to_hit()).spawn(direction);
        *out = ray;
        Ok(BVHC_OK)
    })
}

/// The source id of record `triangle_index`, or `0xFFFFFFFF` when the file has none or the index is out of
/// range.
///
/// # Safety
///
/// `file` is null or a live file.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn bvhc_source_id(file: *const BvhcFile, triangle_index: u32) -> u32 {
    // SAFETY: by the contract `file` is null or live.
    let Some(file) = (unsafe { file.as_ref() }) else { return u32::MAX };
    let view = file.view();
    view.triangle_ids().and_then(|ids| ids.get(triangle_index as usize).copied()).unwrap_or(u32::MAX)
}

/// The source primitive, source vertices and weights of `*hit` (`BvhView::source_corners`), into `*out`:
/// interpolate a per-vertex attribute `A` of that primitive as `weights[0] A[vertices[0]] + weights[1]
/// A[vertices[1]] + weights[2] A[vertices[2]]`. `BVHC_ERROR_NOT_IN_FILE` when the file has no source vertices.
///
/// # Safety
///
/// `file` is null or a live file; `hit` null or a `bvhc_hit` this file's tracing returned; `out` null or
/// writable storage for a `bvhc_source_corners`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn bvhc_hit_source_corners(
    file: *const BvhcFile,
    hit: *const BvhcHit,
    out: *mut BvhcSourceCorners,
) -> c_int {
    guarded(|| {
        // SAFETY: by the contract each pointer is null or valid.
        let (file, hit, out) = unsafe { (file.as_ref(), hit.as_ref(), out.as_mut()) };
        let (Some(file), Some(hit), Some(out)) = (file, hit, out) else {
            return Err(argument("bvhc_hit_source_corners: file, hit and out must not be null"));
        };
        let view = file.view();
        let Some(corners) = view.source_corners(&hit.to_hit()) else {
            let why = if view.source_vertices().is_none() {
                "the file has no source_vertices section (format 1.2; convert without --no-source-vertices)"
            } else {
                "the hit's triangle index is not a record of this file"
            };
            return Err((BVHC_ERROR_NOT_IN_FILE, format!("bvhc_hit_source_corners: {why}")));
        };
        let range = corners.range;
        *out = BvhcSourceCorners {
            vertices: corners.vertices,
            weights: corners.weights,
            source_triangle_id: corners.source_triangle_id,
            node_index: range.node_index,
            mesh_index: range.mesh_index,
            primitive_index: range.primitive_index,
            instance_index: range.instance_index,
        };
        Ok(BVHC_OK)
    })
}

/// The number of triangle records (0 for null).
///
/// # Safety
///
/// `file` is null or a live file.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn bvhc_triangle_count(file: *const BvhcFile) -> usize {
    // SAFETY: by the contract `file` is null or live.
    unsafe { file.as_ref() }.map_or(0, |file| file.view().triangles().len())
}
