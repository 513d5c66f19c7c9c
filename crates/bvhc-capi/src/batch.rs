//! The batch entry points of the C API: closest and any hits for arrays of rays, one ray at a time (streams
//! interleaved over large files) or in coherent groups of 8, checked against the ray contract or (`_unchecked`)
//! not. The caller's arrays are used in place: rays are read where they are (`bvhc_ray` is the Rust `Ray`) and
//! each result is written straight into its slot, with no buffer between. A checked call checks its rays chunk
//! by chunk (`bvhc_loader::tracer::CHECKED_CHUNK`), each just before tracing it, so the rays come from the caches the
//! second time; on `BVHC_ERROR_RAY` the results of the chunks before the named ray have been written.

use bvhc_loader::Order;
use bvhc_loader::Trace;
use std::ffi::c_int;

use bvhc_loader::{BatchRayError, Tracer, tracer::CHECKED_CHUNK};

use crate::boundary::{BVHC_ERROR_RAY, BVHC_OK, BvhcFile, argument, file_ref, guarded};
use crate::records::{BvhcHit, BvhcRay};

/// How a batch call traces: whether it checks its rays first, and whether its rays are coherent.
#[derive(Clone, Copy)]
struct Mode {
    /// The call's name, for messages.
    call: &'static str,
    /// Check every ray against the contract before tracing any.
    check: bool,
    /// Trace each 8 consecutive rays together.
    coherent: bool,
}

impl Mode {
    /// The batch order the loader's `_with` calls take for this mode.
    fn order(&self) -> Order {
        if self.coherent { Order::Coherent } else { Order::Stream }
    }
}

