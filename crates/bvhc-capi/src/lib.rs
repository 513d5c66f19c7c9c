//! The C API of `bvhc-loader` (`include/bvhc.h`): open a `.bvh` file from a path or from memory, verify it,
//! and trace closest-hit and any-hit rays, one at a time or in batches, with the same hit records as Rust.
//!
//! Contract at the boundary: no Rust panic crosses it (every entry point runs under `catch_unwind` and reports
//! `BVHC_ERROR_PANIC`); null pointers and unequal batch sizes are argument errors, never crashes; the message
//! of the last error is per thread (`bvhc_last_error_message`). A `bvhc_file` is immutable once opened, so any
//! number of threads may trace through one at the same time; only `bvhc_close` must not race with them.

use std::cell::RefCell;
use std::ffi::{CStr, CString, c_char, c_int};
use std::panic::{AssertUnwindSafe, catch_unwind};

use bvhc_loader::{BvhFile, Hit, Ray, Tracer};

mod batch;
pub use batch::{bvhc_any_hits, bvhc_any_hits_coherent, bvhc_closest_hits, bvhc_closest_hits_coherent};

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

/// `bvhc_ray`: the Rust `Ray`, field for field.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct BvhcRay {
    /// Start point.
    pub origin: [f32; 3],
    /// Direction, not necessarily normalized.
    pub direction: [f32; 3],
    /// Smallest distance that counts.
    pub t_min: f32,
    /// Largest distance that counts (`INFINITY` for an unbounded ray).
    pub t_max: f32,
}

/// `bvhc_hit`: the Rust `Hit`, with `0xFFFFFFFF` for "no source id" and a byte for the front-face flag.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct BvhcHit {
    /// Distance along the ray.
    pub t: f32,
    /// Barycentric weight of `v1`.
    pub u: f32,
    /// Barycentric weight of `v2`.
    pub v: f32,
    /// Geometric normal `(v1 - v0) x (v2 - v0)`, not normalized.
    pub normal: [f32; 3],
    /// Index of the record in the triangles section.
    pub triangle_index: u32,
    /// Source id, or `0xFFFFFFFF` without one.
    pub source_triangle_id: u32,
    /// 1 when the ray met the front side.
    pub front_face: u8,
    /// Zero.
    pub reserved: [u8; 3],
}

impl From<BvhcRay> for Ray {
    fn from(ray: BvhcRay) -> Ray {
        Ray { origin: ray.origin, direction: ray.direction, t_min: ray.t_min, t_max: ray.t_max }
    }
}

impl From<&Hit> for BvhcHit {
    fn from(hit: &Hit) -> BvhcHit {
        BvhcHit {
            t: hit.t,
            u: hit.u,
            v: hit.v,
            normal: hit.normal,
            triangle_index: hit.triangle_index,
            source_triangle_id: hit.source_triangle_id.unwrap_or(u32::MAX),
            front_face: u8::from(hit.front_face),
            reserved: [0; 3],
        }
    }
}

impl BvhcHit {
    /// The Rust hit this record was made from.
    fn to_hit(self) -> Hit {
        Hit {
            t: self.t,
            triangle_index: self.triangle_index,
            source_triangle_id: (self.source_triangle_id != u32::MAX).then_some(self.source_triangle_id),
            u: self.u,
            v: self.v,
            normal: self.normal,
            front_face: self.front_face != 0,
        }
    }
}

/// `bvhc_source_corners`: where a hit lies in the source scene (the Rust `SourceCorners`, with the source
/// range's indices inline).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct BvhcSourceCorners {
    /// The source vertex of the record's `v0`, `v1`, `v2` in its primitive.
    pub vertices: [u32; 3],
    /// The hit's weight of each: `1 - u - v`, `u`, `v`.
    pub weights: [f32; 3],
    /// The triangle's source id.
    pub source_triangle_id: u32,
    /// The source range's glTF node, or `0xFFFFFFFF`.
    pub node_index: u32,
    /// The source range's glTF mesh or OBJ model, or `0xFFFFFFFF`.
    pub mesh_index: u32,
    /// The source range's glTF primitive, or `0xFFFFFFFF`.
    pub primitive_index: u32,
    /// The source range's `EXT_mesh_gpu_instancing` instance, or `0xFFFFFFFF`.
    pub instance_index: u32,
}

/// An open file (`bvhc_file`, opaque to C).
pub struct BvhcFile {
    file: BvhFile,
}

impl BvhcFile {
    fn tracer(&self) -> Tracer<'_> {
        self.file.view().tracer()
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
fn guarded(body: impl FnOnce() -> Result<c_int, (c_int, String)>) -> c_int {
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

fn status_of(error: &bvhc_loader::Error) -> c_int {
    match error {
        bvhc_loader::Error::Io { .. } => BVHC_ERROR_IO,
        bvhc_loader::Error::OutOfMemory { .. } => BVHC_ERROR_MEMORY,
        _ => BVHC_ERROR_INVALID,
    }
}

fn argument(message: &str) -> (c_int, String) {
    (BVHC_ERROR_ARGUMENT, message.to_string())
}

fn opened(result: Result<BvhFile, bvhc_loader::Error>, out: *mut *mut BvhcFile) -> Result<c_int, (c_int, String)> {
    let file = result.map_err(|e| (status_of(&e), e.to_string()))?;
    let boxed = Box::into_raw(Box::new(BvhcFile { file }));
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
        file.file.view().verify().map_err(|v| (BVHC_ERROR_INVALID, format!("invalid .bvh file: {v}")))?;
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
        match file.tracer().closest_hit(&Ray::from(*ray)) {
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
        Ok(c_int::from(file.tracer().any_hit(&Ray::from(*ray))))
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
        *out = BvhcRay { origin: ray.origin, direction: ray.direction, t_min: ray.t_min, t_max: ray.t_max };
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
    let view = file.file.view();
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
        let view = file.file.view();
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
    unsafe { file.as_ref() }.map_or(0, |file| file.file.view().triangles().len())
}

/// The message of the last error on this thread (empty when none), valid until the next call on this thread.
#[unsafe(no_mangle)]
pub extern "C" fn bvhc_last_error_message() -> *const c_char {
    LAST_ERROR.with(|last| last.borrow().as_ptr())
}
