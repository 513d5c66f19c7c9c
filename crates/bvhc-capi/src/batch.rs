//! The batch entry points of the C API: closest and any hits for arrays of rays, one ray at a time (streams
//! interleaved over large files) or in coherent groups of 8, with the same contract as the rest of the API.

use std::ffi::c_int;

use bvhc_loader::{Hit, Ray, Tracer};

use crate::boundary::{BVHC_OK, BvhcFile, argument, guarded};
use crate::records::{BvhcHit, BvhcRay};

/// Traces `count` rays for their closest hits: `hits[i]` is ray `i`'s hit where `found[i]` is 1 (0: a miss,
/// `hits[i]` zeroed). Rays are interleaved over large files, as `Tracer::closest_hits` does.
///
/// # Safety
///
/// `file` is null or a live file; `rays`, `hits` and `found` are null or point to `count` elements each.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn bvhc_closest_hits(
    file: *const BvhcFile,
    rays: *const BvhcRay,
    count: usize,
    hits: *mut BvhcHit,
    found: *mut u8,
) -> c_int {
    // SAFETY: the caller's contract is this function's.
    unsafe { closest_hits("bvhc_closest_hits", |t, r, h| t.closest_hits(r, h), file, rays, count, hits, found) }
}

/// [`bvhc_closest_hits`] for coherent rays (camera rays of neighbouring pixels): each 8 consecutive rays are
/// traced together (`Tracer::closest_hits_coherent`: the same `t` for each ray; on a tie at it, possibly
/// another triangle).
///
/// # Safety
///
/// As [`bvhc_closest_hits`].
#[unsafe(no_mangle)]
pub unsafe extern "C" fn bvhc_closest_hits_coherent(
    file: *const BvhcFile,
    rays: *const BvhcRay,
    count: usize,
    hits: *mut BvhcHit,
    found: *mut u8,
) -> c_int {
    let name = "bvhc_closest_hits_coherent";
    // SAFETY: the caller's contract is this function's.
    unsafe { closest_hits(name, |t, r, h| t.closest_hits_coherent(r, h), file, rays, count, hits, found) }
}

/// The batch closest-hit calls, tracing with `trace`.
///
/// # Safety
///
/// As [`bvhc_closest_hits`].
unsafe fn closest_hits(
    name: &str,
    trace: fn(&Tracer<'_>, &[Ray], &mut [Option<Hit>]),
    file: *const BvhcFile,
    rays: *const BvhcRay,
    count: usize,
    hits: *mut BvhcHit,
    found: *mut u8,
) -> c_int {
    guarded(|| {
        let outputs_null = hits.is_null() || found.is_null();
        // SAFETY: the caller's contract is this function's.
        let Some((file, rays)) =
            (unsafe { batch_input(name, file, rays, count, outputs_null, "rays, hits and found") })?
        else {
            return Ok(BVHC_OK);
        };
        // SAFETY: not null (checked by `batch_input`), and by the contract each points to `count` elements; the
        // outputs do not overlap the input (they are distinct C arrays of other types).
        let (hits, found) =
            unsafe { (std::slice::from_raw_parts_mut(hits, count), std::slice::from_raw_parts_mut(found, count)) };
        let mut results = vec![None; count.min(CHUNK_RAYS)];
        let chunks = rays.chunks(CHUNK_RAYS).zip(hits.chunks_mut(CHUNK_RAYS)).zip(found.chunks_mut(CHUNK_RAYS));
        for ((rays, hits), found) in chunks {
            let results = &mut results[..rays.len()];
            trace(file.tracer(), rays, results);
            for ((result, hit), flag) in results.iter().zip(hits).zip(found) {
                *hit = result.as_ref().map(BvhcHit::from).unwrap_or_default();
                *flag = u8::from(result.is_some());
            }
        }
        Ok(BVHC_OK)
    })
}

/// Traces `count` rays for occlusion: `occluded[i]` is 1 when ray `i` hits anything.
///
/// # Safety
///
/// `file` is null or a live file; `rays` and `occluded` are null or point to `count` elements each.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn bvhc_any_hits(
    file: *const BvhcFile,
    rays: *const BvhcRay,
    count: usize,
    occluded: *mut u8,
) -> c_int {
    // SAFETY: the caller's contract is this function's.
    unsafe { any_hits("bvhc_any_hits", |t, r, o| t.any_hits(r, o), file, rays, count, occluded) }
}