/// Declares a batch closest-hit entry point of `mode`.
macro_rules! closest_hits_entry {
    ($(#[$doc:meta])* $name:ident, $check:expr, $coherent:expr) => {
        $(#[$doc])*
        #[unsafe(no_mangle)]
        pub unsafe extern "C" fn $name(
            file: *const BvhcFile,
            rays: *const BvhcRay,
            count: usize,
            hits: *mut BvhcHit,
            found: *mut u8,
        ) -> c_int {
            let mode = Mode { call: stringify!($name), check: $check, coherent: $coherent };
            // SAFETY: the caller's contract is this function's.
            unsafe { closest_hits(mode, file, rays, count, hits, found) }
        }
    };
}

/// Declares a batch any-hit entry point of `mode`.
macro_rules! any_hits_entry {
    ($(#[$doc:meta])* $name:ident, $check:expr, $coherent:expr) => {
        $(#[$doc])*
        #[unsafe(no_mangle)]
        pub unsafe extern "C" fn $name(
            file: *const BvhcFile,
            rays: *const BvhcRay,
            count: usize,
            occluded: *mut u8,
        ) -> c_int {
            let mode = Mode { call: stringify!($name), check: $check, coherent: $coherent };
            // SAFETY: the caller's contract is this function's.
            unsafe { any_hits(mode, file, rays, count, occluded) }
        }
    };
}

closest_hits_entry!(
    /// Traces `count` rays for their closest hits: `hits[i]` is ray `i`'s hit where `found[i]` is 1 (0: a miss,
    /// `hits[i]` zeroed). Rays are interleaved over large files, as `Tracer::closest_hits` does. Every ray is
    /// checked (see the module doc): `BVHC_ERROR_RAY` names the first that breaks the contract.
    ///
    /// # Safety
    ///
    /// `file` is null or a live file; `rays`, `hits` and `found` are null or point to `count` elements each.
    bvhc_closest_hits,
    true,
    false
);
closest_hits_entry!(
    /// [`bvhc_closest_hits`] without the ray check (see `bvhc_check_rays`).
    ///
    /// # Safety
    ///
    /// As [`bvhc_closest_hits`].
    bvhc_closest_hits_unchecked,
    false,
    false
);
closest_hits_entry!(
    /// [`bvhc_closest_hits`] for coherent rays (camera rays of neighbouring pixels): each 8 consecutive rays are
    /// traced together (`Tracer::closest_hits_coherent`: the same hit for each ray as one at a time, ties
    /// included; with split references possibly another record of the same triangle).
    ///
    /// # Safety
    ///
    /// As [`bvhc_closest_hits`].
    bvhc_closest_hits_coherent,
    true,
    true
);
closest_hits_entry!(
    /// [`bvhc_closest_hits_coherent`] without the ray check.
    ///
    /// # Safety
    ///
    /// As [`bvhc_closest_hits`].
    bvhc_closest_hits_coherent_unchecked,
    false,
    true
);
any_hits_entry!(
    /// Traces `count` rays for occlusion: `occluded[i]` is 1 when ray `i` hits anything. Rays are checked as
    /// [`bvhc_closest_hits`] checks them.
    ///
    /// # Safety
    ///
    /// `file` is null or a live file; `rays` and `occluded` are null or point to `count` elements each.
    bvhc_any_hits,
    true,
    false
);
any_hits_entry!(
    /// [`bvhc_any_hits`] without the ray check.
    ///
    /// # Safety
    ///
    /// As [`bvhc_any_hits`].
    bvhc_any_hits_unchecked,
    false,
    false
);
any_hits_entry!(
    /// [`bvhc_any_hits`] for coherent rays: each 8 consecutive rays traced together
    /// (`Tracer::any_hits_coherent`, the same answers).
    ///
    /// # Safety
    ///
    /// As [`bvhc_any_hits`].
    bvhc_any_hits_coherent,
    true,
    true
);
any_hits_entry!(
    /// [`bvhc_any_hits_coherent`] without the ray check.
    ///
    /// # Safety
    ///
    /// As [`bvhc_any_hits`].
    bvhc_any_hits_coherent_unchecked,
    false,
    true
);

/// `BVHC_NO_INDEX` and `BVHC_NO_INSTANCE` of `bvhc.h`: no record, no instance.
const BVHC_NO_INDEX: u32 = u32::MAX;
const BVHC_NO_INSTANCE: u32 = u32::MAX;

/// `bvhc_closest_hit_columns`'s flag: each 8 consecutive rays traced together.
pub const BVHC_RAYS_COHERENT: u32 = 1;
/// `bvhc_closest_hit_columns`'s flag: the rays are not checked against the contract.
pub const BVHC_RAYS_UNCHECKED: u32 = 2;

/// Traces `count` rays for their closest hits and writes them as columns, handed off lean (`Trace::
/// closest_hit_cores_with`: in a one-level file no normal, side or source id is computed): `t[i]` ray `i`'s hit
/// distance (`INFINITY` on a miss), and where not null `triangle_index[i]` its record (`BVHC_NO_INDEX` on a
/// miss), `instance_index[i]` its instance (`BVHC_NO_INSTANCE` in a one-level file or on a miss), `u[i]`, `v[i]`
/// its weights (0 on a miss). `flags`: `BVHC_RAYS_COHERENT`, `BVHC_RAYS_UNCHECKED`, or both; the rays are
/// checked as [`bvhc_closest_hits`] checks them unless unchecked.
///
/// # Safety
///
/// `file` is null or a live file; `rays` and `t` are null or point to `count` elements each, and so does each
/// other column that is not null.
#[unsafe(no_mangle)]
#[allow(clippy::too_many_arguments)] // the C signature: the file, the rays, the flags and five columns
pub unsafe extern "C" fn bvhc_closest_hit_columns(
    file: *const BvhcFile,
    rays: *const BvhcRay,
    count: usize,
    flags: u32,
    t: *mut f32,
    triangle_index: *mut u32,
    instance_index: *mut u32,
    u: *mut f32,
    v: *mut f32,
) -> c_int {
    guarded(|| {
        let call = "bvhc_closest_hit_columns";
        if flags & !(BVHC_RAYS_COHERENT | BVHC_RAYS_UNCHECKED) != 0 {
            return Err(argument(&format!("{call}: flags {flags:#x} has bits that are not BVHC_RAYS_ flags")));
        }
        let coherent = flags & BVHC_RAYS_COHERENT != 0;
        let mode = Mode { call, check: flags & BVHC_RAYS_UNCHECKED == 0, coherent };
        // SAFETY: the caller's contract is this function's.
        let Some((tracer, rays)) = (unsafe { batch_input(mode, file, rays, count, t.is_null(), "rays and t") })? else {
            return Ok(BVHC_OK);
        };
        /// `count` elements at `p`, or `None` where it is null.
        ///
        /// # Safety
        ///
        /// `p` is null or points to `count` elements that nothing else refers to during the call.
        unsafe fn column<'c, T>(p: *mut T, count: usize) -> Option<&'c mut [T]> {
            // SAFETY: the caller's contract.
            (!p.is_null()).then(|| unsafe { std::slice::from_raw_parts_mut(p, count) })
        }
        // SAFETY: by the contract each non-null column points to `count` elements of its own; they do not
        // overlap the rays (distinct C arrays of other types).
        let (t, mut triangle_index, mut instance_index, mut u, mut v) = unsafe {
            let t = column(t, count).unwrap_or_default();
            (t, column(triangle_index, count), column(instance_index, count), column(u, count), column(v, count))
        };
        in_chunks(mode, rays, |first, chunk| {
            let each = |i: usize, core: Option<bvhc_loader::HitCore>| {
                let i = first + i;
                let (distance, record, instance, weights) = match core {
                    Some(c) => (c.t, c.triangle_index, c.instance_index.unwrap_or(BVHC_NO_INSTANCE), (c.u, c.v)),
                    None => (f32::INFINITY, BVHC_NO_INDEX, BVHC_NO_INSTANCE, (0.0, 0.0)),
                };
                put(Some(&mut *t), i, distance);
                put(triangle_index.as_deref_mut(), i, record);
                put(instance_index.as_deref_mut(), i, instance);
                put(u.as_deref_mut(), i, weights.0);
                put(v.as_deref_mut(), i, weights.1);
            };
            tracer.closest_hit_cores_with(chunk, mode.order(), each)
        })
    })
}

/// `value` into slot `i` of `column`, where there is one.
#[inline(always)]
fn put<T>(column: Option<&mut [T]>, i: usize, value: T) {
    if let Some(slot) = column.and_then(|c| c.get_mut(i)) {
        *slot = value;
    }
}

/// The batch closest-hit calls.
///
/// # Safety
///
/// As [`bvhc_closest_hits`].
unsafe fn closest_hits(
    mode: Mode,
    file: *const BvhcFile,
    rays: *const BvhcRay,
    count: usize,
    hits: *mut BvhcHit,
    found: *mut u8,
) -> c_int {
    guarded(|| {
        let outputs_null = hits.is_null() || found.is_null();
        // SAFETY: the caller's contract is this function's.
        let Some((tracer, rays)) =
            (unsafe { batch_input(mode, file, rays, count, outputs_null, "rays, hits and found") })?
        else {
            return Ok(BVHC_OK);
        };
        // SAFETY: not null (checked by `batch_input`), and by the contract each points to `count` elements; the
        // outputs do not overlap the input (they are distinct C arrays of other types).
        let (hits, found) =
            unsafe { (std::slice::from_raw_parts_mut(hits, count), std::slice::from_raw_parts_mut(found, count)) };
        in_chunks(mode, rays, |first, chunk| {
            let each = |i: usize, result: Option<bvhc_loader::Hit>| {
                if let (Some(hit), Some(flag)) = (hits.get_mut(first + i), found.get_mut(first + i)) {
                    *hit = result.as_ref().map(BvhcHit::from).unwrap_or_default();
                    *flag = u8::from(result.is_some());
                }
            };
            // The file's tracer trusts its rays (they were checked above): these calls cannot fail.
            tracer.closest_hits_with(chunk, mode.order(), each)
        })
    })
}

/// The batch any-hit calls.
///
/// # Safety
///
/// As [`bvhc_any_hits`].
unsafe fn any_hits(mode: Mode, file: *const BvhcFile, rays: *const BvhcRay, count: usize, occluded: *mut u8) -> c_int {
    guarded(|| {
        // SAFETY: the caller's contract is this function's.
        let Some((tracer, rays)) =
            (unsafe { batch_input(mode, file, rays, count, occluded.is_null(), "rays and occluded") })?
        else {
            return Ok(BVHC_OK);
        };
        // SAFETY: not null (checked by `batch_input`), and by the contract it points to `count` elements.
        let occluded = unsafe { std::slice::from_raw_parts_mut(occluded, count) };
        in_chunks(mode, rays, |first, chunk| {
            let each = |i: usize, hit: bool| {
                if let Some(flag) = occluded.get_mut(first + i) {
                    *flag = u8::from(hit);
                }
            };
            tracer.any_hits_with(chunk, mode.order(), each)
        })
    })
}

/// The tracer of a batch call's file and its rays.
type BatchInput<'f> = (&'f Tracer<'f>, &'f [BvhcRay]);

/// What every batch call checks first: the file and its `count` rays; `None` for an empty batch (nothing to
/// check or write). Argument errors name the call and, when
/// a pointer is null, the `arrays` that must not be (`outputs_null`: whether one of the call's output arrays is).
///
/// # Safety
///
/// `file` is null or a live file; `rays` is null or points to `count` rays that stay unchanged during the call.
unsafe fn batch_input<'f>(
    mode: Mode,
    file: *const BvhcFile,
    rays: *const BvhcRay,
    count: usize,
    outputs_null: bool,
    arrays: &str,
) -> Result<Option<BatchInput<'f>>, (c_int, String)> {
    // SAFETY: the caller's contract is `file_ref`'s.
    let file = unsafe { file_ref(mode.call, file) }?;
    if count == 0 {
        return Ok(None);
    }
    if rays.is_null() || outputs_null {
        return Err(argument(&format!("{}: {arrays} must not be null", mode.call)));
    }
    // SAFETY: not null, and by the contract it points to `count` rays.
    Ok(Some((file.tracer(), unsafe { std::slice::from_raw_parts(rays, count) })))
}

/// Traces `rays` chunk by chunk with `trace(first, chunk)`, each chunk checked first when `mode` checks:
/// `BVHC_ERROR_RAY` naming the first ray that breaks the contract.
fn in_chunks(
    mode: Mode,
    rays: &[BvhcRay],
    mut trace: impl FnMut(usize, &[BvhcRay]) -> Result<(), BatchRayError>,
) -> Result<c_int, (c_int, String)> {
    let refused = |error: BatchRayError| (BVHC_ERROR_RAY, format!("{}: {error}", mode.call));
    for (c, chunk) in rays.chunks(CHECKED_CHUNK).enumerate() {
        let first = c * CHECKED_CHUNK;
        if mode.check {
            bvhc_loader::check_rays(chunk).map_err(|e| refused(BatchRayError { index: first + e.index, ..e }))?;
        }
        trace(first, chunk).map_err(refused)?;
    }
    Ok(BVHC_OK)
}