/// [`bvhc_any_hits`] for coherent rays: each 8 consecutive rays traced together (`Tracer::any_hits_coherent`,
/// the same answers).
///
/// # Safety
///
/// As [`bvhc_any_hits`].
#[unsafe(no_mangle)]
pub unsafe extern "C" fn bvhc_any_hits_coherent(
    file: *const BvhcFile,
    rays: *const BvhcRay,
    count: usize,
    occluded: *mut u8,
) -> c_int {
    // SAFETY: the caller's contract is this function's.
    unsafe { any_hits("bvhc_any_hits_coherent", |t, r, o| t.any_hits_coherent(r, o), file, rays, count, occluded) }
}

/// The batch any-hit calls, tracing with `trace`.
///
/// # Safety
///
/// As [`bvhc_any_hits`].
unsafe fn any_hits(
    name: &str,
    trace: fn(&Tracer<'_>, &[Ray], &mut [bool]),
    file: *const BvhcFile,
    rays: *const BvhcRay,
    count: usize,
    occluded: *mut u8,
) -> c_int {
    guarded(|| {
        // SAFETY: the caller's contract is this function's.
        let Some((file, rays)) =
            (unsafe { batch_input(name, file, rays, count, occluded.is_null(), "rays and occluded") })?
        else {
            return Ok(BVHC_OK);
        };
        // SAFETY: not null (checked by `batch_input`), and by the contract it points to `count` elements.
        let occluded = unsafe { std::slice::from_raw_parts_mut(occluded, count) };
        let mut flags = vec![false; count.min(CHUNK_RAYS)];
        for (rays, occluded) in rays.chunks(CHUNK_RAYS).zip(occluded.chunks_mut(CHUNK_RAYS)) {
            let flags = &mut flags[..rays.len()];
            trace(file.tracer(), rays, flags);
            for (flag, out) in flags.iter().zip(occluded) {
                *out = u8::from(*flag);
            }
        }
        Ok(BVHC_OK)
    })
}

/// The file of a batch call and its rays.
type BatchInput<'f> = (&'f BvhcFile, &'f [BvhcRay]);

/// What every batch call checks first: the file, and its `count` rays; `None` for an empty batch (nothing to
/// check or write). Argument errors name the call and, when a pointer is null, the `arrays` that must not be
/// (`outputs_null`: whether one of the call's output arrays is).
///
/// # Safety
///
/// `file` is null or a live file; `rays` is null or points to `count` rays that stay unchanged during the call.
unsafe fn batch_input<'f>(
    name: &str,
    file: *const BvhcFile,
    rays: *const BvhcRay,
    count: usize,
    outputs_null: bool,
    arrays: &str,
) -> Result<Option<BatchInput<'f>>, (c_int, String)> {
    // SAFETY: by the contract `file` is null or live.
    let file = unsafe { file.as_ref() }.ok_or_else(|| argument(&format!("{name}: file is null")))?;
    if count == 0 {
        return Ok(None);
    }
    if rays.is_null() || outputs_null {
        return Err(argument(&format!("{name}: {arrays} must not be null")));
    }
    // SAFETY: not null, and by the contract it points to `count` rays.
    Ok(Some((file, unsafe { std::slice::from_raw_parts(rays, count) })))
}

/// Rays a batch traces at a time: the results' buffer before their conversion to C records stays in the caches
/// and its memory bounded, whatever the batch's size (a batch is traced as its chunks one after the other, with
/// the same results, since every ray's hit is its own). A multiple of 8, so coherent calls keep their groups.
const CHUNK_RAYS: usize = 4096;
const _: () = assert!(CHUNK_RAYS.is_multiple_of(8));
